#pragma once
// The local contact model of a ForceCommand (Mark et al. 1996, "Adding force feedback to graphics
// systems: issues and solutions", the intermediate representation): the server sends with each
// force the plane the proxy rests on and its spring, so that a driver renders between messages at
// its own servo rate from its tip's current position instead of holding a force that is one
// message old:
//   F_D(p_D) = k * max(0, (contact_point_m_D - p_D) . contact_normal_D) * contact_normal_D,
// clamped to the device's maximum force. k = contact_stiffness_N_per_m = 0 (not in contact, or the
// server is ramping the force in or out) means: output force_N_D as sent. Plain arithmetic: no
// DDS type, real-time safe.

#include <algorithm>
#include <array>
#include <cmath>

#include "transport/views.h"

namespace felt::transport {

/// The force [N, device frame] a driver outputs for its tip at `tip_m_D` [m, device frame] under
/// `command` (the newest ForceCommand): the local contact model above when
/// command.contact_stiffness_N_per_m > 0, else command.force_N_D; then clamped to `max_force_N`
/// [N] (direction kept). Non-finite input gives zero force. Real-time safe.
inline std::array<double, 3> LocalContactForce(const ForceCommandView& command,
                                               const std::array<double, 3>& tip_m_D,
                                               double max_force_N) {
  std::array<double, 3> f = command.force_N_D;
  const double k = command.contact_stiffness_N_per_m;
  if (k > 0.0) {
    // Penetration depth along the normal: how far the tip is behind the plane, m.
    double depth_m = 0.0;
    for (int i = 0; i < 3; ++i) {
      depth_m += (command.contact_point_m_D[i] - tip_m_D[i]) * command.contact_normal_D[i];
    }
    depth_m = std::max(0.0, depth_m);
    for (int i = 0; i < 3; ++i) f[i] = k * depth_m * command.contact_normal_D[i];
  }
  // The device's own clamp; NaN anywhere gives zero.
  const double norm_N = std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
  if (!std::isfinite(norm_N)) return {0.0, 0.0, 0.0};
  if (norm_N > max_force_N) {
    for (double& x : f) x *= max_force_N / norm_N;
  }
  return f;
}

}  // namespace felt::transport
