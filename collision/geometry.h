#pragma once
// Point-triangle and sphere-triangle kernels for the collision structures and the proxy: pure
// functions on Eigen values, no allocation, no exceptions (real-time safe).

#include <cstdint>

#include "collision/mesh.h"

namespace felt {

/// A triangle whose squared doubled area |ab x ac|^2 is at most kDegenerateSin2 |ab|^2 |ac|^2
/// (the sine of its angle at a below 1e-10) is treated as a segment set: it has no face normal.
inline constexpr double kDegenerateSin2 = 1e-20;

/// A contact whose normal n and motion direction d satisfy n.d >= -kApproachCos |d| is "grazing or
/// leaving" and is not reported (the sweep convention, see SweepSphereTriangle). Dimensionless.
inline constexpr double kApproachCos = 1e-9;

/// An edge-cylinder or vertex-sphere contact whose path passes at most kGrazeDepth r inside the
/// cylinder or sphere (its closest approach) is a graze and is not reported. Dimensionless.
inline constexpr double kGrazeDepth = 1e-9;

/// The point of a triangle nearest to a query point.
struct TrianglePoint {
  Vec3 point = Vec3::Zero();        ///< the nearest point of the triangle, world, m
  Vec3 barycentric = Vec3::Zero();  ///< weights of (a, b, c): non-negative, sum to 1
  double distance_sq = 0.0;         ///< |p - point|^2, m^2
};

/// The point of segment [a, b] nearest to p, with its parameter s in [0, 1] (point = a + s (b-a)).
/// A zero-length segment gives s = 0. Real-time safe.
struct SegmentPoint {
  Vec3 point = Vec3::Zero();
  double s = 0.0;
};
SegmentPoint ClosestPointOnSegment(const Vec3& p, const Vec3& a, const Vec3& b);

/// Closest point of triangle (a, b, c) to p, by Voronoi-region classification (Ericson,
/// "Real-Time Collision Detection", 2005, §5.1.5). Robust for degenerate triangles (zero area,
/// repeated or collinear vertices; see kDegenerateSin2): those are handled as the union of their
/// three edges, the nearest edge point winning. All positions in one frame, m. Real-time safe.
TrianglePoint ClosestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

/// True when the triangle is degenerate in the sense of kDegenerateSin2.
bool IsDegenerateTriangle(const Vec3& a, const Vec3& b, const Vec3& c);

/// A first contact between a sphere and a triangle.
struct SweepContact {
  bool hit = false;                 ///< false: no contact in [0, 1]; the other fields are unset
  double toi = 1.0;                 ///< time of impact as a fraction of the motion, in [0, 1]
  Vec3 point = Vec3::Zero();        ///< the triangle's point touched at toi, world, m
  Vec3 normal = Vec3::Zero();       ///< unit contact normal, from the triangle toward the sphere
  Vec3 barycentric = Vec3::Zero();  ///< of `point` in the triangle (a, b, c)
};

/// Exact first time of impact of a sphere of radius r >= 0 [m] whose centre moves linearly from p0
/// to p1 [m] against the static triangle (a, b, c): the least t in [0, 1] with
/// dist(p0 + t (p1 - p0), triangle) = r, found as the ray's entry into the triangle's Minkowski sum
/// with the sphere: the two faces offset by +-r (Ericson §5.3.6 for ray-triangle), the three edge
/// cylinders (Ericson §5.3.7) and the three vertex spheres (Ericson §5.3.2). Degenerate triangles
/// have no faces, only their edges and vertices.
///
/// Convention (what the god-object proxy needs):
/// - a contact counts only if the sphere moves toward the triangle there: on a face,
///   n.(p1 - p0) < -kApproachCos |p1 - p0| with n the contact normal; on an edge or a vertex, the
///   line of motion must pass deeper than kGrazeDepth r inside that edge's cylinder or vertex's
///   sphere (a graze's root is ill-conditioned: O(sqrt(eps)) errors tilt its normal). So a sphere
///   resting at distance r that moves tangentially or away is not blocked, and a grazing touch
///   (distance reaching r with zero approach speed) is not reported; what such a rule lets
///   through is a dip of at most kGrazeDepth r, or kApproachCos times the motion's length;
/// - if the sphere already overlaps at t = 0 (distance <= r) and moves toward the triangle, the
///   contact is at toi = 0 with normal (p0 - closest point)/|...|; when p0 lies on the triangle's
///   plane inside it the normal is the face normal turned against the motion;
/// - the distance along a path is convex in t, so an overlapping sphere that moves away never
///   meets the triangle again in [0, 1].
/// The normal always faces the side the sphere comes from. Real-time safe.
SweepContact SweepSphereTriangle(const Vec3& p0, const Vec3& p1, double r, const Vec3& a,
                                 const Vec3& b, const Vec3& c);

/// Options of MovingTriangleSphereContact.
struct MovingContactOptions {
  double tolerance_m = 1e-7;     ///< stop when the gap dist - r is at most this, m (> 0)
  int32_t max_iterations = 200;  ///< conservative-advancement steps before giving up (see below)
};

/// First contact of a sphere of radius r [m], centre moving linearly from c0 to c1, against a
/// triangle whose vertices move linearly from (a0, b0, c0v) to (a1, b1, c1v) over the same interval
/// t in [0, 1], by conservative advancement (Mirtich 1996; Zhang, Redon, Lee & Kim 2007): every
/// point of the triangle (fixed barycentric weights) moves relative to the centre at most
/// L = max_i |(v_i1 - v_i0) - (c1 - c0)| per unit t, so the gap g(t) = dist - r is L-Lipschitz and
/// t may safely advance by g/L. Returns the first t at which g <= tolerance_m (no contact earlier:
/// g > 0 on [0, toi)); the point, barycentrics and normal are those of the closest point at toi.
/// Overlap at t = 0 (g <= tolerance) reports toi = 0 only if the closest point approaches the
/// centre (relative velocity along the normal above kApproachCos L), else no contact — the same
/// convention as SweepSphereTriangle. If max_iterations is reached (a long grazing approach) the
/// contact is reported at the current, conservative t with its gap larger than the tolerance.
/// Real-time safe.
SweepContact MovingTriangleSphereContact(const Vec3& c0, const Vec3& c1, double r, const Vec3& a0,
                                         const Vec3& b0, const Vec3& c0v, const Vec3& a1,
                                         const Vec3& b1, const Vec3& c1v,
                                         const MovingContactOptions& options = {});

}  // namespace felt
