#pragma once
// Exact static intersection tests between triangles and segments, and the all-pairs count of
// intersecting non-adjacent triangles of a mesh: the reference behind issue 22's target "zero
// intersecting triangle pairs at the end of every frame". Every decision is a sign of an exact
// orientation predicate (collision/self_predicates.h), so touching, coplanar and degenerate
// (zero-area, repeated-vertex) inputs are decided exactly. Sets are closed: touching counts as
// intersecting.

#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "collision/mesh.h"

namespace felt {

/// True when the closed triangles (a1, b1, c1) and (a2, b2, c2) [m, one frame] share at least one
/// point, exactly. Non-coplanar triangles: the orientation-predicate form of the interval overlap
/// test (Guigue & Devillers, "Fast and robust triangle-triangle overlap test using orientation
/// predicates", JGT 8(1), 2003; the interval idea is Moller, "A fast triangle-triangle
/// intersection test", JGT 2(2), 1997). Coplanar triangles: the 2D test in the coordinate plane the
/// first triangle projects onto without degenerating (an edge pair crosses or a vertex lies in the
/// other triangle). A degenerate triangle (collinear or repeated vertices) is the union of its
/// three edges. Real-time safe.
bool TrianglesIntersect(const Vec3& a1, const Vec3& b1, const Vec3& c1, const Vec3& a2,
                        const Vec3& b2, const Vec3& c2);

/// True when the closed segment [p, q] and the closed triangle (a, b, c) [m] share a point,
/// exactly. Either may be degenerate (a point; a segment-like triangle). Real-time safe.
bool SegmentIntersectsTriangle(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b,
                               const Vec3& c);

/// True when the closed segments [p, q] and [a, b] [m] share a point, exactly. Real-time safe.
bool SegmentsIntersect(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b);

/// True when triangles t and u share a vertex index (adjacent: never counted as intersecting).
bool TrianglesShareVertex(const Triangle& t, const Triangle& u);

/// Every unordered pair (i, j), i < j, of triangles of the mesh (positions x [m], triangles as
/// indices into x) that share no vertex index and intersect by TrianglesIntersect, in increasing
/// (i, j) order. Every pair whose closed boxes overlap is tested exactly (found by a sort and
/// sweep of the boxes along x, which misses none): a reference independent of the culling
/// methods, not one of them. Allocates.
std::vector<std::pair<int32_t, int32_t>> FindSelfIntersections(std::span<const Vec3> x,
                                                               std::span<const Triangle> triangles);

/// The number of pairs FindSelfIntersections returns, without storing them.
int64_t CountSelfIntersections(std::span<const Vec3> x, std::span<const Triangle> triangles);

}  // namespace felt
