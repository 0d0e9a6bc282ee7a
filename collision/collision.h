#pragma once
// The query results shared by every collision structure (naive, BVH, spatial hash) and the
// per-triangle accumulators they all run, so that every structure gives bit-identical answers and
// differs from the naive reference only in which triangles it skips. The facade that dispatches
// to a structure is collision/collision_structure.h.
//
// Real-time contract of every query: no allocation, no lock, no exception; results go into a
// caller-provided buffer (fixed capacity) or a single result struct. Positions are passed per
// query as a span; no structure keeps a pointer to them.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "collision/geometry.h"
#include "collision/mesh.h"

namespace felt {

/// One triangle within reach of a point (query 1).
struct PointContact {
  int32_t triangle = -1;            ///< index into the structure's triangle list
  Vec3 point_m = Vec3::Zero();      ///< the triangle's point nearest the query point, world, m
  Vec3 barycentric = Vec3::Zero();  ///< of point_m in the triangle, non-negative, sum 1
  double distance_m = 0.0;          ///< |query point - point_m|, m
};

/// How many triangles a TrianglesWithin query found and how many it could write. Capacity
/// behaviour: the first out.size() triangles found are written (which ones depends on the
/// structure's traversal order), every further one is only counted; overflowed() says so.
struct WithinResult {
  int32_t found = 0;    ///< triangles within the distance
  int32_t written = 0;  ///< entries written to the buffer: min(found, capacity)
  bool overflowed() const { return found > written; }
};

/// The first contact of a moving sphere (queries 2 and 3).
struct SweepHit {
  bool hit = false;                 ///< false: no contact on the whole motion
  double toi = 1.0;                 ///< time of impact as a fraction of the motion, [0, 1]
  int32_t triangle = -1;            ///< the triangle touched first (ties: the lowest index)
  Vec3 point_m = Vec3::Zero();      ///< the touched point of the triangle at toi, world, m
  Vec3 normal = Vec3::Zero();       ///< unit normal from the triangle toward the sphere's centre
  Vec3 barycentric = Vec3::Zero();  ///< of point_m in the triangle at toi
};

/// What one repair of a structure did (counters for tests and the benchmark).
struct RepairStats {
  int32_t node_updates = 0;  ///< bounding volumes rewritten (leaves and parents; 001 Table 2)
  int32_t leaves_refit = 0;  ///< leaf volumes recomputed from their triangle
  /// parents refitted because a child changed (001 §6.3's invalidated parents; kBottomUp's flat
  /// sweep also merges the others, whose volumes cannot change, and does not count them)
  int32_t parents_refit = 0;
  int32_t entries = 0;  ///< spatial hash only: (triangle, cell) entries written
};

/// Relative slack [m] by which every structure enlarges its culling tests, so that rounding in
/// bounding volumes never culls a triangle the exact per-triangle test would accept.
inline double CullSlack(const Vec3& p0, const Vec3& p1, double r) {
  return 1e-9 * (1.0 + r + p0.cwiseAbs().maxCoeff() + p1.cwiseAbs().maxCoeff());
}

/// Calls test(i) for every triangle index i in [0, count): the whole of NaiveCollision's queries
/// and every other structure's fallback when culling would cost more. Real-time safe.
template <class Test>
inline void TestEveryTriangle(size_t count, Test&& test) {
  for (size_t i = 0; i < count; ++i) test(static_cast<int32_t>(i));
}

/// Query 1's per-triangle step: tests one triangle and records it when within r. Real-time safe.
struct WithinAccumulator {
  Vec3 p;                       ///< query point, m
  double r = 0.0;               ///< reach, m
  std::span<PointContact> out;  ///< caller's buffer
  WithinResult result;
  /// Only which triangles: a triangle whose box lies wholly within r is written without its
  /// closest point (point, barycentrics and distance left zero).
  bool ids_only = false;

  /// Tests triangle `tri`, whose corners are x[t[0..2]] (x: positions, m).
  void Test(int32_t tri, const Triangle& t, std::span<const Vec3> x) {
    Test(tri, x[t[0]], x[t[1]], x[t[2]]);
  }

  void Test(int32_t tri, const Vec3& a, const Vec3& b, const Vec3& c) {
    if (ids_only) {
      // Every point of the triangle lies within r when its box's farthest corner does (per axis
      // the larger of |p - lo| and |hi - p|; Arvo 1990's box-sphere test, turned around).
      const Vec3 lo = a.cwiseMin(b).cwiseMin(c), hi = a.cwiseMax(b).cwiseMax(c);
      if ((p - lo).cwiseAbs().cwiseMax((hi - p).cwiseAbs()).squaredNorm() <= r * r) {
        if (static_cast<size_t>(result.written) < out.size()) out[result.written++] = {tri};
        ++result.found;
        return;
      }
    }
    const TrianglePoint cp = ClosestPointOnTriangle(p, a, b, c);
    if (!(cp.distance_sq <= r * r)) return;
    if (static_cast<size_t>(result.written) < out.size()) {
      out[result.written++] = {tri, cp.point, cp.barycentric, std::sqrt(cp.distance_sq)};
    }
    ++result.found;
  }
};

/// Query 2's per-triangle step: keeps the earliest contact (lowest toi, then lowest triangle
/// index, so every structure agrees whatever order it visits triangles in). Real-time safe.
struct SweepAccumulator {
  Vec3 p0;       ///< sphere centre at t = 0, m
  Vec3 p1;       ///< sphere centre at t = 1, m
  double r = 0;  ///< sphere radius, m
  SweepHit best;

  /// The toi beyond which no triangle can improve the result (for pruning).
  double bound() const { return best.hit ? best.toi : std::numeric_limits<double>::infinity(); }

  /// Tests triangle `tri`, whose corners are x[t[0..2]] (x: positions, m).
  void Test(int32_t tri, const Triangle& t, std::span<const Vec3> x) {
    Test(tri, x[t[0]], x[t[1]], x[t[2]]);
  }

  void Test(int32_t tri, const Vec3& a, const Vec3& b, const Vec3& c) {
    const SweepContact sc = SweepSphereTriangle(p0, p1, r, a, b, c);
    Keep(tri, sc);
  }

  void Keep(int32_t tri, const SweepContact& sc) {
    if (!sc.hit) return;
    if (best.hit && (sc.toi > best.toi || (sc.toi == best.toi && tri > best.triangle))) return;
    best = {true, sc.toi, tri, sc.point, sc.normal, sc.barycentric};
  }
};

/// Query 3's per-triangle step: a sphere moving c0 -> c1 against a triangle moving from its old to
/// its new positions over the same interval (MovingTriangleSphereContact). Real-time safe.
struct MovingAccumulator {
  Vec3 c0;                       ///< sphere centre at t = 0 (old snapshot), m
  Vec3 c1;                       ///< sphere centre at t = 1 (new snapshot), m
  double r = 0;                  ///< sphere radius, m
  MovingContactOptions options;  ///< tolerance and iteration cap
  SweepAccumulator keep;         ///< reuses the (toi, index) ordering

  double bound() const { return keep.bound(); }

  /// Tests triangle `tri`, whose corners move from x_old[t[0..2]] to x_new[t[0..2]] (m).
  void Test(int32_t tri, const Triangle& t, std::span<const Vec3> x_old,
            std::span<const Vec3> x_new) {
    Test(tri, x_old[t[0]], x_old[t[1]], x_old[t[2]], x_new[t[0]], x_new[t[1]], x_new[t[2]]);
  }

  void Test(int32_t tri, const Vec3& a0, const Vec3& b0, const Vec3& c0v, const Vec3& a1,
            const Vec3& b1, const Vec3& c1v) {
    keep.Keep(tri, MovingTriangleSphereContact(c0, c1, r, a0, b0, c0v, a1, b1, c1v, options));
  }
};

/// Query 3 on any structure: runs a MovingAccumulator (sphere c0 -> c1 of radius r, m; corners
/// x_old -> x_new, m) over the triangles that cull(test, acc) passes to test when `culls` (the
/// structure bounds the motion), else over every triangle. Real-time safe.
template <class Cull>
SweepHit SweepMovingOver(const std::vector<Triangle>& tris, std::span<const Vec3> x_old,
                         std::span<const Vec3> x_new, const Vec3& c0, const Vec3& c1, double r,
                         const MovingContactOptions& options, bool culls, Cull&& cull) {
  MovingAccumulator acc{c0, c1, r, options, {}};
  const auto test = [&](int32_t tri) { acc.Test(tri, tris[tri], x_old, x_new); };
  if (culls) {
    cull(test, acc);
  } else {
    TestEveryTriangle(tris.size(), test);
  }
  return acc.keep.best;
}

}  // namespace felt
