// The proxy against the scene's static obstacles (issue 4: "a pointer pinching the cloth against
// an obstacle"): kinematic cases with closed-form answers, then the real cloth (sim_loop) draped
// on a table and pressed in lock-step, as coupled_test.cc runs it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "proxy/obstacle_sweep.h"
#include "proxy/proxy.h"
#include "scene/scene_file.h"
#include "server/server_spec.h"
#include "sim_loop/cloth.h"
#include "sim_loop/cloth_scene.h"
#include "sim_loop/frame_motion.h"
#include "tests/proxy/proxy_test_util.h"
#include "tests/test_env.h"

namespace felt {
namespace {

using testing::Box;
using testing::GridMesh;
using testing::Plane;
using testing::Snap;
using testing::Spec;
using testing::Table;
using testing::TestMesh;
using testing::TickAt;
using testing::UnitDevice;

// A small sheet far from every obstacle of these tests (the proxy needs a snapshot to run on).
TestMesh FarSheet() {
  return GridMesh(3, 3, [](double u, double v) { return Vec3(5.0 + 0.1 * u, 5.0 + 0.1 * v, 5.0); });
}

// Every obstacle kind, pressed 2 cm into along its normal: the proxy rests on the surface and the
// force is k times the depth along the outward normal; no force goes to the cloth; moving the
// goal back out releases the contact.
TEST(ObstacleProxyTest, PressOntoEachObstacleGivesStiffnessTimesDepthAlongNormal) {
  struct Case {
    ObstacleSpec obstacle;
    Vec3 surface;  // the surface point pressed
    Vec3 normal;   // its outward normal
  };
  ObstacleSpec sphere;
  sphere.shape = SphereSpec{Vec3(0.1, 0.0, 0.0), 0.05};
  ObstacleSpec capsule;
  capsule.shape = CapsuleSpec{Vec3(-0.1, 0, 0.2), Vec3(0.1, 0, 0.2), 0.03};
  const Vec3 tilted = Vec3(0.3, 1.0, -0.2).normalized();
  const Case cases[] = {
      {Plane(Vec3(0, -0.01, 0), tilted), Vec3(0, -0.01, 0), tilted},
      {sphere, Vec3(0.1, 0.05, 0.0), Vec3::UnitY()},
      {Table(), Vec3(0.02, 0.0, 0.01), Vec3::UnitY()},
      {capsule, Vec3(0.05, 0.0, 0.23), Vec3::UnitZ()},
  };
  const ClothSnapshot s = Snap(FarSheet());
  const DeviceSpec d = UnitDevice(0.004);
  for (size_t i = 0; i < std::size(cases); ++i) {
    const Case& c = cases[i];
    ProxySpec p = Spec();
    p.obstacles = {c.obstacle};
    const ProxyModel pm = CompileProxyModel(d, p);
    ProxyState st = MakeProxyState(pm);
    TickAt(pm, s, c.surface + 0.05 * c.normal, &st);
    const Vec3 goal = c.surface - 0.02 * c.normal;
    const ProxyTickResult r = TickAt(pm, s, goal, &st);
    ASSERT_EQ(r.num_contacts, 1) << i;
    EXPECT_EQ(st.body.contacts[0].triangle, ObstacleContactId(0)) << i;
    EXPECT_NEAR((r.proxy_W_m - (c.surface + d.radius_m * c.normal)).norm(), 0.0, 1e-12) << i;
    const Vec3 expected = d.stiffness_N_per_m * (0.02 + d.radius_m) * c.normal;
    EXPECT_NEAR((r.force_D_N - expected).norm(), 0.0, 1e-9) << i;
    EXPECT_NEAR(st.reaction.TotalImpulse().norm(), 0.0, 0.0) << i << ": the obstacle is static";
    // Held: the same place; then back out to the free side: released, no force.
    const ProxyTickResult held = TickAt(pm, s, goal, &st);
    EXPECT_NEAR((held.proxy_W_m - r.proxy_W_m).norm(), 0.0, 1e-12) << i;
    const ProxyTickResult out = TickAt(pm, s, c.surface + 0.01 * c.normal, &st);
    EXPECT_EQ(out.num_contacts, 0) << i;
    EXPECT_EQ(out.force_D_N, Vec3::Zero()) << i;
  }
}

// A 5 m/s pointer (5 mm per 1 ms tick) through obstacles thinner than the proxy's diameter plus
// one tick's travel: a test of the end points only would step over them.
TEST(ObstacleProxyTest, FivePerSecondPointerThroughObstaclesNeverTunnels) {
  const double r = 0.001;
  ObstacleSpec rod;
  rod.shape = CapsuleSpec{Vec3(-0.1, 0, 0), Vec3(0.1, 0, 0), 0.0002};
  ObstacleSpec ball;
  ball.shape = SphereSpec{Vec3(0.0, 0.0, 0.0), 0.0004};
  const ObstacleSpec thin[] = {Box(Vec3(-0.1, -0.00025, -0.1), Vec3(0.1, 0.00025, 0.1)), rod, ball,
                               Plane(Vec3::Zero(), Vec3::UnitY())};
  const ClothSnapshot s = Snap(FarSheet());
  const DeviceSpec d = UnitDevice(r);
  for (size_t i = 0; i < std::size(thin); ++i) {
    ProxySpec p = Spec();
    p.obstacles = {thin[i]};
    for (double phase : {0.0, 0.0013, 0.0029}) {
      const ProxyModel pm = CompileProxyModel(d, p);
      ProxyState st = MakeProxyState(pm);
      int touched = 0;
      for (int k = 0; k <= 30; ++k) {
        // Down through the obstacle at 5 mm per tick, slightly oblique.
        // (Straight through the ball's centre: off-centre, the proxy slides round the ball.)
        const double drift = i == 2 ? 0.0 : 0.0001;
        const Vec3 goal(drift * k, 0.05 + phase - 0.005 * k, 0.0);
        const ProxyTickResult res = TickAt(pm, s, goal, &st);
        const ObstaclePoint op = ClosestObstaclePoint(thin[i], res.proxy_W_m);
        ASSERT_GE(op.distance_m, r - 1e-12) << i << " tick " << k << ": inside the obstacle";
        ASSERT_GT(res.proxy_W_m.y(), 0.0) << i << " tick " << k << ": tunnelled through";
        touched += res.num_contacts > 0 ? 1 : 0;
      }
      EXPECT_GT(touched, 10) << i;
    }
  }
}

// The three-plane case: a fold of cloth (the vertical sheet z = 0) against two obstacle walls (a
// floor plane y = 0 and a box x < 0). Pushed into the corner, the proxy ends at (r, r, r) within
// the same tick, touching all three; the cloth receives only its own share (along z).
TEST(ObstacleProxyTest, ClothFoldAgainstTwoObstacleWallsResolvesThreePlanesInOneTick) {
  const TestMesh sheet =
      GridMesh(6, 6, [](double u, double v) { return Vec3(0.1 * u, 0.1 * v, 0); });
  const ClothSnapshot s = Snap(sheet);
  const DeviceSpec d = UnitDevice(0.004);
  ProxySpec p = Spec();
  p.obstacles = {Plane(Vec3::Zero(), Vec3::UnitY()),
                 Box(Vec3(-0.2, -0.2, -0.2), Vec3(0.0, 0.2, 0.2))};
  const ProxyModel pm = CompileProxyModel(d, p);
  ProxyState st = MakeProxyState(pm);
  TickAt(pm, s, Vec3(0.03, 0.035, 0.04), &st);
  st.reaction.Clear();
  const ProxyTickResult r = TickAt(pm, s, Vec3(-0.02, -0.01, -0.03), &st);
  ASSERT_EQ(r.num_contacts, 3);
  EXPECT_NEAR((r.proxy_W_m - Vec3(0.004, 0.004, 0.004)).norm(), 0.0, 1e-9);
  int obstacles = 0;
  for (int32_t i = 0; i < st.body.num_contacts; ++i) {
    obstacles += IsObstacleContactId(st.body.contacts[i].triangle) ? 1 : 0;
  }
  EXPECT_EQ(obstacles, 2);
  const Vec3 expected = 400.0 * (Vec3(0.004, 0.004, 0.004) - Vec3(-0.02, -0.01, -0.03));
  EXPECT_NEAR((r.force_D_N - expected).norm(), 0.0, 1e-6);
  // The cloth gets -F along its normal only: the walls take the rest.
  const Vec3 impulse = st.reaction.TotalImpulse();
  EXPECT_NEAR((impulse - Vec3(0, 0, -expected.z() * 1e-3)).norm(), 0.0, 1e-12);
}

// A sheet lying 2 mm above a table (the sim's margin), the pointer 2 cm below the tabletop: the
// proxy rests on the cloth, not on the table, and the force is k times the pointer's depth
// behind it; with the cloth taken away it rests on the table itself.
TEST(ObstacleProxyTest, PointerPinchingAStillSheetOnATableRestsOnTheSheet) {
  const TestMesh sheet = GridMesh(
      11, 11, [](double u, double v) { return Vec3(0.2 * (u - 0.5), 0.002, 0.2 * (v - 0.5)); });
  const ClothSnapshot s = Snap(sheet);
  const DeviceSpec d = UnitDevice(0.004);
  ProxySpec p = Spec(SnapshotMode::kNewest, true);
  p.obstacles = {Table()};
  const ProxyModel pm = CompileProxyModel(d, p);
  ProxyState st = MakeProxyState(pm);
  TickAt(pm, s, Vec3(0.013, 0.05, 0.007), &st);
  const ProxyTickResult r = TickAt(pm, s, Vec3(0.013, -0.02, 0.007), &st);
  ASSERT_EQ(r.num_contacts, 1);
  EXPECT_GE(st.body.contacts[0].triangle, 0) << "on the cloth, not the table";
  EXPECT_NEAR((r.proxy_W_m - Vec3(0.013, 0.006, 0.007)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((r.force_D_N - Vec3(0, 400.0 * 0.026, 0)).norm(), 0.0, 1e-9);
  // Slide off the sheet's edge (x = 0.1) onto the bare table.
  ProxyTickResult off = r;
  for (int k = 1; k <= 40; ++k) off = TickAt(pm, s, Vec3(0.013 + 0.005 * k, -0.02, 0.007), &st);
  ASSERT_EQ(off.num_contacts, 1);
  EXPECT_EQ(st.body.contacts[0].triangle, ObstacleContactId(0));
  EXPECT_NEAR((off.proxy_W_m - Vec3(0.213, 0.004, 0.007)).norm(), 0.0, 1e-12);
}

TEST(ObstacleProxyTest, GoalStartingInsideAnObstacleStartsTheProxyOnItsSurface) {
  const ClothSnapshot s = Snap(FarSheet());
  const DeviceSpec d = UnitDevice(0.004);
  ProxySpec p = Spec();
  p.obstacles = {Table()};
  const ProxyModel pm = CompileProxyModel(d, p);
  ProxyState st = MakeProxyState(pm);
  const ProxyTickResult r = TickAt(pm, s, Vec3(0.1, -0.01, 0.0), &st);
  EXPECT_NEAR((r.proxy_W_m - Vec3(0.1, 0.004, 0.0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR(r.force_D_N.y(), 400.0 * 0.014, 1e-9);
}

TEST(ObstacleProxyTest, ServerSceneGivesTheProxyTheSceneObstacles) {
  const ServerSpec table =
      ParseServerSpec(LoadSceneDocument(FELT_SOURCE_DIR "/scenes/tablecloth.toml"));
  ASSERT_EQ(table.proxy.obstacles.size(), 2u);
  EXPECT_TRUE(std::holds_alternative<BoxSpec>(table.proxy.obstacles[0].shape));
  EXPECT_TRUE(std::holds_alternative<PlaneSpec>(table.proxy.obstacles[1].shape));
  const ServerSpec curtain =
      ParseServerSpec(LoadSceneDocument(FELT_SOURCE_DIR "/scenes/curtain.toml"));
  EXPECT_TRUE(curtain.proxy.obstacles.empty());
}

// ---- The real cloth pinched against a table, coupled both ways in lock-step. ----

// What one pinch run recorded.
struct PinchRun {
  std::vector<Vec3> forces;           ///< every tick's force, device frame
  Vec3 pressed_force = Vec3::Zero();  ///< at the end of the hold
  int32_t pressed_contact = 0;        ///< the proxy's first contact id then
  double min_table_gap_m = 1e300;     ///< least (distance to the table - r) over every tick
  double min_cloth_gap_m = 1e300;     ///< least (distance to the cloth - r) over every tick
  int pop_through = 0;  ///< ticks the proxy was on the other side of its last contact triangle
};

// Runs the sheet at 60 Hz and the proxy at 1 kHz: settle 1 s, come down from 5 cm above the
// sheet's centre to 2 cm below the tabletop over 0.5 s, hold 1.5 s.
PinchRun Pinch(SnapshotMode mode, double stiffness_N_per_m) {
  const SimSpec spec = ParseSimSpec(ParseSceneText(testing::SpringlessSheet(), "pinch.toml"));
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  DeviceSpec device = UnitDevice(0.004);
  device.stiffness_N_per_m = stiffness_N_per_m;
  device.max_force_N = 3.3;
  ProxySpec proxy = Spec(mode, true);
  proxy.obstacles = spec.cloth.obstacles;
  const ObstacleSpec& table = proxy.obstacles[0];
  const double frame_dt = 1.0 / 60.0;
  for (int f = 0; f < 60; ++f) StepFrame(model, {}, frame_dt, &state);
  PinchRun run;
  ProxyState ps = MakeProxyState(CompileProxyModel(device, proxy));
  const Vec3 top(0.003, 0.05, 0.002);
  const Vec3 pressed(0.003, -0.02, 0.002);
  int32_t side_triangle = -1;
  int32_t side = 0;
  int64_t tick = 0;
  testing::RunLockstep(
      model, &state, device, proxy, &ps, 2.0,
      [&](double t) {
        const double s = std::min(1.0, t / 0.5);
        return DeviceSample{top + (s * s * (3.0 - 2.0 * s)) * (pressed - top), Vec3::Zero()};
      },
      [&](double, double since, const ProxyTickResult& r, const ClothSnapshot& prev,
          const ClothSnapshot& next) {
        run.forces.push_back(r.force_D_N);
        // Never inside the table.
        run.min_table_gap_m =
            std::min(run.min_table_gap_m,
                     ClosestObstaclePoint(table, r.proxy_W_m).distance_m - device.radius_m);
        // Never inside the cloth of the tick (the mode's: newest, or one frame late interpolated).
        const double alpha = std::clamp(since / frame_dt, 0.0, 1.0);
        const ClothView view = mode == SnapshotMode::kInterpolate && !r.on_newest
                                   ? ClothView{&prev, &next, alpha, 0.0}
                                   : ClothView::Of(next);
        double best = 1e300;
        for (int32_t k = 0; k < next.num_triangles(); ++k) {
          Vec3 a, b, c;
          view.Corners(k, &a, &b, &c);
          best = std::min(best, ClosestPointOnTriangle(r.proxy_W_m, a, b, c).distance_sq);
        }
        run.min_cloth_gap_m = std::min(run.min_cloth_gap_m, std::sqrt(best) - device.radius_m);
        // Never on the other side of the triangle it last touched while over that triangle
        // (bench_haptic.cc's pop-through).
        if (side_triangle >= 0) {
          Vec3 a, b, c;
          view.Corners(side_triangle, &a, &b, &c);
          const bool interior =
              ClosestPointOnTriangle(r.proxy_W_m, a, b, c).barycentric.minCoeff() > 1e-6;
          const int32_t now_side = SideOfTriangle(r.proxy_W_m, a, b, c);
          if (interior && now_side != 0 && side != 0 && now_side != side) ++run.pop_through;
        }
        side_triangle = -1;
        if (ps.body.num_contacts > 0 && ps.body.contacts[0].triangle >= 0) {
          side_triangle = ps.body.contacts[0].triangle;
          Vec3 a, b, c;
          view.Corners(side_triangle, &a, &b, &c);
          side = SideOfTriangle(r.proxy_W_m, a, b, c);
        }
        if (tick == 1999) {
          run.pressed_force = r.force_D_N;
          run.pressed_contact = ps.body.num_contacts > 0 ? ps.body.contacts[0].triangle : -999;
        }
        ++tick;
      },
      [](double) {});
  EXPECT_EQ(state.counters.nan_events, 0u) << "the coupled cloth went non-finite";
  return run;
}

TEST(ObstacleProxyTest, PointerPinchingTheSimulatedClothAgainstATable) {
  for (SnapshotMode mode : {SnapshotMode::kInterpolate, SnapshotMode::kNewest}) {
    for (double k : {100.0, 200.0}) {
      if (testing::Sanitized() && k != 200.0) continue;  // the same paths (tests/test_env.h)
      const PinchRun run = Pinch(mode, k);
      const std::string label = std::string(SnapshotModeName(mode)) + " k=" + std::to_string(k);
      EXPECT_GE(run.min_table_gap_m, -1e-12) << label << ": the proxy entered the table";
      EXPECT_GE(run.min_cloth_gap_m, -1e-6) << label << ": the proxy entered the cloth";
      EXPECT_EQ(run.pop_through, 0) << label;
      // Resting on the cloth, which lies at the 2 mm margin: k times the pointer's depth behind
      // the proxy, (margin + r + 2 cm), up along the table's normal, clamped to 3.3 N.
      EXPECT_GE(run.pressed_contact, 0) << label << ": on the cloth, not on the table";
      const double on_cloth = std::min(3.3, k * (0.002 + 0.004 + 0.02));
      EXPECT_NEAR(run.pressed_force.y(), on_cloth, 0.02 * on_cloth) << label;
      EXPECT_LT(Vec3(run.pressed_force.x(), 0, run.pressed_force.z()).norm(), 0.05 * on_cloth)
          << label;
    }
  }
}

TEST(ObstacleProxyTest, PinchRepeatRunsAreBitIdentical) {
  const PinchRun a = Pinch(SnapshotMode::kInterpolate, 100.0);
  const PinchRun b = Pinch(SnapshotMode::kInterpolate, 100.0);
  ASSERT_EQ(a.forces.size(), b.forces.size());
  EXPECT_EQ(std::memcmp(a.forces.data(), b.forces.data(), a.forces.size() * sizeof(Vec3)), 0);
}

}  // namespace
}  // namespace felt
