#pragma once
// The proxy against the scene's static obstacles ([[obstacles]], sim_loop/cloth_spec.h): closest
// points and the swept-sphere first contact against a plane, a sphere, an axis-aligned box and a
// capsule, as small pure functions (Ericson, Real-Time Collision Detection 2005, §5.3 and §5.5).
//
// Every obstacle is convex (a plane bounds a half-space), so along a straight motion the distance
// from the sphere's centre to the obstacle is convex in t: a sphere that starts touching and moves
// away (or tangentially) never meets the obstacle again on that motion. The proxy touches the
// obstacle's surface itself; the cloth's margin_m is the sim's and is not added here.
//
// Contact ids: a ProxyContact (proxy/proxy.h) of obstacle k carries the id -1 - k (negative);
// cloth contacts carry their triangle index (>= 0). Obstacle contacts put no force on the cloth.

#include <cstdint>
#include <span>

#include "collision/geometry.h"
#include "sim_loop/cloth_spec.h"

namespace felt {

/// The contact id of obstacle `index` (>= 0): -1 - index, always negative.
inline constexpr int32_t ObstacleContactId(int32_t index) { return -1 - index; }
/// Whether a contact id names an obstacle (negative) rather than a cloth triangle.
inline constexpr bool IsObstacleContactId(int32_t id) { return id < 0; }
/// The obstacle index of a negative contact id: the inverse of ObstacleContactId.
inline constexpr int32_t ObstacleIndexOf(int32_t id) { return -1 - id; }

/// The point of an obstacle's surface nearest to a query point.
struct ObstaclePoint {
  Vec3 point_W_m = Vec3::Zero();  ///< the surface point, world, m
  Vec3 normal_W = Vec3::UnitY();  ///< unit outward surface normal there, world
  double distance_m = 0.0;        ///< signed distance of the query point, < 0 inside, m
};

/// The surface point of `obstacle` nearest to `p_W` [m, world] (inside: the nearest face of a
/// box, the radial point of a sphere or capsule), with its outward normal and the signed distance
/// (sim_loop/cloth.h's ObstacleDistance, margin not included). A query at a sphere's centre or on
/// a capsule's axis takes +y as its normal. Real-time safe.
ObstaclePoint ClosestObstaclePoint(const ObstacleSpec& obstacle, const Vec3& p_W);

/// Entry time t in [0, 1] of the segment p0 + t (p1 - p0) [m] into the solid ball |x - c| <= R
/// (Ericson §5.3.2, a ray against a sphere); false if it does not enter on [0, 1] or starts
/// inside. Real-time safe.
bool SegmentEntersBall(const Vec3& p0, const Vec3& p1, const Vec3& c, double R, double* t);

/// Entry time t in [0, 1] of the segment into the solid capsule of radius R around segment
/// [a, b] [m]: the side of the finite cylinder (Ericson §5.3.7) or either end ball (§5.3.2);
/// false if it does not enter on [0, 1] or starts inside. Real-time safe.
bool SegmentEntersCapsule(const Vec3& p0, const Vec3& p1, const Vec3& a, const Vec3& b, double R,
                          double* t);

/// Entry time t in [0, 1] of the segment into the solid box [lo, hi] [m] (the slab test, Ericson
/// §5.3.3); false if it does not enter on [0, 1] or starts inside. Real-time safe.
bool SegmentEntersBox(const Vec3& p0, const Vec3& p1, const Vec3& lo, const Vec3& hi, double* t);

/// Exact first contact of a sphere of radius r >= 0 [m] whose centre moves linearly p0 -> p1 [m]
/// against the static `obstacle`: the least t in [0, 1] at which the centre's distance to the
/// obstacle is r, found as the motion's entry into the obstacle grown by r (the Minkowski sum):
/// a plane moved by r; a sphere of radius R + r; a capsule of radius R + r; a box as the union of
/// its three face slabs grown by r along one axis and its twelve edge capsules of radius r
/// (Ericson §5.5.7, a moving sphere against an AABB). The contact point and normal are the
/// obstacle's closest point to the centre at toi and its outward normal; barycentric is unused.
/// Convention as SweepSphereTriangle: a sphere that already touches (distance <= r, plus a
/// rounding slack of 1e-12 (1 + r + |p0|_max)) hits at toi = 0 only if it moves toward the
/// obstacle (n . (p1 - p0) < -kApproachCos |p1 - p0|), so a proxy resting on an obstacle slides
/// along it freely. Real-time safe.
SweepContact SweepSphereObstacle(const Vec3& p0, const Vec3& p1, double r,
                                 const ObstacleSpec& obstacle);

/// The earliest SweepSphereObstacle contact over `obstacles` (ties: the lowest index), with the
/// index of the obstacle hit in *index (untouched when none). Real-time safe; O(obstacles).
SweepContact SweepSphereObstacles(const Vec3& p0, const Vec3& p1, double r,
                                  std::span<const ObstacleSpec> obstacles, int32_t* index);

}  // namespace felt
