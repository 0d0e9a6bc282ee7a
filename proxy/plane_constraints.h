#pragma once
// The god-object's constraint solve (Ruspini, Kolarov & Khatib 1997, §3; Zilles & Salisbury 1995):
// the point closest to the goal that lies on the free side of every active constraint plane.

#include <cstdint>
#include <span>

#include "collision/mesh.h"

namespace felt {

/// A half-space constraint on the proxy centre: n . x >= offset_m, `normal` a unit vector pointing
/// to the free side (toward the proxy). World frame, metres.
struct ConstraintPlane {
  Vec3 normal = Vec3::UnitZ();
  double offset_m = 0.0;
  int32_t id = -1;  ///< caller's tag, e.g. the triangle that made the plane

  /// Signed distance of `p` to the plane, positive on the free side [m].
  double Distance(const Vec3& p) const { return normal.dot(p) - offset_m; }
};

/// The result of SolveClosestFeasible.
struct PlaneSolveResult {
  Vec3 point = Vec3::Zero();  ///< the point closest to the goal on the free side of every plane
  uint8_t active_mask = 0;    ///< bit i set: plane i is active (the point lies on it, lambda > 0)
  bool feasible = false;      ///< false when no point satisfies every plane (e.g. pinched)
};

/// Maximum number of planes SolveClosestFeasible takes (Ruspini's three-plane limit).
inline constexpr int kMaxConstraintPlanes = 3;

/// Minimises |x - goal|^2 subject to planes[i].Distance(x) >= -tolerance_m for every i, for up to
/// kMaxConstraintPlanes planes, exactly: every subset of planes is tried as the active set (an
/// equality-constrained projection: Lagrange multipliers from the subset's Gram matrix), and the
/// feasible candidate nearest the goal wins, which is the unique optimum of this convex problem.
/// Dependent subsets (parallel or coincident planes) are skipped; if no candidate is feasible the
/// result has feasible = false and point = goal. Real-time safe (no allocation, no exceptions).
PlaneSolveResult SolveClosestFeasible(const Vec3& goal, std::span<const ConstraintPlane> planes,
                                      double tolerance_m = 1e-12);

}  // namespace felt
