// BuildClothModel: validation messages, topology, masses, pins, auto substeps; spring invariants.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <functional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "sim_loop/cloth.h"
#include "sim_loop/cloth_internal.h"
#include "tests/sim_loop/cloth_test_util.h"

namespace felt {
namespace {

using cloth_test::Corner;
using cloth_test::Curtain;

// The message BuildClothModel throws for `spec`, or "" if it does not throw.
std::string BuildError(const SimSpec& spec) {
  try {
    BuildClothModel(spec);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

struct BadSpec {
  std::function<void(SimSpec*)> edit;
  std::string message_start;
};

TEST(ClothModelTest, ValidationErrorsNameTheFieldAndRule) {
  const std::vector<BadSpec> cases = {
      {[](SimSpec* s) { s->cloth.width = 1; }, "cloth.width: must be in [2, 4096], got 1"},
      {[](SimSpec* s) { s->cloth.height = 0; }, "cloth.height: must be in [2, 4096], got 0"},
      {[](SimSpec* s) { s->cloth.width = 4097; }, "cloth.width: must be in [2, 4096], got 4097"},
      {[](SimSpec* s) {
         s->cloth.width = 4096;
         s->cloth.height = 2048;
       },
       "cloth.width: width * height must be <= 4194304, got 8388608"},
      {[](SimSpec* s) { s->cloth.spacing_m = 0.0; }, "cloth.spacing_m: must be > 0, got 0"},
      {[](SimSpec* s) { s->cloth.mass_kg = NAN; }, "cloth.mass_kg: must be finite"},
      {[](SimSpec* s) { s->cloth.u_axis = Vec3(2, 0, 0); }, "cloth.u_axis: must be a unit vector"},
      {[](SimSpec* s) { s->cloth.v_axis = Vec3::UnitX(); }, "cloth.v_axis: must be orthogonal"},
      {[](SimSpec* s) { s->cloth.structural->stiffness_N_per_m = -1; },
       "cloth.structural.stiffness_N_per_m: must be > 0, got -1"},
      {[](SimSpec* s) { s->cloth.shear->damping_N_s_per_m = -0.5; },
       "cloth.shear.damping_N_s_per_m: must be >= 0, got -0.5"},
      {[](SimSpec* s) { s->cloth.bend->stiffness_N_per_m = INFINITY; },
       "cloth.bend.stiffness_N_per_m: must be finite"},
      {[](SimSpec* s) { s->cloth.drag_N_s_per_m = -1; }, "cloth.drag_N_s_per_m: must be >= 0"},
      {[](SimSpec* s) { s->cloth.gravity_m_per_s2.y() = NAN; },
       "cloth.gravity_m_per_s2: must be finite"},
      {[](SimSpec* s) { s->cloth.pins.push_back(Corner("top_middle")); },
       "cloth.pins[2].name: unknown corner 'top_middle'"},
      {[](SimSpec* s) {
         PinSpec edge;
         edge.kind = PinKind::kEdge;
         edge.name = "middle";
         s->cloth.pins = {edge};
       },
       "cloth.pins[0].name: unknown edge 'middle'"},
      {[](SimSpec* s) {
         PinSpec p;
         p.kind = PinKind::kParticle;
         p.col = 32;
         s->cloth.pins.push_back(p);
       },
       "cloth.pins[2].col: must be in [0, 32), got 32"},
      {[](SimSpec* s) {
         PinSpec p;
         p.kind = PinKind::kParticle;
         p.row = -1;
         s->cloth.pins.push_back(p);
       },
       "cloth.pins[2].row: must be in [0, 32), got -1"},
      {[](SimSpec* s) { s->cloth.pins[1].motion.frequency_hz = -1; },
       "cloth.pins[1].motion.frequency_hz: must be >= 0, got -1"},
      {[](SimSpec* s) {
         s->cloth.pins[0].motion.start_s = 2;
         s->cloth.pins[0].motion.stop_s = 1;
       },
       "cloth.pins[0].motion.stop_s: must be >= start_s"},
      {[](SimSpec* s) {
         PinSpec moving = Corner("top_left");
         moving.motion.velocity_m_per_s = Vec3(0.1, 0, 0);
         s->cloth.pins.push_back(moving);
       },
       "cloth.pins[2]: particle (0, 0) is already held by cloth.pins[0] with a different motion"},
      {[](SimSpec* s) {
         s->cloth.obstacles.push_back({SphereSpec{Vec3::Zero(), 0.0}, 0, 0});
       },
       "cloth.obstacles[0].radius_m: must be > 0, got 0"},
      {[](SimSpec* s) {
         s->cloth.obstacles.push_back({PlaneSpec{}, 0, 0});
         s->cloth.obstacles.push_back({BoxSpec{Vec3(0, 0, 0), Vec3(1, 0, 1)}, 0, 0});
       },
       "cloth.obstacles[1].max_m: must be > min_m"},
      {[](SimSpec* s) {
         s->cloth.obstacles.push_back({PlaneSpec{Vec3::Zero(), Vec3(0, 2, 0)}});
       },
       "cloth.obstacles[0].normal: must be a unit vector"},
      {[](SimSpec* s) {
         s->cloth.obstacles.push_back({CapsuleSpec{Vec3::Zero(), Vec3::UnitX(), 0.1}, -0.1});
       },
       "cloth.obstacles[0].friction: must be >= 0, got -0.1"},
      {[](SimSpec* s) {
         s->cloth.obstacles.push_back({SphereSpec{}, 0.0, -1e-3});
       },
       "cloth.obstacles[0].margin_m: must be >= 0"},
      {[](SimSpec* s) { s->integration.substeps = -2; },
       "integration.substeps: must be in [0, 100000] (0 = auto), got -2"},
      {[](SimSpec* s) { s->integration.frame_rate_hz = 0; },
       "integration.frame_rate_hz: must be > 0, got 0"},
      {[](SimSpec* s) { s->integration.frame_rate_hz = 20000; },
       "integration.frame_rate_hz: must be in (0, 10000], got 20000"},
      {[](SimSpec* s) { s->integration.max_frame_dt_s = -1; },
       "integration.max_frame_dt_s: must be > 0"},
      {[](SimSpec* s) { s->integration.auto_safety = 1.5; },
       "integration.auto_safety: must be in (0, 1], got 1.5"},
      {[](SimSpec* s) { s->integration.cg_max_iterations = 0; },
       "integration.cg_max_iterations: must be >= 1, got 0"},
      {[](SimSpec* s) { s->integration.cg_tolerance = 0; },
       "integration.cg_tolerance: must be in (0, 1), got 0"},
      {[](SimSpec* s) { s->integration.integrator = static_cast<IntegratorKind>(42); },
       "integration.integrator: unknown integrator 42"},
      {[](SimSpec* s) { s->provot.max_elongation = -0.1; },
       "provot.max_elongation: must be > 0, got -0.10000000000000001"},
      {[](SimSpec* s) { s->provot.max_elongation = 0.0; },
       "provot.max_elongation: must be > 0, got 0"},
      {[](SimSpec* s) { s->provot.iterations = 0; },
       "provot.iterations: must be in [1, 10000], got 0"},
      {[](SimSpec* s) { s->provot.iterations = 10001; },
       "provot.iterations: must be in [1, 10000], got 10001"},
      {[](SimSpec* s) { s->provot.coarse_sweeps = 0; },
       "provot.coarse_sweeps: must be in [1, 10000], got 0"},
      {[](SimSpec* s) { s->provot.sweep_headroom = -0.1; },
       "provot.sweep_headroom: must be in [0, 0.5), got -0.10000000000000001"},
      {[](SimSpec* s) { s->provot.sweep_headroom = 0.5; },
       "provot.sweep_headroom: must be in [0, 0.5), got 0.5"},
      {[](SimSpec* s) {
         s->integration.integrator = IntegratorKind::kExplicitEuler;
         s->cloth.structural->damping_N_s_per_m = 0;
         s->cloth.shear.reset();
         s->cloth.bend.reset();
         s->cloth.drag_N_s_per_m = 0;
       },
       "integration.substeps: auto needs"},
  };
  for (size_t k = 0; k < cases.size(); ++k) {
    SimSpec spec = Curtain(32);
    cases[k].edit(&spec);
    const std::string message = BuildError(spec);
    EXPECT_EQ(message.rfind(cases[k].message_start, 0), 0u)
        << "case " << k << ": expected a message starting '" << cases[k].message_start << "', got '"
        << message << "'";
  }
  // The defaults (and the same corner pinned twice, fixed) are valid.
  SimSpec twice = Curtain(32);
  twice.cloth.pins.push_back(Corner("top_left"));
  EXPECT_EQ(BuildError(twice), "");
}

TEST(ClothModelTest, BuildsOnlyTheDeclaredSpringsAndTheGrid) {
  const int32_t w = 7, h = 5;
  SimSpec spec = Curtain(7);
  spec.cloth.height = h;
  const ClothModel all = BuildClothModel(spec);
  size_t counts[3] = {0, 0, 0};
  for (const Spring& s : all.springs) {
    ++counts[static_cast<int>(s.type)];
    const double rest = (all.rest_position_m[s.j] - all.rest_position_m[s.i]).norm();
    EXPECT_DOUBLE_EQ(s.rest_length_m, rest);
  }
  EXPECT_EQ(counts[0], static_cast<size_t>((w - 1) * h + w * (h - 1)));  // structural
  EXPECT_EQ(counts[1], static_cast<size_t>(2 * (w - 1) * (h - 1)));      // both diagonals
  EXPECT_EQ(counts[2], static_cast<size_t>((w - 2) * h + w * (h - 2)));  // skip-one
  EXPECT_EQ(all.triangles.size(), static_cast<size_t>(2 * (w - 1) * (h - 1)));

  spec.cloth.shear.reset();
  spec.cloth.bend.reset();
  const ClothModel structural_only = BuildClothModel(spec);
  EXPECT_EQ(structural_only.springs.size(), counts[0]);
  for (const Spring& s : structural_only.springs) EXPECT_EQ(s.type, SpringType::kStructural);

  // Rest places on the grid, masses uniform.
  EXPECT_EQ(all.rest_position_m[GridIndex(w, 3, 2)],
            spec.cloth.origin_m + 3 * spec.cloth.spacing_m * spec.cloth.u_axis +
                2 * spec.cloth.spacing_m * spec.cloth.v_axis);
  EXPECT_DOUBLE_EQ(all.particle_mass_kg * w * h, spec.cloth.mass_kg);
}

TEST(ClothModelTest, PinsHoldCornersEdgesAndParticles) {
  SimSpec spec = Curtain(6);
  spec.cloth.height = 4;
  spec.cloth.pins = {Corner("bottom_right"), cloth_test::EdgePin("left"),
                     cloth_test::ParticlePin(3, 2), Corner("top_left")};
  const ClothModel model = BuildClothModel(spec);
  std::vector<int32_t> expected = {GridIndex(6, 5, 3), GridIndex(6, 0, 0), GridIndex(6, 0, 1),
                                   GridIndex(6, 0, 2), GridIndex(6, 0, 3), GridIndex(6, 3, 2)};
  EXPECT_EQ(model.pinned, expected);
  EXPECT_EQ(model.pin_spec, (std::vector<int32_t>{0, 1, 1, 1, 1, 2}));
  int32_t zero = 0;
  for (double im : model.inv_mass_per_kg) zero += im == 0.0;
  EXPECT_EQ(zero, 6);
  for (int32_t p : expected) EXPECT_EQ(model.inv_mass_per_kg[p], 0.0);
}

TEST(ClothModelTest, AutoSubstepsFollowTheStabilityLimit) {
  SimSpec spec = Curtain(32);
  const ClothModel model = BuildClothModel(spec);
  const double h = 1.0 / (spec.integration.frame_rate_hz * model.substeps);
  EXPECT_LE(h, spec.integration.auto_safety * model.stable_dt_s);
  EXPECT_GT(h, 0.5 * spec.integration.auto_safety * model.stable_dt_s);  // not wastefully small
  EXPECT_DOUBLE_EQ(model.stable_dt_s, StableStep(model, IntegratorKind::kLeapfrogVerlet));

  // Four times stiffer: omega doubles, so about twice the substeps.
  SimSpec stiff = spec;
  for (auto* s : {&stiff.cloth.structural, &stiff.cloth.shear, &stiff.cloth.bend}) {
    (*s)->stiffness_N_per_m *= 4;
  }
  const ClothModel stiff_model = BuildClothModel(stiff);
  EXPECT_NEAR(stiff_model.omega_max_rad_per_s, 2 * model.omega_max_rad_per_s, 1e-9);
  EXPECT_GE(stiff_model.substeps, 2 * model.substeps - 1);

  // Implicit Euler needs one; a fixed count is kept.
  spec.integration.integrator = IntegratorKind::kImplicitEuler;
  EXPECT_EQ(BuildClothModel(spec).substeps, 1);
  EXPECT_TRUE(std::isinf(BuildClothModel(spec).stable_dt_s));
  spec.integration.integrator = IntegratorKind::kRk4;
  spec.integration.substeps = 3;
  EXPECT_EQ(BuildClothModel(spec).substeps, 3);
}

TEST(ClothModelTest, AutoSubstepsOfAConservativeClothResolveItsFastestMode) {
  // No dashpot, no drag, no limiter: nothing removes leapfrog's energy errors at folded springs,
  // so auto takes omega_max h <= 0.03 (cloth_build.cc, kConservativeOmegaH) instead of a fraction
  // of the stable step; the 10 x 10 curtain gets 51 substeps instead of 2.
  SimSpec spec = Curtain(10);
  const int32_t damped = BuildClothModel(spec).substeps;
  for (auto* s : {&spec.cloth.structural, &spec.cloth.shear, &spec.cloth.bend}) {
    (*s)->damping_N_s_per_m = 0;
  }
  spec.cloth.drag_N_s_per_m = 0;
  spec.provot.enabled = false;
  const ClothModel model = BuildClothModel(spec);
  const double h = 1.0 / (spec.integration.frame_rate_hz * model.substeps);
  EXPECT_LE(model.omega_max_rad_per_s * h, 0.03);
  EXPECT_GT(model.omega_max_rad_per_s * h, 0.03 * (model.substeps - 1) / model.substeps);
  EXPECT_GT(model.substeps, 10 * damped);
  // Any one of the three keeps the stability bound: Provot on, drag, or a dashpot.
  SimSpec limited = spec;
  limited.provot.enabled = true;
  EXPECT_EQ(BuildClothModel(limited).substeps, damped);
  SimSpec dragged = spec;
  dragged.cloth.drag_N_s_per_m = 1e-6;
  EXPECT_LT(BuildClothModel(dragged).substeps, model.substeps);
  SimSpec dashpot = spec;
  dashpot.cloth.bend->damping_N_s_per_m = 1e-6;
  EXPECT_LT(BuildClothModel(dashpot).substeps, model.substeps);
}

TEST(ClothModelTest, StableStepsMatchKnownStabilityIntervals) {
  // Without damping the limits on the imaginary axis are known: leapfrog/Verlet/symplectic Euler
  // h omega < 2, RK4 h omega < 2 sqrt(2); explicit Euler and midpoint have none.
  SimSpec spec = Curtain(16);
  for (auto* s : {&spec.cloth.structural, &spec.cloth.shear, &spec.cloth.bend}) {
    (*s)->damping_N_s_per_m = 0;
  }
  spec.cloth.drag_N_s_per_m = 0;
  const ClothModel model = BuildClothModel(spec);
  const double w = model.omega_max_rad_per_s;
  // The grid symbol's maximum (ComputeFrequencyBounds): 6 k_st + 4 k_sh + 4 k_b at these
  // constants (tests/sim_loop/cloth_bounds_test.cc), plus at most 0.5 % sampling margin.
  const auto& c = spec.cloth;
  const double symbol = 6 * c.structural->stiffness_N_per_m + 4 * c.shear->stiffness_N_per_m +
                        4 * c.bend->stiffness_N_per_m;
  EXPECT_GE(w * w * model.particle_mass_kg, symbol);
  EXPECT_LT(w * w * model.particle_mass_kg, 1.005 * symbol);
  for (IntegratorKind k : {IntegratorKind::kLeapfrogVerlet, IntegratorKind::kSymplecticEuler,
                           IntegratorKind::kBasicVerlet, IntegratorKind::kVelocityVerlet}) {
    EXPECT_NEAR(StableStep(model, k) * w, 2.0, 1e-4) << static_cast<int>(k);
  }
  EXPECT_NEAR(StableStep(model, IntegratorKind::kRk4) * w, 2 * std::sqrt(2.0), 1e-4);
  EXPECT_LT(StableStep(model, IntegratorKind::kExplicitEuler) * w, 1e-3);
  EXPECT_LT(StableStep(model, IntegratorKind::kExplicitMidpoint) * w, 0.05);
  // Damping shrinks the leapfrog limit and opens one for explicit Euler.
  const ClothModel damped = BuildClothModel(Curtain(16));
  EXPECT_LT(StableStep(damped, IntegratorKind::kLeapfrogVerlet) * damped.omega_max_rad_per_s, 2.0);
  EXPECT_GT(StableStep(damped, IntegratorKind::kExplicitEuler), 0.0);
}

TEST(ClothModelTest, RestStateHasNoSpringForce) {
  const ClothModel model = BuildClothModel(Curtain(12));
  const ClothState state = MakeClothState(model);
  std::vector<Vec3> f(state.x.size(), Vec3::Zero());
  AddSpringForces(model, state.x, state.v, f);
  for (const Vec3& fi : f) EXPECT_EQ(fi.norm(), 0.0);
}

TEST(ClothModelTest, RigidMotionKeepsLengthsAndGivesNoSpringForce) {
  const ClothModel model = BuildClothModel(Curtain(12));
  const Eigen::Matrix3d R =
      (Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()) * Eigen::AngleAxisd(-2.1, Vec3::UnitY()))
          .toRotationMatrix();
  const Vec3 shift(3.0, -1.5, 0.25);
  const Vec3 omega(0.3, -1.1, 2.0), v0(0.5, 0.0, -0.2);  // rigid velocity field v0 + omega x r
  std::vector<Vec3> x, v, f(model.rest_position_m.size(), Vec3::Zero());
  for (const Vec3& r : model.rest_position_m) {
    x.push_back(R * r + shift);
    v.push_back(v0 + omega.cross(x.back()));
  }
  for (const Spring& s : model.springs) {
    EXPECT_NEAR((x[s.j] - x[s.i]).norm(), s.rest_length_m, 1e-14);
  }
  AddSpringForces(model, x, v, f);
  double worst = 0.0;
  for (const Vec3& fi : f) worst = std::max(worst, fi.norm());
  // A spring's force is k (len - L) + c dv.u: both vanish up to rounding (k ~ 1 N/m, len ~ 0.05).
  EXPECT_LT(worst, 1e-14);
}

TEST(ClothModelTest, GridForceKernelsMatchTheNaiveSpringLoop) {
  // ComputeAccelerations runs the springs as grid stencils (one family per type and direction,
  // AVX2 where the CPU has it); AddSpringForces is the plain loop over the spring list. On a
  // scrambled state (every spring stretched or squeezed, random velocities) with drag, external
  // forces and pins, the two agree up to the rounding of a different summation order. Odd and
  // even grids and one narrower than a vector exercise the kernels' tails.
  for (int32_t grid : {3, 4, 7, 13, 32}) {
    SimSpec spec = Curtain(grid);
    spec.cloth.width = grid + 2;  // not square: rows and columns differ
    spec.cloth.drag_N_s_per_m = 3e-4;
    const ClothModel model = BuildClothModel(spec);
    ClothState state = MakeClothState(model);
    std::mt19937 rng(11u + static_cast<uint32_t>(grid));
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const double a = 0.4 * spec.cloth.spacing_m;
    for (size_t p = 0; p < state.x.size(); ++p) {
      state.x[p] += a * Vec3(u(rng), u(rng), u(rng));
      state.v[p] = Vec3(u(rng), u(rng), u(rng));
      state.scratch->external_N[p] = 1e-3 * Vec3(u(rng), u(rng), u(rng));
    }
    std::vector<Vec3> fast(state.x.size());
    ComputeAccelerations(model, state.x, state.v, state.scratch.get(), fast);

    std::vector<Vec3> f(state.x.size(), Vec3::Zero());
    AddSpringForces(model, state.x, state.v, f);
    double scale = 0.0;
    for (const Vec3& fi : f) scale = std::max(scale, fi.norm());
    ASSERT_GT(scale, 0.0);
    const Vec3 g = spec.cloth.gravity_m_per_s2;
    for (size_t p = 0; p < state.x.size(); ++p) {
      const double w = model.inv_mass_per_kg[p];
      if (w == 0.0) {
        EXPECT_EQ(fast[p], Vec3::Zero()) << "pinned particle " << p;
        continue;
      }
      const Vec3 naive =
          g + w * (f[p] + state.scratch->external_N[p] - spec.cloth.drag_N_s_per_m * state.v[p]);
      EXPECT_LT((fast[p] - naive).norm(), 1e-12 * w * scale)
          << "grid " << grid << " particle " << p;
    }
  }
}

}  // namespace
}  // namespace felt
