#include "rt/periodic_loop.h"

#include <time.h>

#include <cerrno>
#include <stdexcept>
#include <string>

namespace felt {
namespace {

constexpr int64_t kNsPerS = 1'000'000'000;

timespec ToTimespec(int64_t ns) {
  timespec t{};
  t.tv_sec = static_cast<time_t>(ns / kNsPerS);
  t.tv_nsec = static_cast<long>(ns % kNsPerS);
  return t;
}

// Sleeps until the absolute CLOCK_MONOTONIC time `ns`, retrying after signals.
void SleepUntil(int64_t ns) {
  const timespec t = ToTimespec(ns);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &t, nullptr) == EINTR) {
  }
}

}  // namespace

PeriodicLoop::PeriodicLoop(int64_t period_ns, int64_t spin_ns)
    : period_ns_(period_ns), spin_ns_(spin_ns) {
  if (period_ns <= 0) {
    throw std::invalid_argument("PeriodicLoop: period_ns must be > 0, got " +
                                std::to_string(period_ns));
  }
  if (spin_ns < 0 || spin_ns >= period_ns) {
    throw std::invalid_argument("PeriodicLoop: spin_ns must be in [0, period_ns), got " +
                                std::to_string(spin_ns) + " for a period of " +
                                std::to_string(period_ns) + " ns");
  }
}

void PeriodicLoop::Start(int64_t first_deadline_ns) {
  started_ = true;
  start_ns_ = first_deadline_ns;
  next_index_ = 0;
  last_wake_ns_ = 0;
  ticks_ = 0;
  overruns_ = 0;
  skipped_periods_ = 0;
  if (arrival_ != nullptr) seen_arrivals_ = arrival_->count();
}

void PeriodicLoop::WakeOnArrival(const ArrivalSignal* signal, int64_t grace_ns) {
  arrival_ = signal;
  grace_ns_ = grace_ns >= 0 ? grace_ns : period_ns_ / 10;
  if (arrival_ != nullptr) seen_arrivals_ = arrival_->count();
}

TickInfo PeriodicLoop::WaitNext() {
  const int64_t now = MonotonicNowNs();
  if (!started_) Start(now + period_ns_);

  TickInfo tick;
  tick.previous_wake_ns = last_wake_ns_;

  // Overrun: the work ended after the deadline due next. Skip to the first future boundary.
  int64_t deadline = start_ns_ + static_cast<int64_t>(next_index_) * period_ns_;
  if (now > deadline) {
    const uint64_t first_future = static_cast<uint64_t>((now - start_ns_) / period_ns_) + 1;
    tick.overrun = true;
    tick.periods_skipped = first_future - next_index_;
    ++overruns_;
    skipped_periods_ += tick.periods_skipped;
    next_index_ = first_future;
    deadline = start_ns_ + static_cast<int64_t>(next_index_) * period_ns_;
  }

  int64_t wake = 0;
  if (arrival_ != nullptr) {
    // On arrival (ArrivalTickNs): not before the slot opens (the previous boundary; after a tick
    // on arrival the next waits for it); a sample pending from before the opening ticks at once
    // only within the grace; then until an arrival or the deadline: a futex wait to `spin_ns_`
    // before the deadline, then a spin that watches the signal too.
    const int64_t slot_open = deadline - period_ns_;
    if (now < slot_open) SleepUntil(slot_open);
    uint32_t count = arrival_->count();
    // The count read first: last_ns() is then at least the time of the arrivals it counts.
    if (count != seen_arrivals_ && arrival_->last_ns() < slot_open - grace_ns_) {
      seen_arrivals_ = count;  // too old to tick the slot: read by whichever tick comes
    }
    for (;;) {
      if (count != seen_arrivals_) {
        tick.on_arrival = true;
        break;
      }
      const int64_t t = MonotonicNowNs();
      if (t >= deadline) break;
      if (deadline - t > spin_ns_) (void)arrival_->WaitUntil(count, deadline - spin_ns_);
      count = arrival_->count();
    }
    wake = MonotonicNowNs();
    seen_arrivals_ = count;
    if (tick.on_arrival) tick.arrival_ns = arrival_->last_ns();
  } else if (spin_ns_ > 0) {
    // Sleep to `spin_ns_` before the deadline, then spin on the clock to the deadline.
    if (deadline - spin_ns_ > now) SleepUntil(deadline - spin_ns_);
    do {
      wake = MonotonicNowNs();
    } while (wake < deadline);
  } else {
    SleepUntil(deadline);
    wake = MonotonicNowNs();
  }

  // Describe the wake-up and advance to the next boundary.
  tick.index = ticks_;
  tick.period_index = next_index_;
  tick.deadline_ns = deadline;
  tick.wake_ns = wake;
  tick.lateness_ns = wake > deadline ? wake - deadline : 0;  // a tick on arrival comes early
  ++ticks_;
  ++next_index_;
  last_wake_ns_ = wake;
  return tick;
}

}  // namespace felt
