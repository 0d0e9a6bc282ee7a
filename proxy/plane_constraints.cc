#include "proxy/plane_constraints.h"

#include <Eigen/Dense>
#include <cmath>
#include <limits>

namespace felt {
namespace {

// Projects `goal` onto the intersection of the planes in `mask` (1, 2 or 3 of them):
// x = goal + sum_i lambda_i n_i with n_j . x = offset_j, i.e. G lambda = offset - N^T goal where
// G = N^T N is the Gram matrix (Ruspini 1997 §3, Lagrange multipliers). Returns false when the
// planes are linearly dependent (G singular) or a multiplier is negative (the goal lies on that
// plane's free side, so it is not an active constraint).
bool ProjectOntoSubset(const Vec3& goal, std::span<const ConstraintPlane> planes, uint8_t mask,
                       Vec3* out) {
  int idx[kMaxConstraintPlanes];
  int k = 0;
  for (int i = 0; i < static_cast<int>(planes.size()); ++i) {
    if (mask & (1u << i)) idx[k++] = i;
  }
  Eigen::Matrix3d gram = Eigen::Matrix3d::Identity();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  for (int a = 0; a < k; ++a) {
    const ConstraintPlane& pa = planes[idx[a]];
    rhs(a) = pa.offset_m - pa.normal.dot(goal);
    for (int b = 0; b < k; ++b) gram(a, b) = pa.normal.dot(planes[idx[b]].normal);
  }
  // A (near-)singular Gram matrix means parallel or dependent planes: that subset has no unique
  // projection and another subset covers it.
  const double det = k == 1   ? gram(0, 0)
                     : k == 2 ? gram.topLeftCorner<2, 2>().determinant()
                              : gram.determinant();
  if (std::abs(det) < 1e-12) return false;
  Eigen::Vector3d lambda = Eigen::Vector3d::Zero();
  if (k == 1) {
    lambda(0) = rhs(0) / gram(0, 0);
  } else if (k == 2) {
    lambda.head<2>() = gram.topLeftCorner<2, 2>().inverse() * rhs.head<2>();
  } else {
    lambda = gram.inverse() * rhs;
  }
  // KKT: every active constraint pushes the point toward its free side.
  for (int a = 0; a < k; ++a) {
    if (lambda(a) < 0.0) return false;
  }
  Vec3 x = goal;
  for (int a = 0; a < k; ++a) x += lambda(a) * planes[idx[a]].normal;
  *out = x;
  return true;
}

}  // namespace

PlaneSolveResult SolveClosestFeasible(const Vec3& goal, std::span<const ConstraintPlane> planes,
                                      double tolerance_m) {
  PlaneSolveResult best;
  best.point = goal;
  const int n = static_cast<int>(planes.size()) < kMaxConstraintPlanes
                    ? static_cast<int>(planes.size())
                    : kMaxConstraintPlanes;
  const std::span<const ConstraintPlane> used = planes.first(static_cast<size_t>(n));
  double best_dist2 = std::numeric_limits<double>::infinity();
  // Enumerate active sets (empty set first: the goal itself if it is free).
  for (uint8_t mask = 0; mask < (1u << n); ++mask) {
    Vec3 candidate = goal;
    if (mask != 0 && !ProjectOntoSubset(goal, used, mask, &candidate)) continue;
    bool feasible = true;
    for (int i = 0; i < n && feasible; ++i) {
      if (!(mask & (1u << i)) && used[i].Distance(candidate) < -tolerance_m) feasible = false;
    }
    if (!feasible) continue;
    const double d2 = (candidate - goal).squaredNorm();
    if (d2 < best_dist2) {
      best_dist2 = d2;
      best.point = candidate;
      best.active_mask = mask;
      best.feasible = true;
    }
  }
  return best;
}

}  // namespace felt
