#pragma once
// BVOX-AABB: a self-collision broad phase whose AABB tree is built anew every step from where the
// triangles are, by grouping them in voxels a level at a time (Baciu & Wong 2004, "Image-based
// collision detection for deformable cloth models", §5, the "backward voxel-based" tree;
// 002_a56e6b146de342b8.txt). Its paper's point: a tree fixed at set-up (SelfBvh) keeps triangles
// together that were neighbours on the flat cloth, while a cloth pressed or folded brings distant
// ones together, which a tree rebuilt by voxels puts in one branch.
//
// The tree, per step: the root box AABB0 holds every triangle's swept, padded box (sides
// b_x >= b_y >= b_z after sorting the axes). For each depth d from ceil(log2 T) down to 1 the box
// is cut into 2^n_x x 2^n_y x 2^n_z voxels, n_x + n_y + n_z = d, split as a median cut along the
// longest side would split it (the paper's eqs. 3-5); the nodes of the level below are assigned
// to the voxel holding their box's center and the nodes sharing a voxel become the children of a
// new node (a voxel holding one node passes it up as it is). What is left at the end becomes the
// root's children. Leaves are triangles; a node has any number of children.
//
// Traversal as SelfBvh's, for nodes of many children: a node against itself is each child against
// itself and each pair of children against each other; two overlapping nodes descend into the
// larger box (a leaf never); two leaves pair their triangles' features
// (SelfTriangleTree::PairTriangles). So the candidates are exactly the overlapping swept boxes,
// each once (tests/collision/self_broadphase_test.cc checks it against the brute-force set).
//
// A triangle whose box is not finite (where a NaN or infinite position reached it) is left out of
// the tree: no feature it owns is a candidate (a box that is not a number overlaps nothing in the
// other methods either).

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "collision/self_broadphase.h"

namespace felt {

/// Method (c): the BVOX-AABB tree (Baciu & Wong 2004 §5), rebuilt every step by voxels.
/// SelfBroadPhaseOptions::normal_cones does not apply to it (ignored).
class SelfBvox final : public SelfTriangleTree {
 public:
  /// Sizes every array for `triangles` over positions x [m] (only their number is used). Throws
  /// std::invalid_argument on an index out of range or a bad option.
  SelfBvox(std::span<const Triangle> triangles, std::span<const Vec3> x,
           const SelfBroadPhaseOptions& options = {});
  /// See SelfBroadPhase::FindCandidates. Real-time safe (no allocation; recursion depth at most
  /// about 2 log2 T).
  SelfBroadPhaseStats FindCandidates(std::span<const Vec3> x0, std::span<const Vec3> x1,
                                     double thickness_m) override;
  /// Nodes of the last step's tree, leaves (one per triangle in it) included.
  int32_t num_nodes() const { return num_leaves_ + num_inner_nodes(); }
  /// Inner nodes of the last step's tree (each with two children or more).
  int32_t num_inner_nodes() const { return num_nodes_ - num_triangles_; }
  /// Levels of voxels grouped in the last step (at most ceil(log2 T), T triangles).
  int32_t levels() const { return levels_; }

  /// How many voxels per axis (as powers of two) a box with sides b [m] is cut into at depth d:
  /// n[axis] with n[0] + n[1] + n[2] = d, Baciu & Wong 2004's eqs. (3)-(5) on the sides sorted
  /// longest first. For tests.
  static std::array<int32_t, 3> VoxelSplit(const Vec3& b, int32_t d);

 private:
  // Groups the current level's items (node ids) by voxel at depth d of the root box with low
  // corner lo and half sides `half` [m]; returns the new count.
  int32_t GroupLevel(int32_t count, int32_t d, const Vec3& lo, const Vec3& half);
  void SelfTraverse(int32_t node, SelfBroadPhaseStats* stats);
  void PairTraverse(int32_t a, int32_t b, SelfBroadPhaseStats* stats);
  bool Overlap(int32_t a, int32_t b) const;

  int32_t num_triangles_ = 0;
  int32_t max_levels_ = 0;  ///< ceil(log2 T)
  int32_t levels_ = 0;
  int32_t num_nodes_ = 0;      ///< node ids used this step; ids < num_triangles_ are the leaves
  int32_t num_leaves_ = 0;     ///< triangles with a finite box this step
  int32_t num_children_ = 0;   ///< children_ entries used this step
  int32_t root_ = -1;          ///< -1: no tree (no triangle with a finite box)
  std::vector<Vec3> node_lo_;  ///< [2 T] node box [m]; node t < T is triangle t's
  std::vector<Vec3> node_hi_;  ///< [2 T]
  std::vector<int32_t> child_begin_;   ///< [2 T] an inner node's children: children_[begin, end)
  std::vector<int32_t> child_end_;     ///< [2 T]
  std::vector<int32_t> children_;      ///< [2 T]
  std::vector<int32_t> items_;         ///< [T] the nodes of the level being grouped
  std::vector<int32_t> key_;           ///< [T] their voxels
  std::vector<int32_t> sorted_;        ///< [T] the items by voxel
  std::vector<int32_t> bucket_start_;  ///< [2^max_levels + 1] counting-sort offsets
};

}  // namespace felt
