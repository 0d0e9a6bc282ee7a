// The proxy coupled both ways with the real cloth simulation (sim_loop/cloth.h): a user pressing
// into the curtain and holding still must come to rest without oscillation or drift.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "proxy/proxy.h"
#include "proxy/proxy_scene.h"
#include "scene/scene_file.h"
#include "sim_loop/cloth.h"
#include "sim_loop/cloth_scene.h"
#include "sim_loop/frame_motion.h"
#include "sim_loop/snapshot.h"
#include "tests/proxy/proxy_test_util.h"
#include "tests/test_env.h"

namespace felt {
namespace {

struct Sample {
  double t_s;
  Vec3 force_D_N;
  Vec3 proxy_W_m;
};

// How a press-and-hold run is set up.
struct PressSetup {
  SnapshotMode mode = SnapshotMode::kInterpolate;
  double settle_s = 2.0;           ///< untouched curtain before the approach, s
  double depth_m = 0.02;           ///< the hand's final place behind the curtain, world, m
  double hold_s = 5.0;             ///< holding still after the 0.5 s approach, s
  double drag_scale = 1.0;         ///< the scene's air drag times this
  Vec3 offset_W_m = Vec3::Zero();  ///< press point relative to the centre particle, world, m
};

// What a press-and-hold run gave.
struct PressResult {
  std::vector<Sample> hold;          ///< the samples of the hold
  uint64_t reduced_frames = 0;       ///< frames with k_eff < k, the whole run
  uint64_t reduced_late_frames = 0;  ///< frames from 1 s into the hold on with k_eff < k
};

// Runs the curtain at 60 Hz and one device at 1 kHz in `setup.mode`: settle untouched, approach
// and press `depth_m` behind the press point over 0.5 s, then hold still for `hold_s`.
PressResult PressAndHold(const PressSetup& setup) {
  const SceneDocument doc =
      LoadSceneDocument(std::string(FELT_SOURCE_DIR) + "/scenes/curtain.toml");
  SimSpec spec = ParseSimSpec(doc);
  spec.cloth.drag_N_s_per_m *= setup.drag_scale;
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  DeviceSpec device = ParseDeviceSpec(doc);
  ProxySpec proxy = ParseProxySpec(doc);
  proxy.snapshot_mode = setup.mode;
  const double settle_s = setup.settle_s;
  const double depth_m = setup.depth_m;
  const double hold_s = setup.hold_s;
  const double frame_dt = 1.0 / 60.0;
  // Settle the hanging curtain first (no contact).
  for (int f = 0; f < static_cast<int>(settle_s * 60.0); ++f)
    StepFrame(model, {}, frame_dt, &state);
  // The coupling can only be judged on a cloth that is itself healthy.
  EXPECT_EQ(state.counters.nan_events, 0u)
      << "the curtain went non-finite before any contact: a cloth-sim problem (sim_loop/cloth*)";
  if (state.counters.nan_events != 0) return {};
  PressResult result;
  ProxyState ps = MakeProxyState(CompileProxyModel(device, proxy));
  // The centre particle is where the user presses, from the +z side.
  const int32_t centre = GridIndex(model.width, model.width / 2, model.height / 2);
  const Vec3 target_W = state.x[centre] + setup.offset_W_m + Vec3(0.0, 0.0, -depth_m);
  const Vec3 start_W = state.x[centre] + setup.offset_W_m + Vec3(0.0, 0.0, 0.05);
  std::vector<Sample>& hold = result.hold;
  uint64_t reduced_at_1s = 0;
  testing::RunLockstep(
      model, &state, device, proxy, &ps, 0.5 + hold_s,
      [&](double t) {
        const double s = std::min(1.0, t / 0.5);
        const Vec3 goal_W = start_W + (s * s * (3.0 - 2.0 * s)) * (target_W - start_W);
        return DeviceSample{WorldToDevice(device, goal_W), Vec3::Zero()};
      },
      [&](double t, double, const ProxyTickResult& r, const ClothSnapshot&, const ClothSnapshot&) {
        if (t >= 0.5) hold.push_back({t - 0.5, r.force_D_N, r.proxy_W_m});
      },
      [&](double t) {
        if (t < 1.5) reduced_at_1s = state.counters.coupling_reduced_frames;
      });
  EXPECT_EQ(state.counters.nan_events, 0u) << "the coupled cloth went non-finite";
  EXPECT_EQ(state.counters.coupling_overflows, 0u);
  result.reduced_frames = state.counters.coupling_reduced_frames;
  result.reduced_late_frames = state.counters.coupling_reduced_frames - reduced_at_1s;
  return result;
}

// Peak-to-peak of |force| over samples with t in [a, b).
double ForceSpread(const std::vector<Sample>& s, double a, double b) {
  double lo = 1e300;
  double hi = -1e300;
  for (const Sample& x : s) {
    if (x.t_s < a || x.t_s >= b) continue;
    lo = std::min(lo, x.force_D_N.norm());
    hi = std::max(hi, x.force_D_N.norm());
  }
  return hi - lo;
}

// Under a sanitizer the holds are 1 s long and convergence is not judged (tests/test_env.h): the
// same code runs, the release run checks the physics.
double HoldSeconds(double release_s) { return testing::Sanitized() ? 1.0 : release_s; }

// Converged: the last second of the hold barely moves (force spread under 2 % of the last force
// plus 1 mN, the proxy within 0.5 mm of its last place), and any oscillation decays (the last
// second's spread no larger than the second second's).
void ExpectConverged(const std::vector<Sample>& hold, SnapshotMode mode) {
  if (testing::Sanitized()) return;
  const Sample& last = hold.back();
  const double end = last.t_s;
  const double late = ForceSpread(hold, end - 1.0, end + 1.0);
  const double early = ForceSpread(hold, 1.0, 2.0);
  EXPECT_LT(late, 0.02 * last.force_D_N.norm() + 1e-3) << SnapshotModeName(mode);
  EXPECT_LE(late, early + 1e-6) << SnapshotModeName(mode);
  double drift = 0.0;
  for (const Sample& s : hold) {
    if (s.t_s >= end - 1.0) drift = std::max(drift, (s.proxy_W_m - last.proxy_W_m).norm());
  }
  EXPECT_LT(drift, 5e-4) << SnapshotModeName(mode);
}

// Presses and holds in every snapshot mode (hold_s [s] in release runs, 1 s under a sanitizer;
// the scene's air drag times drag_scale; offset_W [m] from the centre particle) and expects the
// hold to come to rest: the curtain pushes back toward the user (it swings away: ~0.035 N at 2 cm;
// a lost contact gives 0), well inside the device's range, with the contact spring at the device's
// k, and ExpectConverged.
void ExpectPressComesToRest(double hold_s, double drag_scale, const Vec3& offset_W) {
  for (SnapshotMode mode : {SnapshotMode::kInterpolate, SnapshotMode::kNewest,
                            SnapshotMode::kBlendForces, SnapshotMode::kExtrapolate}) {
    PressSetup setup;
    setup.mode = mode;
    setup.hold_s = HoldSeconds(hold_s);
    setup.drag_scale = drag_scale;
    setup.offset_W_m = offset_W;
    const PressResult run = PressAndHold(setup);
    const std::vector<Sample>& hold = run.hold;
    ASSERT_FALSE(hold.empty());
    const Sample& last = hold.back();
    EXPECT_GT(last.force_D_N.z(), 0.01) << SnapshotModeName(mode);
    EXPECT_LT(last.force_D_N.norm(), 3.3) << SnapshotModeName(mode);
    EXPECT_EQ(run.reduced_late_frames, 0u) << SnapshotModeName(mode);
    ExpectConverged(hold, mode);
  }
}

// The press on the default curtain itself (air drag c/m = 0.5 /s, nothing else damps its sway),
// half a cell off the centre vertex, held 12 s: the force settles as the untouched curtain does.
// Measured over a 20 s hold (force spread per 1 s window at 0-1, 4-5, 8-9, 12-13 and 18-19 s, mN):
// interpolate 85, 7.0, 1.8, 0.57, 0.08; newest and extrapolate within 20 % of these from 4 s on.
// The untouched curtain's centre particle moves 35 um within 6-7 s and 0.4 um within 18-19 s: the
// hold decays at the cloth's own rate, halving about every 2 s.
TEST(CoupledTest, PressAndHoldOnTheDefaultCurtainComesToRest) {
  ExpectPressComesToRest(12.0, 1.0, Vec3(0.008, -0.005, 0.0));
}

// Pressed exactly at the centre vertex of the default curtain, held 14 s: the force settles as
// half a cell off it does. The pressed particle makes a funnel, and the proxy comes to rest in the
// crease between two of its faces (their normals 18.5 deg apart). While the sim's contact spring
// pressed on the one nearest point of the cloth, that point hopped between the two faces (30-44
// times in 944 force evaluations per 2 s) and its force flipped sideways by a third of it each
// time; the leapfrog substeps integrated that with an energy error the light drag did not remove:
// over 20-30 s of a 30 s hold, force std 0.20-0.29 mN newest, 0.14-0.15 interpolate, 0.17-0.21
// blend_forces, 0.32-0.52 extrapolate, 1-4.5 mN peak to peak (this test failed: 2.3 mN
// interpolate, 3.6 mN extrapolate in the last second against 1.7 allowed). The proxy's own contact
// stayed on one triangle meanwhile, and with the sim's sphere frozen the jitter stayed: it was the
// sim's nearest point. The sim now smooths that point across creases (sim_loop/cloth_coupling.h,
// AddCouplingForces): std 0.002-0.003 mN, 0.006-0.017 mN peak to peak at 28-30 s in every mode.
TEST(CoupledTest, PressAtTheVertexOfTheDefaultCurtainComesToRest) {
  ExpectPressComesToRest(14.0, 1.0, Vec3::Zero());
}

// The coupling itself comes to rest: the same press on a curtain whose air drag damps its own
// sway (10 x the scene's, c/m = 5 /s), half a cell off the centre vertex and right at it.
// Snapshots are published as the server does, with the frame's motion as velocities
// (sim_loop/frame_motion.h), which mode extrapolate moves the cloth on with. At the vertex the
// proxy's contact hops between the triangles around it; while the sim's contact spring was tied
// to the one triangle of the frame's last tick, that press cycled at 20 Hz between 0.034 and
// 0.046 N in every mode (a spring whose attachment jumps with the cloth is not conservative). The
// sim now presses the proxy's sphere onto the cloth's nearest point (sim_loop/cloth.h,
// ExternalForce), and both presses settle to a constant force.
TEST(CoupledTest, PressAndHoldOnAnAirDampedCurtainComesToRest) {
  for (const Vec3& offset : {Vec3(0.008, -0.005, 0.0), Vec3(0.0, 0.0, 0.0)}) {
    SCOPED_TRACE(offset.isZero() ? "at the centre vertex" : "half a cell off it");
    ExpectPressComesToRest(5.0, 10.0, offset);
  }
}

}  // namespace
}  // namespace felt
