#pragma once
// Broad phase of continuous self-collision (issue 22): the vertex-triangle and edge-edge pairs of a
// mesh, sharing no vertex, whose swept boxes (each primitive's axis-aligned box around its
// vertices at x0 and x1, every side pushed out by half the thickness) overlap. Every pair that
// AllPairsCcd (collision/ccd_all_pairs.h) can report has overlapping boxes (each point of a
// primitive stays in its box for all t in [0, 1], and two boxes more than h apart hold primitives
// more than h apart), so running the narrow phase over the candidates gives exactly its hits.
//
// Three culling methods with the same interface:
// - SelfSpatialHash: spatial hashing of the swept boxes (Teschner, Heidelberger, Mueller,
//   Pomeranets & Gross 2003, "Optimized Spatial Hashing for Collision Detection of Deformable
//   Objects"; 000_25210a744b053ca5.txt, the slides on spatial hashing), cells about the mean edge
//   length;
// - SelfBvh: a binary AABB tree over the triangles, refitted bottom-up from swept boxes every
//   step, traversed against itself (000's BVH self-traversal, without normal cones);
// - SelfBvox (collision/self_bvox.h): an AABB tree built anew every step by grouping the
//   triangles in voxels (Baciu & Wong 2004's BVOX-AABB).
//
// Allocation: every array is sized at construction; FindCandidates and SelfCcd never allocate.
// Overflow never drops a pair silently: the candidate buffer has a fixed capacity and a full
// buffer sets `overflow` (the caller falls back to AllPairsCcd or grows the buffer at set-up);
// the hash's entry array has a fixed capacity and a primitive that does not fit in it (or spans
// more than max_cells_per_primitive cells) is tested against every primitive instead.
//
// Only vertices referenced by some triangle are considered (AllPairsCcd also tests vertices no
// triangle uses; the two agree whenever every vertex is a triangle's corner, as in a cloth).

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "collision/ccd_all_pairs.h"
#include "collision/mesh.h"

namespace felt {

/// A candidate pair: vertex-triangle (first = vertex, second = triangle index) or edge-edge
/// (first < second, indices into MeshEdges(triangles)), as in CcdPairHit.
struct SelfCandidate {
  CcdPairHit::Kind kind = CcdPairHit::Kind::kVertexTriangle;
  int32_t first = 0;   ///< the vertex, or edge e's index in MeshEdges
  int32_t second = 0;  ///< the triangle's index, or edge f's index in MeshEdges (e < f)
};

/// What one FindCandidates call produced.
struct SelfBroadPhaseStats {
  int64_t vertex_triangle = 0;  ///< vertex-triangle candidates found (also those not stored)
  int64_t edge_edge = 0;        ///< edge-edge candidates found (also those not stored)
  /// True when more candidates were found than the buffer holds: the stored ones are a subset,
  /// the counts above are the full totals; the caller must fall back (e.g. to AllPairsCcd).
  bool overflow = false;
  int32_t oversized = 0;  ///< hash only: primitives tested against all others (too many cells)
};

/// Construction options shared by both methods.
struct SelfBroadPhaseOptions {
  /// Candidate buffer capacity (pairs); 0 = 16 x (vertices + edges) at construction.
  int64_t max_candidates = 0;
  /// SelfSpatialHash: grid cell edge [m]; 0 = the mean edge length at construction (Teschner
  /// 2003 §5: cells about the primitives' size).
  double cell_size_m = 0.0;
  /// SelfSpatialHash: a primitive whose box covers more cells is tested against every other.
  int32_t max_cells_per_primitive = 64;
  /// SelfSpatialHash: (primitive, cell) entries per step; 0 = 16 x (vertices + edges). A
  /// primitive whose cells no longer fit is tested against every other instead.
  int64_t max_entries = 0;
  /// SelfBvh: skip a node against itself when its triangles' normals over the step lie in a cone
  /// of half-angle < pi/2 and its contour is star-shaped about one of its vertices in the plane
  /// normal to the cone's axis, over the whole step (see SelfBvh). Pairs in contact are never
  /// lost; pairs within the thickness without contact inside such a node are not reported.
  bool normal_cones = false;
};

/// The interface of a self-collision broad phase. Not thread-safe (one step at a time).
class SelfBroadPhase {
 public:
  virtual ~SelfBroadPhase() = default;
  /// Candidates of the step x0 -> x1 [m] with thickness h = thickness_m [m, > 0]: every
  /// vertex-triangle and edge-edge pair sharing no vertex whose swept boxes padded by
  /// h (1 + 1e-5) / 2 overlap (with SelfBvh's normal cones: except pairs inside a node certified
  /// free of self-contact), each once, in no particular order; stored in candidates() up to
  /// its capacity. x0, x1 must have as many entries as the positions given at construction.
  /// Real-time safe (no allocation, no exceptions; aborts on a size mismatch).
  virtual SelfBroadPhaseStats FindCandidates(std::span<const Vec3> x0, std::span<const Vec3> x1,
                                             double thickness_m) = 0;
  /// The candidates stored by the last FindCandidates.
  std::span<const SelfCandidate> candidates() const {
    return {candidates_.data(), candidates_.size()};
  }
  /// The triangles given at construction.
  std::span<const Triangle> triangles() const { return triangles_; }
  /// MeshEdges(triangles()): the edge numbering of edge-edge candidates and hits.
  std::span<const MeshEdge> edges() const { return edges_; }
  /// Capacity of the candidate buffer (pairs): candidates().size() never exceeds it.
  int64_t max_candidates() const { return max_candidates_; }

 protected:
  /// Copies the mesh, numbers its edges and reserves the candidate buffer. Throws
  /// std::invalid_argument when an index is out of range for num_vertices or an option is bad.
  SelfBroadPhase(std::span<const Triangle> triangles, int32_t num_vertices,
                 const SelfBroadPhaseOptions& options);
  /// Appends a candidate if there is room, else marks the overflow; counts it either way.
  void Emit(CcdPairHit::Kind kind, int32_t first, int32_t second, SelfBroadPhaseStats* stats);
  /// Clears the candidates (capacity kept) and checks the sizes.
  void BeginStep(std::span<const Vec3> x0, std::span<const Vec3> x1, double thickness_m) const;

  std::vector<Triangle> triangles_;
  std::vector<MeshEdge> edges_;
  std::vector<std::array<int32_t, 3>> triangle_edges_;  ///< [triangles] edge ids, -1: degenerate
  std::vector<int32_t> vertex_owner_;  ///< [vertices] first triangle using it, -1: none
  std::vector<int32_t> edge_owner_;    ///< [edges] first triangle having it
  int32_t num_vertices_ = 0;
  int64_t max_candidates_ = 0;
  std::vector<SelfCandidate> candidates_;  ///< capacity max_candidates_, never exceeded
};

/// Method (a): spatial hashing of swept boxes (Teschner et al. 2003). Vertices are hashed into
/// the cells their boxes cover and every triangle's cells are looked up; edges likewise against
/// edges. A pair is reported only in the cell holding the low corner of the two boxes'
/// intersection, so each once. Entries keep their cell, so distinct cells sharing a bucket never
/// mix.
class SelfSpatialHash final : public SelfBroadPhase {
 public:
  /// Sizes every array for `triangles` over positions x [m] (used for the mean edge length).
  /// Throws std::invalid_argument on an index out of range or a bad option (names the field).
  SelfSpatialHash(std::span<const Triangle> triangles, std::span<const Vec3> x,
                  const SelfBroadPhaseOptions& options = {});
  /// See SelfBroadPhase::FindCandidates. Real-time safe.
  SelfBroadPhaseStats FindCandidates(std::span<const Vec3> x0, std::span<const Vec3> x1,
                                     double thickness_m) override;
  double cell_size_m() const { return cell_size_m_; }  ///< grid cell edge [m]
  int32_t table_size() const { return table_size_; }   ///< buckets (a prime)

  /// A (primitive, cell) entry of the table.
  struct Entry {
    int32_t id = 0;                    ///< vertex or edge index
    std::array<int32_t, 3> cell = {};  ///< integer cell coordinates
  };

 private:
  /// A swept, padded box [m].
  struct Box {
    Vec3 lo = Vec3::Zero();
    Vec3 hi = Vec3::Zero();
  };
  double cell_size_m_ = 0.0;
  int32_t table_size_ = 0;
  int32_t max_cells_ = 0;
  int64_t max_entries_ = 0;
  std::vector<Box> vertex_box_;        ///< [vertices]
  std::vector<Box> edge_box_;          ///< [edges]
  std::vector<Box> triangle_box_;      ///< [triangles]
  std::vector<int32_t> bucket_start_;  ///< [table_size + 1] counting-sort offsets
  std::vector<int32_t> bucket_fill_;   ///< [table_size] fill cursors
  std::vector<Entry> entries_;         ///< [max_entries] bucketed entries
  std::vector<uint8_t> hashed_;        ///< [max(vertices, edges)] 1 if in the table
  std::vector<int32_t> oversized_;     ///< [max(vertices, edges)] ids not in the table
};

/// What the tree methods (SelfBvh, SelfBvox) share: each vertex's swept, padded box, each edge's
/// box made from its ends' when a leaf pair first needs it, and the pairing of two triangles'
/// features. Each vertex and edge belongs to one triangle (the first that uses it), and only an
/// owner's primitives are paired with the other triangle's, so a traversal that meets every
/// overlapping pair of triangles once emits every candidate once; pairs sharing a vertex
/// (adjacent triangles' shared features) are skipped.
class SelfTriangleTree : public SelfBroadPhase {
 protected:
  /// Numbers the owned features and sizes the box arrays for `triangles` over x [m]. Throws as
  /// SelfBroadPhase.
  SelfTriangleTree(std::span<const Triangle> triangles, std::span<const Vec3> x,
                   const SelfBroadPhaseOptions& options);
  /// Half the thickness h [m], widened by 1e-5 relative: every box's padding per side [m].
  static double BoxPadding(double thickness_m);
  /// True when the closed boxes [alo, ahi] and [blo, bhi] [m] share a point (false with a NaN).
  static bool BoxesOverlap(const Vec3& alo, const Vec3& ahi, const Vec3& blo, const Vec3& bhi);
  /// Vertex v's box: its sweep x0 -> x1 padded by `pad`, and, when start_pad is larger, its
  /// start position padded by start_pad [m].
  void VertexBox(int32_t v, std::span<const Vec3> x0, std::span<const Vec3> x1, double pad,
                 double start_pad);
  /// New vertex boxes: every edge box is stale (made again by EdgeBox when needed).
  void NewBoxStamp();
  /// Edge e's swept box from its ends' vertex boxes, made once per box stamp.
  void EdgeBox(int32_t e);
  /// The candidates of triangles ta and tb (ta != tb) whose boxes (the unions of their vertex
  /// boxes) are [alo, ahi] and [blo, bhi] [m]: the owned vertices of each against the other
  /// triangle, and the owned edges of ta against those of tb, where their boxes overlap.
  void PairTriangles(int32_t ta, int32_t tb, const Vec3& alo, const Vec3& ahi, const Vec3& blo,
                     const Vec3& bhi, SelfBroadPhaseStats* stats);

  std::vector<Vec3> vertex_lo_;  ///< [vertices] swept, padded vertex box [m]
  std::vector<Vec3> vertex_hi_;
  std::vector<Vec3> edge_lo_;  ///< [edges] swept, padded edge box [m], valid when stamped
  std::vector<Vec3> edge_hi_;
  std::vector<uint32_t> edge_stamp_;  ///< [edges] box_stamp_ when the edge's box was made
  uint32_t box_stamp_ = 0;            ///< this broad phase's vertex boxes (NewBoxStamp)
  std::vector<std::array<int32_t, 3>> owned_vertices_;  ///< [triangles] owned vertices, -1 pad
  std::vector<std::array<int32_t, 3>> owned_edges_;     ///< [triangles] owned edges, -1 pad
};

/// Method (b): a binary AABB tree over the triangles (median split of centroids at
/// construction), refitted bottom-up every step from the triangles' swept boxes and traversed
/// against itself: (A, A) -> its children's pairs, overlapping (A, B) -> recurse, leaf pairs ->
/// vertex-triangle and edge-edge candidates (SelfTriangleTree::PairTriangles).
class SelfBvh final : public SelfTriangleTree {
 public:
  /// Builds the tree for `triangles` over positions x [m] (rest or current). Throws
  /// std::invalid_argument on an index out of range or a bad option.
  SelfBvh(std::span<const Triangle> triangles, std::span<const Vec3> x,
          const SelfBroadPhaseOptions& options = {});
  /// See SelfBroadPhase::FindCandidates. Real-time safe (recursion depth about 2 log2 T).
  SelfBroadPhaseStats FindCandidates(std::span<const Vec3> x0, std::span<const Vec3> x1,
                                     double thickness_m) override;
  /// FindCandidates, with every vertex's box also holding its start position x0 padded by
  /// start_thickness_m (1 + 1e-5) / 2 [m]: the candidates then also hold every pair within
  /// start_thickness_m at x0 (but those inside a patch certified over the step), so that one
  /// broad phase serves a static proximity test at x0 and the continuous test at thickness_m.
  SelfBroadPhaseStats FindCandidates(std::span<const Vec3> x0, std::span<const Vec3> x1,
                                     double thickness_m, double start_thickness_m);
  int32_t num_nodes() const { return static_cast<int32_t>(node_lo_.size()); }  ///< tree nodes
  /// Nodes skipped against themselves by the normal-cone test in the last FindCandidates.
  int32_t cone_culled() const { return cone_culled_; }
  /// Pairs of nodes skipped by the normal-cone test of their union in the last FindCandidates.
  int32_t union_culled() const { return union_culled_; }
  /// With normal cones, node `node`'s cone and fat bound of the last broad phase: axis x, y, z,
  /// cos and sin of the half-angle, least squared altitude bound [m^2], largest squared corner
  /// move [m^2] (for tests: every SIMD level must give the same bits).
  std::array<double, 7> ConeOf(int32_t node) const {
    const Cone& c = cone_[node];
    return {c.axis.x(), c.axis.y(),    c.axis.z(),      c.cos_half,
            c.sin_half, fat_[node].h2, fat_[node].move2};
  }
  /// Carries the last FindCandidates (or UpdateCandidates) of the step x0 -> x1' over to the step
  /// x0 -> x1, where x1 equals x1' except at the vertices p with moved[p] != 0 (x0 and
  /// thickness_m [m] the same as there): the candidates of two triangles none of whose vertices
  /// moved are kept (their trajectories did not change, so their boxes still overlap, and a pair
  /// the last traversal culled, by boxes or by a patch certified free of contact, still cannot
  /// touch: contact of two primitives depends on their own vertices only), and the tree is
  /// refitted and traversed again only where a triangle has a moved vertex (its boxes, cones
  /// and certificates recomputed on the new motion). The result holds every pair a fresh
  /// FindCandidates(x0, x1, thickness_m) holds, in another order: candidates()[0, kept) are the
  /// kept ones in their old order (kept_from() gives their old indices), the rest are new.
  /// moved has one flag per vertex. Undefined if the precondition is broken; after an overflow
  /// the caller must call FindCandidates again. Real-time safe.
  /// start_thickness_m as in the 4-argument FindCandidates (the same as there; 0 if it was not
  /// given).
  SelfBroadPhaseStats UpdateCandidates(std::span<const Vec3> x0, std::span<const Vec3> x1,
                                       double thickness_m, double start_thickness_m,
                                       std::span<const uint8_t> moved);
  /// After UpdateCandidates: the index before the update of each kept candidate (kept ones
  /// come first in candidates()); empty after FindCandidates.
  std::span<const int32_t> kept_from() const { return {kept_from_.data(), kept_from_.size()}; }

 private:
  /// A cone of directions: unit axis and cosine / sine of its half-angle; cos_half <= 0 means
  /// "no cone below pi/2" (the node is never skipped).
  struct Cone {
    Vec3 axis = Vec3::UnitZ();
    double cos_half = -1.0;
    double sin_half = 0.0;
  };
  // What bounds a patch's corners' distances to their opposite edges from below over a step,
  // squared (self_broadphase.cc, SelfLeafConeLanes): the least squared altitude bound h^2 at the
  // step's ends [m^2] and the largest squared move of a corner over the step [m^2]; every corner
  // stays at least sqrt(h2) - sqrt(move2) from its opposite edge.
  struct FatBound {
    double h2 = 0.0;
    double move2 = 0.0;
  };
  void BuildContours(std::span<const Vec3> x, const std::vector<int32_t>& order,
                     const std::vector<std::array<int32_t, 2>>& range);
  bool SelfContactFree(int32_t a, int32_t b, const Cone& cone) const;
  static Cone MergeCones(const Cone& l, const Cone& r);
  // A cone as the lane kernels read and write it (self_leaf_cone.inc): axis x, y, z, cos_half,
  // sin_half into out[0 .. 4], and back.
  static void PackCone(const Cone& cone, double* out);
  static Cone UnpackCone(const double* in);
  // True when the patch's corners stay far enough from their opposite edges that the cone's
  // certificate also holds at the step's thickness (SelfContactFree's comment).
  bool SelfFat(const Cone& cone, const FatBound& fat) const;
  // The bound of two patches together: the least h2, the largest move2.
  static FatBound MergeFat(const FatBound& l, const FatBound& r);
  void Traverse(int32_t a, int32_t b, SelfBroadPhaseStats* stats);
  void LeafPair(int32_t ta, int32_t tb, SelfBroadPhaseStats* stats);
  bool Overlap(int32_t a, int32_t b) const;
  void RefitLeaf(int32_t node, std::span<const Vec3> x0, std::span<const Vec3> x1);
  void RefitParent(int32_t node);
  // A leaf's box from its triangle's vertex boxes.
  void LeafBox(int32_t node);
  // A parent's box and fat bound from its children's (not its cone).
  void RefitParentBounds(int32_t node);
  // Every parent, a level at a time from the deepest, its cones merged a level at once.
  void RefitParents();
  // A leaf's cone and fat bound from out[0 .. 6] (axis x, y, z, cos_half, sin_half, h2, move2).
  void TakeLeafCone(int32_t node, const double* out);
  std::vector<int32_t> left_;         ///< [nodes] left child, -1 for a leaf
  std::vector<int32_t> right_;        ///< [nodes] right child, or the triangle of a leaf
  std::vector<Vec3> node_lo_;         ///< [nodes] swept box low corner [m]
  std::vector<Vec3> node_hi_;         ///< [nodes] swept box high corner [m]
  std::vector<int32_t> refit_order_;  ///< nodes, children before parents
  std::vector<int32_t> parent_order_;  ///< the parents, deepest level first (FindCandidates)
  std::vector<int32_t> level_start_;   ///< parent_order_'s levels: [level_start_[k], [k + 1])
  std::vector<double> merge_in_;       ///< [10 parents] the children's cones (RefitParents)
  std::vector<double> merge_out_;      ///< [5 parents] the merged cones
  // Normal cones (options.normal_cones; Volino & Magnenat-Thalmann 1994, Provot 1997, with the
  // continuous normal cones of Tang et al. 2009 and the star contours of Schvartzman et al.
  // 2010): per node its cone over the step, and, for nodes that may be skipped, a center
  // triangle (its centroid is the star's center) and its directed contour edges
  // contour_[contour_begin_[node] .. contour_begin_[node + 1]).
  bool normal_cones_ = false;
  std::vector<Cone> cone_;                       ///< [nodes]
  /// [nodes] what bounds every distance from a corner of the node's triangles to its triangle's
  /// opposite edge from below over the step (FatBound): with the cone,
  /// what keeps a certificate from hiding pairs within the detection's thickness (SelfFat).
  std::vector<FatBound> fat_;
  double certify_m_ = 0.0;                       ///< the thickness the step is traversed for [m]
  std::vector<int32_t> leaf_tri_;                ///< the leaves' triangles, in the refit's order
  std::vector<int32_t> leaf_slot_;  ///< [nodes] a leaf's index in leaf_tri_ (-1: a parent)
  std::vector<double> leaf_out_;    ///< [7 leaves] the batched cones (axis, cos, sin, h2, move2)
  std::vector<int32_t> center_;                  ///< [nodes] center triangle, -1: never skipped
  std::vector<int32_t> contour_begin_;           ///< [nodes + 1]
  std::vector<std::array<int32_t, 2>> contour_;  ///< directed contour edges (region on the left)
  std::span<const Vec3> step_x0_, step_x1_;      ///< the step being traversed
  int32_t cone_culled_ = 0;
  int32_t union_culled_ = 0;
  // UpdateCandidates: triangles and nodes holding a moved vertex; while `incremental_`, the
  // traversal skips pairs of nodes neither of which is dirty.
  bool incremental_ = false;
  bool still_ = false;                   ///< the step being traversed has x1 = x0 (the same array)
  std::vector<uint8_t> triangle_dirty_;  ///< [triangles]
  std::vector<uint8_t> node_dirty_;      ///< [nodes]
  std::vector<int32_t> kept_from_;       ///< [kept candidates] index before the update
};

/// Outcome of SelfCcd.
struct SelfCcdStats {
  SelfBroadPhaseStats broad;  ///< the broad phase's counts
  int64_t hits = 0;           ///< colliding pairs found (also those not stored)
  /// True when the broad phase or the hit buffer overflowed: the hits are incomplete and the
  /// caller must fall back (AllPairsCcd) or enlarge the buffers at set-up.
  bool overflow = false;
};

/// Runs `broad` on the step x0 -> x1 [m] and the narrow phase (VertexTriangleCcd / EdgeEdgeCcd,
/// or the *Separation tests, per options) on its candidates; writes the colliding pairs to *hits
/// in AllPairsCcd's form and order (vertex-triangle by (vertex, triangle), then edge-edge by
/// (e, f)), never growing it beyond hits->capacity() (reserve it at set-up; overflow is
/// reported). options.box_prefilter is ignored (the broad phase is the filter). Real-time safe
/// when hits has capacity: no allocation (the sort is in place).
SelfCcdStats SelfCcd(SelfBroadPhase* broad, std::span<const Vec3> x0, std::span<const Vec3> x1,
                     const AllPairsCcdOptions& options, std::vector<CcdPairHit>* hits);

}  // namespace felt
