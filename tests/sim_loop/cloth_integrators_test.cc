// Each integrator's order of convergence on a damped spring against its closed form, and the
// energy behaviour of the symplectic ones without damping; leapfrog with changing substep lengths.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "sim_loop/cloth.h"
#include "sim_loop/cloth_internal.h"
#include "tests/sim_loop/cloth_test_util.h"
#include "tests/test_env.h"

namespace felt {
namespace {

using cloth_test::Corner;

constexpr double kMassFree_kg = 0.025;
constexpr double kStiffness_N_per_m = 10.0;
constexpr double kDamping_N_s_per_m = 0.05;  // damping ratio 0.05
constexpr double kStretch0_m = 0.02;

// A single damped spring: a 2 x 2 grid with only shear springs, three corners pinned, so the free
// bottom-right particle hangs on the one diagonal spring to the pinned top-left corner.
SimSpec SingleSpring(IntegratorKind kind, int32_t substeps) {
  SimSpec spec;
  spec.cloth.width = 2;
  spec.cloth.height = 2;
  spec.cloth.spacing_m = 0.1;
  spec.cloth.origin_m = Vec3::Zero();
  spec.cloth.mass_kg = 4 * kMassFree_kg;
  spec.cloth.structural.reset();
  spec.cloth.bend.reset();
  spec.cloth.shear = SpringSpec{kStiffness_N_per_m, kDamping_N_s_per_m};
  spec.cloth.drag_N_s_per_m = 0.0;
  spec.cloth.gravity_m_per_s2 = Vec3::Zero();
  spec.cloth.pins = {Corner("top_left"), Corner("top_right"), Corner("bottom_left")};
  spec.provot.enabled = false;
  spec.integration.integrator = kind;
  spec.integration.substeps = substeps;
  spec.integration.cg_tolerance = 1e-14;
  return spec;
}

struct Errors {
  double x_m, v_m_per_s;
};

// The free particle of SingleSpring, its pinned anchor, the spring's direction and rest length.
struct SpringGeometry {
  int32_t free_particle;
  Vec3 anchor_m, u;
  double rest_m;
};

SpringGeometry Geometry(const ClothModel& model) {
  const int32_t free_particle = GridIndex(2, 1, 1);
  const Vec3 anchor = model.rest_position_m[GridIndex(2, 0, 0)];
  const Vec3 d = model.rest_position_m[free_particle] - anchor;
  return {free_particle, anchor, d.normalized(), d.norm()};
}

// A SingleSpring state stretched by kStretch0_m at rest.
ClothState StretchedSpring(const ClothModel& model) {
  ClothState state = MakeClothState(model);
  const SpringGeometry g = Geometry(model);
  state.x[g.free_particle] += kStretch0_m * g.u;
  return state;
}

// Position and velocity errors of the free particle at time t against the closed form
// e(t) = e0 exp(-zeta w0 t) (cos wd t + zeta w0 / wd sin wd t), e'(t) = -e0 w0^2/wd exp(.) sin wd
// t.
Errors SpringErrors(const ClothModel& model, const ClothState& state, double t) {
  const SpringGeometry g = Geometry(model);
  const double w0 = std::sqrt(kStiffness_N_per_m / kMassFree_kg);
  const double zeta = kDamping_N_s_per_m / (2 * kMassFree_kg * w0);
  const double wd = w0 * std::sqrt(1 - zeta * zeta);
  const double decay = std::exp(-zeta * w0 * t);
  const double e = kStretch0_m * decay * (std::cos(wd * t) + zeta * w0 / wd * std::sin(wd * t));
  const double e_dot = -kStretch0_m * w0 * w0 / wd * decay * std::sin(wd * t);
  const Vec3 x_exact = g.anchor_m + (g.rest_m + e) * g.u;
  return {(state.x[g.free_particle] - x_exact).norm(),
          (state.v[g.free_particle] - e_dot * g.u).norm()};
}

// Runs the spring from a stretch of kStretch0_m at rest for 30 frames (0.5 s) and returns the
// errors against the closed form.
Errors RunSpring(IntegratorKind kind, int32_t substeps) {
  const ClothModel model = BuildClothModel(SingleSpring(kind, substeps));
  ClothState state = StretchedSpring(model);
  constexpr int kFrames = 30;
  for (int f = 0; f < kFrames; ++f) StepFrame(model, {}, 1.0 / 60.0, &state);
  return SpringErrors(model, state, state.time_s);
}

struct OrderCase {
  IntegratorKind kind;
  const char* name;
  double order;
  int32_t substeps;  // coarsest run; then twice and four times as many
};

TEST(ClothIntegratorsTest, EachIntegratorConvergesAtItsOrder) {
  const OrderCase cases[] = {
      {IntegratorKind::kExplicitEuler, "explicit Euler", 1, 16},
      {IntegratorKind::kSymplecticEuler, "symplectic Euler", 1, 16},
      {IntegratorKind::kImplicitEuler, "implicit Euler", 1, 16},
      {IntegratorKind::kExplicitMidpoint, "explicit midpoint", 2, 4},
      {IntegratorKind::kLeapfrogVerlet, "leapfrog Verlet", 2, 4},
      {IntegratorKind::kVelocityVerlet, "velocity Verlet", 2, 4},
      {IntegratorKind::kBasicVerlet, "basic Verlet", 2, 4},
      {IntegratorKind::kRk4, "RK4", 4, 2},
  };
  for (const OrderCase& c : cases) {
    const Errors e1 = RunSpring(c.kind, c.substeps);
    const Errors e2 = RunSpring(c.kind, 2 * c.substeps);
    const Errors e4 = RunSpring(c.kind, 4 * c.substeps);
    // Observed order from successive halvings of h: log2(err(h) / err(h/2)).
    for (const auto& [a, b, what] :
         {std::tuple{e1.x_m, e2.x_m, "x h"}, std::tuple{e2.x_m, e4.x_m, "x h/2"},
          std::tuple{e1.v_m_per_s, e2.v_m_per_s, "v h"},
          std::tuple{e2.v_m_per_s, e4.v_m_per_s, "v h/2"}}) {
      const double observed = std::log2(a / b);
      EXPECT_NEAR(observed, c.order, 0.25)
          << c.name << " (" << what << "): errors " << a << " -> " << b;
    }
    EXPECT_LT(e4.x_m, 0.05 * kStretch0_m) << c.name;  // and it is the right solution
  }
}

// Energy of a bouncing, swinging cloth (no damping, no drag, no Provot) over 10 s.
struct EnergyRun {
  double max_deviation_J;  // max |E(t) - E(0)|
  double drift_J;          // mean E over the last second minus mean E over the first second
  double max_kinetic_J;
};

// A curtain hung by its top edge, released at its rest shape so it bounces on its springs
// (stiffer than the default so that no spring goes slack: a slack spring's force is not smooth).
EnergyRun SwingEnergy(IntegratorKind kind) {
  SimSpec spec = cloth_test::Curtain(8);
  PinSpec top;
  top.kind = PinKind::kEdge;
  top.name = "top";
  spec.cloth.pins = {top};
  spec.cloth.v_axis = Vec3(0.0, -1.0, 1.0).normalized();  // tilted: it also swings
  for (auto* s : {&spec.cloth.structural, &spec.cloth.shear, &spec.cloth.bend}) {
    (*s)->stiffness_N_per_m *= 100;
    (*s)->damping_N_s_per_m = 0.0;
  }
  spec.cloth.drag_N_s_per_m = 0.0;
  spec.provot.enabled = false;
  spec.integration.integrator = kind;
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  const double e0 = TotalEnergy(model, state);
  EnergyRun run{0.0, 0.0, 0.0};
  double first = 0.0, last = 0.0;
  // Ten seconds; three under a sanitizer (tests/test_env.h): the same paths, a shorter swing.
  const int kFrames = testing::Sanitized() ? 180 : 600;
  for (int f = 0; f < kFrames; ++f) {
    StepFrame(model, {}, 1.0 / 60.0, &state);
    const double e = TotalEnergy(model, state);
    run.max_deviation_J = std::max(run.max_deviation_J, std::abs(e - e0));
    if (f < 60) first += e / 60;
    if (f >= kFrames - 60) last += e / 60;
    double kinetic = 0.0;
    for (const Vec3& v : state.v) kinetic += 0.5 * model.particle_mass_kg * v.squaredNorm();
    run.max_kinetic_J = std::max(run.max_kinetic_J, kinetic);
  }
  run.drift_J = last - first;
  return run;
}

TEST(ClothIntegratorsTest, SymplecticIntegratorsKeepEnergyWithoutDamping) {
  struct Bound {
    IntegratorKind kind;
    const char* name;
    double deviation;  // fraction of the largest kinetic energy
  };
  const Bound bounds[] = {{IntegratorKind::kLeapfrogVerlet, "leapfrog", 0.02},
                          {IntegratorKind::kVelocityVerlet, "velocity Verlet", 0.02},
                          {IntegratorKind::kBasicVerlet, "basic Verlet", 0.02},
                          {IntegratorKind::kSymplecticEuler, "symplectic Euler", 0.10}};
  for (const Bound& b : bounds) {
    const EnergyRun run = SwingEnergy(b.kind);
    ASSERT_GT(run.max_kinetic_J, 1e-3) << b.name;  // it really swings
    EXPECT_LT(run.max_deviation_J, b.deviation * run.max_kinetic_J) << b.name;
    EXPECT_LT(std::abs(run.drift_J), 0.01 * run.max_kinetic_J) << b.name;
  }
}

// Leapfrog on SingleSpring for 0.5 s in pairs of substeps of `pair_s` together, the first
// `share` of each pair long, driven through IntegrateSubstep directly (share 0.5: fixed steps).
Errors RunLeapfrogPairs(double pair_s, double share) {
  const ClothModel model = BuildClothModel(SingleSpring(IntegratorKind::kLeapfrogVerlet, 1));
  ClothState state = StretchedSpring(model);
  const int pairs = static_cast<int>(std::lround(0.5 / pair_s));
  for (int i = 0; i < pairs; ++i) {
    IntegrateSubstep(model, share * pair_s, &state);
    IntegrateSubstep(model, (1.0 - share) * pair_s, &state);
  }
  return SpringErrors(model, state, pairs * pair_s);
}

TEST(ClothIntegratorsTest, LeapfrogStaysSecondOrderWhenTheSubstepChanges) {
  // Substeps alternating 2h/3 and h/3 (StepFrame changes the length when a frame is late or holds
  // a stiff contact spring). Recovering v_{n-1/2} with the new length instead of h_old was off by
  // (h - h_old)/2 a at every substep: first order, x error 4.1e-4, 2.1e-4, 1.0e-4 m for h = 1/120,
  // 1/240, 1/480 s, 12 to 49 times the fixed-step error; with h_old it is 4.2e-5, 1.0e-5, 2.6e-6 m.
  const double pair_s[] = {1.0 / 120.0, 1.0 / 240.0, 1.0 / 480.0};
  Errors varied[3];
  for (int i = 0; i < 3; ++i) {
    varied[i] = RunLeapfrogPairs(pair_s[i], 2.0 / 3.0);
    const Errors fixed = RunLeapfrogPairs(pair_s[i], 0.5);
    EXPECT_LT(varied[i].x_m, 1.5 * fixed.x_m) << "pair " << pair_s[i] << " s";
    EXPECT_LT(varied[i].v_m_per_s, 1.5 * fixed.v_m_per_s) << "pair " << pair_s[i] << " s";
  }
  for (int i = 0; i < 2; ++i) {
    EXPECT_NEAR(std::log2(varied[i].x_m / varied[i + 1].x_m), 2.0, 0.25) << "x, pair " << pair_s[i];
    EXPECT_NEAR(std::log2(varied[i].v_m_per_s / varied[i + 1].v_m_per_s), 2.0, 0.25)
        << "v, pair " << pair_s[i];
  }
}

TEST(ClothIntegratorsTest, ImplicitEulerTakesOneLargeStableStep) {
  // One implicit step per frame on springs 100 times the default: explicit methods would need
  // many substeps; backward Euler stays bounded and dissipates.
  SimSpec spec = cloth_test::HorizontalCurtain(12);
  for (auto* s : {&spec.cloth.structural, &spec.cloth.shear, &spec.cloth.bend}) {
    (*s)->stiffness_N_per_m *= 100;
  }
  spec.integration.integrator = IntegratorKind::kImplicitEuler;
  const ClothModel model = BuildClothModel(spec);
  ASSERT_EQ(model.substeps, 1);
  ClothState state = MakeClothState(model);
  const double e0 = TotalEnergy(model, state);
  for (int f = 0; f < 120; ++f) {
    const FrameResult r = StepFrame(model, {}, 1.0 / 60.0, &state);
    EXPECT_EQ(r.substeps, 1);
    EXPECT_LE(TotalEnergy(model, state), e0 + 1e-9);
  }
  EXPECT_EQ(state.counters.nan_events, 0u);
  EXPECT_EQ(state.counters.cg_not_converged, 0u);
  EXPECT_LT(state.x[GridIndex(12, 5, 11)].y(), 0.25);  // it fell
}

}  // namespace
}  // namespace felt
