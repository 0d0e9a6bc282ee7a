// ProxyModel (compiled once from the specs) and steps of ProxyTick tested alone: the choice of
// the tick's cloth by snapshot mode (ChooseTickCloth) and the force clamp (ClampDeviceForce).

#include "proxy/proxy_model.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "proxy/proxy.h"
#include "tests/proxy/proxy_test_util.h"

namespace felt {
namespace {

using testing::FlatSheet;
using testing::Snap;
using testing::TestMesh;

// The message of the std::invalid_argument CompileProxyModel throws, or "" if none.
std::string CompileError(const DeviceSpec& device, const ProxySpec& proxy) {
  try {
    CompileProxyModel(device, proxy);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(ProxyModelTest, CompiledConstantsAreTheTicksExpressions) {
  DeviceSpec d;
  d.stiffness_N_per_m = 437.0;
  d.scale = 2.7;
  d.max_force_N = 3.1;
  d.rotation_WD = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  d.offset_W_m = Vec3(0.1, -0.2, 0.3);
  ProxySpec p;
  p.friction_static = 0.3;
  p.friction_dynamic = 0.3;
  p.obstacles = {testing::Table()};
  const ProxyModel m = CompileProxyModel(d, p);
  EXPECT_EQ(m.stiffness_W_N_per_m, d.stiffness_N_per_m / (d.scale * d.scale));
  EXPECT_EQ(m.max_force_W_N, d.max_force_N / d.scale);
  EXPECT_EQ(m.friction_dynamic, 0.3);
  EXPECT_EQ(m.radius_m, d.radius_m);  // the one default: DeviceSpec's
  EXPECT_EQ(m.max_iterations, p.max_iterations);
  EXPECT_EQ(m.candidate_capacity, p.candidate_capacity);
  EXPECT_EQ(m.snapshot_mode, p.snapshot_mode);
  ASSERT_EQ(m.obstacles.size(), 1u);
  const Vec3 p_D(0.013, -0.021, 0.034);
  const Vec3 a = m.ToWorld(p_D);
  const Vec3 b = DeviceToWorld(d, p_D);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(a(i), b(i)) << i;  // bit for bit
}

TEST(ProxyModelTest, ValidationNamesTheField) {
  DeviceSpec d;
  d.radius_m = 0.0;
  EXPECT_EQ(CompileError(d, ProxySpec{}).rfind("device.radius_m: must be > 0", 0), 0u);
  d = DeviceSpec{};
  d.scale = -1.0;
  EXPECT_EQ(CompileError(d, ProxySpec{}).rfind("device.scale: must be > 0", 0), 0u);
  d = DeviceSpec{};
  d.damping_N_s_per_m = -0.1;
  EXPECT_EQ(CompileError(d, ProxySpec{}).rfind("device.damping_N_s_per_m", 0), 0u);
  ProxySpec p;
  p.max_iterations = 0;
  EXPECT_EQ(CompileError(DeviceSpec{}, p), "proxy.max_iterations: must be in [1, 100], got 0");
  p = ProxySpec{};
  p.candidate_capacity = 8;  // the scene parser's rule and message (proxy_scene_test)
  EXPECT_EQ(CompileError(DeviceSpec{}, p),
            "proxy.candidate_capacity: must be in [16, 65536], got 8");
  p = ProxySpec{};
  p.friction_static = 0.2;
  p.friction_dynamic = 0.3;
  EXPECT_EQ(CompileError(DeviceSpec{}, p),
            "proxy.friction_dynamic: must be <= friction_static (0.2), got 0.3");
  EXPECT_EQ(CompileError(DeviceSpec{}, ProxySpec{}), "");
}

TEST(ProxyModelTest, ClampKeepsSmallForcesAndTheDirectionOfLargeOnes) {
  DeviceSpec d;
  d.max_force_N = 2.0;
  const ProxyModel m = CompileProxyModel(d, ProxySpec{});
  const Vec3 small(0.5, -1.0, 0.25);
  const ClampedForce kept = ClampDeviceForce(m, small);
  EXPECT_FALSE(kept.clamped);
  EXPECT_EQ(kept.factor, 1.0);
  EXPECT_EQ(kept.force_D_N, small);
  const Vec3 large(3.0, 0.0, -4.0);  // 5 N
  const ClampedForce cut = ClampDeviceForce(m, large);
  EXPECT_TRUE(cut.clamped);
  EXPECT_EQ(cut.factor, 2.0 / 5.0);
  EXPECT_NEAR(cut.force_D_N.norm(), 2.0, 1e-12);
  EXPECT_NEAR((cut.force_D_N.normalized() - large.normalized()).norm(), 0.0, 1e-12);
}

TEST(ProxyModelTest, TickClothFollowsTheModeAndTheSnapshots) {
  const TestMesh sheet = FlatSheet();
  const std::vector<Vec3> zero(sheet.x.size(), Vec3::Zero());
  ClothSnapshot prev = Snap(sheet);
  ClothSnapshot next = Snap(sheet);
  testing::Refill(sheet.x, zero, 1, 0.0, 0.016, &prev);
  testing::Refill(sheet.x, zero, 2, 0.016, 0.016, &next);
  ProxySpec p;
  p.snapshot_mode = SnapshotMode::kInterpolate;
  const ProxyModel m = CompileProxyModel(DeviceSpec{}, p);
  ProxyState st = MakeProxyState(m);

  // Without a previous snapshot every mode acts as mode (a).
  const TickCloth alone = ChooseTickCloth(m, next, nullptr, 0.004, &st);
  EXPECT_EQ(alone.mode, SnapshotMode::kNewest);
  EXPECT_TRUE(alone.first);
  EXPECT_TRUE(alone.arrived);
  EXPECT_FALSE(alone.moved);
  EXPECT_EQ(alone.now.to, &next);
  EXPECT_EQ(st.counters.new_snapshots, 0u);

  // Mode (c), half a frame after the newest arrived: halfway from prev to next, one frame late.
  const TickCloth half = ChooseTickCloth(m, next, &prev, 0.008, &st);
  EXPECT_EQ(half.mode, SnapshotMode::kInterpolate);
  EXPECT_FALSE(half.first);
  EXPECT_FALSE(half.arrived);  // frame 2 was seen by the first call
  EXPECT_TRUE(half.interpolated);
  EXPECT_EQ(half.alpha, 0.5);
  EXPECT_EQ(half.now.from, &prev);
  EXPECT_EQ(half.now.to, &next);
  EXPECT_EQ(half.now.alpha, 0.5);

  // A previous snapshot of another cloth is ignored.
  const TestMesh other_mesh = FlatSheet(0.2, 5);
  const ClothSnapshot other = Snap(other_mesh);
  EXPECT_EQ(ChooseTickCloth(m, next, &other, 0.008, &st).mode, SnapshotMode::kNewest);

  // A newer frame arrives: counted, and the proxy is carried from the previous tick's cloth.
  std::swap(prev, next);
  testing::Refill(sheet.x, zero, 3, 0.032, 0.016, &next);
  const TickCloth arrived = ChooseTickCloth(m, next, &prev, 0.0, &st);
  EXPECT_TRUE(arrived.arrived);
  EXPECT_EQ(st.counters.new_snapshots, 1u);
  EXPECT_EQ(st.newest_frame, 3u);
  EXPECT_EQ(arrived.alpha, 0.0);
}

}  // namespace
}  // namespace felt
