#pragma once
// The cloth near the proxy for one haptic tick: the triangles a proxy can touch this tick,
// gathered once from a snapshot's collision structure (query 1, collision/collision_structure.h)
// with their vertices placed at the tick's cloth (a snapshot, an interpolation between two, or an
// extrapolation), then swept against exactly (SweepSphereTriangle, MovingTriangleSphereContact).
//
// Why not query the structure directly: the interpolated and extrapolated cloths of the snapshot
// modes (issue 4, modes c and d) have no repaired structure of their own, and repairing one per
// tick costs more than the whole tick budget (bench/results/haptic.md). Every vertex of the tick's
// cloth is within a known distance `inflation` of the snapshot the structure was repaired for, so
// the triangles within r of a region in the tick's cloth are among those within r + inflation in
// the snapshot's: the gather is exact as long as it does not overflow its capacity.

#include <cstdint>
#include <span>
#include <vector>

#include "collision/collision.h"
#include "collision/geometry.h"
#include "sim_loop/cloth_patch.h"
#include "sim_loop/snapshot.h"

namespace felt {

/// A cloth at one instant, as a recipe over one or two snapshots (nothing is copied):
/// x_i = from.x_i + alpha (to.x_i - from.x_i) + tau to.v_i, world, m. With from == to, alpha = 0,
/// tau = 0 it is exactly `to` (bit for bit). In mode patch the local patch's particles
/// (sim_loop/cloth_patch.h) are read from its arrays instead (`patch_role` not null).
struct ClothView {
  const ClothSnapshot* from = nullptr;  ///< interpolation start (== to when not interpolating)
  const ClothSnapshot* to = nullptr;    ///< interpolation end; its velocities extrapolate
  double alpha = 0.0;                   ///< interpolation weight in [0, 1]
  double tau_s = 0.0;                   ///< extrapolation time, s
  const PatchRole* patch_role = nullptr;  ///< mode patch: each particle's role (null: no patch)
  const Vec3* patch_x = nullptr;          ///< the patch's positions [m] (its particles only)
  const ClothPatch* patch = nullptr;      ///< the patch, for its free particles' normals

  /// The cloth `s` itself.
  static ClothView Of(const ClothSnapshot& s) { return {&s, &s, 0.0, 0.0}; }
  /// Position of particle i [m]. Real-time safe.
  Vec3 Position(int32_t i) const {
    if (patch_role != nullptr && patch_role[i] != PatchRole::kOutside) return patch_x[i];
    return from->x[i] + alpha * (to->x[i] - from->x[i]) + tau_s * to->v[i];
  }
  /// Unit vertex normal of particle i (interpolated like the positions, not extrapolated; a free
  /// particle of the patch: the patch's); zero where the snapshots have none. Real-time safe.
  Vec3 Normal(int32_t i) const;
  /// Positions of triangle t's three corners [m]. Real-time safe.
  void Corners(int32_t t, Vec3* a, Vec3* b, Vec3* c) const;
};

/// One gathered triangle.
struct LocalTriangle {
  int32_t triangle = -1;  ///< index into the snapshot's triangle list
  Vec3 a, b, c;           ///< corners at the tick's cloth, world, m
  Vec3 a0, b0, c0;        ///< corners at the previous tick's cloth (for the moving test), m
  Vec3 center;            ///< centre of a sphere bounding both a,b,c and a0,b0,c0, m
  double radius_m = 0.0;  ///< its radius, m
  Vec3 lo, hi;            ///< the box of a, b, c (the tick's corners), m
};

/// The triangles near the proxy this tick. Sized once; Gather and the queries are real-time safe.
class LocalCloth {
 public:
  /// Room for `capacity` >= 1 triangles. Allocates (set-up time).
  explicit LocalCloth(int32_t capacity);

  /// Replaces the contents with every triangle that comes within `radius_m` of `center_W` in
  /// `now` (or in `before`, when given), found through `query`'s structure with the radius
  /// enlarged by `inflation_m`, an upper bound on how far any vertex of `now` and `before` lies
  /// from `query`'s positions. Without `before` the previous-tick corners equal the current ones.
  /// Returns false when more triangles were found than fit: the tick then falls back to querying
  /// `query`'s structure directly (exact for `query`'s own positions, which for the interpolated
  /// and extrapolated cloths stand in for the tick's cloth; the moving test uses the triangles
  /// kept). `query` must outlive the queries. Mode patch (`now.patch` set): `inflation_m` bounds
  /// the particles outside the patch's windows and `patch_offset_m` [m] those in them; when the
  /// query enlarged by both overflows, the triangles with a corner in a window are gathered from
  /// the windows at `now`'s and `before`'s positions instead, and the query is enlarged by
  /// `inflation_m` alone. Real-time safe.
  bool Gather(const ClothSnapshot& query, double inflation_m, const ClothView& now,
              const ClothView* before, const Vec3& center_W, double radius_m,
              double patch_offset_m = 0.0);

  /// First contact of a sphere of radius r [m] moving p0 -> p1 [m] against the gathered triangles
  /// at the tick's cloth (SweepSphereTriangle's convention; ties: lowest triangle index); after an
  /// overflow, against the query snapshot's structure. Real-time safe.
  SweepHit Sweep(const Vec3& p0, const Vec3& p1, double r) const;

  /// First contact of a sphere moving c0 -> c1 while each gathered triangle moves over the part
  /// [s0, s1] of its linear motion from its previous-tick corners (s = 0) to its current ones
  /// (s = 1) (MovingTriangleSphereContact), skipping the triangles listed in `skip`. The hit's
  /// toi is a fraction of [s0, s1]; its point, normal and barycentrics are at toi. Real-time safe.
  SweepHit SweepMoving(const Vec3& c0, const Vec3& c1, double r, std::span<const int32_t> skip,
                       double s0 = 0.0, double s1 = 1.0) const;

  /// Corners [m] of `triangle` at the tick's cloth if gathered, else (after an overflow) at the
  /// query snapshot; false when neither has it. Real-time safe.
  bool Corners(int32_t triangle, Vec3* a, Vec3* b, Vec3* c) const;

  /// True when the last Gather overflowed and the queries use the structure directly.
  bool fallback() const { return fallback_; }

  /// The gathered triangles.
  std::span<const LocalTriangle> triangles() const { return {tris_.data(), size_}; }
  /// Capacity given at construction.
  int32_t capacity() const { return static_cast<int32_t>(tris_.size()); }

 private:
  // True when a corner of `triangle` lies in one of now.patch's windows.
  static bool TouchesPatch(const ClothView& now, int32_t triangle);
  // `triangle`'s corners now and before and a sphere bounding both.
  static void Place(int32_t triangle, const ClothView& now, const ClothView* before,
                    LocalTriangle* t);
  // Mode patch: appends the triangles with a corner in a window that come within radius_m of
  // center_W now or before, from the windows' own positions; false when they do not fit.
  bool GatherPatch(const ClothView& now, const ClothView* before, const Vec3& center_W,
                   double radius_m);

  std::vector<PointContact> found_;  // [capacity] query 1's buffer
  std::vector<LocalTriangle> tris_;  // [capacity]
  size_t size_ = 0;
  const ClothSnapshot* query_ = nullptr;
  bool fallback_ = false;
};

}  // namespace felt
