#pragma once
// A phase-locked tick schedule: the alternative to the tick on arrival (rt/periodic_loop.h,
// WakeOnArrival) that issue 23 proposed, kept as a pure model. `felt bench transport` runs it
// over the arrival times of its own end-to-end run to compare it with the tick on arrival on the
// same samples (bench/results/transport.md says why the server ticks on arrival instead).
//
// The tick of period slot (open, open + period] falls at open + offset: the offset follows the
// estimated arrival phase plus a margin, by at most max_slew_ns per period (so the tick period
// stays period +- max_slew_ns), and stays within [0, period] (never after the periodic deadline,
// never two ticks in one slot: no drift). The phase estimate is an alpha-beta tracker (a second-
// order PLL) on the arrival phase modulo the period: it follows a device clock whose period
// differs from the server's (a constant phase ramp) without a steady error (Brookner 1998,
// "Tracking and Kalman Filtering Made Easy", ch. 1: the g-h filter).

#include <cstdint>

namespace felt {

/// How a PhaseLock tracks and places the tick.
struct PhaseLockSpec {
  int64_t period_ns = 1'000'000;  ///< the tick period (the periodic grid's), ns
  int64_t margin_ns = 100'000;    ///< tick this long after the expected arrival, ns
  int64_t max_slew_ns = 20'000;   ///< the tick's offset moves at most this much per period, ns
  double phase_gain = 0.1;        ///< g: share of a phase error corrected per arrival (0, 1]
  double rate_gain = 0.005;       ///< h: share of it added to the drift estimate (ns per period)
};

/// The phase-locked schedule over one periodic grid (slot k opens at start + (k - 1) period).
/// Pure: no clock read; one thread.
class PhaseLock {
 public:
  /// A schedule on the grid whose boundaries are start_ns + k * period_ns.
  PhaseLock(const PhaseLockSpec& spec, int64_t start_ns);

  /// Observes an arrival at `arrival_ns` (updates the phase and drift estimates).
  void Observe(int64_t arrival_ns);

  /// The tick time of the slot that opens at `open_ns` (a boundary, increasing call by call):
  /// advances the estimate by the drift per period, slews the offset toward phase + margin,
  /// returns open_ns + offset, in [open_ns, open_ns + period].
  int64_t TickNs(int64_t open_ns);

  /// The estimated arrival phase after a boundary, ns in [0, period).
  double phase_ns() const;
  /// The estimated drift of the arrival phase, ns per period (a device 100 ppm fast: -100).
  double drift_ns_per_period() const { return drift_; }
  /// The current offset of the tick after its slot's opening, ns in [0, period].
  int64_t offset_ns() const { return offset_; }

 private:
  // `x` wrapped into [-period/2, period/2).
  double Centered(double x) const;

  PhaseLockSpec spec_;
  int64_t start_ns_;
  bool locked_ = false;  // an arrival has been seen
  double phase_ = 0;     // unwrapped estimate of the arrival phase, ns
  double drift_ = 0;     // ns per period
  int64_t offset_;       // the tick's offset after the slot opens, ns
};

}  // namespace felt
