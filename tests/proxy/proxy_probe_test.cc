// ProbeProxy (proxy/proxy_probe.h): the reach into the tick's cloth and the pop-through flag on
// closed-form cases: a proxy resting on a flat sheet, and one forced through it.
#include "proxy/proxy_probe.h"

#include <gtest/gtest.h>

#include "proxy_test_util.h"

namespace felt {
namespace {

using testing::FlatSheet;
using testing::Snap;
using testing::Spec;
using testing::TickAt;
using testing::UnitDevice;

TEST(ProxyProbeTest, ProxyPressedOnASheetReachesNothingAndDoesNotPop) {
  const ClothSnapshot s = Snap(FlatSheet());
  const ProxyModel pm = CompileProxyModel(UnitDevice(0.004), Spec());
  ProxyState st = MakeProxyState(pm);
  ProxyProbeMemory memory;
  for (double z = 0.03; z >= -0.01 - 1e-12; z -= 0.001) {
    TickAt(pm, s, Vec3(0.013, 0.021, z), &st);
    const ProxyProbe probe = ProbeProxy(pm, st, &memory);
    EXPECT_LT(probe.reach_m, 1e-9) << "z " << z;
    EXPECT_FALSE(probe.popped) << "z " << z;
  }
  EXPECT_GE(memory.triangle, 0);
  EXPECT_EQ(memory.side, 1);
}

TEST(ProxyProbeTest, ProxyMovedThroughTheSheetIsCountedAndItsReachIsMeasured) {
  const ClothSnapshot s = Snap(FlatSheet());
  const ProxyModel pm = CompileProxyModel(UnitDevice(0.004), Spec());
  ProxyState st = MakeProxyState(pm);
  ProxyProbeMemory memory;
  for (double z = 0.02; z >= -0.002 - 1e-12; z -= 0.001) {  // in contact, on the +z side
    TickAt(pm, s, Vec3(0.013, 0.021, z), &st);
    ProbeProxy(pm, st, &memory);
  }
  ASSERT_EQ(memory.side, 1);
  // Put the proxy 1 mm behind the sheet by hand (what a broken mode would do).
  st.body.p_W_m = Vec3(0.013, 0.021, -0.001);
  const ProxyProbe probe = ProbeProxy(pm, st, &memory);
  EXPECT_TRUE(probe.popped);
  EXPECT_NEAR(probe.reach_m, 0.003, 1e-12);
}

}  // namespace
}  // namespace felt
