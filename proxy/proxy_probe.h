#pragma once
// How a proxy sits against the cloth it was rendered on, measured after its tick (issue 20): how
// deep the proxy sphere reaches into that cloth and whether it went through it. For comparisons
// and benchmarks (compare/lockstep.h); not part of the tick, so it costs the tick nothing.
//
// The cloth measured is the tick's own (the triangles ProxyTick gathered, at the positions it
// rendered: the newest snapshot, an interpolated or extrapolated cloth, or the local patch), so a
// mode that lags the real cloth is judged on what its user felt, not on the lag. Mode blend_forces
// gathers for its second proxy (on the previous snapshot) last, so there that proxy is measured.

#include <cstdint>

#include "collision/mesh.h"
#include "proxy/proxy.h"
#include "proxy/proxy_model.h"

namespace felt {

/// What one probe saw.
struct ProxyProbe {
  /// How deep the proxy sphere reaches into the tick's cloth: max(0, r - d), d the distance from
  /// its centre to the nearest gathered triangle, m (0 when nothing was gathered).
  double reach_m = 0.0;
  /// The proxy went through the cloth: its centre ended this tick on the other side of the
  /// triangle it touched at the previous probe (side taken then), with its nearest point strictly
  /// inside that triangle (going round the cloth's border is not counted).
  bool popped = false;
};

/// What a probe keeps for the next one: the previous tick's first cloth contact and its side.
struct ProxyProbeMemory {
  int32_t triangle = -1;  ///< the contact triangle (-1: none)
  int32_t side = 0;       ///< SideOfTriangle of the proxy centre then (+1, -1; 0: unknown)
};

/// Probes `state` after a ProxyTick under `model` (see the file comment), updating `memory`.
/// Not real-time code (a few closest-point queries over the gathered triangles).
ProxyProbe ProbeProxy(const ProxyModel& model, const ProxyState& state, ProxyProbeMemory* memory);

}  // namespace felt
