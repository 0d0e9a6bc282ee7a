// Each integrator's order of convergence on a damped spring against its closed form, and the
// energy behaviour of the symplectic ones without damping.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "sim_loop/cloth.h"
#include "tests/sim_loop/cloth_test_util.h"

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

// Runs the spring from a stretch of kStretch0_m at rest for 30 frames (0.5 s) and returns the
// position and velocity errors against the closed form
// e(t) = e0 exp(-zeta w0 t) (cos wd t + zeta w0 / wd sin wd t), e'(t) = -e0 w0^2/wd exp(.) sin wd
// t.
Errors RunSpring(IntegratorKind kind, int32_t substeps) {
  const ClothModel model = BuildClothModel(SingleSpring(kind, substeps));
  ClothState state = MakeClothState(model);
  const int32_t free_particle = GridIndex(2, 1, 1);
  const Vec3 anchor = model.rest_position_m[GridIndex(2, 0, 0)];
  const Vec3 u = (model.rest_position_m[free_particle] - anchor).normalized();
  const double rest = (model.rest_position_m[free_particle] - anchor).norm();
  state.x[free_particle] += kStretch0_m * u;
  constexpr int kFrames = 30;
  for (int f = 0; f < kFrames; ++f) StepFrame(model, {}, 1.0 / 60.0, &state);
  const double t = state.time_s;
  const double w0 = std::sqrt(kStiffness_N_per_m / kMassFree_kg);
  const double zeta = kDamping_N_s_per_m / (2 * kMassFree_kg * w0);
  const double wd = w0 * std::sqrt(1 - zeta * zeta);
  const double decay = std::exp(-zeta * w0 * t);
  const double e = kStretch0_m * decay * (std::cos(wd * t) + zeta * w0 / wd * std::sin(wd * t));
  const double e_dot = -kStretch0_m * w0 * w0 / wd * decay * std::sin(wd * t);
  const Vec3 x_exact = anchor + (rest + e) * u;
  return {(state.x[free_particle] - x_exact).norm(), (state.v[free_particle] - e_dot * u).norm()};
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
  constexpr int kFrames = 600;
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
