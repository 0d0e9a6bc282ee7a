// Every vector kernel of sim_loop (base/simd.h's levels) against its portable reference, bit
// for bit: at each level this CPU has, the spring forces (ComputeAccelerations, and streamed a row
// at a time by StreamAccelerations), Provot's sweeps
// with and without the multiresolution families, the long range attachments and the
// structure-of-arrays conversion (ApplyProvot) and the exact AABB repair (Bvh::Repair) must give
// the memcmp-equal output of the portable level, on scrambled states of grids whose sizes are and
// are not multiples of the vector widths (4 doubles, 8 and 16 floats).
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "base/simd.h"
#include "collision/bvh.h"
#include "sim_loop/cloth.h"
#include "sim_loop/cloth_coupling.h"
#include "sim_loop/cloth_internal.h"
#include "tests/collision/collision_test_util.h"
#include "tests/sim_loop/cloth_test_util.h"

namespace felt::simd_test {
namespace {

using cloth_test::BitwiseEqual;
using cloth_test::Curtain;

// Grid sizes: narrower than one vector, odd, even but not a multiple of 4, 8 or 16, and 64.
constexpr int32_t kGrids[] = {3, 5, 10, 33, 64};

// The levels above kPortable that this CPU runs (each is compared with kPortable).
std::vector<SimdLevel> VectorLevels() {
  std::vector<SimdLevel> levels;
  for (SimdLevel l : {SimdLevel::kAvx2, SimdLevel::kAvx512}) {
    if (l <= CpuSimdLevel()) levels.push_back(l);
  }
  return levels;
}

// Runs `run` with every kernel capped at `level`, then lifts the cap.
template <class Run>
auto AtLevel(SimdLevel level, Run run) {
  LimitSimdLevel(level);
  auto out = run();
  LimitSimdLevel(kWidestSimdLevel);
  return out;
}

// True if the two arrays hold the same bits.
template <class T>
bool SameBits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

using cloth_test::ScrambledState;

// A curtain `grid` wide and grid + 2 high (rows and columns differ), with drag.
SimSpec CurtainSpec(int32_t grid) {
  SimSpec spec = Curtain(grid);
  spec.cloth.height = grid + 2;
  spec.cloth.drag_N_s_per_m = 3e-4;
  return spec;
}

// What ComputeAccelerations leaves: the accelerations and the summed forces fx, fy, fz (before
// the division by the mass, which could hide a last-bit difference).
struct SpringOutput {
  std::vector<Vec3> accel;
  std::vector<double> force;
};

SpringOutput SpringForcesAt(SimdLevel level, const ClothModel& model, uint32_t seed) {
  return AtLevel(level, [&] {
    ClothState state = ScrambledState(model, 0.4, 1.0, seed);
    SpringOutput out;
    out.accel.resize(state.x.size());
    ComputeAccelerations(model, state.x, state.v, state.scratch.get(), out.accel);
    const size_t n = state.x.size(), stride = SoaStride(n);
    const double* soa = state.scratch->soa.data();
    for (size_t k = 6; k < 9; ++k)
      out.force.insert(out.force.end(), soa + k * stride, soa + k * stride + n);
    return out;
  });
}

TEST(SimdKernelsTest, SpringForcesGiveThePortableBitsAtEveryLevel) {
  // Widths 3 and 5 give families with offsets below 4 (the two-pass path); the wider grids the
  // both-ends kernel with tails of every length.
  for (int32_t grid : kGrids) {
    const ClothModel model = BuildClothModel(CurtainSpec(grid));
    const uint32_t seed = 5u + static_cast<uint32_t>(grid);
    const SpringOutput portable = SpringForcesAt(SimdLevel::kPortable, model, seed);
    for (SimdLevel level : VectorLevels()) {
      const SpringOutput got = SpringForcesAt(level, model, seed);
      EXPECT_TRUE(SameBits(got.force, portable.force)) << grid << " " << SimdLevelName(level);
      EXPECT_TRUE(BitwiseEqual(got.accel, portable.accel)) << grid << " " << SimdLevelName(level);
    }
  }
}

// Two contact springs pressing a scrambled state's cloth 3 mm deep at two triangles (one by a
// pinned corner), so that their accelerations land in several rows.
void PressTwice(const ClothModel& model, ClothState* state) {
  BeginCouplingFrame(&state->scratch->coupling);
  for (int32_t tri : {0, static_cast<int32_t>(model.triangles.size()) / 2 + 1}) {
    const Triangle& t = model.triangles[static_cast<size_t>(tri)];
    const Vec3 b(0.5, 0.3, 0.2);
    const Vec3 p = b[0] * state->x[t[0]] + b[1] * state->x[t[1]] + b[2] * state->x[t[2]];
    ExternalForce e;
    e.triangle = tri;
    e.barycentric = b;
    e.normal = Vec3::UnitZ();
    e.radius_m = 0.004;
    e.anchor_m = p - 0.003 * Vec3::UnitZ();
    e.stiffness_N_per_m = 40.0;
    e.max_force_N = 1.0;
    AddCouplingSpring(model, e, 1e-4, state);
  }
}

// StreamAccelerations at `level`: the rows it hands over, in order, each copied when handed (the
// sink then overwrites the row's positions and velocities with NaN, which a later row's forces
// would carry into its accelerations if they read them).
std::vector<Vec3> StreamedAt(SimdLevel level, const ClothModel& model, uint32_t seed,
                             bool pressed) {
  return AtLevel(level, [&] {
    ClothState state = ScrambledState(model, 0.4, 1.0, seed);
    if (pressed) PressTwice(model, &state);
    struct Sink {
      ClothState* state;
      int32_t width;
      int32_t next_row = 0;
      std::vector<Vec3> accel;
    } sink{&state, model.width, 0, {}};
    auto rows = [](void* context, int32_t row, const double* accel) {
      Sink& s = *static_cast<Sink*>(context);
      EXPECT_EQ(row, s.next_row++);
      const double nan = std::numeric_limits<double>::quiet_NaN();
      for (int32_t c = 0; c < s.width; ++c) {
        s.accel.emplace_back(accel[3 * c], accel[3 * c + 1], accel[3 * c + 2]);
        const size_t p = static_cast<size_t>(row * s.width + c);
        s.state->x[p] = s.state->v[p] = Vec3::Constant(nan);
      }
    };
    StreamAccelerations(model, state.x, state.v, state.scratch.get(), {&sink, rows});
    EXPECT_EQ(sink.next_row, model.height);
    return sink.accel;
  });
}

TEST(SimdKernelsTest, StreamedAccelerationsAreComputeAccelerationsBitsAtEveryLevel) {
  // The fused leapfrog's row-by-row accelerations (one pass over the particles) against
  // ComputeAccelerations at the portable level, with and without contact springs, on grids with
  // rows narrower than a vector, and with fewer rows than the bend springs reach.
  for (int32_t grid : kGrids) {
    for (bool pressed : {false, true}) {
      const ClothModel model = BuildClothModel(CurtainSpec(grid));
      const uint32_t seed = 11u + static_cast<uint32_t>(grid);
      ClothState state = ScrambledState(model, 0.4, 1.0, seed);
      if (pressed) PressTwice(model, &state);
      ASSERT_EQ(state.scratch->coupling.count, pressed ? 2 : 0);
      std::vector<Vec3> reference(state.x.size());
      AtLevel(SimdLevel::kPortable, [&] {
        ComputeAccelerations(model, state.x, state.v, state.scratch.get(), reference);
        return 0;
      });
      for (SimdLevel level : {SimdLevel::kPortable, SimdLevel::kAvx2, SimdLevel::kAvx512}) {
        if (level > CpuSimdLevel()) continue;
        EXPECT_TRUE(BitwiseEqual(StreamedAt(level, model, seed, pressed), reference))
            << grid << (pressed ? " pressed " : " ") << SimdLevelName(level);
      }
    }
  }
}

// ApplyProvot at `level` on a scrambled state: the positions and velocities it leaves.
std::vector<Vec3> ProvotAt(SimdLevel level, const ClothModel& model, double stretch,
                           uint32_t seed) {
  return AtLevel(level, [&] {
    ClothState state = ScrambledState(model, 0.4, stretch, seed);
    ApplyProvot(model, 1.0 / 600.0, &state);
    std::vector<Vec3> out = state.x;
    out.insert(out.end(), state.v.begin(), state.v.end());
    return out;
  });
}

TEST(SimdKernelsTest, ProvotSweepsGiveThePortableBitsAtEveryLevel) {
  for (int32_t grid : kGrids) {
    for (const cloth_test::ProvotCase& c : cloth_test::kProvotCases) {
      const ClothModel model = BuildClothModel(cloth_test::WithProvotCase(CurtainSpec(grid), c));
      const uint32_t seed = 7u + static_cast<uint32_t>(grid);
      const std::vector<Vec3> portable = ProvotAt(SimdLevel::kPortable, model, 1.0, seed);
      for (SimdLevel level : VectorLevels()) {
        EXPECT_TRUE(BitwiseEqual(ProvotAt(level, model, 1.0, seed), portable))
            << cloth_test::ProvotCaseName(grid, c) << " " << SimdLevelName(level);
      }
    }
  }
}

TEST(SimdKernelsTest, AttachmentsAndConversionGiveThePortableBitsAtEveryLevel) {
  // No sweep families: ApplyProvot is the conversion, the attachments and the conversion back.
  // The cloth stretched to 1.3 times its height, so that many particles are outside their balls.
  for (int32_t grid : kGrids) {
    SimSpec spec = CurtainSpec(grid);
    spec.provot.long_range_attachments = true;
    ClothModel model = BuildClothModel(spec);
    ASSERT_GT(model.attachment_ranks, 0) << grid;
    model.provot_families.clear();
    const uint32_t seed = 9u + static_cast<uint32_t>(grid);
    const std::vector<Vec3> portable = ProvotAt(SimdLevel::kPortable, model, 1.3, seed);
    // Not vacuous: the attachments moved particles (an unmoved one keeps every bit).
    const ClothState before = ScrambledState(model, 0.4, 1.3, seed);
    EXPECT_NE(std::memcmp(portable.data(), before.x.data(), before.x.size() * sizeof(Vec3)), 0)
        << grid;
    for (SimdLevel level : VectorLevels()) {
      EXPECT_TRUE(BitwiseEqual(ProvotAt(level, model, 1.3, seed), portable))
          << grid << " " << SimdLevelName(level);
    }
  }
}

// The boxes and counters of an exact AABB tree over `tree_cloth`'s triangles, repaired at `level`
// to every test cloth with the same triangles, twice over.
std::vector<PackedAabb> RepairsAt(SimdLevel level, const Bvh& start,
                                  const std::vector<testing::TestCloth>& cloths,
                                  const testing::TestCloth& tree_cloth) {
  return AtLevel(level, [&] {
    Bvh bvh = start;
    std::vector<PackedAabb> out;
    for (int pass = 0; pass < 2; ++pass) {
      for (const testing::TestCloth& c : cloths) {
        if (c.triangles != tree_cloth.triangles) continue;
        const RepairStats stats = bvh.Repair(c.x);
        out.insert(out.end(), bvh.aabbs().begin(), bvh.aabbs().end());
        // The counters as one more box's lanes (exact: they are far below 2^24).
        PackedAabb counters;
        counters.lo[0] = static_cast<float>(stats.node_updates);
        counters.lo[1] = static_cast<float>(stats.parents_refit);
        counters.lo[2] = static_cast<float>(stats.leaves_refit);
        out.push_back(counters);
      }
    }
    return out;
  });
}

TEST(SimdKernelsTest, BvhRepairsGiveThePortableBitsAtEveryLevel) {
  // (The test cloths need a grid of at least 5: the degenerate one edits column 6.)
  for (int32_t grid : {5, 10, 33, 64}) {
    const std::vector<testing::TestCloth> cloths =
        testing::MakeTestCloths(grid, 9u + static_cast<uint32_t>(grid));
    for (const testing::TestCloth& tree_cloth : {cloths.front(), cloths.back()}) {
      for (int32_t arity : {2, 4}) {
        const Bvh start(tree_cloth.triangles, cloths.front().x,
                        {BoundingVolume::kAabb, arity, BvhRepair::kBottomUp, 0.0});
        const std::vector<PackedAabb> portable =
            RepairsAt(SimdLevel::kPortable, start, cloths, tree_cloth);
        for (SimdLevel level : VectorLevels()) {
          EXPECT_TRUE(SameBits(RepairsAt(level, start, cloths, tree_cloth), portable))
              << grid << " " << tree_cloth.name << " arity " << arity << " "
              << SimdLevelName(level);
        }
      }
    }
  }
}

TEST(SimdKernelsTest, LimitCapsAtTheCpuLevelAndLifts) {
  const SimdLevel cpu = CpuSimdLevel();
  // At start: the CPU's level, capped by FELT_SIMD when the test runs with it set.
  EXPECT_EQ(ActiveSimdLevel(), StartedSimdLevel());
  EXPECT_LE(StartedSimdLevel(), cpu);
  LimitSimdLevel(SimdLevel::kPortable);
  EXPECT_EQ(ActiveSimdLevel(), SimdLevel::kPortable);
  LimitSimdLevel(SimdLevel::kAvx2);
  EXPECT_EQ(ActiveSimdLevel(), cpu < SimdLevel::kAvx2 ? cpu : SimdLevel::kAvx2);
  LimitSimdLevel(kWidestSimdLevel);
  EXPECT_EQ(ActiveSimdLevel(), cpu);
  EXPECT_STREQ(SimdLevelName(SimdLevel::kPortable), "portable");
  LimitSimdLevel(StartedSimdLevel());  // back to the cap the process started with
}

TEST(SimdKernelsTest, EnvNamesRoundTripAndUnknownNamesAreRejected) {
  for (SimdLevel level : {SimdLevel::kPortable, SimdLevel::kAvx2, SimdLevel::kAvx512}) {
    EXPECT_EQ(SimdLevelFromEnvName(SimdLevelEnvName(level)), level) << SimdLevelEnvName(level);
  }
  EXPECT_STREQ(SimdLevelEnvName(SimdLevel::kAvx512), "avx512");
  EXPECT_EQ(SimdLevelFromEnvName("AVX2"), std::nullopt);
  EXPECT_EQ(SimdLevelFromEnvName("avx512f+avx2"), std::nullopt);
  EXPECT_EQ(SimdLevelFromEnvName(""), std::nullopt);
}

}  // namespace
}  // namespace felt::simd_test
