#include "haptic_loop/safety.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace felt {
namespace {

bool Finite(const Vec3& v) {
  return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z());
}

void Require(bool ok, const char* field, const std::string& rule, double value) {
  if (!ok) {
    throw std::invalid_argument(std::string("safety.") + field + ": " + rule + ", got " +
                                std::to_string(value));
  }
}

// Scales `f` down to magnitude `max` (direction kept); true when it did.
bool ClampMagnitude(double max, Vec3* f) {
  const double norm = f->norm();
  if (norm <= max) return false;
  *f *= max / norm;
  return true;
}

}  // namespace

void ValidateSafetySpec(const SafetySpec& spec) {
  Require(spec.max_force_N > 0 && std::isfinite(spec.max_force_N), "max_force_N", "must be > 0",
          spec.max_force_N);
  Require(spec.max_force_rate_N_per_s > 0 && std::isfinite(spec.max_force_rate_N_per_s),
          "max_force_rate_N_per_s", "must be > 0", spec.max_force_rate_N_per_s);
  Require(spec.ramp_in_s > 0 && std::isfinite(spec.ramp_in_s), "ramp_in_s", "must be > 0",
          spec.ramp_in_s);
  Require(spec.ramp_out_s > 0 && std::isfinite(spec.ramp_out_s), "ramp_out_s", "must be > 0",
          spec.ramp_out_s);
  Require(spec.max_passivity_damping_N_s_per_m >= 0 &&
              std::isfinite(spec.max_passivity_damping_N_s_per_m),
          "max_passivity_damping_N_s_per_m", "must be >= 0", spec.max_passivity_damping_N_s_per_m);
}

namespace {

// 2. Ramp gain: up with fresh input (ramp-in), down with stale input (ramp to zero); the flags
// say which.
void RampGain(const SafetySpec& spec, bool input_fresh, double dt_s, SafetyState* state,
              uint32_t* flags) {
  if (input_fresh) {
    state->gain = std::min(1.0, state->gain + dt_s / spec.ramp_in_s);
    if (state->gain < 1.0) *flags |= kSafetyRamping;
  } else {
    state->gain = std::max(0.0, state->gain - dt_s / spec.ramp_out_s);
    *flags |= kSafetyStaleInput;
  }
}

// 4. Force-rate (jerk) limit relative to the force sent last tick; true if it limited `force`.
bool LimitForceRate(const SafetySpec& spec, const Vec3& last_force_D_N, double dt_s, Vec3* force) {
  const Vec3 last = Finite(last_force_D_N) ? last_force_D_N : Vec3::Zero();
  const Vec3 step = *force - last;
  const double max_step = spec.max_force_rate_N_per_s * dt_s;
  if (!(step.norm() > max_step)) return false;
  *force = last + step * (max_step / step.norm());
  return true;
}

// 5. Passivity observer and controller (Hannaford & Ryu 2002, eqs. (9) and (11)): the energy
// E accumulates the power the user puts into the environment, F_user . v = -F_D . v; returns the
// new E, and true in *clamped if the controller's force had to be clamped.
double ObservePassivity(const SafetySpec& spec, const Vec3& v, double dt_s, SafetyState* state,
                        Vec3* force, bool* clamped) {
  double energy = state->energy_J - force->dot(v) * dt_s;
  const double v2 = v.squaredNorm();
  if (spec.passivity_controller && energy < 0.0 && v2 > 1e-12) {
    // Least damping that brings E back to 0: alpha |v|^2 dt = -E, capped.
    const double alpha = std::min(-energy / (v2 * dt_s), spec.max_passivity_damping_N_s_per_m);
    *force -= alpha * v;  // the device resists the motion
    *clamped = ClampMagnitude(spec.max_force_N, force) || *clamped;
    state->dissipated_J += alpha * v2 * dt_s;
    ++state->controller_ticks;
    energy = state->energy_J - force->dot(v) * dt_s;
  }
  return energy;
}

}  // namespace

SafetyOutput ApplySafety(const SafetySpec& spec, const SafetyInput& input, double dt_s,
                         SafetyState* state) {
  SafetyOutput out;
  if (input.sim_stalled) out.flags |= kSafetySimStalled;

  // 1. Non-finite input or proxy force: target zero, counted.
  Vec3 v = input.velocity_D_m_per_s;
  Vec3 target = input.proxy_force_D_N;
  if (input.input_nan || !Finite(v) || !Finite(target)) {
    out.nan = true;
    target.setZero();
  }
  if (!Finite(v)) v.setZero();

  // A non-finite value zeroes the force at once (no rate limit on the way down) and restarts the
  // ramp-in: the next good sample fades in like a reconnect. Otherwise: ramp (2; with stale
  // input the target is the proxy's last force, so the force fades out from there), magnitude
  // clamp to the device's maximum (3), rate limit (4), passivity (5).
  Vec3 force = Vec3::Zero();
  bool clamped = false;
  double energy = state->energy_J;
  if (out.nan) {
    state->gain = 0.0;
    if (!input.input_fresh) out.flags |= kSafetyStaleInput;
  } else {
    RampGain(spec, input.input_fresh, dt_s, state, &out.flags);
    force = state->gain * target;
    clamped = ClampMagnitude(spec.max_force_N, &force);
    clamped = LimitForceRate(spec, state->last_force_D_N, dt_s, &force) || clamped;
    energy = ObservePassivity(spec, v, dt_s, state, &force, &clamped);
  }

  // 6. Final check of the output.
  if (!Finite(force) || !std::isfinite(energy)) {
    out.nan = true;
    force.setZero();
    energy = std::isfinite(state->energy_J) ? state->energy_J : 0.0;
  }
  if (clamped) {
    out.flags |= kSafetyClamped;
    ++state->clamped_ticks;
  }
  if (out.nan) ++state->nan_events;
  state->energy_J = energy;
  state->last_force_D_N = force;
  out.force_D_N = force;
  return out;
}

}  // namespace felt
