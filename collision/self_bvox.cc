#include "collision/self_bvox.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "base/check.h"

namespace felt {

SelfBvox::SelfBvox(std::span<const Triangle> triangles, std::span<const Vec3> x,
                   const SelfBroadPhaseOptions& options)
    : SelfTriangleTree(triangles, x, options) {
  num_triangles_ = static_cast<int32_t>(triangles_.size());
  while ((int64_t{1} << max_levels_) < num_triangles_) ++max_levels_;
  const size_t t = static_cast<size_t>(num_triangles_);
  // Every inner node has two children or more, so there are fewer than T of them.
  for (std::vector<Vec3>* a : {&node_lo_, &node_hi_}) a->assign(2 * t + 1, Vec3::Zero());
  for (std::vector<int32_t>* a : {&child_begin_, &child_end_, &children_}) a->assign(2 * t + 1, 0);
  for (std::vector<int32_t>* a : {&items_, &key_, &sorted_}) a->assign(t, 0);
  bucket_start_.assign((size_t{1} << max_levels_) + 1, 0);
}

std::array<int32_t, 3> SelfBvox::VoxelSplit(const Vec3& b, int32_t d) {
  // The axes by side, longest first (ties by index).
  std::array<int32_t, 3> axis = {0, 1, 2};
  for (int32_t i = 1; i < 3; ++i) {  // insertion sort (std::stable_sort may allocate)
    for (int32_t j = i; j > 0 && b[axis[j]] > b[axis[j - 1]]; --j) std::swap(axis[j], axis[j - 1]);
  }
  const double bx = b[axis[0]], by = b[axis[1]], bz = b[axis[2]];
  int32_t nx = d, ny = 0, nz = 0;
  // Eq. (3): the longest side alone is cut while it stays the longest (also a flat or degenerate
  // box: by = 0 or not a number).
  if (bx < std::ldexp(by, d - 1)) {
    // Eq. (4): the two longest sides, while the second stays longer than half the third.
    nx = std::min(static_cast<int32_t>(std::floor((std::log2(bx / by) + d + 1) / 2)), d);
    ny = d - nx;
    if (!(std::ldexp(by, 1 - ny) >= bz)) {
      // Eq. (5): all three.
      nx = std::clamp(
          static_cast<int32_t>(std::floor((std::log2(bx * bx / (by * bz)) + d + 2) / 3)), 0, d);
      ny =
          std::clamp(static_cast<int32_t>(std::floor((std::log2(by * by / (bx * bz)) + d + 2) / 3)),
                     0, d - nx);
    }
    nz = d - nx - ny;
  }
  std::array<int32_t, 3> n = {0, 0, 0};
  n[axis[0]] = nx;
  n[axis[1]] = ny;
  n[axis[2]] = nz;
  return n;
}

bool SelfBvox::Overlap(int32_t a, int32_t b) const {
  return BoxesOverlap(node_lo_[a], node_hi_[a], node_lo_[b], node_hi_[b]);
}

int32_t SelfBvox::GroupLevel(int32_t count, int32_t d, const Vec3& lo, const Vec3& half) {
  const std::array<int32_t, 3> n = VoxelSplit(half, d);
  // Voxel of an item: the cell holding its box's center c along each axis, from
  // u = (c - lo) / (hi - lo) in [0, 1], computed in halves (c / 2 - lo / 2) / half so that no
  // sum overflows, however far apart finite coordinates lie (clamped to the grid; a coordinate
  // that is not a number goes to cell 0). Packed as i + j 2^n0 + k 2^(n0 + n1).
  std::array<double, 3> scale{};
  for (int32_t a = 0; a < 3; ++a) scale[a] = half[a] > 0.0 ? std::ldexp(1.0, n[a]) / half[a] : 0.0;
  for (int32_t i = 0; i < count; ++i) {
    const int32_t node = items_[i];
    int32_t key = 0, shift = 0;
    for (int32_t a = 0; a < 3; ++a) {
      const int32_t cells = 1 << n[a];
      const double f = std::floor(
          (0.25 * node_lo_[node][a] + 0.25 * node_hi_[node][a] - 0.5 * lo[a]) * scale[a]);
      const int32_t cell = f > 0.0 ? (f < cells ? static_cast<int32_t>(f) : cells - 1) : 0;
      key |= cell << shift;
      shift += n[a];
    }
    key_[i] = key;
  }
  // Counting sort by voxel: bucket k ends at bucket_start_[k] after the placement.
  const int32_t buckets = 1 << d;
  std::fill(bucket_start_.begin(), bucket_start_.begin() + buckets + 1, 0);
  for (int32_t i = 0; i < count; ++i) ++bucket_start_[key_[i] + 1];
  for (int32_t k = 0; k < buckets; ++k) bucket_start_[k + 1] += bucket_start_[k];
  for (int32_t i = 0; i < count; ++i) sorted_[bucket_start_[key_[i]]++] = items_[i];
  // One node per voxel of two items or more; a voxel's single item goes up as it is.
  int32_t next = 0, begin = 0;
  for (int32_t k = 0; k < buckets; ++k) {
    const int32_t end = bucket_start_[k];
    if (end - begin == 1) {
      items_[next++] = sorted_[begin];
    } else if (end - begin > 1) {
      const int32_t node = num_nodes_++;
      child_begin_[node] = num_children_;
      Vec3 box_lo = node_lo_[sorted_[begin]], box_hi = node_hi_[sorted_[begin]];
      for (int32_t i = begin; i < end; ++i) {
        const int32_t c = sorted_[i];
        children_[num_children_++] = c;
        box_lo = box_lo.cwiseMin(node_lo_[c]);
        box_hi = box_hi.cwiseMax(node_hi_[c]);
      }
      child_end_[node] = num_children_;
      node_lo_[node] = box_lo;
      node_hi_[node] = box_hi;
      items_[next++] = node;
    }
    begin = end;
  }
  return next;
}

SelfBroadPhaseStats SelfBvox::FindCandidates(std::span<const Vec3> x0, std::span<const Vec3> x1,
                                             double thickness_m) {
  BeginStep(x0, x1, thickness_m);
  candidates_.clear();
  SelfBroadPhaseStats stats;
  const double pad = BoxPadding(thickness_m);
  for (int32_t v = 0; v < num_vertices_; ++v) VertexBox(v, x0, x1, pad, 0.0);
  NewBoxStamp();
  // The leaves: each triangle's box, the union of its vertices' boxes; AABB0 around them all.
  num_nodes_ = num_triangles_;
  num_children_ = 0;
  int32_t count = 0;
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (int32_t t = 0; t < num_triangles_; ++t) {
    const Triangle& tri = triangles_[t];
    node_lo_[t] = vertex_lo_[tri[0]].cwiseMin(vertex_lo_[tri[1]]).cwiseMin(vertex_lo_[tri[2]]);
    node_hi_[t] = vertex_hi_[tri[0]].cwiseMax(vertex_hi_[tri[1]]).cwiseMax(vertex_hi_[tri[2]]);
    if (!node_lo_[t].allFinite() || !node_hi_[t].allFinite()) continue;
    lo = lo.cwiseMin(node_lo_[t]);
    hi = hi.cwiseMax(node_hi_[t]);
    items_[count++] = t;
  }
  num_leaves_ = count;
  levels_ = 0;
  root_ = -1;
  if (count == 0) return stats;
  // Level by level from the finest voxels (2^d of them at depth d) up.
  const Vec3 half = 0.5 * hi - 0.5 * lo;  // half the root box's sides (finite for finite boxes)
  for (int32_t d = max_levels_; d >= 1 && count > 1; --d) {
    count = GroupLevel(count, d, lo, half);
    ++levels_;
  }
  if (count == 1) {
    root_ = items_[0];
  } else {
    // What no voxel grouped (the coarsest level kept them apart) under one root.
    root_ = num_nodes_++;
    child_begin_[root_] = num_children_;
    node_lo_[root_] = lo;
    node_hi_[root_] = hi;
    for (int32_t i = 0; i < count; ++i) children_[num_children_++] = items_[i];
    child_end_[root_] = num_children_;
  }
  FELT_CHECK(num_nodes_ <= std::ssize(node_lo_));
  SelfTraverse(root_, &stats);
  return stats;
}

void SelfBvox::SelfTraverse(int32_t node, SelfBroadPhaseStats* stats) {
  if (node < num_triangles_) return;  // one triangle: its own features are all incident
  const int32_t begin = child_begin_[node], end = child_end_[node];
  for (int32_t i = begin; i < end; ++i) SelfTraverse(children_[i], stats);
  for (int32_t i = begin; i < end; ++i) {
    for (int32_t j = i + 1; j < end; ++j) PairTraverse(children_[i], children_[j], stats);
  }
}

void SelfBvox::PairTraverse(int32_t a, int32_t b, SelfBroadPhaseStats* stats) {
  if (!Overlap(a, b)) return;
  const bool leaf_a = a < num_triangles_, leaf_b = b < num_triangles_;
  if (leaf_a && leaf_b) {
    PairTriangles(a, b, node_lo_[a], node_hi_[a], node_lo_[b], node_hi_[b], stats);
    return;
  }
  // Into the children of the larger box (never of a leaf).
  const bool into_b = leaf_a || (!leaf_b && (node_hi_[b] - node_lo_[b]).prod() >
                                                (node_hi_[a] - node_lo_[a]).prod());
  if (into_b) {
    for (int32_t i = child_begin_[b]; i < child_end_[b]; ++i) PairTraverse(a, children_[i], stats);
  } else {
    for (int32_t i = child_begin_[a]; i < child_end_[a]; ++i) PairTraverse(children_[i], b, stats);
  }
}

}  // namespace felt
