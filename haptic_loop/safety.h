#pragma once
// The safety layer between the proxy and the device (issue 5, "Safety"): a pure function of the
// proxy's force, the device's motion and a small per-device state, applied once per device and
// per 1 kHz tick after ProxyTick. In order:
//  1. NaN/inf in the input (position, velocity) or in the proxy's force: the force target is zero
//     this tick, counted;
//  2. a gain g in [0, 1] on the proxy's force: it rises by dt / ramp_in_s per tick while the input
//     is fresh (ramp-in at start and after a reconnect: g is 0 after a stale spell) and falls by
//     dt / ramp_out_s while it is stale (no new pointer sample for longer than the scene's limit),
//     so stale input ramps the force to zero and zero forces keep being sent;
//  3. the magnitude clamp to the device's max_force_N (direction kept);
//  4. the force-rate (jerk) limit: |F - F_previous| <= max_force_rate_N_per_s * dt;
//  5. the passivity observer and the optional passivity controller (Hannaford & Ryu 2002, "Time
//     domain passivity control of haptic interfaces", IEEE T-RA 18(1)): the observed energy
//     E = sum over ticks of F_user . v . dt, where F_user = -F_D is the force the hand puts on the
//     device (F_D: the force the device puts on the hand, device frame) and v the device's
//     velocity, is the energy the virtual environment has absorbed; E < 0 means it has generated
//     energy. The controller then adds the damping alpha = -E / (|v|^2 dt) (capped) along v, the
//     least that brings E back to zero;
//  6. a final clamp and NaN check of the output.
// Everything is plain arithmetic on the arguments: deterministic, real-time safe.
#include <cstdint>

#include "collision/mesh.h"

namespace felt {

/// What the safety layer enforces for one device (from [haptic] and the device's max_force_N).
struct SafetySpec {
  double max_force_N = 3.3;               ///< magnitude clamp, device frame, N (> 0)
  double max_force_rate_N_per_s = 500.0;  ///< jerk limit on |dF/dt|, N/s (> 0)
  double ramp_in_s = 0.5;                 ///< gain 0 -> 1 over this long with fresh input, s (> 0)
  double ramp_out_s = 0.05;               ///< gain 1 -> 0 over this long with stale input, s (> 0)
  bool passivity_controller = false;      ///< add damping to keep the observed energy >= 0
  double max_passivity_damping_N_s_per_m = 50.0;  ///< cap on the controller's alpha, N s/m (>= 0)
};

/// What the safety layer keeps per device between ticks. Plain data; starts at rest, gain 0.
struct SafetyState {
  double gain = 0.0;                   ///< ramp gain in [0, 1]
  Vec3 last_force_D_N = Vec3::Zero();  ///< force sent last tick, device frame, N
  double energy_J = 0.0;               ///< passivity observer E (see the file comment), J
  double dissipated_J = 0.0;           ///< energy the passivity controller removed, J (>= 0)
  uint64_t nan_events = 0;             ///< ticks with a non-finite input or output
  uint64_t clamped_ticks = 0;          ///< ticks whose force was clamped (magnitude or rate)
  uint64_t controller_ticks = 0;       ///< ticks at which the passivity controller acted
};

/// One tick's input to the safety layer. Device frame.
struct SafetyInput {
  Vec3 proxy_force_D_N = Vec3::Zero();     ///< the proxy's force (0 when no proxy ran), N
  Vec3 velocity_D_m_per_s = Vec3::Zero();  ///< device velocity, m/s (0 when unknown)
  bool input_fresh = false;  ///< a pointer sample no older than the stale limit is in use
  bool input_nan = false;    ///< the newest pointer sample held a non-finite value
  bool sim_stalled = false;  ///< the newest snapshot is older than the stall limit
};

/// Flags of one force (the values of transport/views.h's kForce* bits).
enum SafetyFlag : uint32_t {
  kSafetyClamped = 1,     ///< clamped to the maximum force or rate
  kSafetyStaleInput = 2,  ///< no fresh pointer sample: force ramping to zero
  kSafetySimStalled = 4,  ///< the sim is late: the last snapshot was used
  kSafetyRamping = 8,     ///< ramp-in after start or reconnect (gain < 1)
};

/// One tick's output.
struct SafetyOutput {
  Vec3 force_D_N = Vec3::Zero();  ///< the force to send, device frame, N (finite, <= max)
  uint32_t flags = 0;             ///< SafetyFlag bits
  bool nan = false;               ///< a non-finite value was met (force zeroed, counted)
};

/// Throws std::invalid_argument naming the field when `spec` breaks a rule above.
void ValidateSafetySpec(const SafetySpec& spec);

/// Applies the safety rules of the file comment for one tick of `dt_s` [s] (> 0) and updates
/// `state`. Real-time safe: no allocation, lock, exception, log or I/O.
SafetyOutput ApplySafety(const SafetySpec& spec, const SafetyInput& input, double dt_s,
                         SafetyState* state);

}  // namespace felt
