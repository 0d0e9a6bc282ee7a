#pragma once
// A periodic timer on absolute deadlines (clock_nanosleep TIMER_ABSTIME on CLOCK_MONOTONIC), with
// an optional short spin before each deadline. It measures the lateness of every wake-up, counts
// overruns and skips missed periods instead of bunching ticks (shared/STYLE.md, "Threads and the
// real-time tick"; ros2_control's habit). Used by the 1 kHz haptic and the 60 Hz sim threads.

#include <cstdint>

#include "rt/clock.h"

namespace felt {

/// What one wake-up of a PeriodicLoop looked like. Times are CLOCK_MONOTONIC in ns.
struct TickInfo {
  uint64_t index = 0;         ///< ticks returned before this one (0 for the first)
  uint64_t period_index = 0;  ///< period boundaries since the start: deadline = start + this*period
  int64_t deadline_ns = 0;    ///< the absolute deadline this tick was due at
  int64_t wake_ns = 0;        ///< when WaitNext() returned (after the sleep and spin)
  int64_t lateness_ns = 0;    ///< wake_ns - deadline_ns (>= 0)
  int64_t previous_wake_ns = 0;  ///< the previous tick's wake_ns (0 for the first tick)
  uint64_t periods_skipped = 0;  ///< boundaries skipped before this deadline after an overrun
  bool overrun = false;  ///< the previous tick's work finished after this tick's first deadline
};

/// A periodic timer with absolute deadlines: deadline k = start + k * period.
///
/// Call WaitNext() once per tick, after the tick's work. If the work finished later than the
/// deadline that was due next (an overrun), that period and every other boundary already passed
/// are skipped: the next deadline is the first boundary in the future, and the skipped count is
/// reported, so ticks are never bunched up to "catch up". One thread at a time uses an instance.
class PeriodicLoop {
 public:
  /// A loop with `period_ns` > 0 that sleeps until `spin_ns` (>= 0, < period) before each
  /// deadline and then spins on the clock. Throws std::invalid_argument for a bad period or spin.
  /// Does not start the clock: see Start().
  explicit PeriodicLoop(int64_t period_ns, int64_t spin_ns = 0);

  /// Sets the first deadline (CLOCK_MONOTONIC ns) and resets the counters. Without a call, the
  /// first WaitNext() starts the loop one period after it is called. A first deadline already
  /// passed when WaitNext() is called counts as an overrun and is skipped. Real-time safe.
  void Start(int64_t first_deadline_ns);

  /// Sleeps (then spins) until the next deadline, skipping passed boundaries after an overrun,
  /// and returns what the wake-up looked like. Retries after signals (EINTR). Real-time safe: no
  /// allocation, lock, log, exception or I/O.
  TickInfo WaitNext();

  /// The period in ns.
  int64_t period_ns() const { return period_ns_; }
  /// The spin before each deadline in ns.
  int64_t spin_ns() const { return spin_ns_; }
  /// Ticks returned by WaitNext() since the start.
  uint64_t ticks() const { return ticks_; }
  /// Overruns since the start (ticks whose work ended after the next deadline).
  uint64_t overruns() const { return overruns_; }
  /// Period boundaries skipped since the start.
  uint64_t skipped_periods() const { return skipped_periods_; }

 private:
  int64_t period_ns_;
  int64_t spin_ns_;
  bool started_ = false;
  int64_t start_ns_ = 0;     // deadline of period_index 0
  uint64_t next_index_ = 0;  // period index of the next deadline
  int64_t last_wake_ns_ = 0;
  uint64_t ticks_ = 0;
  uint64_t overruns_ = 0;
  uint64_t skipped_periods_ = 0;
};

}  // namespace felt
