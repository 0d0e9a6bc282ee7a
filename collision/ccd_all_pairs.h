#pragma once
// The all-pairs continuous self-collision reference (issue 22's "zero collisions missed against an
// all-pairs continuous reference"): for a mesh moving linearly from x0 to x1 over a step, every
// non-incident vertex-triangle and edge-edge pair is tested with the exact primitives of
// collision/ccd.h, without culling. O(V T + E^2): for test sizes and for checking the culling
// methods built on top of it, not for a frame budget.

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "collision/ccd.h"
#include "collision/mesh.h"

namespace felt {

/// An edge as its two vertex indices, first < second.
using MeshEdge = std::array<int32_t, 2>;

/// The distinct edges of the triangles (those with two equal indices left out), sorted.
/// Allocates its result.
std::vector<MeshEdge> MeshEdges(std::span<const Triangle> triangles);

/// One colliding primitive pair.
struct CcdPairHit {
  enum class Kind : uint8_t { kVertexTriangle, kEdgeEdge };
  Kind kind = Kind::kVertexTriangle;
  int32_t first = 0;   ///< vertex-triangle: the vertex; edge-edge: index of edge e in MeshEdges
  int32_t second = 0;  ///< vertex-triangle: the triangle's index; edge-edge: index of edge f
  /// The four vertices: {vertex, a, b, c} or {e0, e1, f0, f1}.
  std::array<int32_t, 4> vertices = {};
  bool capped = false;         ///< see VertexTriangleHit::capped
  double toi = 1.0;            ///< time of impact as a fraction of the step, in [0, 1]
  double distance_m = 0.0;     ///< distance at toi, m
  Vec3 normal = Vec3::Zero();  ///< unit, from the triangle (edge f) toward the vertex (edge e)
  /// Weights w with sum_i w_i x_i(toi) the vector from the triangle's (f's) closest point to the
  /// vertex (e's): {1, -wa, -wb, -wc} or {1 - s, s, -(1 - u), -u} (the weights of Bridson et al.
  /// 2002's impulses, 003_b6c1450a5a1611e7.txt §6).
  std::array<double, 4> weights = {};
};

/// Options of AllPairsCcd.
struct AllPairsCcdOptions {
  CcdOptions ccd;                   ///< thickness and step cap of every pair test
  bool minimal_separation = false;  ///< the *Separation tests instead of the coplanarity ones
  /// Skip a pair whose boxes around both positions (x0 and x1) of its vertices are more than the
  /// thickness apart on an axis: such primitives are never within it (every point lies in the
  /// box at every t). Gives the same result, faster; off by default so the reference stays plain.
  bool box_prefilter = false;
};

/// The narrow phase of one vertex-triangle pair, vertex `v` against triangle `triangle` (index
/// `ti`), over the step x0 -> x1 [m] by VertexTriangleCcd (or VertexTriangleSeparation with
/// options.minimal_separation): true with *hit filled when they collide. Real-time safe.
bool VertexTrianglePairHit(std::span<const Vec3> x0, std::span<const Vec3> x1, int32_t v,
                           int32_t ti, const Triangle& triangle, const AllPairsCcdOptions& options,
                           CcdPairHit* hit);

/// The narrow phase of one edge-edge pair, edges `e` (index `ei`) and `f` (index `fi`), over the
/// step x0 -> x1 [m] by EdgeEdgeCcd (or EdgeEdgeSeparation): true with *hit filled when they
/// collide. Real-time safe.
bool EdgeEdgePairHit(std::span<const Vec3> x0, std::span<const Vec3> x1, int32_t ei,
                     const MeshEdge& e, int32_t fi, const MeshEdge& f,
                     const AllPairsCcdOptions& options, CcdPairHit* hit);

/// Every vertex-triangle pair (the vertex not a corner of the triangle) and every edge-edge pair
/// (no shared vertex) of the mesh that collides over the step x0 -> x1 [m] by VertexTriangleCcd /
/// EdgeEdgeCcd (or the separation tests), in order: vertex-triangle pairs by (vertex, triangle),
/// then edge-edge pairs by (e, f) with e < f. Throws nothing; aborts (FELT_CHECK) when x0 and x1
/// differ in size or an index is out of range. Allocates.
std::vector<CcdPairHit> AllPairsCcd(std::span<const Vec3> x0, std::span<const Vec3> x1,
                                    std::span<const Triangle> triangles,
                                    const AllPairsCcdOptions& options = {});

}  // namespace felt
