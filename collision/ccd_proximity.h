#pragma once
// Proximity kernels for self-collision (issue 22): the closest points of two segments (edge-edge)
// beside the point-triangle query ClosestPointOnTriangle (collision/geometry.h), robust for
// parallel, nearly parallel and zero-length segments. Pure functions, no allocation, no
// exceptions (real-time safe).

#include "collision/geometry.h"
#include "collision/mesh.h"

namespace felt {

/// The closest points of two segments [p0, p1] and [q0, q1].
struct SegmentsClosest {
  double s = 0.0;               ///< point_a = p0 + s (p1 - p0), s in [0, 1]
  double u = 0.0;               ///< point_b = q0 + u (q1 - q0), u in [0, 1]
  Vec3 point_a = Vec3::Zero();  ///< on [p0, p1], m
  Vec3 point_b = Vec3::Zero();  ///< on [q0, q1], m
  double distance_sq = 0.0;     ///< |point_a - point_b|^2, m^2
};

/// Closest points of the segments [p0, p1] and [q0, q1] [m, one frame]: the minimum of the convex
/// quadratic |p0 + s (p1 - p0) - q0 - u (q1 - q0)|^2 over the unit square (s, u). Its interior
/// stationary point (Ericson, "Real-Time Collision Detection", 2005, §5.1.9, in cross-product
/// form, accurate to about epsilon / sin(angle)) is the answer when it lies in the square and the
/// segments are far from parallel; otherwise the minimum lies on the square's boundary, i.e. is
/// one of the four end-point-to-segment distances (each a clamped projection,
/// ClosestPointOnSegment), and for nearly parallel segments the least of those and the stationary
/// point wins. Parallel segments get one of their closest pairs; a zero-length segment is a
/// point. Real-time safe.
SegmentsClosest ClosestPointsOfSegments(const Vec3& p0, const Vec3& p1, const Vec3& q0,
                                        const Vec3& q1);

}  // namespace felt
