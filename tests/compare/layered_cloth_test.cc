// The proxy against layered cloth (issue 22's haptic hard case; scenes/self_fold_press.toml): a
// cloth folded back over itself on a table, with self-collision, driven by a scripted hand
// through the real server in lock-step virtual time (compare/lockstep.h), in every snapshot mode.
// Each tick the proxy is placed against the cloth it was rendered on (the triangles its tick
// gathered, at the tick's positions): which layers lie straight above and below its centre.
// Each frame the sim's cloth is checked for intersecting non-adjacent triangle pairs (the exact
// test). Targets (issue 22): a fold never closes on the proxy (it comes to rest between the
// layers, or outside them, never with a layer through it); the proxy never ends between two
// layers it did not enter through; pressing two layers together is felt as two layers (the force
// rises when the second layer is reached, with the first one still between); no pop-through.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "collision/self_intersection.h"
#include "compare/lockstep.h"
#include "server/server.h"
#include "tests/test_env.h"

namespace felt {
namespace {

// What one tick saw.
struct LayeredTick {
  double t_s = 0.0;
  Vec3 proxy_W_m = Vec3::Zero();
  double force_N = 0.0;      // |the proxy's force| (before the safety layer), N
  bool layer_above = false;  // a gathered triangle straight above the proxy's centre
  int32_t layers_below = 0;  // distinct layers straight below (heights more than 0.2 mm apart)
};

// One run of the fold scene.
struct LayeredRun {
  std::vector<LayeredTick> ticks;
  int64_t max_intersections = 0;  // sim cloth, end of every frame
  int64_t first_bad_frame = -1;
  uint64_t unresolved = 0;  // sim self-collision: substeps left unresolved
  uint64_t guard_pushes = 0;        // the server's report: the sim's sphere guard pushes
  uint64_t patch_guard_pushes = 0;  // ... the patch's
  VariantSummary summary;   // pop_through, max_reach_mm, nan_events
};

// The height of triangle (a, b, c) straight above or below p (its vertical line through p's x, z
// inside the triangle's projection on the x-z plane, borders included); false if it misses.
bool LayeredHeightAt(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, double* y) {
  const double d = (b.x() - a.x()) * (c.z() - a.z()) - (c.x() - a.x()) * (b.z() - a.z());
  if (std::abs(d) < 1e-14) return false;  // seen edge-on from above
  const double u = ((p.x() - a.x()) * (c.z() - a.z()) - (c.x() - a.x()) * (p.z() - a.z())) / d;
  const double v = ((b.x() - a.x()) * (p.z() - a.z()) - (p.x() - a.x()) * (b.z() - a.z())) / d;
  if (u < 0.0 || v < 0.0 || u + v > 1.0) return false;
  *y = a.y() + u * (b.y() - a.y()) + v * (c.y() - a.y());
  return true;
}

// Runs the scene in snapshot mode `mode` with the hand at hand(t) (world = device: scale 1),
// for `seconds` of virtual time.
LayeredRun RunFold(const std::string& mode, const std::function<Vec3(double)>& hand,
                   double seconds) {
  const SceneDocument scene =
      LoadSceneDocument(std::string(FELT_SOURCE_DIR "/scenes/self_fold_press.toml"));
  const ServerSpec spec = VariantSpec(scene, ParseVariantList("snapshot=" + mode)[0], 0);
  std::vector<TraceSample> samples;
  for (int64_t k = 0; k * 1e-3 <= seconds + 1e-9; ++k) {
    const double t = static_cast<double>(k) * 1e-3;
    samples.push_back({t, hand(t), (hand(t + 1e-4) - hand(t)) / 1e-4, 0});
  }
  LayeredRun run;
  std::vector<double> below;
  LockstepOptions options;
  options.on_frame = [&](const Server& server, int64_t frame) {
    const int64_t count = CountSelfIntersections(server.cloth().x, server.model().triangles);
    if (count > 0 && run.first_bad_frame < 0) run.first_bad_frame = frame;
    run.max_intersections = std::max(run.max_intersections, count);
    run.unresolved = server.cloth().counters.self_unresolved_substeps;
  };
  options.on_tick = [&](const Server& server, int64_t tick) {
    const ProxyState& ps = server.haptic().proxy_state(0);
    LayeredTick out;
    out.t_s = static_cast<double>(tick - 1) * 1e-3;
    out.proxy_W_m = ps.body.p_W_m;
    out.force_N = server.haptic().last_result(0).force_W_N.norm();
    below.clear();
    for (const LocalTriangle& tri : ps.local.triangles()) {
      double y = 0.0;
      if (!LayeredHeightAt(out.proxy_W_m, tri.a, tri.b, tri.c, &y)) continue;
      if (y > out.proxy_W_m.y()) {
        out.layer_above = true;
      } else {
        below.push_back(y);
      }
    }
    // Triangles meeting on the vertical line (an edge under it) are one layer.
    std::sort(below.begin(), below.end());
    for (size_t i = 0; i < below.size(); ++i) {
      if (i == 0 || below[i] - below[i - 1] > 2e-4) ++out.layers_below;
    }
    run.ticks.push_back(out);
    if (tick % 500 == 0) {  // the stats as `felt serve` reports them (they only grow)
      const std::unique_ptr<ServerReport> report = server.Report();
      run.guard_pushes = report->guard_pushes;
      run.patch_guard_pushes = report->patch_guard_pushes;
    }
  };
  std::vector<LockstepRun> runs;
  runs.push_back(RunLockstep(spec, samples, options));
  run.summary = SummarizeRuns(runs)[0];
  return run;
}

// The hand: waits 8 cm above the table at x = -15 mm, z = 0 (over the top of the fold's loop)
// while the fold forms, then from t = 0.9 s comes down at 9 cm/s to 1 cm under the table's top
// (the force reaches the 3.3 N clamp), pushing the loop shut and pinching its two layers.
Vec3 LayeredPressHand(double t) {
  const double s = std::clamp((t - 0.9) / 1.0, 0.0, 1.0);
  return Vec3(-0.015, 0.08 - 0.09 * s, 0.0);
}

// LayeredPressHand at x = x_m instead of -15 mm.
std::function<Vec3(double)> LayeredPressHandAt(double x_m) {
  return [x_m](double t) {
    const double s = std::clamp((t - 0.9) / 1.0, 0.0, 1.0);
    return Vec3(x_m, 0.08 - 0.09 * s, 0.0);
  };
}

// The hand: comes down onto the cloth at x = x_m, z = 0 in the first 0.2 s and presses it lightly
// onto the table (1 mm deep: 0.4 N), held there while the fold forms (t = 0.3 s to 0.8 s) and its
// flap lands over the hand.
std::function<Vec3(double)> LayeredClosingHandAt(double x_m) {
  return [x_m](double t) { return Vec3(x_m, 0.03 - 0.025 * std::min(t / 0.2, 1.0), 0.0); };
}

// The scene's hand, at x = -45 mm.
Vec3 LayeredClosingHand(double t) { return LayeredClosingHandAt(-0.045)(t); }

// What every mode and trace keeps: the sim's cloth never intersects itself (exact test, end of
// every frame) and leaves no collision unresolved under the hand's push; no pop-through, no reach
// into the cloth beyond 0.5 mm (an eighth of the radius, as LockstepPatch's bound); no NaN.
void ExpectLayeredBasics(const LayeredRun& run) {
  EXPECT_EQ(run.max_intersections, 0) << "first at frame " << run.first_bad_frame;
  EXPECT_EQ(run.unresolved, 0u);
  EXPECT_EQ(run.summary.pop_through, 0u);
  EXPECT_LT(run.summary.max_reach_mm, 0.5);
  EXPECT_EQ(run.summary.nan_events, 0u);
}

// Pressing the fold shut from above: the proxy never has a layer above it (it came from above and
// may not end between the layers or under them), and over the last 0.1 s, pressed at the clamp,
// it rests on two layers (the loop's top and the lower layer): the force rose at the second layer,
// with the first still between.
void ExpectPressFeelsTwoLayers(const LayeredRun& run) {
  ExpectLayeredBasics(run);
  int64_t above = 0;
  for (const LayeredTick& t : run.ticks) above += t.layer_above ? 1 : 0;
  EXPECT_EQ(above, 0) << "ticks with a layer above the proxy";
  ASSERT_GT(run.ticks.size(), 100u);
  int64_t on_two = 0;
  const size_t last = run.ticks.size() - 100;  // the last 0.1 s, the hand at its lowest
  for (size_t k = last; k < run.ticks.size(); ++k) {
    EXPECT_GT(run.ticks[k].force_N, 3.0) << "tick " << k;
    on_two += run.ticks[k].layers_below >= 2 ? 1 : 0;
  }
  EXPECT_EQ(on_two, 100) << "of the last 100 ticks, on two layers";
}

// The flap landing on a proxy held on the lower layer: it never closes through the proxy (never
// two layers under it), and nothing ever gets between the proxy and the table's layer from below.
void ExpectFoldNeverClosesOnTheProxy(const LayeredRun& run) {
  ExpectLayeredBasics(run);
  int64_t under_two = 0, flap_above = 0;
  for (const LayeredTick& t : run.ticks) {
    under_two += t.layers_below >= 2 ? 1 : 0;
    flap_above += t.layer_above ? 1 : 0;
  }
  EXPECT_EQ(under_two, 0) << "ticks with two layers under the proxy (the flap went through it)";
  EXPECT_GT(flap_above, 0) << "the flap never came over the proxy: the case is not tested";
}

// The modes that meet the targets; the others are measured in the DISABLED_ tests below. Under a
// sanitizer the first mode of each list only (a run is 2 s of virtual time with the fold's
// self-collision: about ten times slower there).
std::vector<std::string> LayeredModes(std::vector<std::string> modes) {
  if (testing::Sanitized()) modes.resize(1);
  return modes;
}

TEST(LayeredCloth, PressingAFoldShutIsFeltAsTwoLayers) {
  for (const std::string& mode : LayeredModes({"interpolate", "newest"})) {
    SCOPED_TRACE(mode);
    ExpectPressFeelsTwoLayers(RunFold(mode, LayeredPressHand, 2.0));
  }
}

TEST(LayeredCloth, AFoldNeverClosesOnTheProxy) {
  for (const std::string& mode :
       LayeredModes({"patch", "newest", "extrapolate", "interpolate", "blend_forces"})) {
    SCOPED_TRACE(mode);
    const LayeredRun run = RunFold(mode, LayeredClosingHand, 2.0);
    ExpectFoldNeverClosesOnTheProxy(run);
    // The sphere guard kept the flap out, and the server's stats say so (the patch's only in
    // mode patch).
    EXPECT_GT(run.guard_pushes, 0u);
    if (mode != "patch") {
      EXPECT_EQ(run.patch_guard_pushes, 0u);
    }
  }
}

// The flap landing on the hand elsewhere: the hand at x = -51 to -39 mm, 2 mm apart (-45 mm, the
// scene's, is AFoldNeverClosesOnTheProxy's), in every mode. Before the proxy's sphere kept the
// other layers out (self_collision.guard_proxy; sim_loop/cloth_coupling.h) 15 of these 30 runs
// failed (patch at 4 positions, newest at 5, extrapolate at 1, blend_forces at 5), and
// blend_forces at the scene's -45 mm too: where the flap landed decided it, nothing in the sim
// keeping another layer out of the proxy. Physics only: under a sanitizer the same scene, mode
// and code paths are AFoldNeverClosesOnTheProxy's run (a run is about ten times slower there;
// CI's 20 minutes).
TEST(LayeredCloth, AFoldNeverClosesOnTheProxyWhereverItLands) {
  if (testing::Sanitized()) GTEST_SKIP() << "physics only; the release run checks it";
  const std::vector<double> positions = {-0.051, -0.049, -0.047, -0.043, -0.041, -0.039};
  for (const std::string& mode :
       LayeredModes({"patch", "newest", "extrapolate", "interpolate", "blend_forces"})) {
    for (double x : positions) {
      SCOPED_TRACE(mode + ", hand at x = " + std::to_string(x) + " m");
      ExpectFoldNeverClosesOnTheProxy(RunFold(mode, LayeredClosingHandAt(x), 2.0));
    }
  }
}

// Known failures (issue 22, left open; docs/proxy.md, "Layered cloth"), kept compiled and runnable
// with --gtest_also_run_disabled_tests. Measured (release, 2026-11-28, this scene): pressing the
// fold shut, mode patch has a layer above the proxy on 49 ticks and reaches 3.6 mm into the cloth
// (40 ticks and no reach without the sphere guard), and is never on two layers at the clamp (the
// local patch has no self-collision: the loop's top goes through the lower layer there);
// extrapolate has a layer above it on 59 ticks (between layers it did not enter through), and
// blend_forces on 4. The sim's cloth never intersects itself in any of them.
TEST(LayeredCloth, DISABLED_PressingAFoldShutInTheOtherModes) {
  for (const char* mode : {"patch", "extrapolate", "blend_forces"}) {
    SCOPED_TRACE(mode);
    ExpectPressFeelsTwoLayers(RunFold(mode, LayeredPressHand, 2.0));
  }
}

// Pressing with the hand at x = -27 to -3 mm, 2 mm apart, instead of the scene's -15 mm. Measured
// (release, 2026-11-28): mode interpolate meets the targets at -27 to -15 mm (7 of 13), newest at
// -27 to -21, -17 and -15 mm (6), patch at none; from -13 mm on the hand meets one layer only in
// every mode, and at -13 mm (interpolate, newest, patch), at -19, -11, -9, -5 and -3 mm (newest)
// and at 7 of 13 positions (patch) a layer comes above the proxy. The same runs pass and fail with
// and without the sphere guard.
TEST(LayeredCloth, DISABLED_PressingAFoldShutWhereverTheHandComes) {
  for (const char* mode : {"interpolate", "newest", "patch"}) {
    for (int i = 0; i < 13; ++i) {
      const double x = -0.027 + 0.002 * i;
      SCOPED_TRACE(std::string(mode) + ", hand at x = " + std::to_string(x) + " m");
      ExpectPressFeelsTwoLayers(RunFold(mode, LayeredPressHandAt(x), 2.0));
    }
  }
}

// The flap landing on the hand farther afield: x = -57 to -33 mm, 2 mm apart, every mode.
// Measured (release, 2026-11-28): 64 of 65 meet the target; patch fails at -57 mm (the proxy
// reaches 0.83 mm into the cloth). Without the sphere guard: 28 of 65; with it moving only the
// patch's free particles, not its driven rings, patch failed at -35 mm too (two layers under the
// proxy on 18 ticks, reach 3.9 mm).
TEST(LayeredCloth, DISABLED_AFoldNeverClosesOnTheProxyFartherAfield) {
  for (const char* mode : {"patch", "newest", "extrapolate", "interpolate", "blend_forces"}) {
    for (int i = 0; i < 13; ++i) {
      const double x = -0.057 + 0.002 * i;
      SCOPED_TRACE(std::string(mode) + ", hand at x = " + std::to_string(x) + " m");
      ExpectFoldNeverClosesOnTheProxy(RunFold(mode, LayeredClosingHandAt(x), 2.0));
    }
  }
}

}  // namespace
}  // namespace felt
