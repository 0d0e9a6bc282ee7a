// ApplyRealtime and CpuDmaLatencyHold: refusals are reported with their errno text and the loop
// still runs; granted steps really change the thread. Each test applies settings on a thread of
// its own, so the test runner's thread keeps normal scheduling.
#include "rt/realtime.h"

#include <gtest/gtest.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/prctl.h>

#include <cerrno>
#include <string>
#include <thread>

#include "rt/loop_runner.h"

namespace felt {
namespace {

// Runs ApplyRealtime(settings) and then `check` on a fresh thread.
template <typename Check>
RealtimeReport ApplyOnThread(const RealtimeSettings& settings, Check check) {
  RealtimeReport report;
  std::thread thread([&] {
    report = ApplyRealtime(settings);
    check(report);
  });
  thread.join();
  return report;
}

bool Contains(const std::string& text, const char* part) {
  return text.find(part) != std::string::npos;
}

TEST(RealtimeTest, NothingRequestedNothingDone) {
  const RealtimeReport report = ApplyOnThread(RealtimeSettings{}, [](const RealtimeReport&) {});
  EXPECT_EQ(report.fifo.status, RealtimeStepStatus::kNotRequested);
  EXPECT_EQ(report.affinity.status, RealtimeStepStatus::kNotRequested);
  EXPECT_EQ(report.memory_lock.status, RealtimeStepStatus::kNotRequested);
  EXPECT_EQ(report.timer_slack.status, RealtimeStepStatus::kNotRequested);
  EXPECT_FALSE(report.fifo_granted);
  EXPECT_TRUE(report.all_granted());
}

TEST(RealtimeTest, InvalidSettingsAreRefusedWithErrnoText) {
  RealtimeSettings settings;
  settings.fifo_priority = 150;  // outside SCHED_FIFO's 1..99
  settings.cpu = 100'000;        // beyond cpu_set_t
  settings.timer_slack_ns = -5;  // negative slack
  const RealtimeReport report = ApplyOnThread(settings, [](const RealtimeReport&) {
    int policy = -1;
    sched_param param{};
    pthread_getschedparam(pthread_self(), &policy, &param);
    EXPECT_EQ(policy, SCHED_OTHER);  // unchanged
  });
  EXPECT_TRUE(report.fifo.refused());
  EXPECT_FALSE(report.fifo_granted);
  EXPECT_TRUE(Contains(report.fifo.error, "EINVAL")) << report.fifo.error;
  EXPECT_TRUE(report.affinity.refused());
  EXPECT_TRUE(Contains(report.affinity.error, "EINVAL")) << report.affinity.error;
  EXPECT_TRUE(report.timer_slack.refused());
  EXPECT_FALSE(report.all_granted());
  EXPECT_TRUE(Contains(report.Summary(), "SCHED_FIFO refused")) << report.Summary();
  EXPECT_TRUE(Contains(report.Summary(), "mlockall off")) << report.Summary();
}

TEST(RealtimeTest, CpuInsideTheSetButAbsentIsRefused) {
  RealtimeSettings settings;
  settings.cpu = CPU_SETSIZE - 1;  // expressible, but no such CPU here
  const RealtimeReport report = ApplyOnThread(settings, [](const RealtimeReport&) {});
  EXPECT_TRUE(report.affinity.refused());
  EXPECT_TRUE(Contains(report.affinity.error, "EINVAL")) << report.affinity.error;
  settings.cpu = -2;  // neither "none" nor an index
  EXPECT_TRUE(ApplyOnThread(settings, [](const RealtimeReport&) {}).affinity.refused());
}

TEST(RealtimeTest, RefusedSettingsStillRunTheLoop) {
  LoopStats stats(1'000'000);
  LoopRunOptions options;
  options.duration_ns = 30'000'000;
  options.realtime.fifo_priority = 1000;
  options.realtime.cpu = 100'000;
  uint64_t ticks = 0;
  const RealtimeReport report = RunLoopOnThread(options, &stats, [&](const TickInfo&) { ++ticks; });
  EXPECT_FALSE(report.fifo_granted);
  EXPECT_TRUE(report.affinity.refused());
  // It ran, and recorded what it ran (a loaded machine may skip many of the 30 periods).
  LoopStatsSnapshot snapshot;
  stats.Snapshot(&snapshot);
  EXPECT_GE(ticks, 1u);
  EXPECT_EQ(snapshot.ticks, ticks);
  EXPECT_LE(snapshot.ticks + snapshot.skipped_periods, 31u);
}

TEST(RealtimeTest, GrantedStepsChangeTheThreadOrAreRefusedForPermission) {
  // Pin to a CPU this process may use, FIFO priority 1, 1 ns of timer slack.
  cpu_set_t allowed;
  ASSERT_EQ(sched_getaffinity(0, sizeof(allowed), &allowed), 0);
  int cpu = 0;
  while (cpu < CPU_SETSIZE && !CPU_ISSET(cpu, &allowed)) ++cpu;
  ASSERT_LT(cpu, CPU_SETSIZE);
  RealtimeSettings settings;
  settings.fifo_priority = 1;
  settings.cpu = cpu;
  settings.timer_slack_ns = 1;
  const RealtimeReport report = ApplyOnThread(settings, [&](const RealtimeReport& r) {
    int policy = -1;
    sched_param param{};
    pthread_getschedparam(pthread_self(), &policy, &param);
    if (r.fifo.granted()) {
      EXPECT_EQ(policy, SCHED_FIFO);
      EXPECT_EQ(param.sched_priority, 1);
    } else {
      EXPECT_TRUE(Contains(r.fifo.error, "EPERM")) << r.fifo.error;  // not root: refused
    }
    EXPECT_TRUE(r.affinity.granted()) << r.affinity.error;
    EXPECT_EQ(sched_getcpu(), cpu);
    EXPECT_TRUE(r.timer_slack.granted()) << r.timer_slack.error;
    // 1 ns, or 0 where the kernel gives SCHED_FIFO threads no slack at all (Linux >= 6.7).
    EXPECT_LE(prctl(PR_GET_TIMERSLACK, 0, 0, 0, 0), 1);
  });
  EXPECT_EQ(report.fifo_granted, report.fifo.granted());
}

#if !defined(__SANITIZE_THREAD__) && !defined(__SANITIZE_ADDRESS__)
// (Sanitizers reserve terabytes of shadow memory that mlockall must not try to lock.)
TEST(RealtimeTest, LockMemoryGrantedOrRefusedForPermission) {
  RealtimeSettings settings;
  settings.lock_memory = true;
  const RealtimeReport report = ApplyOnThread(settings, [](const RealtimeReport&) {});
  if (report.memory_lock.granted()) {
    EXPECT_EQ(munlockall(), 0);  // undo: the rest of the tests need no locked memory
  } else {
    EXPECT_TRUE(Contains(report.memory_lock.error, "EPERM") ||
                Contains(report.memory_lock.error, "ENOMEM"))
        << report.memory_lock.error;
  }
}
#endif

TEST(CpuDmaLatencyHoldTest, MissingDeviceIsRefusedWithReason) {
  CpuDmaLatencyHold hold("/nonexistent/cpu_dma_latency");
  EXPECT_FALSE(hold.held());
  EXPECT_TRUE(Contains(hold.error(), "ENOENT")) << hold.error();
}

TEST(CpuDmaLatencyHoldTest, RealDeviceHeldOrRefused) {
  CpuDmaLatencyHold hold;
  if (hold.held()) {
    EXPECT_TRUE(hold.error().empty());
  } else {
    EXPECT_FALSE(hold.error().empty());  // not root or no such device: a reason, no crash
  }
}

}  // namespace
}  // namespace felt
