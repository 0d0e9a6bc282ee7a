// The Provot sweeps' vector kernels skip a step of pairs that are all within their limits
// (sim_loop/cloth_constraints.cc, NothingToProject), but not a step holding a -0.0 coordinate,
// which the projection's +0 move turns into +0.0: so even the sweeps' single-precision positions
// keep the portable level's bits. A cloth at rest with -0.0 coordinates (relative to the first
// particle, the origin of those positions), every pair within its limit: at every level the
// single-precision positions ApplyProvot leaves and the state are the portable level's bits. (The
// state alone would not tell: a coordinate that started at -0.0 moves back by a - (-0.0), +0 for
// a = -0.0 and a = +0.0 alike; without the -0.0 test only the single-precision positions differ.)
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include "base/simd.h"
#include "sim_loop/cloth.h"
#include "sim_loop/cloth_internal.h"
#include "tests/sim_loop/cloth_test_util.h"

namespace felt::provot_skip_test {
namespace {

// What ApplyProvot leaves at `level` on `model`'s rest state (flat in z = 0) with z = -0.0 for
// every particle but the first (left at +0.0, so that the others' z relative to it is -0.0 too).
struct Result {
  std::vector<float> soa;  // the sweeps' x, y, z, [3 n]
  std::vector<Vec3> xv;    // the state's x then v
};

Result AtRestWithNegativeZeros(SimdLevel level, const ClothModel& model) {
  LimitSimdLevel(level);
  ClothState state = MakeClothState(model);
  for (size_t p = 1; p < state.x.size(); ++p) state.x[p].z() = -0.0;
  ApplyProvot(model, 1.0 / 600.0, &state);
  LimitSimdLevel(kWidestSimdLevel);
  Result out;
  const ClothState::Scratch& s = *state.scratch;
  const size_t n = state.x.size();
  for (size_t k = 0; k < 3; ++k) {
    const float* a = s.provot_soa.data() + s.provot_soa_first + k * s.provot_soa_stride;
    out.soa.insert(out.soa.end(), a, a + n);
  }
  out.xv = state.x;
  out.xv.insert(out.xv.end(), state.v.begin(), state.v.end());
  return out;
}

TEST(ProvotSweepSkipTest, NegativeZerosKeepThePortableBitsAtEveryLevel) {
  for (int32_t grid : {5, 10, 33, 64}) {
    const ClothModel model = BuildClothModel(cloth_test::Curtain(grid));
    const Result portable = AtRestWithNegativeZeros(SimdLevel::kPortable, model);
    // Not vacuous: the portable sweeps turned some of the -0.0 into +0.0.
    size_t positive = 0;
    for (size_t p = 1; p < model.rest_position_m.size(); ++p) {
      positive += std::signbit(portable.soa[2 * model.rest_position_m.size() + p]) ? 0 : 1;
    }
    EXPECT_GT(positive, 0u) << grid;
    for (SimdLevel level : {SimdLevel::kAvx2, SimdLevel::kAvx512}) {
      if (level > CpuSimdLevel()) continue;
      const Result got = AtRestWithNegativeZeros(level, model);
      EXPECT_EQ(std::memcmp(got.soa.data(), portable.soa.data(), got.soa.size() * sizeof(float)), 0)
          << grid << " " << SimdLevelName(level);
      EXPECT_TRUE(cloth_test::BitwiseEqual(got.xv, portable.xv))
          << grid << " " << SimdLevelName(level);
    }
  }
}

}  // namespace
}  // namespace felt::provot_skip_test
