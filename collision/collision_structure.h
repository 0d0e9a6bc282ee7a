#pragma once
// The one interface the proxy (issue 4) calls: a std::variant over the collision structures and
// free functions that dispatch once per call (std::visit), never per triangle. Every structure
// returns bit-identical answers (they share the per-triangle kernels of collision.h).
//
// Snapshot use: a CollisionStructure is a value. The sim thread repairs its own copy and
// publishes it with the positions it was repaired with; the haptic thread queries the published
// copy. Copies share the immutable triangle list and BVH shape (shared_ptr<const>); copying one
// into an existing object of the same kind and size reuses its arrays (no allocation).

#include <memory>
#include <span>
#include <string>
#include <variant>
#include <vector>

#include "collision/bvh.h"
#include "collision/collision.h"
#include "collision/naive_collision.h"
#include "collision/spatial_hash.h"

namespace felt {

/// Any collision structure.
using CollisionStructure = std::variant<NaiveCollision, Bvh, SpatialHash>;

/// Which structure to build, with its options (what a scene file would select).
struct CollisionStructureSpec {
  enum class Kind : uint8_t { kNaive, kBvh, kSpatialHash };
  Kind kind = Kind::kBvh;
  BvhOptions bvh;           ///< used when kind == kBvh
  SpatialHashOptions hash;  ///< used when kind == kSpatialHash
};

/// The default structure of a scene that names none: the AABB quad tree with bottom-up repair,
/// the fastest to repair and to query in bench/results/README-collision.md (0.061 against 0.242
/// ms for the sphere quad tree at 4802 triangles, queries faster too).
inline CollisionStructureSpec DefaultCollisionStructure() {
  CollisionStructureSpec spec;
  spec.kind = CollisionStructureSpec::Kind::kBvh;
  spec.bvh.volume = BoundingVolume::kAabb;
  spec.bvh.arity = 4;
  spec.bvh.repair = BvhRepair::kBottomUp;
  return spec;
}

/// Builds the structure over `triangles` at positions x [m]. Throws std::invalid_argument as the
/// structure's constructor does. Not real-time safe (allocates).
CollisionStructure MakeCollisionStructure(const CollisionStructureSpec& spec,
                                          std::shared_ptr<const std::vector<Triangle>> triangles,
                                          std::span<const Vec3> x);

/// A short name, e.g. "naive", "osh", "bvh-sphere-4-bottomup", "bvh-aabb-4-queue" (001 §6.3's
/// queue repair, BvhRepair::kBottomUpQueue), "bvh-aabb-2-topdown-d5mm".
std::string CollisionStructureName(const CollisionStructureSpec& spec);

/// Brings the structure up to date with positions x [m]. Real-time safe.
inline RepairStats Repair(CollisionStructure& s, std::span<const Vec3> x) {
  return std::visit([&](auto& v) { return v.Repair(x); }, s);
}

/// Makes the structure bound the linear motion x_old -> x_new (for SweepSphereMoving; the other
/// queries stay exact on either snapshot). Real-time safe.
inline RepairStats RepairSwept(CollisionStructure& s, std::span<const Vec3> x_old,
                               std::span<const Vec3> x_new) {
  return std::visit([&](auto& v) { return v.RepairSwept(x_old, x_new); }, s);
}

/// Query 1: every triangle within distance r [m] of p [m], written to `out` (closest point,
/// barycentrics, distance; order unspecified; see WithinResult for capacity and overflow).
/// `ids_only`: the same triangles, but those wholly within r without their closest point
/// (WithinAccumulator::ids_only). Real-time safe.
inline WithinResult TrianglesWithin(const CollisionStructure& s, std::span<const Vec3> x,
                                    const Vec3& p, double r, std::span<PointContact> out,
                                    bool ids_only = false) {
  return std::visit([&](const auto& v) { return v.TrianglesWithin(x, p, r, out, ids_only); }, s);
}

/// Query 2: first contact of a sphere of radius r [m] whose centre moves p0 -> p1 [m] against the
/// triangles at x: exact time of impact, never tunnels. Convention (SweepSphereTriangle): only
/// contacts the sphere moves toward count; an overlap at the start gives toi = 0 if moving in,
/// nothing if moving tangentially or away. Ties: lowest triangle index. Real-time safe.
inline SweepHit SweepSphere(const CollisionStructure& s, std::span<const Vec3> x, const Vec3& p0,
                            const Vec3& p1, double r) {
  return std::visit([&](const auto& v) { return v.SweepSphere(x, p0, p1, r); }, s);
}

/// Query 3: first contact of a sphere of radius r [m] moving c0 -> c1 while the cloth moves
/// linearly x_old -> x_new over the same interval (conservative advancement to within
/// options.tolerance_m; MovingTriangleSphereContact). Culls with the structure only after
/// RepairSwept(x_old, x_new); otherwise tests every triangle. Real-time safe.
inline SweepHit SweepSphereMoving(const CollisionStructure& s, std::span<const Vec3> x_old,
                                  std::span<const Vec3> x_new, const Vec3& c0, const Vec3& c1,
                                  double r, const MovingContactOptions& options = {}) {
  return std::visit(
      [&](const auto& v) { return v.SweepSphereMoving(x_old, x_new, c0, c1, r, options); }, s);
}

}  // namespace felt
