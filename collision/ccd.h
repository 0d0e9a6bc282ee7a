#pragma once
// Continuous collision detection of a vertex against a triangle and of an edge against an edge,
// the four points moving linearly from x0 (t = 0) to x1 (t = 1) over a step (issue 22).
//
// VertexTriangleCcd / EdgeEdgeCcd follow Provot 1997 and Bridson, Fedkiw & Anderson 2002:
// the four points can only meet when they are coplanar, i.e. at a root of the coplanarity cubic;
// at those times a proximity test with a thickness h decides. Here the roots are not trusted to
// floating point: CoplanarCandidateTimes (collision/ccd_cubic.h) returns intervals certain to
// contain every exact root, and inside each the earliest time the distance is within h is found by
// conservative advancement (Mirtich 1996; the distance is Lipschitz in t with the largest relative
// speed of the four points as constant), which cannot step over it. So:
// - never missed: every time t at which the four points are exactly coplanar and the primitives
//   are within h of each other is reported (a hit at some toi <= t); in particular every actual
//   contact (distance 0) is;
// - false positives, by design and bounded by the thickness: a hit means the distance was at most
//   h (1 + kCcdDistanceSlack) at toi, at a time the points were coplanar up to rounding;
// - coplanar motion (the cubic zero up to rounding, also degenerate triangles and parallel edges,
//   whose cubic is identically zero) needs no special case: its interval is all of [0, 1], and
//   the advancement finds the first time the distance comes within h.
// VertexTriangleSeparation / EdgeEdgeSeparation are the minimal-separation variant: the earliest
// time the distance is within h, whether coplanar or not (advancement over all of [0, 1]).
//
// Each advancement stops after max_steps steps (only reachable on long grazing approaches, where
// the distance creeps toward h); the pair is then reported as a hit with `capped` set, at a time
// before any contact: conservative, never a miss. Real-time safe: no allocation, no exceptions.

#include <array>
#include <cstdint>

#include "collision/mesh.h"

namespace felt {

/// Four positions [m, one frame]. Vertex-triangle: {vertex, a, b, c}. Edge-edge:
/// {e0, e1, f0, f1} for the edges [e0, e1] and [f0, f1].
using CcdPoints = std::array<Vec3, 4>;

/// A hit may be reported at a distance up to h (1 + kCcdDistanceSlack) (dimensionless): the
/// advancement's stopping tolerance, so that a distance creeping down to exactly h terminates.
inline constexpr double kCcdDistanceSlack = 1e-6;

/// Settings of the continuous tests.
struct CcdOptions {
  double thickness_m = 1e-3;  ///< h: primitives within h of each other collide, m (> 0)
  int32_t max_steps = 1000;   ///< advancement steps per interval before a capped report (>= 0)
};

/// The earliest collision of a vertex with a triangle over the step.
struct VertexTriangleHit {
  bool hit = false;            ///< false: no collision in [0, 1]; the other fields are unset
  bool capped = false;         ///< reported at the step cap: distance at toi may still exceed h
  double toi = 1.0;            ///< time of impact as a fraction of the step, in [0, 1]
  double distance_m = 0.0;     ///< vertex-triangle distance at toi, m
  Vec3 normal = Vec3::Zero();  ///< unit, from the triangle toward the vertex's side (below)
  Vec3 barycentric = Vec3::Zero();  ///< of the triangle point nearest the vertex at toi, (a, b, c)
};

/// The earliest collision of two edges over the step.
struct EdgeEdgeHit {
  bool hit = false;            ///< false: no collision in [0, 1]; the other fields are unset
  bool capped = false;         ///< reported at the step cap: distance at toi may still exceed h
  double toi = 1.0;            ///< time of impact as a fraction of the step, in [0, 1]
  double distance_m = 0.0;     ///< edge-edge distance at toi, m
  Vec3 normal = Vec3::Zero();  ///< unit, from edge f toward edge e's side (below)
  double s = 0.0;              ///< closest point on e at toi: e0 + s (e1 - e0), s in [0, 1]
  double u = 0.0;              ///< closest point on f at toi: f0 + u (f1 - f0), u in [0, 1]
};

/// First time in [0, 1] the vertex x[0] and the triangle (x[1], x[2], x[3]), moving linearly from
/// x0 to x1 [m], are coplanar (up to rounding) and within options.thickness_m of each other (see
/// the file comment for the guarantee). Normal: the triangle's unit normal at toi (for a
/// degenerate triangle, the direction from its nearest point to the vertex, else against their
/// relative velocity), turned to the side of the triangle the vertex started on at t = 0 (same
/// barycentric point), or against the relative velocity when it started on the triangle.
/// Real-time safe.
VertexTriangleHit VertexTriangleCcd(const CcdPoints& x0, const CcdPoints& x1,
                                    const CcdOptions& options = {});

/// First time in [0, 1] the edges [x[0], x[1]] and [x[2], x[3]], moving linearly from x0 to x1
/// [m], are coplanar (up to rounding) and within options.thickness_m of each other. Normal: the
/// unit normal of both edges' directions at toi (for nearly parallel edges, the direction between
/// their closest points, else against their relative velocity), turned to the side edge e started
/// on at t = 0 (same parameters s, u). Real-time safe.
EdgeEdgeHit EdgeEdgeCcd(const CcdPoints& x0, const CcdPoints& x1, const CcdOptions& options = {});

/// Minimal separation: first time in [0, 1] the vertex-triangle distance is at most
/// options.thickness_m (at t = 0 if it starts within it), coplanar or not. Normal: from the
/// triangle's nearest point toward the vertex when they are apart, else as VertexTriangleCcd.
/// Real-time safe.
VertexTriangleHit VertexTriangleSeparation(const CcdPoints& x0, const CcdPoints& x1,
                                           const CcdOptions& options = {});

/// Minimal separation: first time in [0, 1] the edge-edge distance is at most options.thickness_m.
/// Normal: from f's closest point toward e's when apart, else as EdgeEdgeCcd. Real-time safe.
EdgeEdgeHit EdgeEdgeSeparation(const CcdPoints& x0, const CcdPoints& x1,
                               const CcdOptions& options = {});

/// Position at t in [0, 1] of a point moving linearly from a to b, exactly a at t = 0 and exactly
/// b at t = 1 [m].
Vec3 LinearPointAt(const Vec3& a, const Vec3& b, double t);

/// The largest speed [m per unit t] of any point of the triangle (fixed barycentric weights)
/// relative to the vertex: max over the corners of |(x1[0] - x0[0]) - (x1[i] - x0[i])|, the
/// Lipschitz constant of the vertex-triangle distance in t.
double VertexTriangleRelativeSpeed(const CcdPoints& x0, const CcdPoints& x1);

/// The largest relative speed [m per unit t] of a point of one edge and a point of the other:
/// max over i in {0, 1}, j in {2, 3} of |(x1[i] - x0[i]) - (x1[j] - x0[j])|.
double EdgeEdgeRelativeSpeed(const CcdPoints& x0, const CcdPoints& x1);

}  // namespace felt
