// The server's haptic tick and sim frame driven on a test clock (no threads): no allocation in the
// tick, two devices on one cloth, stale input, NaN input, reconnection, a stalled sim, and a
// bundled trace replayed in-process.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "haptic_loop/pointer_source.h"
#include "recordings/trace.h"
#include "server/server.h"
#include "tests/alloc_counter.h"  // FELT_DEFINE_ALLOC_COUNTER is in alloc_counter_test.cc
#include "tests/server/server_test_util.h"
#include "tests/test_env.h"

namespace felt {
namespace {

using testing_server::DeviceAt;
using testing_server::Driver;
using testing_server::PressFeed;
using testing_server::PressUntilForce;
using testing_server::SmallCurtain;

ServerOptions Quiet() {
  ServerOptions options;
  options.apply_realtime = false;
  options.monitor_log = false;
  return options;
}

// The small curtain with a short ramp-in (50 ms), so a press reaches its full force quickly.
ServerSpec QuickRamp(std::vector<DeviceSpec> devices = {}) {
  ServerSpec spec = SmallCurtain(std::move(devices));
  spec.haptic.safety.ramp_in_s = 0.05;
  return spec;
}

// A one-device server on the test clock: its source, sink, server and driver.
struct OneDevice {
  explicit OneDevice(ServerSpec spec)
      : server(std::move(spec), &source, &sink, Quiet()), driver(&server, &source) {}
  LatestPointerSource source{1};
  CapturingForceSink sink{1};
  Server server;
  Driver driver;
};

// One haptic tick at now_ns [ns] without a sim frame, the hand pressing (sample seq 1000000 + i).
void PressWithoutFrame(OneDevice* one, int i, int64_t now_ns) {
  PointerInput in;
  in.seq = 1'000'000 + static_cast<uint64_t>(i);
  in.receive_time_ns = now_ns;
  in.p_D_m = testing_server::PressPosition(1000.0);
  one->source.Set(0, in);
  one->server.HapticTick(now_ns, 1e-3);
}

// The newest force sent to `device`.
ForceOutput Newest(CapturingForceSink& sink, uint32_t device = 0) {
  ForceOutput out;
  EXPECT_TRUE(sink.Newest(device, &out));
  return out;
}

TEST(ServerTick, HapticTickNeverAllocates) {
  // Every snapshot mode: those that keep the previous snapshot copy it each frame; mode patch
  // places and steps its windows.
  for (SnapshotMode mode : kSnapshotModes) {
    ServerSpec spec =
        SmallCurtain({DeviceAt("left", Vec3(-0.1, 0, 0)), DeviceAt("right", Vec3(0.1, 0, 0))});
    spec.proxy.snapshot_mode = mode;
    LatestPointerSource source(2);
    CapturingForceSink sink(2);
    Server server(spec, &source, &sink, Quiet());
    Driver driver(&server, &source);
    auto feed = PressFeed();
    // Warm-up (first snapshot copies, first contacts), then 2000 counted ticks: feeding and the
    // sim frame outside the guard, the tick inside.
    for (int i = 0; i < 300; ++i) driver.Tick(2, feed);
    uint64_t allocations = 0;
    int64_t now = driver.now_ns();
    for (int i = 0; i < 2000; ++i) {
      if (i % 16 == 0) server.SimFrame(1.0 / 60.0, now);
      PointerInput in;
      in.seq = 100000 + static_cast<uint64_t>(i);
      in.receive_time_ns = now;
      in.p_D_m = testing_server::PressPosition(1000.0);
      source.Set(0, in);
      source.Set(1, in);
      AllocationGuard guard;
      server.HapticTick(now, 1e-3);
      allocations += guard.allocations();
      now += testing_server::kTickNs;
    }
    EXPECT_EQ(allocations, 0u) << SnapshotModeName(mode);
    const std::unique_ptr<ServerReport> report = server.Report();
    EXPECT_GT(report->contacts, 0u) << SnapshotModeName(mode);
    EXPECT_GT(report->reaction_batches, 0u) << SnapshotModeName(mode);
    if (mode == SnapshotMode::kPatch) {
      EXPECT_GT(server.haptic().counters().patch_ticks.load(), 1000u);
    }
  }
}

TEST(ServerTick, TwoDevicesInModePatchShareOneWindowWhereTheyMeet) {
  // Two hands 3 cm apart on the small curtain (16 x 16, 33 mm spacing): their windows merge into
  // one simulation; 36 cm apart: two windows (radius 3). Both hands feel the cloth either way.
  for (double half_gap : {0.015, 0.18}) {
    ServerSpec spec = QuickRamp(
        {DeviceAt("left", Vec3(-half_gap, 0.0, 0.0)), DeviceAt("right", Vec3(half_gap, 0.0, 0.0))});
    spec.proxy.snapshot_mode = SnapshotMode::kPatch;
    spec.proxy.patch_radius = 3;
    LatestPointerSource source(2);
    CapturingForceSink sink(2);
    Server server(spec, &source, &sink, Quiet());
    Driver driver(&server, &source);
    ASSERT_TRUE(PressUntilForce(&driver, &sink, 2, 0.2)) << half_gap;
    for (uint32_t d = 0; d < 2; ++d) {
      const ForceOutput force = Newest(sink, d);
      EXPECT_TRUE(force.in_contact) << d;
      EXPECT_GT(force.force_D_N.z(), 0.2) << d;
    }
    const ClothPatch* patch = server.haptic().patch();
    ASSERT_NE(patch, nullptr);
    std::string windows;
    for (const PatchWindow& w : patch->windows()) {
      windows += " [" + std::to_string(w.col0) + "," + std::to_string(w.row0) + " - " +
                 std::to_string(w.col1) + "," + std::to_string(w.row1) + "]";
    }
    EXPECT_EQ(patch->windows().size(), half_gap < 0.05 ? 1u : 2u) << half_gap << windows;
    if (half_gap < 0.05) {
      EXPECT_GT(patch->counters().merges, 0u);
    }
  }
}

TEST(ServerTick, TwoDevicesPressTheClothAtTwoPlaces) {
  const Vec3 left_W(-0.12, 0.0, 0.0);
  const Vec3 right_W(0.12, 0.0, 0.0);
  LatestPointerSource source(2);
  CapturingForceSink sink(2);
  Server server(QuickRamp({DeviceAt("left", left_W), DeviceAt("right", right_W)}), &source, &sink,
                Quiet());
  Driver driver(&server, &source);
  // Both hands feel the cloth at the same time: in contact, pushed back (+z), within the limits.
  ASSERT_TRUE(PressUntilForce(&driver, &sink, 2, 0.2));
  const std::unique_ptr<ServerReport> report = server.Report();
  ASSERT_EQ(report->devices.size(), 2u);
  for (uint32_t d = 0; d < 2; ++d) {
    const ForceOutput force = Newest(sink, d);
    EXPECT_TRUE(force.in_contact) << d;
    EXPECT_GT(force.force_D_N.z(), 0.2) << d;
    EXPECT_LE(force.force_D_N.norm(), server.spec().devices[d].max_force_N + 1e-9);
    EXPECT_GT(report->devices[d].contact_ticks, 0u) << d;
  }
  // Two more frames, so the reactions of the last frame reach the cloth.
  for (int i = 0; i < 40; ++i) driver.Tick(2, PressFeed());
  const std::unique_ptr<ServerReport> after = server.Report();
  for (uint32_t d = 0; d < 2; ++d) EXPECT_GT(after->devices[d].reaction_impulse_N_s, 0.0) << d;

  // Both reactions reached the cloth: it is pushed back (-z) under each hand, and the impulse the
  // sim applied is the impulse the two proxies queued (nothing lost, up to the batch in flight).
  const ClothState& cloth = server.cloth();
  auto depth_near = [&](const Vec3& p_W) {
    double z = 0.0;
    for (const Vec3& x : cloth.x) {
      if (std::hypot(x.x() - p_W.x(), x.y() - p_W.y()) < 0.05) z = std::min(z, x.z());
    }
    return z;
  };
  EXPECT_LT(depth_near(left_W), -0.002);
  EXPECT_LT(depth_near(right_W), -0.002);
  EXPECT_GT(server.applied_impulse_N_s(), 0.0);
  EXPECT_GE(after->reaction_batches_applied + 1, after->reaction_batches);
}

TEST(ServerTick, StaleInputRampsToZeroWhileZeroForcesKeepFlowing) {
  OneDevice one(QuickRamp());
  auto& [source, sink, server, driver] = one;
  ASSERT_TRUE(PressUntilForce(&driver, &sink, 1, 0.2));

  // The samples stop now: fresh for the 50 ms limit, then ramped out over 50 ms.
  const uint64_t pushed_before = sink.pushed(0);
  double previous = Newest(sink).force_D_N.norm();
  bool flagged = false;
  for (int i = 0; i < 300; ++i) {
    driver.Tick(1, [](uint32_t, double, PointerInput*) { return false; });
    const ForceOutput f = Newest(sink);
    if (f.flags & kSafetyStaleInput) {
      flagged = true;
      EXPECT_LE(f.force_D_N.norm(), previous + 1e-12);
    }
    previous = f.force_D_N.norm();
  }
  EXPECT_TRUE(flagged);
  EXPECT_EQ(Newest(sink).force_D_N, Vec3::Zero());
  EXPECT_TRUE(Newest(sink).flags & kSafetyStaleInput);
  EXPECT_EQ(sink.pushed(0), pushed_before + 300);  // a force every tick, stale or not
  EXPECT_GE(server.Report()->devices[0].stale_ticks, 150u);
  EXPECT_FALSE(server.Report()->devices[0].connected);
}

TEST(ServerTick, NanInputGivesZeroForceAndIsCounted) {
  OneDevice one(QuickRamp());
  auto& [source, sink, server, driver] = one;
  ASSERT_TRUE(PressUntilForce(&driver, &sink, 1, 0.2));

  driver.Tick(1, [](uint32_t, double, PointerInput* in) {
    in->p_D_m = Vec3(std::numeric_limits<double>::quiet_NaN(), 0, 0);
    return true;
  });
  EXPECT_EQ(Newest(sink).force_D_N, Vec3::Zero());
  EXPECT_EQ(server.Report()->nan_events, 1u);
  // Good samples again: the force ramps back in.
  driver.Tick(1, PressFeed());
  EXPECT_TRUE(Newest(sink).flags & kSafetyRamping);
  for (const Vec3& x : server.cloth().x) ASSERT_TRUE(x.allFinite());
}

TEST(ServerTick, ReconnectionRampsTheForceIn) {
  ServerSpec spec = SmallCurtain();
  spec.haptic.safety.ramp_in_s = 0.5;
  OneDevice one(spec);
  auto& [source, sink, server, driver] = one;
  // Connected and ramped in: no ramping flag after 0.5 s.
  for (int i = 0; i < 600; ++i) driver.Tick(1, PressFeed());
  EXPECT_FALSE(Newest(sink).flags & kSafetyRamping);
  EXPECT_EQ(server.Report()->devices[0].connects, 1u);
  // 200 ms of silence (the device unplugged): stale, zero force.
  for (int i = 0; i < 200; ++i) {
    driver.Tick(1, [](uint32_t, double, PointerInput*) { return false; });
  }
  EXPECT_EQ(Newest(sink).force_D_N, Vec3::Zero());
  EXPECT_FALSE(server.Report()->devices[0].connected);
  // Samples again: flagged ramping for 0.5 s, the force at most gain x max force.
  const double max_N = server.spec().devices[0].max_force_N;
  for (int i = 1; i <= 499; ++i) {
    driver.Tick(1, PressFeed());
    const ForceOutput f = Newest(sink);
    ASSERT_TRUE(f.flags & kSafetyRamping) << i;
    ASSERT_LE(f.force_D_N.norm(), max_N * i / 500.0 + 1e-9) << i;
  }
  for (int i = 0; i < 5; ++i) driver.Tick(1, PressFeed());
  EXPECT_FALSE(Newest(sink).flags & kSafetyRamping);
  EXPECT_EQ(server.Report()->devices[0].connects, 2u);
  EXPECT_TRUE(server.Report()->devices[0].connected);
}

TEST(ServerTick, StalledSimIsFlaggedAndTheTickRunsOnTheLastSnapshot) {
  OneDevice one(SmallCurtain());
  auto& [source, sink, server, driver] = one;
  for (int i = 0; i < 600; ++i) driver.Tick(1, PressFeed());
  ASSERT_FALSE(Newest(sink).flags & kSafetySimStalled);
  // No SimFrame for 300 ms: ticks go on against the last snapshot, flagged after 100 ms.
  int64_t now = driver.now_ns();
  const uint64_t pushed = sink.pushed(0);
  for (int i = 0; i < 300; ++i) {
    PressWithoutFrame(&one, i, now);
    now += testing_server::kTickNs;
  }
  EXPECT_EQ(sink.pushed(0), pushed + 300);  // still rendering, on the last cloth
  const ForceOutput f = Newest(sink);
  EXPECT_TRUE(f.flags & kSafetySimStalled);
  EXPECT_FALSE(f.flags & kSafetyStaleInput);
  const std::unique_ptr<ServerReport> report = server.Report();
  EXPECT_TRUE(report->sim_stalled);
  EXPECT_NEAR(static_cast<double>(report->sim_stalled_ticks), 200.0, 20.0);
  // The sim comes back: the flag clears.
  server.SimFrame(1.0 / 60.0, now);
  server.HapticTick(now, 1e-3);
  EXPECT_FALSE(Newest(sink).flags & kSafetySimStalled);
}

// The sim stalls for 20 s while a still hand presses the swinging cloth. The modes that
// extrapolate the last snapshot along its velocities (extrapolate, and patch at the rims of its
// windows) extrapolate at most haptic.sim_stall_s (100 ms) past it: the tick goes on rendering
// the cloth as extrapolated then (flagged "sim stalled"), so once the stall is older than that
// the proxy stays about where it is, and the device is told so (felt/force's proxy position,
// OmniFeedback's lock position). Unbounded, the proxy went 1.37 m (device frame) in mode
// extrapolate and 0.45 m in mode patch over the stall.
TEST(ServerTick, ALongStallDoesNotCarryTheProxyAway) {
  for (SnapshotMode mode : kSnapshotModes) {
    // Under a sanitizer only the two modes that extrapolate (9 and 15 s of ASan and TSan for all
    // five, in CI), and 12 s instead of 20 (tests/test_env.h).
    const bool extrapolates = mode == SnapshotMode::kExtrapolate || mode == SnapshotMode::kPatch;
    if (felt::testing::Sanitized() && !extrapolates) continue;
    ServerSpec spec = QuickRamp();
    spec.proxy.snapshot_mode = mode;
    OneDevice one(spec);
    auto& [source, sink, server, driver] = one;
    for (int i = 0; i < 300; ++i) driver.Tick(1, PressFeed());
    const double max_N = server.spec().devices[0].max_force_N;
    const int64_t stall_ticks = static_cast<int64_t>(spec.haptic.sim_stall_s * 1000.0);
    int64_t now = driver.now_ns();
    Vec3 settled = Vec3::Zero(), halfway = Vec3::Zero();
    double farthest = 0.0, drift = 0.0;
    const int ticks = felt::testing::Sanitized() ? 12000 : 20000;
    for (int i = 0; i < ticks; ++i) {
      PressWithoutFrame(&one, i, now);
      const ForceOutput f = Newest(sink);
      ASSERT_TRUE(f.proxy_D_m.allFinite()) << SnapshotModeName(mode) << " tick " << i;
      ASSERT_LE(f.force_D_N.norm(), max_N + 1e-9) << SnapshotModeName(mode) << " tick " << i;
      // 50 ticks of the stall past the horizon (the snapshot is up to 17 ticks older: driver.Tick
      // ran a frame then); mode patch's windows settle onto their fixed rims.
      if (i == stall_ticks + 50) settled = f.proxy_D_m;
      if (i > stall_ticks + 50) {
        farthest = std::max(farthest, (f.proxy_D_m - settled).norm());
      }
      if (i == ticks / 2) halfway = f.proxy_D_m;
      if (i > ticks / 2) drift = std::max(drift, (f.proxy_D_m - halfway).norm());
      now += testing_server::kTickNs;
    }
    // Past the horizon only mode patch's windows still move, settling under the hand onto their
    // fixed rims: 0.42 mm in the device frame at most, then within 4 um (8 um in 12 s) over the
    // stall's second half.
    EXPECT_LT(farthest, 1e-3) << SnapshotModeName(mode);
    EXPECT_LT(drift, 2e-5) << SnapshotModeName(mode);
    std::printf(
        "%s: past the horizon the proxy moved at most %.2e m, over the second half %.2e m "
        "(device frame)\n",
        SnapshotModeName(mode), farthest, drift);
  }
}

TEST(ServerTick, BundledTraceTouchesTheCloth) {
  const Trace trace = ReadTrace(std::string(FELT_SOURCE_DIR "/recordings/poke_hold.trace"));
  TracePointerSource source({trace.samples});
  CapturingForceSink sink(1);
  Server server(SmallCurtain(), &source, &sink, Quiet());
  // The trace on the test clock: 3 s covers the approach and the press.
  int64_t now = 1'000'000'000'000;
  int64_t next_frame = now;
  for (int i = 0; i < 3000; ++i) {
    if (now >= next_frame) {
      server.SimFrame(1.0 / 60.0, now);
      next_frame += 16'666'667;
    }
    server.HapticTick(now, 1e-3);
    now += testing_server::kTickNs;
  }
  const std::unique_ptr<ServerReport> report = server.Report();
  EXPECT_GT(report->contacts, 100u);
  EXPECT_GT(report->peak_force_N, 0.1);
  EXPECT_LE(report->peak_force_N, server.spec().devices[0].max_force_N + 1e-9);
  EXPECT_EQ(report->nan_events, 0u);
  EXPECT_GT(sink.peak_force_N(0), 0.1);
}

}  // namespace
// The cloth moving onto a still pointer catches the proxy and pushes it in every snapshot mode,
// mode newest included: the server keeps the previous snapshot for it too, without which the
// proxy was neither caught nor carried (ProxyTick takes a missing previous snapshot as a cloth
// that did not move) and the cloth passed through the still proxy.
TEST(ServerTick, ClothMovingOntoAStillPointerCatchesItInEveryMode) {
  for (SnapshotMode mode : {SnapshotMode::kNewest, SnapshotMode::kBlendForces,
                            SnapshotMode::kInterpolate, SnapshotMode::kExtrapolate}) {
    LatestPointerSource source(1);
    CapturingForceSink sink(1);
    // The device's origin 20 mm in front of the curtain's centre; gravity along +z, so the
    // curtain (pinned at its top corners) falls toward and through that still point.
    ServerSpec spec = QuickRamp({DeviceAt("still", Vec3(0.0, 0.0, 0.02))});
    spec.sim.cloth.gravity_m_per_s2 = Vec3(0.0, 0.0, 9.81);
    spec.proxy.snapshot_mode = mode;
    Server server(spec, &source, &sink, Quiet());
    Driver driver(&server, &source);
    const auto still = [](uint32_t, double, PointerInput* in) {
      in->p_D_m = Vec3::Zero();
      in->v_D_m_per_s = Vec3::Zero();
      return true;
    };
    double max_push_N = 0.0;
    for (int i = 0; i < 600; ++i) {
      driver.Tick(1, still);
      ForceOutput f;
      if (sink.Newest(0, &f)) max_push_N = std::max(max_push_N, f.force_D_N.z());
    }
    // The proxy rides on the falling cloth (+z), so the device is pushed along +z.
    EXPECT_GT(max_push_N, 0.5) << SnapshotModeName(mode);
    EXPECT_GT(server.Report()->devices[0].contact_ticks, 0u) << SnapshotModeName(mode);
  }
}

}  // namespace felt
