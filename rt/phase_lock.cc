#include "rt/phase_lock.h"

#include <algorithm>
#include <cmath>

namespace felt {

PhaseLock::PhaseLock(const PhaseLockSpec& spec, int64_t start_ns)
    : spec_(spec), start_ns_(start_ns), offset_(spec.period_ns) {}

double PhaseLock::Centered(double x) const {
  const auto period = static_cast<double>(spec_.period_ns);
  return x - period * std::floor(x / period + 0.5);
}

void PhaseLock::Observe(int64_t arrival_ns) {
  const auto period = static_cast<double>(spec_.period_ns);
  const double measured = std::fmod(static_cast<double>(arrival_ns - start_ns_), period);
  if (!locked_) {
    phase_ = measured < 0 ? measured + period : measured;
    locked_ = true;
    return;
  }
  // g-h update on the wrapped error: the phase by g, the drift by h.
  const double error = Centered(measured - phase_);
  phase_ += spec_.phase_gain * error;
  drift_ += spec_.rate_gain * error;
}

int64_t PhaseLock::TickNs(int64_t open_ns) {
  const auto period = static_cast<double>(spec_.period_ns);
  if (locked_) phase_ += drift_;  // one period passes per slot
  // Target: phase + margin, wrapped into [0, period]; without a lock, the periodic deadline.
  double target = period;
  if (locked_) {
    target = std::fmod(phase_ + static_cast<double>(spec_.margin_ns), period);
    if (target < 0) target += period;
  }
  // Slew toward it, at most max_slew_ns, never leaving [0, period] (no tick outside its slot).
  const auto step = static_cast<int64_t>(std::llround(target)) - offset_;
  offset_ += std::clamp(step, -spec_.max_slew_ns, spec_.max_slew_ns);
  offset_ = std::clamp<int64_t>(offset_, 0, spec_.period_ns);
  return open_ns + offset_;
}

double PhaseLock::phase_ns() const {
  const auto period = static_cast<double>(spec_.period_ns);
  const double p = std::fmod(phase_, period);
  return p < 0 ? p + period : p;
}

}  // namespace felt
