#pragma once
// A bounding volume hierarchy over the cloth's triangles, built once from the topology and
// repaired every frame (001_0f9f1b7fedff7723.txt §4.1 and §6.3; 000_25210a744b053ca5.txt slides
// 24-27; 004_aff31237b107e6f0.txt for inflated volumes).
//
// Layout: nodes are numbered breadth-first in flat arrays, so every parent's id is lower than its
// children's and siblings are consecutive (001 §6.3). The tree's shape depends only on the number
// of triangles and the arity (a node of m triangles splits into min(arity, m) groups of as equal
// sizes as possible); which triangle goes to which leaf comes from a top-down median split over
// triangle centroids. The shape is shared (shared_ptr<const>) between copies; the volumes and the
// leaf order belong to each copy, so a Bvh can be double-buffered in a snapshot: the haptic thread
// queries one copy while the sim repairs the other.

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "collision/collision.h"

namespace felt {

/// The bounding volume kind of a Bvh.
enum class BoundingVolume : uint8_t { kSphere, kAabb };

/// How Bvh::Repair brings the volumes up to date with new positions.
enum class BvhRepair : uint8_t {
  /// Bottom-up over flat arrays: every leaf refitted in one pass over the leaf slots, then every
  /// internal node evaluated once in decreasing id order, with no queue and no branch on which
  /// node is invalidated (a changed-flag per node decides what counts and, with inflation, what is
  /// stored). Same volumes and counters as kBottomUpQueue; the fast choice when the whole cloth
  /// moves, as it does every frame in the sim.
  kBottomUp,
  kTopDown,  ///< recursive refit from the root (children first, then the parent)
  kRebuild,  ///< re-split the triangles by their current centroids, then refit everything
  /// 001 §6.3 as written: leaves in an array, a changed node queues its parent, only queued
  /// (invalidated) parents are refitted, each at most once, in decreasing id order. Does less work
  /// than kBottomUp when few triangles move.
  kBottomUpQueue,
};

/// Construction options of a Bvh.
struct BvhOptions {
  BoundingVolume volume = BoundingVolume::kSphere;
  int32_t arity = 4;  ///< children per internal node: 2 or 4
  BvhRepair repair = BvhRepair::kBottomUp;
  /// Inflation margin d [m] >= 0 (000 slide 27, Mezger et al. 2003; 004): a volume is stored
  /// enlarged by d and recomputed only when what it must contain escapes it. 0 = exact refit:
  /// every volume equals the tight fit of its contents after each repair (for AABBs, the tight
  /// fit of the contents' float32 bounds rounded outward: see PackedAabb).
  double inflation_m = 0.0;
};

/// An axis-aligned box, world frame, m.
struct Aabb {
  Vec3 lo = Vec3::Zero();
  Vec3 hi = Vec3::Zero();
};

/// How a Bvh stores an axis-aligned box [m]: float32 bounds rounded outward from the double
/// coordinates (lo never above, hi never below the exact value), so the box always contains
/// what it bounds and a query, which tests the triangles themselves in double, answers exactly as
/// with double boxes; only the pruning is looser, by about 1e-7 of the coordinates' magnitude.
/// The upper bound is stored negated so that merging boxes is one elementwise minimum over the
/// eight lanes (lane 3 of each half is padding, equal in every box). 32 bytes, one AVX register.
struct alignas(32) PackedAabb {
  float lo[4] = {0, 0, 0, 0};      ///< lower bound x, y, z [m], rounded down; lane 3 padding
  float neg_hi[4] = {0, 0, 0, 0};  ///< minus the upper bound x, y, z [m], rounded down; lane 3

  /// The box in double (exact: every float is a double).
  Aabb ToAabb() const {
    const auto d = [](float f) { return static_cast<double>(f); };
    return {Vec3(d(lo[0]), d(lo[1]), d(lo[2])), Vec3(-d(neg_hi[0]), -d(neg_hi[1]), -d(neg_hi[2]))};
  }
};

/// A sphere, world frame, m.
struct BoundingSphere {
  Vec3 center = Vec3::Zero();
  double radius = 0.0;
};

/// The shape of a Bvh: breadth-first node arrays, independent of positions. Immutable once made.
struct BvhTopology {
  int32_t arity = 2;
  std::vector<int32_t> first_child;   ///< [nodes] id of the first child, -1 for a leaf
  std::vector<int32_t> num_children;  ///< [nodes] 0 for a leaf, else 2..arity
  std::vector<int32_t> parent;        ///< [nodes] parent id, -1 for the root (id 0)
  std::vector<int32_t> begin;         ///< [nodes] first slot of the node's range in the leaf order
  std::vector<int32_t> end;           ///< [nodes] one past its last slot (a leaf holds one slot)
  std::vector<int32_t> leaves_desc;   ///< ids of the leaves in decreasing order (001 §6.3's array)
  std::vector<int32_t> leaf_of_slot;  ///< [triangles] the leaf whose range is that one slot
  std::vector<int32_t> internal_desc;  ///< ids of the internal nodes in decreasing order
  int32_t num_internal = 0;            ///< nodes with children
  int32_t depth = 0;                   ///< edges from the root to the deepest leaf

  int32_t num_nodes() const { return static_cast<int32_t>(parent.size()); }
  bool is_leaf(int32_t node) const { return first_child[node] < 0; }

  /// The shape for `num_triangles` >= 0 triangles and arity 2 or 4. Throws std::invalid_argument
  /// on another arity or a count too large for the fixed traversal stack.
  static BvhTopology Make(int32_t num_triangles, int32_t arity);
};

/// A BVH over triangles with sphere or AABB volumes, arity 2 or 4, and three repair modes.
/// Queries are const and real-time safe; Repair/RepairSwept/RefitAll write only this object's own
/// preallocated arrays and are real-time safe too (no allocation). The positions span given to a
/// query must be the one the structure was last repaired with (either snapshot of RepairSwept).
class Bvh {
 public:
  /// Builds the tree over `triangles` (indices into x) with the median split over centroids of x
  /// (rest or current positions, m) and fits every volume. Throws std::invalid_argument if
  /// triangles is null, an index is out of range for x, or the options are invalid.
  Bvh(std::shared_ptr<const std::vector<Triangle>> triangles, std::span<const Vec3> x,
      const BvhOptions& options);

  const BvhOptions& options() const { return options_; }
  const std::vector<Triangle>& triangles() const { return *triangles_; }
  const BvhTopology& topology() const { return *topology_; }
  int32_t num_nodes() const { return topology_->num_nodes(); }
  /// [nodes] the node volumes as stored, float32 rounded outward (AABB trees; empty for sphere
  /// trees); aabb(node) converts one to double.
  std::span<const PackedAabb> aabbs() const { return aabb_; }
  /// The box of `node` in double [m] (AABB trees only).
  Aabb aabb(int32_t node) const { return aabb_[static_cast<size_t>(node)].ToAabb(); }
  /// [nodes] the node volumes (sphere trees; empty for AABB trees).
  std::span<const BoundingSphere> spheres() const { return sphere_; }
  /// [triangles] the triangle held by each leaf slot (topology().begin of a leaf indexes it).
  std::span<const int32_t> order() const { return order_; }
  /// True after RepairSwept: the volumes cover the motion between two snapshots (query 3).
  bool covers_motion() const { return covers_motion_; }

  /// Brings the volumes up to date with positions x [m] using options().repair. Real-time safe.
  RepairStats Repair(std::span<const Vec3> x);
  /// Like Repair, but each leaf volume encloses its triangle at both x_old and x_new (so the
  /// convex hull of its six vertices, which contains every linear in-between position); needed
  /// by SweepSphereMoving. Real-time safe.
  RepairStats RepairSwept(std::span<const Vec3> x_old, std::span<const Vec3> x_new);
  /// Recomputes every volume from scratch (tight fit enlarged by the inflation margin), keeping
  /// the leaf order: the reference the repairs are tested against. Real-time safe.
  RepairStats RefitAll(std::span<const Vec3> x);

  /// Query 1: every triangle within distance r [m] of p; see WithinResult for capacity.
  /// Real-time safe.
  WithinResult TrianglesWithin(std::span<const Vec3> x, const Vec3& p, double r,
                               std::span<PointContact> out, bool ids_only = false) const;
  /// Query 2: first contact of a sphere of radius r [m] moving p0 -> p1 (SweepSphereTriangle's
  /// convention; children visited nearest-entry first, pruned by the best toi). Real-time safe.
  SweepHit SweepSphere(std::span<const Vec3> x, const Vec3& p0, const Vec3& p1, double r) const;
  /// Query 3: sphere moving c0 -> c1 against the cloth moving linearly x_old -> x_new. Uses the
  /// tree when covers_motion() (after RepairSwept(x_old, x_new)); otherwise falls back to testing
  /// every triangle (still correct, slower). Real-time safe.
  SweepHit SweepSphereMoving(std::span<const Vec3> x_old, std::span<const Vec3> x_new,
                             const Vec3& c0, const Vec3& c1, double r,
                             const MovingContactOptions& options = {}) const;

 private:
  template <class Ops>
  friend struct BvhImpl;

  BvhOptions options_;
  std::shared_ptr<const std::vector<Triangle>> triangles_;
  std::shared_ptr<const BvhTopology> topology_;
  std::vector<int32_t> order_;           // [triangles] leaf slot -> triangle
  std::vector<PackedAabb> aabb_;         // [nodes] if volume == kAabb
  std::vector<PackedAabb> vertex_box_;   // [vertices] exact AABB repair scratch: each vertex's box
  std::vector<BoundingSphere> sphere_;   // [nodes] if volume == kSphere
  std::vector<Triangle> slot_vertices_;  // [triangles] the vertices of order_[slot], by slot
  std::vector<uint8_t> changed_;         // [nodes] kBottomUp: 1 if the last repair changed it
  std::vector<int32_t> queue_;           // [internal nodes] kBottomUpQueue's parent queue
  std::vector<Vec3> centroid_;           // [triangles] rebuild scratch
  bool covers_motion_ = false;
};

}  // namespace felt
