// The server with its three threads: loop rates, stats correctness, the handoffs under load (run
// under ThreadSanitizer in CI), an injected sim stall, and stop. Each test runs about a second.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <memory>
#include <string>
#include <thread>

#include "haptic_loop/pointer_source.h"
#include "rt/periodic_loop.h"
#include "server/server.h"
#include "tests/server/server_test_util.h"
#include "tests/test_env.h"

namespace felt {
namespace {

using testing_server::DeviceAt;
using testing_server::PressPosition;
using testing_server::PressVelocity;
using testing_server::SmallCurtain;

// Modest real-time settings: SCHED_FIFO at a low priority without spinning or memory locking,
// so the rates hold on a loaded machine without starving it; refused (not root), it runs anyway.
ServerSpec ThreadedSpec(std::vector<DeviceSpec> devices = {}) {
  ServerSpec spec = SmallCurtain(std::move(devices));
  spec.haptic.haptic_realtime = RealtimeSettings{.fifo_priority = 20, .timer_slack_ns = 1};
  spec.haptic.sim_realtime = RealtimeSettings{.fifo_priority = 10, .timer_slack_ns = 1};
  spec.haptic.monitor_period_s = 0.2;
  return spec;
}

ServerOptions Options() {
  ServerOptions options;
  options.monitor_log = false;
  return options;
}

// Feeds every device a press at ~1 kHz from this thread until `until_ns` or `done()`.
template <typename Done>
void FeedUntil(LatestPointerSource* source, uint32_t devices, int64_t start_ns, int64_t until_ns,
               uint64_t* seq, Done&& done) {
  while (MonotonicNowNs() < until_ns && !done()) {
    const int64_t now = MonotonicNowNs();
    const double ms = static_cast<double>(now - start_ns) * 1e-6;
    PointerInput in;
    in.seq = ++*seq;
    in.receive_time_ns = now;
    in.device_time_ns = now;
    in.p_D_m = PressPosition(ms);
    in.v_D_m_per_s = PressVelocity(ms);
    for (uint32_t d = 0; d < devices; ++d) source->Set(d, in);
    std::this_thread::sleep_for(std::chrono::microseconds(1000));
  }
}

TEST(ServerThreads, RatesStatsAndHandoffsOverOneSecond) {
  LatestPointerSource source(2);
  CapturingForceSink sink(2);
  std::atomic<int> reports{0};
  ServerOptions options = Options();
  options.on_report = [&](const ServerReport& r) {
    EXPECT_GE(r.haptic.ticks, 0u);
    reports.fetch_add(1);
  };
  Server server(
      ThreadedSpec({DeviceAt("left", Vec3(-0.12, 0, 0)), DeviceAt("right", Vec3(0.12, 0, 0))}),
      &source, &sink, options);
  uint64_t seq = 0;
  const int64_t start = MonotonicNowNs();
  server.Start();
  FeedUntil(&source, 2, start, start + 1'000'000'000, &seq, [] { return false; });
  server.Stop();

  const std::unique_ptr<ServerReport> r = server.Report();
  const double seconds = static_cast<double>(MonotonicNowNs() - start) * 1e-9;
  // Rates within loose bounds (the loops start one period after Start()). Never more than the
  // nominal rate (missed periods are skipped, not bunched); under a sanitizer (make test-asan /
  // test-tsan set FELT_SANITIZER) a tick or frame can outlast its period, so fewer are allowed.
  const bool sanitized = testing::Sanitized();
  // The lower bounds are loose on purpose: CI is a shared 2-core VM running two tests at once.
  // Under a sanitizer they only ask that both loops kept running: the rate there measures the
  // instrumentation, not Felt (CI's TSan run of 8de6eec got 349 haptic ticks in 1.006 s beside
  // another test, with the sim thread and this feeder on the same two cores).
  const double haptic_min = sanitized ? 0.2 : 0.6;
  const double sim_min = sanitized ? 0.1 : 0.5;
  const double haptic_ticks = static_cast<double>(r->haptic.ticks);
  const double sim_frames = static_cast<double>(r->sim.ticks);
  EXPECT_GE(haptic_ticks, haptic_min * 1000.0 * seconds);
  EXPECT_LE(haptic_ticks, 1.15 * 1000.0 * seconds);
  EXPECT_GE(sim_frames, sim_min * 60.0 * seconds);
  EXPECT_LE(sim_frames, 1.15 * 60.0 * seconds);
  // Stats correctness: the loop recorded exactly the ticks the body ran; every tick of a device
  // with input pushed one force; the sim published the frames it counted.
  EXPECT_EQ(r->body_ticks, r->haptic.ticks);
  EXPECT_EQ(r->haptic.lateness.count, r->haptic.ticks);
  EXPECT_EQ(r->haptic.snapshot_age.count, r->haptic.ticks);
  EXPECT_EQ(server.sim_frames(), r->sim.ticks);
  for (uint32_t d = 0; d < 2; ++d) {
    EXPECT_EQ(sink.pushed(d), r->devices[d].forces_sent);
    EXPECT_GT(r->devices[d].contact_ticks, 0u) << d;
  }
  // The handoffs: reactions went haptic -> sim, snapshots sim -> haptic (snapshot age < stall).
  EXPECT_GT(r->reaction_batches, 10u);
  EXPECT_GE(r->reaction_batches_applied + 1, r->reaction_batches);
  EXPECT_GT(server.applied_impulse_N_s(), 0.0);
  EXPECT_GE(reports.load(), 3);
  // The JSON carries the keys.
  const std::string json = Server::ReportJson(*r);
  for (const char* key :
       {"\"realtime\"", "\"lateness_us\"", "\"frame_ms\"", "\"p999\"", "\"overruns\"", "\"ticks\"",
        "\"frames\"", "\"contacts\"", "\"peak_force_N\"", "\"left\"", "\"right\""}) {
    EXPECT_NE(json.find(key), std::string::npos) << key;
  }
}

TEST(ServerThreads, InjectedSimStallIsFlaggedWhileTheHapticLoopRuns) {
  LatestPointerSource source(1);
  CapturingForceSink sink(1);
  Server server(ThreadedSpec(), &source, &sink, Options());
  uint64_t seq = 0;
  const int64_t start = MonotonicNowNs();
  server.Start();
  // Press until the sim has run a few frames, then block the sim thread for 300 ms.
  FeedUntil(&source, 1, start, start + 5'000'000'000, &seq,
            [&] { return server.sim_frames() >= 20; });
  ASSERT_GE(server.sim_frames(), 20u);
  const uint64_t frames_before = server.sim_frames();
  server.InjectSimStall(300'000'000);
  // Wait (with a deadline) for the flag on the forces.
  ForceOutput force;
  FeedUntil(&source, 1, start, MonotonicNowNs() + 2'000'000'000, &seq,
            [&] { return sink.Newest(0, &force) && (force.flags & kSafetySimStalled) != 0; });
  EXPECT_TRUE(force.flags & kSafetySimStalled);
  const uint64_t ticks_at_flag = server.Report()->body_ticks;
  // While stalled, the haptic loop keeps ticking and sending forces on the last snapshot.
  FeedUntil(&source, 1, start, MonotonicNowNs() + 2'000'000'000, &seq,
            [&] { return !server.Report()->sim_stalled; });
  const std::unique_ptr<ServerReport> r = server.Report();
  server.Stop();
  EXPECT_FALSE(r->sim_stalled);  // the sim came back
  EXPECT_GT(r->body_ticks - ticks_at_flag, 50u);
  // About 200 ticks at 1 kHz (the 300 ms stall less the 100 ms limit, plus the last frame's age);
  // at least half of them, a quarter under a sanitizer, whose ticks are slower (a TSan run in CI
  // counted 98 on the loaded 2-core machine). Not a loop-timing target: `felt bench loops` is.
  EXPECT_GT(r->sim_stalled_ticks, testing::Sanitized() ? 50u : 100u);
  EXPECT_GT(server.sim_frames(), frames_before);
  // The blocked frame overran and its periods were skipped (recorded once the loop woke again).
  EXPECT_GE(server.Report()->sim.overruns, 1u);
  EXPECT_GE(server.Report()->sim.skipped_periods, 10u);
  // Every frame, the one after the stall included, integrated one nominal period: the stalled
  // time was dropped, not integrated in the next frame (which would make it overrun again).
  const double frame_dt = 1.0 / ThreadedSpec().sim.integration.frame_rate_hz;
  EXPECT_NEAR(server.sim_time_s(), static_cast<double>(server.sim_frames()) * frame_dt, 1e-9);
}

TEST(ServerThreads, StopIsIdempotentAndDestructionStops) {
  LatestPointerSource source(1);
  CapturingForceSink sink(1);
  {
    Server server(ThreadedSpec(), &source, &sink, Options());
    server.Start();
    EXPECT_TRUE(server.running());
    const int64_t deadline = MonotonicNowNs() + 2'000'000'000;
    while (server.Report()->haptic.ticks < 20 && MonotonicNowNs() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    server.Stop();
    EXPECT_FALSE(server.running());
    const uint64_t ticks = server.Report()->haptic.ticks;
    EXPECT_GE(ticks, 20u);
    server.Stop();
    EXPECT_EQ(server.Report()->haptic.ticks, ticks);  // nothing runs after Stop
  }
  Server running(ThreadedSpec(), &source, &sink, Options());
  running.Start();  // the destructor stops and joins
}

}  // namespace
}  // namespace felt
