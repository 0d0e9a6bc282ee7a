#include "proxy/proxy_probe.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "collision/geometry.h"

namespace felt {

ProxyProbe ProbeProxy(const ProxyModel& model, const ProxyState& state, ProxyProbeMemory* memory) {
  ProxyProbe out;
  // Mode blend_forces gathers for its second proxy (on the previous snapshot) last.
  const GodObject& body =
      model.snapshot_mode == SnapshotMode::kBlendForces && state.body_prev.placed
          ? state.body_prev
          : state.body;
  const Vec3& p = body.p_W_m;
  // Reach: the nearest gathered triangle at the tick's positions.
  double best_sq = std::numeric_limits<double>::infinity();
  for (const LocalTriangle& t : state.local.triangles()) {
    best_sq = std::min(best_sq, ClosestPointOnTriangle(p, t.a, t.b, t.c).distance_sq);
  }
  if (std::isfinite(best_sq)) out.reach_m = std::max(0.0, model.radius_m - std::sqrt(best_sq));

  // Pop-through: the other side of the last contact triangle, nearest point strictly inside it.
  Vec3 a, b, c;
  if (memory->triangle >= 0 && memory->side != 0 &&
      state.local.Corners(memory->triangle, &a, &b, &c)) {
    const TrianglePoint cp = ClosestPointOnTriangle(p, a, b, c);
    const bool interior = cp.barycentric.minCoeff() > 1e-9;
    const int32_t side = SideOfTriangle(p, a, b, c);
    out.popped = interior && side != 0 && side != memory->side;
  }

  // The contact of this tick, for the next probe.
  memory->triangle = -1;
  memory->side = 0;
  for (int32_t i = 0; i < body.num_contacts; ++i) {
    const ProxyContact& k = body.contacts[i];
    if (k.triangle < 0) continue;  // an obstacle
    if (state.local.Corners(k.triangle, &a, &b, &c)) {
      memory->triangle = k.triangle;
      memory->side = SideOfTriangle(p, a, b, c);
    }
    break;
  }
  return out;
}

}  // namespace felt
