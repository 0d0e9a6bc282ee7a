#pragma once
// The all-triangle reference for the collision queries: obviously correct, O(triangles) per query.
// Every other structure is tested against it (shared/STYLE.md: fast structures vs a slow
// reference).

#include <memory>
#include <span>
#include <vector>

#include "collision/collision.h"

namespace felt {

/// Tests every triangle on every query. Copyable (shares the triangle list). Queries are
/// real-time safe.
class NaiveCollision {
 public:
  /// Throws std::invalid_argument if `triangles` is null or holds a negative index.
  explicit NaiveCollision(std::shared_ptr<const std::vector<Triangle>> triangles);

  /// The triangle list every query's indices refer to.
  const std::vector<Triangle>& triangles() const { return *triangles_; }

  /// Nothing to repair; returns zero counters. Real-time safe.
  RepairStats Repair(std::span<const Vec3> /*x*/) { return {}; }
  /// Nothing to repair; returns zero counters. Real-time safe.
  RepairStats RepairSwept(std::span<const Vec3> /*x_old*/, std::span<const Vec3> /*x_new*/) {
    return {};
  }

  /// Query 1: every triangle within distance r [m] of p (see WithinResult for capacity).
  /// x: [num vertices] positions, m. Real-time safe.
  WithinResult TrianglesWithin(std::span<const Vec3> x, const Vec3& p, double r,
                               std::span<PointContact> out, bool ids_only = false) const;

  /// Query 2: first contact of a sphere of radius r moving p0 -> p1 (SweepSphereTriangle's
  /// convention). Real-time safe.
  SweepHit SweepSphere(std::span<const Vec3> x, const Vec3& p0, const Vec3& p1, double r) const;

  /// Query 3: first contact of a sphere moving c0 -> c1 with the cloth moving linearly from x_old
  /// to x_new over the same interval (MovingTriangleSphereContact). Real-time safe.
  SweepHit SweepSphereMoving(std::span<const Vec3> x_old, std::span<const Vec3> x_new,
                             const Vec3& c0, const Vec3& c1, double r,
                             const MovingContactOptions& options = {}) const;

 private:
  std::shared_ptr<const std::vector<Triangle>> triangles_;
};

}  // namespace felt
