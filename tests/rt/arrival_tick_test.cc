// The haptic tick on arrival (rt/arrival_signal.h, PeriodicLoop::WakeOnArrival): the slot rule
// as a pure function over simulated sample streams (a device clock 100 ppm off, 500 Hz, 2 kHz,
// silence), the signal's timed wait, and the real loop woken by a notifying thread. Timing
// bounds are loose (shared machine, sanitizers).
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <thread>
#include <vector>

#include "rt/arrival_signal.h"
#include "rt/periodic_loop.h"
#include "rt/phase_lock.h"
#include "rt/realtime.h"
#include "tests/test_env.h"

namespace felt {
namespace {

constexpr int64_t kTickNs = 1'000'000;

constexpr int64_t kGraceNs = kTickNs / 10;  // PeriodicLoop's default

TEST(ArrivalTick, RuleTicksAtTheArrivalWithinItsSlotOnly) {
  // Slot (1000, 2000], grace 100: an arrival inside it ticks at once; none, or a later one, at the
  // deadline; a pending one from before the opening at the opening only within the grace.
  EXPECT_EQ(ArrivalTickNs(1000, 2000, 100, INT64_MIN, 1300), 1300);
  EXPECT_EQ(ArrivalTickNs(1000, 2000, 100, INT64_MIN, 2000), 2000);
  EXPECT_EQ(ArrivalTickNs(1000, 2000, 100, INT64_MIN, 2001), 2000);
  EXPECT_EQ(ArrivalTickNs(1000, 2000, 100, INT64_MIN, INT64_MAX), 2000);
  EXPECT_EQ(ArrivalTickNs(1000, 2000, 100, 950, 1300), 1000);
  EXPECT_EQ(ArrivalTickNs(1000, 2000, 100, 900, 1300), 1000);
  EXPECT_EQ(ArrivalTickNs(1000, 2000, 100, 899, 1300), 1300);
  EXPECT_EQ(ArrivalTickNs(1000, 2000, 100, 899, INT64_MAX), 2000);
}

// What the rule does to a stream of arrivals over `slots` period slots: the tick times, and per
// sample answered (the newest one at or before a tick that no earlier tick read) the wait from
// its arrival to that tick; the others were superseded by a newer sample before a tick.
struct StreamOutcome {
  std::vector<int64_t> ticks_ns;
  std::vector<int64_t> wait_ns;  // per answered sample
  size_t superseded = 0;
};

StreamOutcome Simulate(const std::vector<int64_t>& arrivals_ns, int slots,
                       int64_t grace_ns = kGraceNs) {
  StreamOutcome out;
  size_t next = 0;  // first arrival no tick has read
  for (int k = 1; k <= slots; ++k) {
    const int64_t open = (k - 1) * kTickNs;
    const int64_t deadline = k * kTickNs;
    size_t after_open = next;  // first arrival after the opening
    while (after_open < arrivals_ns.size() && arrivals_ns[after_open] <= open) ++after_open;
    const int64_t pending = after_open > next ? arrivals_ns[after_open - 1] : INT64_MIN;
    const int64_t in_slot = after_open < arrivals_ns.size() ? arrivals_ns[after_open] : INT64_MAX;
    const int64_t tick = ArrivalTickNs(open, deadline, grace_ns, pending, in_slot);
    out.ticks_ns.push_back(tick);
    size_t read = next;
    while (read < arrivals_ns.size() && arrivals_ns[read] <= tick) ++read;
    if (read > next) {
      out.wait_ns.push_back(tick - arrivals_ns[read - 1]);
      out.superseded += read - next - 1;
      next = read;
    }
  }
  return out;
}

// Arrivals of a device with period `period_ns`, first at `phase_ns`, each delayed by a
// deterministic pseudo-random jitter in [0, jitter_ns), up to `end_ns`.
std::vector<int64_t> Stream(int64_t phase_ns, double period_ns, int64_t jitter_ns, int64_t end_ns) {
  std::vector<int64_t> t;
  uint64_t lcg = 12345;
  for (int64_t i = 0;; ++i) {
    lcg = lcg * 6364136223846793005ULL + 1442695040888963407ULL;  // Knuth's MMIX LCG
    const int64_t jitter = jitter_ns > 0 ? static_cast<int64_t>((lcg >> 33) % jitter_ns) : 0;
    const auto at = phase_ns + static_cast<int64_t>(static_cast<double>(i) * period_ns) + jitter;
    if (at >= end_ns) break;
    t.push_back(at);
  }
  return t;
}

int64_t Quantile(std::vector<int64_t> v, double q) {
  std::sort(v.begin(), v.end());
  return v[static_cast<size_t>(q * static_cast<double>(v.size() - 1))];
}

// Every tick inside its own slot: after the previous boundary, at most at its deadline.
void ExpectTicksInTheirSlots(const StreamOutcome& o) {
  for (size_t k = 0; k < o.ticks_ns.size(); ++k) {
    ASSERT_GE(o.ticks_ns[k], static_cast<int64_t>(k) * kTickNs) << "tick " << k;
    ASSERT_LE(o.ticks_ns[k], static_cast<int64_t>(k + 1) * kTickNs) << "tick " << k;
  }
}

TEST(ArrivalTick, DeviceClockOneHundredPpmFastWithJitterIsAnsweredAtOnce) {
  // 20 s: the phase sweeps two whole periods, so every phase (and the slot with two arrivals
  // when it wraps) occurs. 50 us of jitter.
  const int slots = 20'000;
  const std::vector<int64_t> arrivals =
      Stream(300'000, kTickNs * (1.0 - 100e-6), 50'000, slots * int64_t{kTickNs});
  const StreamOutcome o = Simulate(arrivals, slots);
  ExpectTicksInTheirSlots(o);
  // Periodic, the same stream would wait 0..1 ms (uniform phase). On arrival: at once, and at
  // most the grace when the phase wraps; 20,002 samples in 20,000 slots, so a few superseded.
  EXPECT_EQ(Quantile(o.wait_ns, 0.5), 0);
  EXPECT_LE(Quantile(o.wait_ns, 0.99), kGraceNs);
  EXPECT_LE(Quantile(o.wait_ns, 1.0), kGraceNs);
  EXPECT_GE(o.superseded, arrivals.size() - static_cast<size_t>(slots));
  EXPECT_LE(o.superseded, arrivals.size() / 1000);
}

TEST(ArrivalTick, WithoutTheGraceAFastDeviceClockDriftsBackToThePeriodicWait) {
  // The same stream, but a pending sample of any age ticks the slot at its opening: after the
  // phase wraps, each sample waits for the next opening, longer by 0.1 us every period.
  const int slots = 20'000;
  const std::vector<int64_t> arrivals =
      Stream(300'000, kTickNs * (1.0 - 100e-6), 50'000, slots * int64_t{kTickNs});
  const StreamOutcome o = Simulate(arrivals, slots, INT64_MAX / 4);
  ExpectTicksInTheirSlots(o);
  EXPECT_GT(Quantile(o.wait_ns, 0.99), 5 * kGraceNs);
}

TEST(ArrivalTick, FiveHundredHertzDeviceTicksOnArrivalAndAtDeadlinesBetween) {
  const int slots = 2'000;
  const std::vector<int64_t> arrivals = Stream(700'000, 2.0 * kTickNs, 0, slots * int64_t{kTickNs});
  const StreamOutcome o = Simulate(arrivals, slots);
  ExpectTicksInTheirSlots(o);
  EXPECT_EQ(Quantile(o.wait_ns, 1.0), 0);  // every sample answered at once
  EXPECT_EQ(o.superseded, 0u);
  int at_deadline = 0;
  for (size_t k = 0; k < o.ticks_ns.size(); ++k) {
    if (o.ticks_ns[k] == static_cast<int64_t>(k + 1) * kTickNs) ++at_deadline;
  }
  EXPECT_EQ(at_deadline, slots / 2);  // the silent slots fall back to the periodic deadline
}

TEST(ArrivalTick, TwoKilohertzDeviceStillTicksOncePerPeriod) {
  const int slots = 2'000;
  const std::vector<int64_t> arrivals = Stream(100'000, 0.5 * kTickNs, 0, slots * int64_t{kTickNs});
  const StreamOutcome o = Simulate(arrivals, slots);
  ExpectTicksInTheirSlots(o);
  EXPECT_EQ(o.ticks_ns.size(), static_cast<size_t>(slots));
  // The first sample of each slot at once; the second (0.4 ms old when the next slot opens) is
  // superseded by the next slot's first.
  EXPECT_EQ(Quantile(o.wait_ns, 1.0), 0);
  EXPECT_EQ(o.wait_ns.size(), static_cast<size_t>(slots));
}

TEST(ArrivalTick, SilenceFallsBackToThePeriodicDeadlines) {
  const int slots = 1'000;
  std::vector<int64_t> arrivals = Stream(250'000, kTickNs, 0, 100 * kTickNs);  // then silence
  const StreamOutcome o = Simulate(arrivals, slots);
  ExpectTicksInTheirSlots(o);
  for (int k = 100; k < slots; ++k) EXPECT_EQ(o.ticks_ns[k], (k + 1) * kTickNs) << "tick " << k;
}

// The phase-locked alternative (rt/phase_lock.h): its estimate converges on a drifting stream, and
// its ticks stay in their slots with the period within the slew bound.
TEST(PhaseLock, EstimateConvergesOnADeviceClockOneHundredPpmFast) {
  const int slots = 6'000;
  const double device_period = kTickNs * (1.0 - 100e-6);
  const std::vector<int64_t> arrivals = Stream(300'000, device_period, 20'000, slots * kTickNs);
  PhaseLockSpec spec;
  PhaseLock lock(spec, 0);
  size_t observed = 0;
  int64_t previous_tick = -1;
  double drift_sum = 0;  // over the second half (the estimate is noisy: 20 us of jitter)
  for (int k = 1; k <= slots; ++k) {
    const int64_t open = (k - 1) * kTickNs;
    const int64_t tick = lock.TickNs(open);
    if (k > slots / 2) drift_sum += lock.drift_ns_per_period();
    ASSERT_GE(tick, open) << "slot " << k;
    ASSERT_LE(tick, open + kTickNs) << "slot " << k;
    if (previous_tick >= 0) {
      ASSERT_LE(std::abs(tick - previous_tick - kTickNs), spec.max_slew_ns) << "slot " << k;
    }
    previous_tick = tick;
    while (observed < arrivals.size() && arrivals[observed] <= tick) {
      lock.Observe(arrivals[observed++]);
    }
  }
  // The true phase at the end: the last arrival's, plus the jitter's mean (10 us), modulo 1 ms.
  const int64_t last = static_cast<int64_t>(
      300'000 + static_cast<double>(arrivals.size() - 1) * device_period + 10'000);
  double error = lock.phase_ns() - static_cast<double>(last % kTickNs);
  error -= kTickNs * std::floor(error / kTickNs + 0.5);
  EXPECT_LT(std::abs(error), 10'000.0);
  EXPECT_NEAR(drift_sum / (slots / 2), -100.0, 30.0);
}

TEST(PhaseLock, WithoutArrivalsTicksAtTheDeadline) {
  PhaseLock lock(PhaseLockSpec{}, 0);
  for (int k = 1; k <= 10; ++k) EXPECT_EQ(lock.TickNs((k - 1) * kTickNs), k * kTickNs);
}

TEST(ArrivalSignal, WaitTimesOutAtTheDeadlineAndWakesOnNotify) {
  ArrivalSignal signal;
  // Nothing arrives: returns false, not before the deadline.
  const int64_t deadline = MonotonicNowNs() + 5 * kTickNs;
  uint32_t seen = signal.count();
  bool woken = false;
  while (MonotonicNowNs() < deadline && !woken) woken = signal.WaitUntil(seen, deadline);
  EXPECT_FALSE(woken);
  EXPECT_GE(MonotonicNowNs(), deadline);
  // An arrival already counted: returns at once.
  signal.Notify(MonotonicNowNs());
  EXPECT_TRUE(signal.WaitUntil(seen, MonotonicNowNs() + 1'000 * kTickNs));
  // An arrival from another thread wakes a wait with a far deadline.
  seen = signal.count();
  std::thread notifier([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    signal.Notify(MonotonicNowNs());
  });
  const int64_t t0 = MonotonicNowNs();
  const int64_t far = t0 + 10'000 * kTickNs;  // 10 s
  while (!signal.WaitUntil(seen, far) && MonotonicNowNs() < far) {
  }
  const int64_t waited = MonotonicNowNs() - t0;
  notifier.join();
  EXPECT_NE(signal.count(), seen);
  EXPECT_GT(signal.last_ns(), t0);
  EXPECT_LT(waited, 5'000 * kTickNs);  // woken, not timed out
}

// The real loop: a thread notifies mid-slot for 150 periods, then falls silent for 150; the loop
// ticks on the arrivals, then on its deadlines, every tick in its slot.
TEST(PeriodicLoopTest, TicksOnArrivalThenFallsBackToItsDeadlinesOnSilence) {
  ArrivalSignal signal;
  constexpr int kArriving = 150, kSilent = 150;
  std::vector<TickInfo> ticks;
  ticks.reserve(kArriving + kSilent);
  const int64_t start = MonotonicNowNs() + 20 * kTickNs;
  std::atomic<bool> done{false};
  std::thread device([&] {
    RealtimeSettings settings;
    settings.fifo_priority = 10;
    (void)ApplyRealtime(settings);
    for (int i = 0; i < kArriving && !done.load(); ++i) {
      // Mid-slot of deadline i: 0.4 ms after boundary i - 1.
      const int64_t at = start + (i - 1) * kTickNs + 400'000;
      const timespec ts{static_cast<time_t>(at / 1'000'000'000),
                        static_cast<long>(at % 1'000'000'000)};
      while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
      }
      signal.Notify(MonotonicNowNs());
    }
  });
  std::thread haptic([&] {
    RealtimeSettings settings;
    settings.fifo_priority = 20;
    (void)ApplyRealtime(settings);
    PeriodicLoop loop(kTickNs);
    loop.WakeOnArrival(&signal);
    loop.Start(start);
    for (int i = 0; i < kArriving + kSilent; ++i) ticks.push_back(loop.WaitNext());
  });
  haptic.join();
  done.store(true);
  device.join();

  int on_arrival = 0;
  std::vector<int64_t> wake_after_arrival;
  for (const TickInfo& t : ticks) {
    // No drift: the deadline is the periodic boundary; no tick before its slot opens.
    ASSERT_EQ(t.deadline_ns, start + static_cast<int64_t>(t.period_index) * kTickNs);
    ASSERT_GE(t.wake_ns, t.deadline_ns - kTickNs);
    ASSERT_EQ(t.lateness_ns, std::max<int64_t>(0, t.wake_ns - t.deadline_ns));
    if (t.on_arrival) {
      ++on_arrival;
      wake_after_arrival.push_back(t.wake_ns - t.arrival_ns);
    }
  }
  // Silence: no tick on arrival once the device stopped (after its last sample's slot).
  const int64_t last_arrival = start + (kArriving - 2) * kTickNs + 400'000;
  for (const TickInfo& t : ticks) {
    if (t.deadline_ns - kTickNs > last_arrival + 2 * kTickNs) {
      EXPECT_FALSE(t.on_arrival) << "tick " << t.index;
      EXPECT_FALSE(t.wake_ns < t.deadline_ns) << "tick " << t.index << " early without input";
    }
  }
  // Most of the arriving half ticked on arrival, soon after it (loose: shared machine).
  EXPECT_GE(on_arrival, felt::testing::Sanitized() ? kArriving / 3 : kArriving * 2 / 3);
  ASSERT_FALSE(wake_after_arrival.empty());
  if (!felt::testing::Sanitized()) {
    EXPECT_LT(Quantile(wake_after_arrival, 0.5), 300'000);
  }
}

}  // namespace
}  // namespace felt
