#pragma once
// Optimized spatial hashing (Teschner, Heidelberger, Müller, Pomeranets & Gross 2003, "Optimized
// Spatial Hashing for Collision Detection of Deformable Objects", VMV'03) over the cloth's
// triangles only, as 001_0f9f1b7fedff7723.txt §6.3 adapts it for a haptic pointer: the vertex
// phase is dropped, each triangle's bounding box is mapped to the uniform grid cells it touches,
// and each cell to a bucket of a hash table sized once. Rehashed every frame without allocation
// (a counting sort into flat arrays).

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "collision/collision.h"

namespace felt {

/// Construction options of a SpatialHash.
struct SpatialHashOptions {
  /// Grid cell edge [m]; 0 = the average edge length of the triangles at construction (Teschner
  /// 2003 §5: a cell about the primitives' size works best).
  double cell_size_m = 0.0;
  /// Buckets; 0 = the smallest prime >= 4 x triangles (Teschner 2003: a prime, larger than the
  /// number of primitives).
  int32_t table_size = 0;
  /// A triangle whose box touches more cells than this is not hashed but kept in a list that
  /// every query tests (so entries fit a buffer of this many per triangle, sized once).
  int32_t max_cells_per_triangle = 8;
};

/// Spatial hash over triangles. Copyable (shares the triangle list). Queries are const and
/// real-time safe; Repair/RepairSwept write only this object's preallocated arrays (real-time
/// safe). Query positions must be the ones of the last repair (either snapshot of RepairSwept).
class SpatialHash {
 public:
  /// Sizes every array and hashes x [m]. Throws std::invalid_argument if triangles is null, an
  /// index is out of range, or an option is out of range (the message names the field).
  SpatialHash(std::shared_ptr<const std::vector<Triangle>> triangles, std::span<const Vec3> x,
              const SpatialHashOptions& options = {});

  const std::vector<Triangle>& triangles() const { return *triangles_; }
  double cell_size_m() const { return cell_size_m_; }
  int32_t table_size() const { return table_size_; }
  /// Triangles too large to hash at the last repair (tested by every query).
  int32_t num_oversized() const { return num_oversized_; }
  /// (triangle, cell) entries written by the last repair.
  int32_t num_entries() const { return num_entries_; }
  /// True after RepairSwept: the cells cover the motion between two snapshots (query 3).
  bool covers_motion() const { return covers_motion_; }

  /// Rehashes every triangle's box at positions x [m]. Real-time safe.
  RepairStats Repair(std::span<const Vec3> x);
  /// Rehashes each triangle's box over both snapshots (for SweepSphereMoving). Real-time safe.
  RepairStats RepairSwept(std::span<const Vec3> x_old, std::span<const Vec3> x_new);

  /// Query 1 (see NaiveCollision::TrianglesWithin); each triangle is tested once, in the first
  /// cell it shares with the query box. Falls back to testing every triangle when the query box
  /// spans more cells than there are triangles. Real-time safe.
  WithinResult TrianglesWithin(std::span<const Vec3> x, const Vec3& p, double r,
                               std::span<PointContact> out, bool ids_only = false) const;
  /// Query 2: walks the segment (clipped to the hashed region) in pieces one cell long, testing
  /// the triangles of each piece's cells and stopping once a contact precedes the next piece.
  /// Real-time safe.
  SweepHit SweepSphere(std::span<const Vec3> x, const Vec3& p0, const Vec3& p1, double r) const;
  /// Query 3, like Bvh::SweepSphereMoving (falls back to every triangle unless covers_motion()).
  /// Real-time safe.
  SweepHit SweepSphereMoving(std::span<const Vec3> x_old, std::span<const Vec3> x_new,
                             const Vec3& c0, const Vec3& c1, double r,
                             const MovingContactOptions& options = {}) const;

 private:
  struct CellRange {
    std::array<int32_t, 3> lo;
    std::array<int32_t, 3> hi;
  };
  RepairStats Rehash(std::span<const Vec3> x0, std::span<const Vec3> x1);
  CellRange CellsOf(const Vec3& lo, const Vec3& hi) const;
  int32_t Bucket(int32_t ix, int32_t iy, int32_t iz) const;
  /// Calls test(triangle) once for each hashed triangle whose cell range overlaps the cells q,
  /// in the first cell of q the two share (hash collisions skipped). Real-time safe.
  template <class Test>
  void VisitCells(const CellRange& q, Test&& test) const;
  template <class Test, class Bound>
  void WalkSegment(const Vec3& p0, const Vec3& p1, double r, Test&& test, Bound&& bound) const;

  SpatialHashOptions options_;
  std::shared_ptr<const std::vector<Triangle>> triangles_;
  double cell_size_m_ = 1.0;
  double inv_cell_ = 1.0;
  int32_t table_size_ = 1;
  std::vector<int32_t> bucket_start_;  // [table + 1] first entry of each bucket
  std::vector<int32_t> cursor_;        // [table] fill scratch
  std::vector<int32_t> entries_;       // [max_cells_per_triangle x triangles] triangle ids
  std::vector<CellRange> range_;       // [triangles] cells of each triangle's box
  std::vector<int32_t> oversized_;     // [triangles] the first num_oversized_ are in use
  int32_t num_oversized_ = 0;
  int32_t num_entries_ = 0;
  Vec3 lo_ = Vec3::Zero();  // box of every hashed position
  Vec3 hi_ = Vec3::Zero();
  bool covers_motion_ = false;
};

}  // namespace felt
