// StepFrame: Provot's limit, pins, determinism, no allocation, and the hard cases of issue 2.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "scene/scene_file.h"
#include "sim_loop/cloth.h"
#include "sim_loop/cloth_scene.h"
#include "tests/alloc_counter.h"  // FELT_DEFINE_ALLOC_COUNTER is in collision_alloc_test.cc
#include "tests/sim_loop/cloth_test_util.h"
#include "tests/test_env.h"

namespace felt {
namespace {

using cloth_test::Corner;
using cloth_test::Curtain;
using cloth_test::HorizontalCurtain;

using cloth_test::BitwiseEqual;
using cloth_test::kFrame_s;

bool AllFinite(const ClothState& s) {
  for (size_t p = 0; p < s.x.size(); ++p) {
    if (!s.x[p].allFinite() || !s.v[p].allFinite() || !s.normals[p].allFinite()) return false;
  }
  return true;
}

// A shipped curtain scene (scenes/curtain.toml: auto substeps, 3 sweeps, attachments and
// multiresolution levels; scenes/curtain_128.toml: the same with the finishing limiter) regridded
// to `grid`, hanging or released horizontal.
SimSpec ShippedCurtain(const char* scene, int32_t grid, bool horizontal) {
  SimSpec spec = ResizedCloth(
      ParseSimSpec(LoadSceneDocument(std::string(FELT_SOURCE_DIR) + "/scenes/" + scene)), grid);
  if (horizontal) spec.cloth.v_axis = Vec3::UnitZ();
  return spec;
}

// Largest structural stretch after any of `frames` frames of `scene`'s curtain at `grid`.
double WorstStretch(const char* scene, int32_t grid, bool horizontal, int frames) {
  const SimSpec spec = ShippedCurtain(scene, grid, horizontal);
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  double worst = 0.0;
  for (int f = 0; f < frames; ++f) {
    StepFrame(model, {}, kFrame_s, &state);
    worst = std::max(worst, MaxStretch(model, state));
  }
  EXPECT_TRUE(AllFinite(state)) << grid;
  return worst;
}

// Issue 21's target: the shipped settings hold 10 % after every frame, the release transient (its
// peak at frames 5-8) and the settling included, at every grid. Missed with the default limiter
// (scenes/curtain.toml): over 120 frames, hanging 1.111-1.126 and released horizontal 1.120-1.138
// (10: 1.138, 128: 1.133), so it is disabled rather than loosened; run it with
// --gtest_also_run_disabled_tests. The finishing limiter meets it (the next test); enable this one
// when the default is switched to it.
TEST(ClothStepTest, DISABLED_ShippedSettingsHoldTheStretchLimitAfterEveryFrame) {
  for (int32_t grid : {10, 20, 32, 40, 50, 64, 128}) {
    for (bool horizontal : {false, true}) {
      EXPECT_LE(WorstStretch("curtain.toml", grid, horizontal, 120), 1.10 + 1e-9)
          << grid << (horizontal ? " horizontal" : " hanging");
    }
  }
}

// A guard, not the target (the test above): the default settings stay within the stretch they
// reach today (the release peaks above: 1.111-1.138 on these grids), so a change that makes the
// limiter worse fails here while issue 21 is open.
TEST(ClothStepTest, ShippedSettingsDoNotStretchPastTodaysRelease) {
  for (int32_t grid : {10, 20, 32, 64}) {
    for (bool horizontal : {false, true}) {
      if (grid >= 64 && horizontal) continue;  // the slowest case adds nothing the others miss
      EXPECT_LE(WorstStretch("curtain.toml", grid, horizontal, 30), 1.145)
          << grid << (horizontal ? " horizontal" : " hanging");
    }
  }
}

// Issue 21's target with the finishing limiter as scenes/curtain_128.toml ships it (sweeps 1 %
// under the limit, the multiresolution families in the first, the worklist, auto substeps at 0.75
// of the stable step), regridded: 10 % after every frame, the release transient and the settling
// included, at every grid, hanging and released flat. The sweeps alone reached 1.111-1.138 here.
// Under the sanitizers (ten times slower) the grids up to 64 only.
TEST(ClothStepTest, FinishingLimiterHoldsTheStretchLimitAfterEveryFrame) {
  for (int32_t grid : {10, 20, 32, 40, 50, 64, 128}) {
    if (grid > 64 && felt::testing::Sanitized()) continue;
    for (bool horizontal : {false, true}) {
      EXPECT_LE(WorstStretch("curtain_128.toml", grid, horizontal, 120), 1.10 + 1e-9)
          << grid << (horizontal ? " horizontal" : " hanging");
    }
  }
}

TEST(ClothStepTest, WithoutProvotPinnedCornersStretchSuperElastically) {
  // The control for the test above (000_25210a744b053ca5.txt slide 7): soft springs alone hang far
  // beyond 10%.
  SimSpec spec = Curtain(20);
  spec.provot.enabled = false;
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  for (int f = 0; f < 60; ++f) StepFrame(model, {}, kFrame_s, &state);
  EXPECT_GT(MaxStretch(model, state), 1.5);
}

TEST(ClothStepTest, FixedPinsNeverMoveBitwise) {
  SimSpec spec = HorizontalCurtain(16);
  PinSpec edge;
  edge.kind = PinKind::kEdge;
  edge.name = "left";
  spec.cloth.pins.push_back(edge);
  for (IntegratorKind kind :
       {IntegratorKind::kLeapfrogVerlet, IntegratorKind::kBasicVerlet, IntegratorKind::kRk4,
        IntegratorKind::kImplicitEuler, IntegratorKind::kExplicitMidpoint}) {
    spec.integration.integrator = kind;
    const ClothModel model = BuildClothModel(spec);
    ClothState state = MakeClothState(model);
    // A push on the pinned corner's triangle must not move it either.
    const ExternalForce push{0, Vec3(1.0 / 3, 1.0 / 3, 1.0 / 3), Vec3(0.0, 0.0, 5.0)};
    for (int f = 0; f < 30; ++f) {
      StepFrame(model, std::span(&push, 1), kFrame_s, &state);
      for (int32_t p : model.pinned) {
        ASSERT_EQ(std::memcmp(state.x[p].data(), model.rest_position_m[p].data(), sizeof(Vec3)), 0)
            << static_cast<int>(kind) << " particle " << p;
        ASSERT_EQ(state.v[p], Vec3::Zero());
      }
    }
  }
}

TEST(ClothStepTest, ScriptedPinsFollowTheirScriptExactly) {
  SimSpec spec = Curtain(12);
  PinMotionSpec rail;
  rail.velocity_m_per_s = Vec3(0.2, 0.0, 0.0);
  rail.amplitude_m = Vec3(0.0, 0.03, 0.0);
  rail.frequency_hz = 1.5;
  rail.start_s = 0.1;
  rail.stop_s = 0.4;
  for (PinSpec& pin : spec.cloth.pins) pin.motion = rail;
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  for (int f = 0; f < 45; ++f) {
    StepFrame(model, {}, kFrame_s, &state);
    for (int32_t p : model.pinned) {
      EXPECT_EQ(state.x[p], model.rest_position_m[p] + PinOffset(rail, state.time_s));
      EXPECT_EQ(state.v[p], PinVelocity(rail, state.time_s));
    }
  }
  // The formula of PinMotionSpec: drift stops at stop_s, the sinusoid goes on.
  const double t = 0.7;
  const Vec3 expected =
      rail.velocity_m_per_s * (0.4 - 0.1) + rail.amplitude_m * std::sin(2 * M_PI * 1.5 * (t - 0.1));
  EXPECT_NEAR((PinOffset(rail, t) - expected).norm(), 0.0, 1e-15);
  EXPECT_EQ(PinOffset(rail, 0.05), Vec3::Zero());
  // The cloth follows the rail (it moved right) and stays within the limit.
  EXPECT_GT(state.x[GridIndex(12, 6, 11)].x(), 0.03);
}

TEST(ClothStepTest, TwoRunsAreBitIdentical) {
  for (IntegratorKind kind : {IntegratorKind::kLeapfrogVerlet, IntegratorKind::kImplicitEuler}) {
    SimSpec spec = HorizontalCurtain(16);
    spec.integration.integrator = kind;
    spec.cloth.obstacles.push_back({SphereSpec{Vec3(0.0, 0.0, 0.25), 0.1}, 0.3, 0.002});
    const ClothModel model = BuildClothModel(spec);
    ClothState a = MakeClothState(model), b = MakeClothState(model);
    const ExternalForce push{40, Vec3(0.2, 0.3, 0.5), Vec3(0.0, -0.5, 0.2)};
    for (int f = 0; f < 40; ++f) {
      const double dt = kFrame_s * (1.0 + 0.1 * std::sin(f));  // jittery frame times
      StepFrame(model, std::span(&push, 1), dt, &a);
      StepFrame(model, std::span(&push, 1), dt, &b);
    }
    EXPECT_TRUE(BitwiseEqual(a.x, b.x));
    EXPECT_TRUE(BitwiseEqual(a.v, b.v));
    EXPECT_TRUE(BitwiseEqual(a.normals, b.normals));
  }
}

TEST(ClothStepTest, SteppingAllocatesNothing) {
  for (int k = 0; k <= static_cast<int>(IntegratorKind::kImplicitEuler); ++k) {
    SimSpec spec = HorizontalCurtain(12);
    spec.integration.integrator = static_cast<IntegratorKind>(k);
    spec.integration.substeps = 4;
    spec.cloth.obstacles = {{PlaneSpec{Vec3(0, -0.3, 0), Vec3::UnitY()}, 0.5, 0.002},
                            {SphereSpec{Vec3(0.0, 0.0, 0.25), 0.1}, 0.0, 0.002},
                            {BoxSpec{Vec3(-0.1, -0.2, 0.0), Vec3(0.1, -0.1, 0.2)}, 0.2, 0.001},
                            {CapsuleSpec{Vec3(-0.2, 0.0, 0.1), Vec3(0.2, 0.0, 0.1), 0.02}}};
    const ClothModel model = BuildClothModel(spec);
    ClothState state = MakeClothState(model);
    const ExternalForce pushes[2] = {{3, Vec3(0.2, 0.3, 0.5), Vec3(0.0, -0.5, 0.2)},
                                     {-1, Vec3(1, 0, 0), Vec3::UnitX()}};  // the second is invalid
    StepFrame(model, pushes, kFrame_s, &state);  // warm (nothing is lazily allocated, but be fair)
    AllocationGuard guard;
    for (int f = 0; f < 20; ++f) StepFrame(model, pushes, kFrame_s * (f % 3 + 1), &state);
    EXPECT_EQ(guard.allocations(), 0u) << "integrator " << k;
    EXPECT_EQ(state.counters.invalid_external_forces, 21u);
  }
}

TEST(ClothStepTest, ExternalForceIsSplitByBarycentricWeights) {
  SimSpec spec = Curtain(6);
  spec.cloth.gravity_m_per_s2 = Vec3::Zero();
  spec.provot.enabled = false;
  spec.integration.integrator = IntegratorKind::kExplicitEuler;
  spec.integration.substeps = 1;
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  const int32_t tri = 7;
  const ExternalForce push{tri, Vec3(0.5, 0.3, 0.2), Vec3(0.0, 0.0, 0.01)};
  StepFrame(model, std::span(&push, 1), kFrame_s, &state);
  // Explicit Euler from rest: one step changes only v, by h F_k / m, at the three corners.
  const Triangle& t = model.triangles[tri];
  for (int c = 0; c < 3; ++c) {
    const double expected = kFrame_s * push.barycentric[c] * 0.01 / model.particle_mass_kg;
    EXPECT_NEAR(state.v[t[c]].z(), expected, 1e-12 * expected);
  }
  int32_t moved = 0;
  for (const Vec3& v : state.v) moved += v.z() != 0.0;
  EXPECT_EQ(moved, 3);
}

TEST(ClothStepTest, StiffSpringsAtLargeDtWithAutoSubstepsStayBounded) {
  // Springs 1000 times the default, a 100 ms frame (clamped to the 33 ms maximum), auto substeps.
  // Explicit Euler has no usable auto step here (its drag-damped modes need h < 1e-7 s): auto
  // refuses it (tests/sim_loop/cloth_bounds_test.cc), and it runs stiff scenes with drag there.
  for (IntegratorKind kind :
       {IntegratorKind::kLeapfrogVerlet, IntegratorKind::kRk4, IntegratorKind::kSymplecticEuler}) {
    SimSpec spec = HorizontalCurtain(8);
    for (auto* s : {&spec.cloth.structural, &spec.cloth.shear, &spec.cloth.bend}) {
      (*s)->stiffness_N_per_m *= 1000;
      (*s)->damping_N_s_per_m *= 1000;
    }
    spec.integration.integrator = kind;
    const ClothModel model = BuildClothModel(spec);
    ClothState state = MakeClothState(model);
    for (int f = 0; f < 60; ++f) StepFrame(model, {}, 0.1, &state);
    EXPECT_EQ(state.counters.nan_events, 0u) << static_cast<int>(kind);
    EXPECT_TRUE(AllFinite(state));
    for (const Vec3& x : state.x) EXPECT_LT(x.norm(), 2.0);  // a 0.5 m cloth hung from y = 0.25
    EXPECT_LT(MaxStretch(model, state), 1.2);
  }
}

// Provot's limit on a cloth lying over a box's edges: scenes/tablecloth.toml draped over its table
// (3 s), and scenes/self_tablecloth_pull.toml without its [self_collision] (its corner pulled off
// the table at 1.5 m/s, 3 s), with the finishing limiter, which holds 1.10 exactly on a free cloth.
// Missed today, so disabled rather than loosened: the draped tablecloth reaches 1.560, the pulled
// one 5.76 (with the default limiter 1.566 and 7.85, the latter at t = 1.42 s). Measured: the
// particles next to the table's rim hang on its side faces 2-3 mm under the top while the springs
// to their neighbours on the top cut through the box; the limiter pulls them horizontally into the
// box and the obstacle puts them back on the side face, so nothing lifts them over the rim (the
// obstacles see particles, not the springs between them). Interleaving the two (Provot, then the
// obstacles, twice or four times a substep; default limiter) only eased it: 1.379 / 1.253 draped,
// 4.29 / 3.45 pulled. Projecting a particle at the rim onto the top's shell when it started within
// a margin of the top's plane (default limiter): pulled 5.76. Moving out every structural and
// shear spring whose ends are outside the shell but whose middle dips into it (ternary search
// along the segment, after the vertex pass): worse, 1.84 draped and 1.63 pulled, and 33 ms a frame
// (every spring lying on the table top passed the cheap test). Run with
// --gtest_also_run_disabled_tests.
TEST(ClothStepTest, DISABLED_ProvotHoldsTheLimitOverATablesEdges) {
  for (const char* scene : {"tablecloth.toml", "self_tablecloth_pull.toml"}) {
    SimSpec spec =
        ParseSimSpec(LoadSceneDocument(std::string(FELT_SOURCE_DIR) + "/scenes/" + scene));
    spec.self_collision.reset();
    // The finishing limiter (as scenes/curtain_128.toml), which holds 1.10 exactly on a free cloth.
    spec.provot.finish = true;
    spec.provot.sweep_headroom = 0.01;
    spec.provot.coarse_sweeps = 1;
    const ClothModel model = BuildClothModel(spec);
    ClothState state = MakeClothState(model);
    double worst = 0.0;
    for (int f = 0; f < 180; ++f) {
      StepFrame(model, {}, kFrame_s, &state);
      worst = std::max(worst, MaxStretch(model, state));
    }
    EXPECT_LE(worst, 1.10 + 1e-9) << scene;
  }
}

TEST(ClothStepTest, FastClothDoesNotPassThroughThinObstacles) {
  // A cloth thrown down at 20 m/s onto a 4 mm board and onto a small sphere: at 60 Hz a particle
  // travels 8 substep lengths of the board's thickness per frame.
  // A particle that tunnels through in one substep ends outside the obstacle, where the distance
  // check cannot see it; the impact frame's check of the middle particle can: it must be on top.
  struct Case {
    ObstacleSpec obstacle;
    double top_y;      // the obstacle's top surface under the middle particle
    bool cloth_stays;  // the obstacle is wider than the cloth, so the cloth stays on it
  };
  const Case cases[] = {
      {{BoxSpec{Vec3(-0.4, -0.004, -0.4), Vec3(0.4, 0.0, 0.4)}, 0.3, 0.002}, 0.0, true},
      // The sphere is smaller than the cloth: the edges fall on past it at 20 m/s and drag the
      // middle off its top (Provot's constraints carry their momentum), so only the impact counts.
      {{SphereSpec{Vec3(0.0, -0.1, 0.0), 0.1}, 0.5, 0.002}, 0.0, false},
  };
  for (const Case& c : cases) {
    SimSpec spec;
    spec.cloth.width = 16;
    spec.cloth.height = 16;
    spec.cloth.spacing_m = 0.02;
    spec.cloth.origin_m = Vec3(-0.15, 0.3, -0.15);
    spec.cloth.v_axis = Vec3::UnitZ();
    spec.cloth.obstacles = {c.obstacle};
    spec.integration.substeps = 1;  // one step per frame: the worst case for tunnelling
    const ClothModel model = BuildClothModel(spec);
    ClothState state = MakeClothState(model);
    for (Vec3& v : state.v) v = Vec3(0.0, -20.0, 0.0);
    for (int f = 0; f < 60; ++f) {
      StepFrame(model, {}, kFrame_s, &state);
      for (int32_t p = 0; p < model.num_particles(); ++p) {
        Vec3 normal;
        ASSERT_GE(ObstacleDistance(c.obstacle, state.x[p], &normal), 0.0)
            << "frame " << f << " particle " << p;
      }
      // The impact (t = 0.015 s) is in frame 0: the middle of the cloth ends it on top, not under
      // (a tunnelled particle would be 0.03 m below); on the board it is still there at frame 10.
      if (f == 0 || (f == 10 && c.cloth_stays)) {
        EXPECT_GT(state.x[GridIndex(16, 8, 8)].y(), c.top_y - 0.01) << "frame " << f;
      }
    }
  }
}

TEST(ClothStepTest, ALightParticlePushedIntoATableForOneFrameStaysOnItAndIsNotThrownUp) {
  // A sheet without springs (Provot's limits alone, leapfrog, one substep) lying on a 0.75 m
  // table, its middle particle (18 mg) pushed down with 0.1 N for one frame and then let go: the
  // reaction a proxy leaving the cloth within a frame hands the sim (TableSlideTest). The push
  // moves it over a metre down in that substep, through the table and out of its underside; stopped
  // on the tabletop instead, leapfrog's recovered half-step velocity v - h/2 a_last used to give it
  // back the half kick h/2 (0.1 N / 18 mg) = 46 m/s upward the table had taken.
  SimSpec spec;
  spec.cloth.width = 5;
  spec.cloth.height = 5;
  spec.cloth.spacing_m = 0.01;
  spec.cloth.mass_kg = 25 * 18e-6;
  spec.cloth.origin_m = Vec3(-0.02, 0.004, -0.02);
  spec.cloth.v_axis = Vec3::UnitZ();
  spec.cloth.structural.reset();
  spec.cloth.shear.reset();
  spec.cloth.bend.reset();
  const ObstacleSpec table{BoxSpec{Vec3(-0.3, -0.75, -0.2), Vec3(0.3, 0.0, 0.2)}, 0.5, 0.002};
  spec.cloth.obstacles = {table};
  const ClothModel model = BuildClothModel(spec);
  ASSERT_EQ(model.substeps, 1);
  ClothState state = MakeClothState(model);
  for (int f = 0; f < 30; ++f) StepFrame(model, {}, kFrame_s, &state);
  const std::vector<Vec3> rest = state.x;
  const int32_t middle = GridIndex(5, 2, 2);
  ExternalForce push;
  push.force_N = Vec3(0.0, -0.1, 0.0);
  for (size_t t = 0; t < model.triangles.size(); ++t) {
    for (int c = 0; c < 3; ++c) {
      if (model.triangles[t][c] != middle) continue;
      push.triangle = static_cast<int32_t>(t);
      push.barycentric = Vec3::Unit(c);
    }
  }
  for (int f = 0; f < 60; ++f) {
    const std::vector<ExternalForce> external =
        f == 0 ? std::vector<ExternalForce>{push} : std::vector<ExternalForce>{};
    StepFrame(model, external, kFrame_s, &state);
    for (int32_t p = 0; p < model.num_particles(); ++p) {
      Vec3 normal;
      ASSERT_GE(ObstacleDistance(table, state.x[p], &normal), 0.0) << "frame " << f << " " << p;
      ASSERT_LT((state.x[p] - rest[p]).norm(), 0.01) << "frame " << f << " particle " << p;
    }
  }
}

TEST(ClothStepTest, ZeroLengthSpringsAndDegenerateTrianglesGiveNoNaN) {
  for (IntegratorKind kind :
       {IntegratorKind::kLeapfrogVerlet, IntegratorKind::kImplicitEuler, IntegratorKind::kRk4}) {
    SimSpec spec = HorizontalCurtain(8);
    spec.integration.integrator = kind;
    spec.cloth.pins.clear();
    const ClothModel model = BuildClothModel(spec);
    // Fully crumpled: every particle at one point (all springs zero length, all triangles
    // degenerate), then a half-collapsed state (one row on top of the next).
    ClothState crumpled = MakeClothState(model);
    for (Vec3& x : crumpled.x) x = Vec3(0.1, 0.2, 0.3);
    ResetIntegratorHistory(&crumpled);
    ClothState folded = MakeClothState(model);
    for (int32_t c = 0; c < 8; ++c) folded.x[GridIndex(8, c, 1)] = folded.x[GridIndex(8, c, 0)];
    for (ClothState* s : {&crumpled, &folded}) {
      std::vector<Vec3> f(s->x.size(), Vec3::Zero());
      AddSpringForces(model, s->x, s->v, f);
      for (const Vec3& fi : f) ASSERT_TRUE(fi.allFinite());
      for (int k = 0; k < 30; ++k) StepFrame(model, {}, kFrame_s, s);
      EXPECT_EQ(s->counters.nan_events, 0u) << static_cast<int>(kind);
      EXPECT_TRUE(AllFinite(*s));
      EXPECT_TRUE(std::isfinite(TotalEnergy(model, *s)));
      EXPECT_TRUE(std::isfinite(MaxStretch(model, *s)));
    }
  }
}

TEST(ClothStepTest, NaNInjectedIntoOneParticleIsRecovered) {
  const ClothModel model = BuildClothModel(Curtain(16));
  ClothState state = MakeClothState(model);
  for (int f = 0; f < 10; ++f) StepFrame(model, {}, kFrame_s, &state);
  const std::vector<Vec3> good_x = state.x;
  const double good_t = state.time_s;
  state.x[GridIndex(16, 7, 9)].y() = std::numeric_limits<double>::quiet_NaN();
  const FrameResult r = StepFrame(model, {}, kFrame_s, &state);
  EXPECT_TRUE(r.recovered);
  EXPECT_EQ(state.counters.nan_events, 1u);
  EXPECT_TRUE(BitwiseEqual(state.x, good_x));
  EXPECT_EQ(state.time_s, good_t);
  EXPECT_TRUE(AllFinite(state));
  // An infinite velocity too, then the run simply goes on.
  state.v[3] = Vec3(std::numeric_limits<double>::infinity(), 0, 0);
  EXPECT_TRUE(StepFrame(model, {}, kFrame_s, &state).recovered);
  EXPECT_EQ(state.counters.nan_events, 2u);
  for (int f = 0; f < 30; ++f) EXPECT_FALSE(StepFrame(model, {}, kFrame_s, &state).recovered);
  EXPECT_TRUE(AllFinite(state));
  EXPECT_GT(state.time_s, good_t + 0.4);
}

TEST(ClothStepTest, StalledFrameIsClamped) {
  SimSpec spec = Curtain(16);
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  const FrameResult normal = StepFrame(model, {}, kFrame_s, &state);
  EXPECT_FALSE(normal.clamped);
  EXPECT_EQ(normal.substeps, model.substeps);
  const FrameResult stalled = StepFrame(model, {}, 0.5, &state);
  EXPECT_TRUE(stalled.clamped);
  EXPECT_EQ(stalled.dt_s, spec.integration.max_frame_dt_s);
  // The substep length stays at most the nominal one: twice the substeps for a 1/30 s clamp.
  EXPECT_EQ(stalled.substeps, 2 * model.substeps);
  EXPECT_EQ(state.counters.clamped_frames, 1u);
  EXPECT_NEAR(state.time_s, kFrame_s + spec.integration.max_frame_dt_s, 1e-15);
  EXPECT_TRUE(AllFinite(state));
  // Zero, negative or NaN frame times do nothing.
  const ClothState before = state;
  for (double dt : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN()}) {
    EXPECT_EQ(StepFrame(model, {}, dt, &state).substeps, 0);
  }
  EXPECT_TRUE(BitwiseEqual(state.x, before.x));
}

TEST(ClothStepTest, ACopiedStateOwnsItsIntegratorHistory) {
  // Leapfrog carries the last acceleration in the state's scratch: a copy must carry its own, so
  // stepping the original does not change how the copy steps (they once shared one block).
  const ClothModel model = BuildClothModel(Curtain(8));
  ClothState original = MakeClothState(model);
  for (int f = 0; f < 3; ++f) StepFrame(model, {}, kFrame_s, &original);
  ClothState copy = original;
  ClothState moved_from = original;
  const ClothState moved = std::move(moved_from);
  for (int f = 0; f < 3; ++f) StepFrame(model, {}, kFrame_s, &original);
  ClothState copy_stepped = copy;
  for (int f = 0; f < 3; ++f) StepFrame(model, {}, kFrame_s, &copy_stepped);
  EXPECT_TRUE(BitwiseEqual(copy_stepped.x, original.x));
  EXPECT_TRUE(BitwiseEqual(copy_stepped.v, original.v));
  EXPECT_TRUE(BitwiseEqual(moved.x, copy.x));
  EXPECT_NE(copy.scratch.get(), original.scratch.get());
}

TEST(ClothStepTest, TenMinutesWithDampingKeepEnergyBounded) {
  // 36000 frames of a small flag swinging from two corners under a sinusoidal push.
  const ClothModel model = BuildClothModel(HorizontalCurtain(5));
  ClothState state = MakeClothState(model);
  const double e0 = TotalEnergy(model, state);
  double e_max = e0;
  for (int f = 0; f < 36000; ++f) {
    const ExternalForce push{5, Vec3(1.0 / 3, 1.0 / 3, 1.0 / 3),
                             Vec3(0.0, 0.0, 0.002 * std::sin(f * 0.05))};
    StepFrame(model, std::span(&push, 1), kFrame_s, &state);
    e_max = std::max(e_max, TotalEnergy(model, state));
  }
  EXPECT_NEAR(state.time_s, 600.0, 1e-6);
  EXPECT_EQ(state.counters.nan_events, 0u);
  EXPECT_TRUE(AllFinite(state));
  EXPECT_LT(e_max, e0 + 0.01);  // the push adds little; damping keeps it from accumulating
  EXPECT_LT(MaxStretch(model, state), 1.0 + 0.1 + 0.02);
}

}  // namespace
}  // namespace felt
