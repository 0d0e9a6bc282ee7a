// Provot's constraint sweeps (sim_loop/cloth_constraints.cc) against a naive one-pair-at-a-time
// Gauss-Seidel reference, and what the multiresolution families buy. White-box: ApplyProvot is
// called directly through sim_loop/cloth_internal.h.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <random>
#include <set>
#include <tuple>
#include <utility>
#include <vector>

#include "base/simd.h"
#include "sim_loop/cloth.h"
#include "sim_loop/cloth_internal.h"
#include "tests/sim_loop/cloth_test_util.h"

namespace felt {
namespace {

using cloth_test::Curtain;

// The relaxation factor of cloth_constraints.cc (1: plain projection), which the reference repeats
// (the limits and the convergence tolerance come from ProvotLimitsOf).
constexpr float kRelaxation = 1.0f;

// Every pair of a family's runs, in sweep order (ProvotFamily::runs).
std::vector<std::pair<int32_t, int32_t>> PairsOf(const ProvotFamily& f, int32_t width) {
  std::vector<std::pair<int32_t, int32_t>> pairs;
  const int32_t off = f.dr * width + f.dc;
  for (const ProvotFamily::Run& run : f.runs) {
    if (f.strided()) {
      for (int32_t c = run.lo; c < run.hi; c += 2 * f.dc) {
        for (int32_t k = 0; k < f.dc && c + k < run.hi; ++k)
          pairs.emplace_back(c + k, c + k + f.dc);
      }
    } else {
      for (int32_t p = run.lo; p < run.hi; ++p) pairs.emplace_back(p, p + off);
    }
  }
  return pairs;
}

// Provot 1995 with Jakobsen's square-root-free length, one pair at a time in sweep order, in
// single precision relative to the first particle: what ApplyProvot must compute, bit for bit.
void ReferenceProvot(const ClothModel& model, double h_s, ClothState* state) {
  const size_t n = state->x.size();
  const Vec3 origin = state->x[0];
  std::vector<Eigen::Vector3f> before(n), x(n);
  for (size_t p = 0; p < n; ++p) {
    for (int k = 0; k < 3; ++k) before[p][k] = static_cast<float>(state->x[p][k] - origin[k]);
  }
  x = before;
  for (const PinAttachment& a : model.attachments) {
    const float dx = x[a.particle].x() - x[a.pin].x(), dy = x[a.particle].y() - x[a.pin].y(),
                dz = x[a.particle].z() - x[a.pin].z();
    const float len2 = dx * dx + dy * dy + dz * dz;
    const float max_len = static_cast<float>(a.max_length_m);
    if (len2 <= max_len * max_len) continue;
    const float len = std::sqrt(len2);
    const float scale = (len - max_len) / len;
    x[a.particle].x() -= scale * dx;
    x[a.particle].y() -= scale * dy;
    x[a.particle].z() -= scale * dz;
  }
  for (int32_t sweep = 0; sweep < model.provot_iterations; ++sweep) {
    bool loose = false;
    for (const ProvotFamily& f : model.provot_families) {
      if (f.level > 1 && sweep >= model.provot_coarse_sweeps) continue;
      const ProvotLimits lim = ProvotLimitsOf(f);
      for (const auto& [p, q] : PairsOf(f, model.width)) {
        const float dx = x[q].x() - x[p].x(), dy = x[q].y() - x[p].y(), dz = x[q].z() - x[p].z();
        const float len2 = dx * dx + dy * dy + dz * dz;
        const float over = len2 - lim.max2;
        const float excess = over > 0.0f ? over : 0.0f;
        const float wp = model.provot_movable[p], wq = model.provot_movable[q];
        const float share = 1.0f - 0.5f * (wp * wq);
        const float s = kRelaxation * excess / (len2 + lim.max2) * share;
        x[p].x() += wp * s * dx;
        x[p].y() += wp * s * dy;
        x[p].z() += wp * s * dz;
        x[q].x() -= wq * s * dx;
        x[q].y() -= wq * s * dy;
        x[q].z() -= wq * s * dz;
        loose = loose || len2 > lim.loose2;
      }
    }
    if (!loose) break;
  }
  const double inv_h = 1.0 / h_s;
  for (size_t p = 0; p < n; ++p) {
    for (int k = 0; k < 3; ++k) {
      const double move = static_cast<double>(x[p][k]) - static_cast<double>(before[p][k]);
      state->x[p][k] += move;
      state->v[p][k] += inv_h * move;
    }
  }
}

// A state with every particle displaced at random by up to `amplitude` of the spacing per axis,
// so that most pairs are over their limits.
// `model`'s rest state scrambled (cloth_test::ScrambledState, not stretched).
ClothState Scrambled(const ClothModel& model, double amplitude, uint32_t seed) {
  return cloth_test::ScrambledState(model, amplitude, 1.0, seed);
}

using cloth_test::BitwiseEqual;

TEST(ProvotTest, RunsVisitEveryPairOfEveryFamilyOnceAndColoursShareNoParticle) {
  for (int32_t grid : {5, 13, 64}) {
    SimSpec spec = Curtain(grid);
    const ClothModel model = BuildClothModel(spec);
    ASSERT_FALSE(model.provot_families.empty());
    int64_t total = 0;
    for (const ProvotFamily& f : model.provot_families) {
      const auto pairs = PairsOf(f, model.width);
      total += static_cast<int64_t>(pairs.size());
      // Every grid pair (c, r)-(c + dc, r + dr) exactly once.
      std::set<std::pair<int32_t, int32_t>> seen(pairs.begin(), pairs.end());
      EXPECT_EQ(seen.size(), pairs.size()) << grid << " (" << f.dc << ", " << f.dr << ")";
      int64_t expected = 0;
      for (int32_t r = 0; r + f.dr < grid; ++r) {
        for (int32_t c = 0; c < grid; ++c) {
          if (c + f.dc < 0 || c + f.dc >= grid) continue;
          ++expected;
          EXPECT_TRUE(seen.count({r * grid + c, (r + f.dr) * grid + c + f.dc}));
        }
      }
      EXPECT_EQ(static_cast<int64_t>(pairs.size()), expected);
      // Two colours, each a run of consecutive entries whose pairs share no particle: the
      // first pair of the second colour is the first one whose particle was already used.
      std::vector<int> used(static_cast<size_t>(grid * grid), 0);
      int colour = 0;
      for (const auto& [p, q] : pairs) {
        if (used[p] > colour || used[q] > colour) {
          ++colour;
          ASSERT_LE(colour, 1) << grid << " (" << f.dc << ", " << f.dr << ")";
          std::fill(used.begin(), used.end(), 0);
        }
        used[p] = used[q] = colour + 1;
      }
    }
    EXPECT_EQ(ProvotPairCount(model), total);
  }
}

TEST(ProvotTest, AttachmentsHoldEveryFreeParticleToTheNearestPinOfEachPinGroup) {
  // Against a brute-force reference: the groups are the corners or edges declared, each particle
  // attached to the nearest pin of every group (of the four nearest groups), the nearest group
  // first, at (1 + e) times the straight rest distance; and the dense ranks hold the same.
  struct Case {
    std::vector<PinSpec> pins;
    std::vector<std::vector<int32_t>> groups;  // by particle index on a 9 x 9 grid
  };
  const PinSpec top_edge = cloth_test::EdgePin("top");
  const PinSpec single = cloth_test::ParticlePin(4, 6);
  std::vector<int32_t> top_row(9);
  for (int32_t c = 0; c < 9; ++c) top_row[static_cast<size_t>(c)] = c;
  const std::vector<Case> cases = {
      {{cloth_test::Corner("top_left"), cloth_test::Corner("top_right")}, {{0}, {8}}},
      {{top_edge}, {top_row}},
      {{top_edge, single}, {top_row, {6 * 9 + 4}}},
      {{cloth_test::Corner("top_left"), cloth_test::Corner("top_right"),
        cloth_test::Corner("bottom_left")},
       {{0}, {8}, {72}}},
      // Five groups: the four nearest of each particle.
      {{cloth_test::Corner("top_left"), cloth_test::Corner("top_right"),
        cloth_test::Corner("bottom_left"), cloth_test::Corner("bottom_right"), single},
       {{0}, {8}, {72}, {80}, {6 * 9 + 4}}},
  };
  for (size_t k = 0; k < cases.size(); ++k) {
    SimSpec spec = Curtain(9);
    spec.cloth.pins = cases[k].pins;
    const ClothModel model = BuildClothModel(spec);
    std::vector<PinAttachment> expected;
    for (int32_t p = 0; p < model.num_particles(); ++p) {
      if (model.inv_mass_per_kg[p] == 0.0) continue;
      std::vector<std::pair<double, int32_t>> nearest;
      for (const std::vector<int32_t>& group : cases[k].groups) {
        std::pair<double, int32_t> best{1e300, -1};
        for (int32_t q : group) {
          best = std::min(best, {(model.rest_position_m[q] - model.rest_position_m[p]).norm(), q});
        }
        nearest.push_back(best);
      }
      std::stable_sort(nearest.begin(), nearest.end(),
                       [](const auto& a, const auto& b) { return a.first < b.first; });
      nearest.resize(std::min<size_t>(nearest.size(), 4));
      for (const auto& [d, q] : nearest) {
        expected.push_back({p, q, (1.0 + spec.provot.max_elongation) * d});
      }
    }
    ASSERT_EQ(model.attachments.size(), expected.size()) << "case " << k;
    for (size_t i = 0; i < expected.size(); ++i) {
      EXPECT_EQ(model.attachments[i].particle, expected[i].particle) << "case " << k << " " << i;
      EXPECT_EQ(model.attachments[i].pin, expected[i].pin) << "case " << k << " " << i;
      EXPECT_NEAR(model.attachments[i].max_length_m, expected[i].max_length_m, 1e-12)
          << "case " << k << " " << i;
    }
    const size_t n = static_cast<size_t>(model.num_particles());
    const size_t ranks = std::min<size_t>(cases[k].groups.size(), 4);
    ASSERT_EQ(model.attachment_ranks, static_cast<int32_t>(ranks)) << "case " << k;
    size_t next = 0;
    for (size_t p = 0; p < n; ++p) {
      for (size_t r = 0; r < ranks; ++r) {
        const int32_t pin = model.attachment_pin[r * n + p];
        const float max_len = model.attachment_max_m[r * n + p];
        if (model.inv_mass_per_kg[p] == 0.0) {
          EXPECT_EQ(pin, static_cast<int32_t>(p));
          EXPECT_EQ(max_len, 0.0f);
          continue;
        }
        EXPECT_EQ(pin, expected[next].pin) << "case " << k << " particle " << p << " rank " << r;
        EXPECT_EQ(max_len, static_cast<float>(expected[next].max_length_m));
        ++next;
      }
    }
    EXPECT_EQ(next, expected.size());
  }
}

TEST(ProvotTest, ColouredSweepsGiveTheBitsOfNaiveGaussSeidel) {
  // At the widest kernel level this CPU runs (every other level gives its bits:
  // SimdKernelsTest); odd and even grids (the vector kernels' tails), every sweep setting.
  for (int32_t grid : {7, 13, 32, 64}) {
    for (const cloth_test::ProvotCase& c : cloth_test::kProvotCases) {
      // The sweeps alone (the finishing worklist has its own tests).
      SimSpec spec = cloth_test::WithProvotCase(Curtain(grid), c);
      spec.provot.finish = false;
      const ClothModel model = BuildClothModel(spec);
      ClothState fast = Scrambled(model, 0.4, 7u + static_cast<uint32_t>(grid));
      ClothState naive = Scrambled(model, 0.4, 7u + static_cast<uint32_t>(grid));
      const double h = 1.0 / 600.0;
      ApplyProvot(model, h, &fast);
      ReferenceProvot(model, h, &naive);
      const std::string name = cloth_test::ProvotCaseName(grid, c);
      EXPECT_TRUE(BitwiseEqual(fast.x, naive.x)) << name;
      EXPECT_TRUE(BitwiseEqual(fast.v, naive.v)) << name;
    }
  }
}

// Largest length / limit over the springs the finishing worklist holds (structural and shear).
double WorstOverLimit(const ClothModel& model, const ClothState& state) {
  double worst = 0.0;
  for (const Spring& s : model.springs) {
    if (s.type == SpringType::kBend) continue;
    const double limit = 1.1 * s.rest_length_m;
    worst = std::max(worst, (state.x[s.j] - state.x[s.i]).norm() / limit);
  }
  return worst;
}

TEST(ProvotTest, FinishingWorklistLeavesNoSpringOverItsLimitAndKeepsVelocitiesConsistent) {
  // Scrambled states (every particle moved by up to 0.3 spacings per axis, the rows pulled 8 %
  // apart), one sweep and several, with and without the multiresolution families: after
  // ApplyProvot no structural or shear spring is longer than its limit (up to rounding), pins have
  // not moved, and every velocity changed by exactly its particle's move / h (to rounding). The
  // sweeps alone leave springs over in most of these cases (the control). The worklist is a
  // finisher, not a solver: a cloth pulled taut as a whole (rows 10 % apart and more) runs out of
  // its budget, counted in ClothCounters::limiter_unconverged.
  int left_over = 0;
  for (int32_t grid : {7, 13, 32, 64}) {
    for (const cloth_test::ProvotCase& c : cloth_test::kProvotCases) {
      const std::string name = cloth_test::ProvotCaseName(grid, c);
      SimSpec spec = cloth_test::WithProvotCase(Curtain(grid), c);
      const double h = 1.0 / 600.0;
      double without = 0.0;
      for (bool finish : {false, true}) {
        spec.provot.finish = finish;
        const ClothModel model = BuildClothModel(spec);
        ClothState state = cloth_test::ScrambledState(model, 0.3, 1.08, 5u + grid);
        const std::vector<Vec3> x0 = state.x, v0 = state.v;
        ApplyProvot(model, h, &state);
        const double worst = WorstOverLimit(model, state);
        if (!finish) {
          without = worst;
          left_over += worst > 1.0 + 1e-3 ? 1 : 0;
          EXPECT_EQ(state.counters.limiter_projections, 0u) << name;
          continue;
        }
        EXPECT_LE(worst, 1.0 + 1e-12) << name << " (sweeps alone: " << without << ")";
        EXPECT_EQ(state.counters.limiter_unconverged, 0u) << name;
        EXPECT_EQ(state.counters.limiter_projections > 0, without > 1.0) << name;
        for (int32_t p : model.pinned) EXPECT_EQ(state.x[p], x0[p]) << name;
        double v_error = 0.0;
        for (size_t p = 0; p < x0.size(); ++p) {
          const Vec3 dv = state.v[p] - v0[p], dx_over_h = (state.x[p] - x0[p]) / h;
          v_error = std::max(v_error, (dv - dx_over_h).norm() / (1.0 + dx_over_h.norm()));
        }
        EXPECT_LT(v_error, 1e-9) << name << ": v += dx / h";
      }
    }
  }
  EXPECT_GE(left_over, 12) << "cases of 16 where the sweeps alone left a spring over its limit";
}

TEST(ProvotTest, AWorklistOutOfBudgetLeavesTheSweepsResult) {
  // A cloth pulled taut as a whole (rows 50 % apart, one sweep, no multiresolution families) is
  // more than the worklist can finish: it runs
  // out of its budget, and then everything it moved goes back, so ApplyProvot leaves exactly the
  // sweeps' result (positions and velocities, bit for bit), not a half-finished projection. Without
  // the undo, scenes/self_rail_twist.toml (a pin carried past the cloth's reach) ran out in every
  // substep and reached 32 times the rest length at 58 m/s against the self-collision response.
  for (int32_t grid : {32, 64}) {
    SCOPED_TRACE(grid);
    SimSpec spec = Curtain(grid);
    spec.provot.iterations = 1;
    spec.provot.multiresolution = false;
    std::vector<ClothState> after;
    for (bool finish : {false, true}) {
      spec.provot.finish = finish;
      const ClothModel model = BuildClothModel(spec);
      ClothState state = cloth_test::ScrambledState(model, 0.3, 1.5, 11u + grid);
      ApplyProvot(model, 1.0 / 600.0, &state);
      EXPECT_EQ(state.counters.limiter_unconverged, finish ? 1u : 0u);
      EXPECT_EQ(state.counters.limiter_projections > 0, finish);
      after.push_back(std::move(state));
    }
    EXPECT_TRUE(BitwiseEqual(after[0].x, after[1].x));
    EXPECT_TRUE(BitwiseEqual(after[0].v, after[1].v));
  }
}

TEST(ProvotTest, SweepsNeverMovePinsAndOnlyShortenPairs) {
  SimSpec spec = Curtain(20);
  spec.provot.iterations = 3;
  const ClothModel model = BuildClothModel(spec);
  ClothState state = Scrambled(model, 0.4, 3u);
  const std::vector<Vec3> before = state.x;
  ApplyProvot(model, 1.0 / 600.0, &state);
  for (int32_t p : model.pinned) EXPECT_EQ(state.x[p], before[p]);
  // Every structural spring that was over the limit is shorter than it was.
  for (const Spring& s : model.springs) {
    if (s.type != SpringType::kStructural) continue;
    const double was = (before[s.j] - before[s.i]).norm();
    const double now = (state.x[s.j] - state.x[s.i]).norm();
    if (was > 1.5 * s.rest_length_m) {
      EXPECT_LT(now, was);
    }
  }
}

TEST(ProvotTest, MultiresolutionLowersTheReleasePeakAtEqualSweeps) {
  // A 32 x 32 two-corner curtain released from rest, 3 sweeps a substep: the peak stretch of the
  // first second with the multiresolution families against without (the transient peaks at
  // frames 5-8). Measured: 1.10-1.12 with, 1.2-1.3 without (bench/results/cloth.md).
  double peak[2] = {0.0, 0.0};
  for (int m = 0; m < 2; ++m) {
    SimSpec spec = Curtain(32);
    spec.provot.iterations = 3;
    spec.provot.multiresolution = m == 1;
    spec.provot.finish = false;  // the sweeps alone (with it both hold 1.10)
    const ClothModel model = BuildClothModel(spec);
    ClothState state = MakeClothState(model);
    for (int f = 0; f < 60; ++f) {
      StepFrame(model, {}, 1.0 / 60.0, &state);
      peak[m] = std::max(peak[m], MaxStretch(model, state));
    }
  }
  EXPECT_LT(peak[1], peak[0] - 0.03) << "without " << peak[0] << ", with " << peak[1];
  EXPECT_LT(peak[1], 1.15);
}

TEST(ProvotTest, AttachmentsStopTheMultiresolutionLevelsAtStrideEight) {
  // With long range attachments the levels go 8, 4, 2 (the attachments hold what coarser levels
  // did: sim_loop/cloth_build.cc, kMaxAttachedStride); without them, or with no pin to attach to,
  // up to the largest power of two below the grid's side (32 at 64 x 64). Sweep order: coarse
  // to fine, the spring families (level 1) last.
  const auto levels = [](bool attachments, bool pins) {
    SimSpec spec = Curtain(64);
    spec.provot.long_range_attachments = attachments;
    if (!pins) spec.cloth.pins.clear();
    const ClothModel model = BuildClothModel(spec);
    std::vector<int32_t> out;
    for (const ProvotFamily& f : model.provot_families) out.push_back(f.level);
    return out;
  };
  for (const auto& [attachments, pins, coarsest] :
       {std::tuple{true, true, 8}, std::tuple{false, true, 32}, std::tuple{true, false, 32}}) {
    const std::vector<int32_t> l = levels(attachments, pins);
    ASSERT_FALSE(l.empty());
    EXPECT_EQ(l.front(), coarsest) << "attachments " << attachments << " pins " << pins;
    EXPECT_TRUE(std::is_sorted(l.rbegin(), l.rend())) << "coarse to fine";
    EXPECT_EQ(l.back(), 1);
    // Rows, columns and both diagonals (shear is constrained) at every level above 1.
    for (int32_t s = 2; s <= coarsest; s *= 2) EXPECT_EQ(std::count(l.begin(), l.end(), s), 4) << s;
    EXPECT_EQ(std::count(l.begin(), l.end(), 2 * coarsest), 0);
  }
}

TEST(ProvotTest, MultiresolutionHoldsTheShearSpringsOfAHangingCurtain) {
  // A 32 x 32 two-corner curtain after 2 s: its tension runs along diagonals from the pins, which
  // the diagonal levels carry in one sweep. Shear springs, multiresolution on against off: 1.1023
  // against 1.1253 measured. (With row and column levels only and 1.5 over-relaxation, the 64 x 64
  // curtain's shear springs stayed 13 % long: bench/results/cloth.md before 2026-11-22.)
  double shear[2] = {0.0, 0.0};
  for (int m = 0; m < 2; ++m) {
    SimSpec spec = Curtain(32);
    spec.provot.multiresolution = m == 1;
    spec.provot.finish = false;  // the sweeps alone (with it both hold 1.10)
    // The sweeps alone, at the substep count these figures were measured at (6; auto_safety 0.5).
    // At the shipped 0.75 (4 substeps) the sweeps alone leave 1.1123 with the levels; the shipped
    // limiter, finishing worklist included, holds 1.10 there
    // (ClothStepTest.ShippedSettingsHoldTheStretchLimitAfterEveryFrame).
    spec.integration.auto_safety = 0.5;
    const ClothModel model = BuildClothModel(spec);
    ClothState state = MakeClothState(model);
    for (int f = 0; f < 120; ++f) StepFrame(model, {}, 1.0 / 60.0, &state);
    shear[m] = MaxStretchOf(model, state, SpringType::kShear);
  }
  EXPECT_LT(shear[1], shear[0] - 0.01) << "without " << shear[0] << ", with " << shear[1];
  EXPECT_LT(shear[1], 1.11);
}

TEST(ProvotTest, SinglePrecisionSweepsWorkAsWellFarFromTheOrigin) {
  // The sweeps run in float on positions relative to the first particle: the same cloth 10 km
  // from the origin gets the same moves to 0.1 um (a float ulp of the relative positions is ~30 nm;
  // float positions alone would be ~1 mm apart there).
  SimSpec spec = Curtain(32);
  const ClothModel model = BuildClothModel(spec);
  ClothState near = Scrambled(model, 0.4, 11u);
  ClothState far = Scrambled(model, 0.4, 11u);
  const Vec3 shift(1e4, -2e4, 5e3);
  // Pins are put back at their rest places after each substep, so shift the whole state (and keep
  // ApplyProvot alone: it never reads the rest places).
  for (Vec3& x : far.x) x += shift;
  const std::vector<Vec3> near0 = near.x, far0 = far.x;
  ApplyProvot(model, 1.0 / 600.0, &near);
  ApplyProvot(model, 1.0 / 600.0, &far);
  double worst = 0.0;
  for (size_t p = 0; p < near.x.size(); ++p) {
    worst = std::max(worst, ((far.x[p] - far0[p]) - (near.x[p] - near0[p])).norm());
  }
  EXPECT_LT(worst, 1e-7) << "largest difference in a particle's move, m";
}

TEST(ProvotTest, ACurtainWithinItsLimitsKeepsEveryBit) {
  // Nothing over its limit: no particle moves, positions and velocities keep every bit (the moves
  // are added back to the double-precision state, not the float positions copied back).
  const ClothModel model = BuildClothModel(Curtain(20));
  ClothState state = MakeClothState(model);
  std::mt19937 rng(5u);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (Vec3& v : state.v) v = Vec3(u(rng), u(rng), u(rng));
  // Off the float grid: a rest place plus a fraction of a nanometre.
  for (Vec3& x : state.x) x += 1e-10 * Vec3(u(rng), u(rng), u(rng));
  const std::vector<Vec3> x0 = state.x, v0 = state.v;
  ApplyProvot(model, 1.0 / 600.0, &state);
  EXPECT_TRUE(BitwiseEqual(state.x, x0));
  EXPECT_TRUE(BitwiseEqual(state.v, v0));
}

}  // namespace
}  // namespace felt
