#pragma once
// What the 60 Hz sim thread publishes each frame and the 1 kHz haptic thread reads (issue 5's
// triple buffer holds three of these; the proxy keeps the previous one for the snapshot modes
// that need two cloths, 001_0f9f1b7fedff7723.txt §7).
//
// A snapshot is sized once (MakeClothSnapshot, allocates) and then refilled every frame by
// FillSnapshot without allocating. Copy-assigning a snapshot into another of the same cloth and
// structure kind reuses the destination's arrays (std::vector and the structure's own arrays keep
// their capacity; the triangle list and the BVH shape are shared_ptr<const>), so no allocation.

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "collision/collision_structure.h"
#include "collision/mesh.h"
#include "sim_loop/cloth.h"

namespace felt {

/// The cloth as the haptic thread sees it for one frame. World frame (_W), SI units.
struct ClothSnapshot {
  std::vector<Vec3> x;        ///< [n] particle positions, world, m
  std::vector<Vec3> v;        ///< [n] particle velocities, world, m/s
  std::vector<Vec3> normals;  ///< [n] unit area-weighted vertex normals, world (zero if degenerate)
  std::shared_ptr<const std::vector<Triangle>> triangles;  ///< shared, immutable topology
  CollisionStructure structure;    ///< repaired for exactly `x` (queries take `x`)
  uint64_t frame = 0;              ///< the sim's frame number (strictly increasing per publisher)
  double time_s = 0.0;             ///< sim time of `x`, s
  double frame_dt_s = 0.0;         ///< sim time since the previous snapshot, s (> 0 once stepping)
  double max_speed_m_per_s = 0.0;  ///< max_i |v_i|, m/s (bounds extrapolated motion)
  /// MaxDisplacement from the snapshot of frame `frame - 1` of the same publisher, m, when the
  /// publisher knows it (FillSnapshotWithFrameMotion); negative: unknown.
  double displacement_from_previous_m = -1.0;

  /// Number of particles.
  int32_t num_particles() const { return static_cast<int32_t>(x.size()); }
  /// Number of triangles.
  int32_t num_triangles() const { return static_cast<int32_t>(triangles->size()); }
};

/// A snapshot for `triangles` (indices into positions `x`, m) with its collision structure built
/// by `spec` at `x`; velocities zero, normals computed, frame 0, time 0. Set-up time: allocates;
/// throws std::invalid_argument as MakeCollisionStructure does, or if a triangle index is out of
/// range.
ClothSnapshot MakeClothSnapshot(std::shared_ptr<const std::vector<Triangle>> triangles,
                                std::span<const Vec3> x, const CollisionStructureSpec& spec);

/// A snapshot sized for `model`, at the positions of `state`, with the structure of `spec`.
/// Set-up time: allocates; throws std::invalid_argument like MakeClothSnapshot.
ClothSnapshot MakeClothSnapshot(const ClothModel& model, const ClothState& state,
                                const CollisionStructureSpec& spec);

/// Refills `snapshot` from raw arrays (each [snapshot->num_particles()], world): copies positions
/// [m], velocities [m/s] and normals, repairs the structure for the new positions and sets frame,
/// time [s], frame dt [s] and max speed. Returns the repair's counters. Precondition (aborts if
/// broken): every span has the snapshot's size. Real-time safe (no allocation, no exception).
RepairStats FillSnapshot(std::span<const Vec3> x, std::span<const Vec3> v,
                         std::span<const Vec3> normals, uint64_t frame, double time_s,
                         double frame_dt_s, ClothSnapshot* snapshot);

/// What the sim thread calls after each StepFrame: FillSnapshot from `state` (x, v, normals,
/// time_s). `frame_dt_s` is the sim time since the previous published snapshot. Real-time safe.
RepairStats FillSnapshot(const ClothModel& model, const ClothState& state, uint64_t frame,
                         double frame_dt_s, ClothSnapshot* snapshot);

/// Largest vertex displacement max_i |a.x[i] - b.x[i]| [m] between two snapshots of one cloth
/// (0 if their sizes differ). Real-time safe; O(particles).
double MaxDisplacement(const ClothSnapshot& a, const ClothSnapshot& b);

}  // namespace felt
