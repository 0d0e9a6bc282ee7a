#pragma once
// A periodic timer on absolute deadlines (clock_nanosleep TIMER_ABSTIME on CLOCK_MONOTONIC), with
// an optional short spin before each deadline. It measures the lateness of every wake-up, counts
// overruns and skips missed periods instead of bunching ticks (shared/STYLE.md, "Threads and the
// real-time tick"; ros2_control's habit). Used by the 1 kHz haptic and the 60 Hz sim threads.

#include <cstdint>

#include "rt/arrival_signal.h"
#include "rt/clock.h"

namespace felt {

/// What one wake-up of a PeriodicLoop looked like. Times are CLOCK_MONOTONIC in ns.
struct TickInfo {
  uint64_t index = 0;         ///< ticks returned before this one (0 for the first)
  uint64_t period_index = 0;  ///< period boundaries since the start: deadline = start + this*period
  int64_t deadline_ns = 0;    ///< the absolute deadline this tick was due at
  int64_t wake_ns = 0;        ///< when WaitNext() returned (after the sleep and spin)
  int64_t lateness_ns = 0;    ///< wake_ns - deadline_ns, 0 when earlier (a tick on arrival)
  int64_t previous_wake_ns = 0;  ///< the previous tick's wake_ns (0 for the first tick)
  uint64_t periods_skipped = 0;  ///< boundaries skipped before this deadline after an overrun
  bool overrun = false;  ///< the previous tick's work finished after this tick's first deadline
  bool on_arrival = false;  ///< woken by an arrival before the deadline (WakeOnArrival)
  int64_t arrival_ns = 0;   ///< on_arrival: CLOCK_MONOTONIC of the newest arrival (its Notify)
};

/// When the tick of period slot (open_ns, deadline_ns] falls if it runs on arrival (pure; the
/// rule PeriodicLoop::WaitNext follows with WakeOnArrival). One tick per slot, so the rate stays
/// the periodic one and never drifts, and never after the slot's periodic deadline (the fallback
/// when nothing arrives):
/// - a sample that came before the slot opened and has not been read by a tick
///   (`newest_pending_ns`, INT64_MIN for none) ticks it at its opening when it is at most
///   `grace_ns` old then (it just missed the previous slot, e.g. jitter across the boundary);
/// - otherwise the first arrival inside the slot (`next_arrival_ns`, INT64_MAX for none) ticks
///   it, or the deadline; an older pending sample is read by that tick (or superseded).
/// Why the grace: a device whose clock runs fast sends one sample more than the slots every
/// 1 / drift periods (10 s at 100 ppm); were a pending sample of any age to tick the slot at its
/// opening, every later sample would arrive just after its own slot's tick and wait for the next
/// opening, a wait growing by the drift each period up to a whole period (the periodic tick's
/// latency); so one old sample is superseded instead and the stream locks on again.
constexpr int64_t ArrivalTickNs(int64_t open_ns, int64_t deadline_ns, int64_t grace_ns,
                                int64_t newest_pending_ns, int64_t next_arrival_ns) {
  if (newest_pending_ns != INT64_MIN && newest_pending_ns >= open_ns - grace_ns) return open_ns;
  return next_arrival_ns < deadline_ns ? next_arrival_ns : deadline_ns;
}

/// A periodic timer with absolute deadlines: deadline k = start + k * period.
///
/// Call WaitNext() once per tick, after the tick's work. If the work finished later than the
/// deadline that was due next (an overrun), that period and every other boundary already passed
/// are skipped: the next deadline is the first boundary in the future, and the skipped count is
/// reported, so ticks are never bunched up to "catch up". One thread at a time uses an instance.
///
/// With WakeOnArrival(signal), a tick runs as soon as the signal counts an arrival, within its
/// period slot by the rule of ArrivalTickNs: never before the previous boundary, never after its
/// own deadline, which stays start + k * period (the periodic tick is the fallback: a silent
/// input still ticks at every deadline). Lateness is still measured against that deadline (0 for a
/// tick on arrival, which comes before it), and overruns and skips are counted as without the
/// signal.
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

  /// Ticks on the arrivals `signal` counts (see the class comment and ArrivalTickNs), with a
  /// grace of `grace_ns` (< 0: a tenth of the period); nullptr: periodic only. Arrivals counted
  /// before this call do not trigger a tick. `signal` must outlive the loop's use. Set-up,
  /// before the first WaitNext().
  void WakeOnArrival(const ArrivalSignal* signal, int64_t grace_ns = -1);

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
  const ArrivalSignal* arrival_ = nullptr;
  uint32_t seen_arrivals_ = 0;  // the signal's count at the previous tick's wake-up
  int64_t grace_ns_ = 0;
};

}  // namespace felt
