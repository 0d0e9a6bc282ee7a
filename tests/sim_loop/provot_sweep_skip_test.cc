// The Provot sweeps' vector kernels skip a step of pairs that are all within their limits
// (sim_loop/cloth_constraints.cc, NothingToProject): its projection would move every coordinate by
// +0 or -0, which keeps its value but turns a -0.0 into +0.0, so a skipped step may leave a -0.0
// where the portable level has +0.0 in the single-precision positions; no result may see it. A
// cloth at rest whose coordinates are -0.0 relative to the first particle (the origin of those
// positions), every pair within its limit: at every level the single-precision positions hold the
// portable level's values, and the state its bits.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "base/simd.h"
#include "sim_loop/cloth.h"
#include "sim_loop/cloth_internal.h"
#include "tests/sim_loop/cloth_test_util.h"

namespace felt::provot_skip_test {
namespace {

// What ApplyProvot leaves at `level` on `model`'s rest state (flat in z = 0) stretched down from
// the top row by `stretch` (1: at rest, every pair within its limit), with z = -0.0 for every
// particle but the first (left at +0.0, so that the others' z relative to it is -0.0 too).
struct Result {
  std::vector<float> soa;  // the sweeps' x, y, z, [3 n]
  std::vector<Vec3> xv;    // the state's x then v
};

Result WithNegativeZeros(SimdLevel level, const ClothModel& model, double stretch) {
  LimitSimdLevel(level);
  ClothState state = MakeClothState(model);
  const double top = state.x[0].y();
  for (size_t p = 1; p < state.x.size(); ++p) {
    state.x[p].z() = -0.0;
    if (model.inv_mass_per_kg[p] > 0.0) state.x[p].y() = top + stretch * (state.x[p].y() - top);
  }
  ApplyProvot(model, 1.0 / 600.0, &state);
  LimitSimdLevel(kWidestSimdLevel);
  Result out;
  const size_t n = state.x.size();
  const ProvotSoaArrays arrays = ProvotSoaIn(&state.scratch->provot_soa, n);
  for (const float* a : {arrays.x, arrays.y, arrays.z}) out.soa.insert(out.soa.end(), a, a + n);
  out.xv = state.x;
  out.xv.insert(out.xv.end(), state.v.begin(), state.v.end());
  return out;
}

TEST(ProvotSweepSkipTest, NegativeZerosLeaveThePortableStateAtEveryLevel) {
  for (int32_t grid : {5, 10, 33, 64}) {
    const ClothModel model = BuildClothModel(cloth_test::Curtain(grid));
    // At rest (every step skipped), and stretched to 1.3 times its height (steps projected, with
    // moves of +-0 in z).
    for (double stretch : {1.0, 1.3}) {
      const Result portable = WithNegativeZeros(SimdLevel::kPortable, model, stretch);
      // Not vacuous: the portable sweeps turned some of the -0.0 into +0.0.
      size_t positive = 0;
      for (size_t p = 1; p < model.rest_position_m.size(); ++p) {
        positive += std::signbit(portable.soa[2 * model.rest_position_m.size() + p]) ? 0 : 1;
      }
      EXPECT_GT(positive, 0u) << grid << " " << stretch;
      for (SimdLevel level : {SimdLevel::kAvx2, SimdLevel::kAvx512}) {
        if (level > CpuSimdLevel()) continue;
        const Result got = WithNegativeZeros(level, model, stretch);
        // As values (a zero's sign may differ), then the state bit for bit.
        EXPECT_EQ(got.soa, portable.soa) << grid << " " << stretch << " " << SimdLevelName(level);
        EXPECT_TRUE(cloth_test::BitwiseEqual(got.xv, portable.xv))
            << grid << " " << stretch << " " << SimdLevelName(level);
      }
    }
  }
}

}  // namespace
}  // namespace felt::provot_skip_test
