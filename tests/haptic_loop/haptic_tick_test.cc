// The 1 kHz tick on its own (haptic_loop/haptic_tick.h): a HapticLoop against a SimLoop's two
// handoffs, no Server and no threads. A device that has not spoken gets nothing; a press is felt
// and its reaction reaches the sim loop through the queue (impulse counted on both sides); a
// non-finite sample is rejected and counted and the device gets zero force.
#include "haptic_loop/haptic_tick.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "rt/loop_stats.h"
#include "sim_loop/sim_frame.h"
#include "tests/server/server_test_util.h"

namespace felt {
namespace {

using testing_server::PressPosition;
using testing_server::SmallCurtain;

constexpr int64_t kT0Ns = 1'000'000'000;
constexpr int64_t kTickNs = 1'000'000;

// A sim loop and a haptic loop wired as the server wires them, on a test clock.
struct Loops {
  explicit Loops(const ServerSpec& spec)
      : sim(spec.sim, spec.proxy.structure),
        source(static_cast<uint32_t>(spec.devices.size())),
        sink(static_cast<uint32_t>(spec.devices.size())),
        stats(kTickNs),
        haptic(spec.proxy, spec.devices, spec.haptic, sim.model(), sim.snapshots().read_slot().snapshot,
               &sim.snapshots(), &sim.reactions(), &source, &sink, &stats) {
    sim.PublishInitialSnapshot(kT0Ns);
  }

  // One tick at ms `k` (a sim frame first every 16 ms), device 0 at `p_D` when `feed`.
  void Tick(int k, bool feed, const Vec3& p_D) {
    const int64_t now = kT0Ns + int64_t{k} * kTickNs;
    if (k % 16 == 0) sim.Frame(1.0 / 60.0, now);
    if (feed) {
      PointerInput in;
      in.seq = static_cast<uint64_t>(k) + 1;
      in.receive_time_ns = now;
      in.p_D_m = p_D;
      source.Set(0, in);
    }
    haptic.Tick(now, 1e-3);
  }

  SimLoop sim;
  LatestPointerSource source;
  CapturingForceSink sink;
  LoopStats stats;
  HapticLoop haptic;
};

TEST(HapticTick, ASilentDeviceGetsNothing) {
  Loops loops(SmallCurtain());
  for (int k = 0; k < 50; ++k) loops.Tick(k, false, Vec3::Zero());
  EXPECT_EQ(loops.haptic.counters().ticks.load(), 50u);
  EXPECT_EQ(loops.sink.pushed(0), 0u);
  EXPECT_EQ(loops.haptic.device_counters(0).ticks_with_input.load(), 0u);
}

TEST(HapticTick, APressIsFeltAndItsReactionReachesTheSim) {
  ServerSpec spec = SmallCurtain();
  spec.haptic.safety.ramp_in_s = 0.05;
  Loops loops(spec);
  for (int k = 0; k < 600; ++k) loops.Tick(k, true, PressPosition(k));
  const DeviceCounters& c = loops.haptic.device_counters(0);
  EXPECT_EQ(loops.sink.pushed(0), 600u);
  EXPECT_GT(c.contact_ticks.load(), 0u);
  EXPECT_GT(loops.sink.peak_force_N(0), 0.1);
  // Reactions: batches staged per new snapshot, pushed, applied by the sim's frames; the impulse
  // the haptic side queued is what the sim applied (up to the batch still in flight).
  const uint64_t pushed = loops.haptic.counters().reaction_batches.load();
  EXPECT_GT(pushed, 0u);
  EXPECT_GE(loops.sim.counters().reaction_batches_applied.load() + 1, pushed);
  EXPECT_GT(c.reaction_impulse_N_s.load(), 0.0);
  EXPECT_GT(loops.sim.counters().applied_impulse_N_s.load(), 0.0);
  EXPECT_EQ(loops.haptic.counters().sim_stalled_ticks.load(), 0u);
}

TEST(HapticTick, ANonFiniteSampleIsCountedAndGivesZeroForce) {
  Loops loops(SmallCurtain());
  for (int k = 0; k < 300; ++k) loops.Tick(k, true, PressPosition(k));
  const Vec3 bad(std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0);
  loops.Tick(300, true, bad);
  ForceOutput out;
  ASSERT_TRUE(loops.sink.Newest(0, &out));
  EXPECT_TRUE(out.force_D_N.allFinite());
  EXPECT_EQ(out.force_D_N, Vec3::Zero());
  EXPECT_EQ(loops.haptic.device_counters(0).nan_events.load(), 1u);
}

// The local contact model sent with each force (Mark et al. 1996) reproduces the force at the
// tick's own position: k max(0, (point - p) . n) n = F_D for one frictionless contact without
// force shading, damping or clamp. Its plane is zero out of contact and during the ramp-in.
TEST(HapticTick, TheContactPlaneReproducesTheForceAtTheTicksPosition) {
  ServerSpec spec = SmallCurtain();
  spec.proxy.force_shading = false;
  spec.proxy.friction_static = 0.0;
  spec.proxy.friction_dynamic = 0.0;
  spec.devices[0].damping_N_s_per_m = 0.0;
  spec.haptic.safety.ramp_in_s = 0.05;
  spec.haptic.safety.max_force_rate_N_per_s = 1e9;
  Loops loops(spec);
  int planes = 0, checked = 0;
  double worst_N = 0.0;
  for (int k = 0; k < 600; ++k) {
    const Vec3 p_D = PressPosition(k);
    loops.Tick(k, true, p_D);
    ForceOutput out;
    ASSERT_TRUE(loops.sink.Newest(0, &out));
    if (out.contact_stiffness_N_per_m <= 0.0) {
      EXPECT_EQ(out.contact_normal_D, Vec3::Zero());
      EXPECT_TRUE(!out.in_contact || (out.flags & kSafetyRamping) != 0)
          << k << " flags " << out.flags;
      continue;
    }
    ++planes;
    EXPECT_TRUE(out.in_contact);
    EXPECT_EQ(out.flags & (kSafetyRamping | kSafetyStaleInput), 0u);
    EXPECT_NEAR(out.contact_normal_D.norm(), 1.0, 1e-9);
    EXPECT_EQ(out.contact_stiffness_N_per_m, spec.devices[0].stiffness_N_per_m);
    if (out.flags & kSafetyClamped) continue;
    const double depth_m = std::max(0.0, (out.contact_point_D_m - p_D).dot(out.contact_normal_D));
    const Vec3 local_N = out.contact_stiffness_N_per_m * depth_m * out.contact_normal_D;
    worst_N = std::max(worst_N, (local_N - out.force_D_N).norm());
    ++checked;
  }
  std::printf("planes %d, checked %d, worst %.3g N\n", planes, checked, worst_N);
  EXPECT_GT(planes, 100);
  EXPECT_GT(checked, 100);
  EXPECT_LT(worst_N, 1e-9);  // measured: 7.3e-16 N over 481 ticks
}

}  // namespace
}  // namespace felt

namespace felt {
namespace {

// A frame that receives no batch (the sim running ahead of the haptic loop: two frames per tick,
// or a late tick) keeps the hand's contact spring of the last batch, at most kMaxHeldSpringFrames
// frames; a batch without a spring (a brief touch) is not held.
TEST(HapticTick, TheBatchOfAnArrivalTickCarriesThatTicksOwnContact) {
  // The reactions are staged after the proxies ran: the batch a new snapshot triggers holds the
  // contact spring of that very tick (its sphere centred on the proxy where the tick left it), so
  // with a frame every tick the cloth answers the hand one tick late, not two (docs/compare.md).
  ServerSpec spec = SmallCurtain();
  Loops loops(spec);
  ReactionBatch batch;
  int checked = 0;
  for (int k = 0; k < 400; ++k) {
    // Drain every batch the sim would read (the frames of Loops::Tick pop none before this tick).
    loops.Tick(k, true, PressPosition(k));
    while (loops.sim.reactions().TryPop(&batch)) {
      if (k % 16 != 0 || batch.count != 1 || !(batch.forces[0].stiffness_N_per_m > 0.0)) continue;
      const ExternalForce& e = batch.forces[0];
      const Vec3 centre = e.anchor_m + e.radius_m * e.normal;
      EXPECT_LT((centre - loops.haptic.proxy_state(0).body.p_W_m).norm(), 1e-12) << "tick " << k;
      ++checked;
    }
  }
  // The hand moves into the cloth for 200 ms: the proxy differs from tick to tick, so a batch
  // holding the tick before's contact fails the check above.
  EXPECT_GE(checked, 10);
}

TEST(SimFrameHold, AContactSpringIsHeldOverFramesWithoutABatchThenLetGo) {
  const ServerSpec spec = SmallCurtain();
  SimLoop sim(spec.sim, spec.proxy.structure);
  sim.PublishInitialSnapshot(kT0Ns);
  const int32_t centre = (sim.model().height / 2) * sim.model().width + sim.model().width / 2;
  int32_t tri = -1;
  for (size_t t = 0; t < sim.model().triangles.size(); ++t) {
    if (sim.model().triangles[t][0] == centre) tri = static_cast<int32_t>(t);
  }
  ASSERT_GE(tri, 0);
  ReactionBatch batch;
  batch.count = 1;
  batch.duration_s = 1.0 / 60.0;
  ExternalForce& e = batch.forces[0];
  e.triangle = tri;
  e.stiffness_N_per_m = 44.0;
  e.normal = Vec3::UnitZ();
  e.radius_m = 0.004;
  e.anchor_m = sim.model().rest_position_m[centre] - Vec3(0, 0, 0.02);
  e.max_force_N = 1.1;
  ASSERT_TRUE(sim.reactions().TryPush(batch));
  for (int f = 1; f <= kMaxHeldSpringFrames + 3; ++f) sim.Frame(1.0 / 60.0, kT0Ns + f);
  EXPECT_EQ(sim.counters().held_spring_frames.load(), static_cast<uint64_t>(kMaxHeldSpringFrames));
  // A plain force (no spring) is applied once and not held.
  batch.forces[0].stiffness_N_per_m = 0.0;
  batch.forces[0].force_N = Vec3(0, 0, -0.01);
  ASSERT_TRUE(sim.reactions().TryPush(batch));
  for (int f = 0; f < 3; ++f) sim.Frame(1.0 / 60.0, kT0Ns + 100 + f);
  EXPECT_EQ(sim.counters().held_spring_frames.load(), static_cast<uint64_t>(kMaxHeldSpringFrames));
}

}  // namespace
}  // namespace felt
