// Continuous vertex-triangle and edge-edge tests: closed forms (falling through at a known time,
// edges crossing at a known time, grazing, coplanar sliding, degenerate triangles, parallel edges,
// touching exactly at t = 1, roots near 0 and 1, double and nearly double roots), then a
// randomized differential test against a sampled reference that cannot miss: zero misses.
#include "collision/ccd.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "collision/ccd_cubic.h"
#include "collision/ccd_proximity.h"
#include "collision/geometry.h"
#include "collision/self_predicates.h"
#include "tests/test_env.h"

namespace felt {
namespace {

// The unit right triangle in z = 0, static, and a vertex moving from p0 to p1.
void VertexOverBase(const Vec3& p0, const Vec3& p1, CcdPoints* x0, CcdPoints* x1) {
  *x0 = {p0, Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  *x1 = {p1, Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
}

TEST(CcdTest, VertexFallsThroughStaticTriangleAtKnownTime) {
  CcdPoints x0, x1;
  VertexOverBase(Vec3(0.2, 0.3, 1), Vec3(0.2, 0.3, -1), &x0, &x1);
  const VertexTriangleHit hit = VertexTriangleCcd(x0, x1, {1e-6});
  ASSERT_TRUE(hit.hit);
  EXPECT_FALSE(hit.capped);
  EXPECT_NEAR(hit.toi, 0.5, 1e-12);
  EXPECT_LE(hit.toi, 0.5 + 1e-15);  // not after the crossing
  EXPECT_LT(hit.distance_m, 1e-12);
  EXPECT_NEAR((hit.barycentric - Vec3(0.5, 0.2, 0.3)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((hit.normal - Vec3(0, 0, 1)).norm(), 0.0, 1e-12);  // the side it came from
  // From below: the normal faces down.
  VertexOverBase(Vec3(0.2, 0.3, -1), Vec3(0.2, 0.3, 3), &x0, &x1);
  const VertexTriangleHit up = VertexTriangleCcd(x0, x1, {1e-6});
  ASSERT_TRUE(up.hit);
  EXPECT_NEAR(up.toi, 0.25, 1e-12);
  EXPECT_NEAR((up.normal - Vec3(0, 0, -1)).norm(), 0.0, 1e-12);
}

TEST(CcdTest, VertexThroughThePlaneOutsideTheTriangle) {
  const double h = 1e-3;
  CcdPoints x0, x1;
  // Far outside: no hit.
  VertexOverBase(Vec3(0.8, 0.8, 1), Vec3(0.8, 0.8, -1), &x0, &x1);
  EXPECT_FALSE(VertexTriangleCcd(x0, x1, {h}).hit);
  // Outside the hypotenuse x + y = 1 by 0.9 h, then by 1.1 h.
  for (double k : {0.9, 1.1}) {
    const double off = 0.5 + k * h / std::sqrt(2.0);
    VertexOverBase(Vec3(off, off, 1), Vec3(off, off, -1), &x0, &x1);
    const VertexTriangleHit hit = VertexTriangleCcd(x0, x1, {h});
    EXPECT_EQ(hit.hit, k < 1.0) << k;
    if (hit.hit) {
      EXPECT_NEAR(hit.toi, 0.5, 1e-12);
      EXPECT_NEAR(hit.distance_m, 0.9 * h, 1e-12);
    }
  }
}

TEST(CcdTest, EdgesCrossAtKnownTime) {
  // e along x at y = 0.5 falls from z = 1 to z = -1; f along y at x = 0.5 rests in z = 0.
  const CcdPoints x0 = {Vec3(0, 0.5, 1), Vec3(1, 0.5, 1), Vec3(0.5, 0, 0), Vec3(0.5, 1, 0)};
  const CcdPoints x1 = {Vec3(0, 0.5, -1), Vec3(1, 0.5, -1), Vec3(0.5, 0, 0), Vec3(0.5, 1, 0)};
  const EdgeEdgeHit hit = EdgeEdgeCcd(x0, x1, {1e-6});
  ASSERT_TRUE(hit.hit);
  EXPECT_NEAR(hit.toi, 0.5, 1e-12);
  EXPECT_NEAR(hit.s, 0.5, 1e-9);
  EXPECT_NEAR(hit.u, 0.5, 1e-9);
  EXPECT_NEAR((hit.normal - Vec3(0, 0, 1)).norm(), 0.0, 1e-12);  // toward e's starting side
  // Shifted along x so that they pass beside each other (e ends at x = 1 < 1.2).
  CcdPoints y0 = x0, y1 = x1;
  for (int i : {2, 3}) y0[i].x() = y1[i].x() = 1.2;
  EXPECT_FALSE(EdgeEdgeCcd(y0, y1, {1e-3}).hit);
}

TEST(CcdTest, GrazingIsProximityNotCollision) {
  const double h = 1e-3;
  CcdPoints x0, x1;
  // Sliding over the face at h / 2: never coplanar, so not a collision; within h from the start.
  VertexOverBase(Vec3(-0.5, 0.2, 0.5 * h), Vec3(0.9, 0.2, 0.5 * h), &x0, &x1);
  EXPECT_FALSE(VertexTriangleCcd(x0, x1, {h}).hit);
  const VertexTriangleHit sep = VertexTriangleSeparation(x0, x1, {h});
  ASSERT_TRUE(sep.hit);
  // It enters the h-neighbourhood over the edge x = 0 where the distance is
  // sqrt(x^2 + (h/2)^2) = h: x = -sqrt(3) h / 2, t = (0.5 - sqrt(3) h / 2) / 1.4.
  EXPECT_NEAR(sep.toi, (0.5 - std::sqrt(3.0) * h / 2) / 1.4, 1e-9);
  EXPECT_NEAR(sep.distance_m, h, 1e-9);
  EXPECT_GT(sep.normal.z(), 0.0);
  // At 2 h: nothing at all.
  VertexOverBase(Vec3(-0.5, 0.2, 2 * h), Vec3(0.9, 0.2, 2 * h), &x0, &x1);
  EXPECT_FALSE(VertexTriangleCcd(x0, x1, {h}).hit);
  EXPECT_FALSE(VertexTriangleSeparation(x0, x1, {h}).hit);
}

TEST(CcdTest, CoplanarSlidingIsFoundByTheDistance) {
  const double h = 1e-3;
  CcdPoints x0, x1;
  // In the triangle's plane, sliding into it: the cubic is zero, the hit is where the vertex comes
  // within h of the edge x = 0, at x = -h: t = (1 - h) / 2.
  VertexOverBase(Vec3(-1, 0.25, 0), Vec3(1, 0.25, 0), &x0, &x1);
  VertexTriangleHit hit = VertexTriangleCcd(x0, x1, {h});
  ASSERT_TRUE(hit.hit);
  EXPECT_FALSE(hit.capped);
  EXPECT_NEAR(hit.toi, (1 - h) / 2, 1e-9);
  EXPECT_NEAR(hit.distance_m, h, 1e-9);
  EXPECT_NEAR(std::abs(hit.normal.z()), 1.0, 1e-12);  // the face normal
  // Sliding past it in the plane: no hit.
  VertexOverBase(Vec3(-1, 1.5, 0), Vec3(1, 1.5, 0), &x0, &x1);
  EXPECT_FALSE(VertexTriangleCcd(x0, x1, {h}).hit);
  // Two edges in z = 0, e sliding along x into f's end: e's tip reaches within h of f at
  // x = 0.5 - h: t = (0.5 - h) / 1.
  const CcdPoints e0 = {Vec3(-1, 0.3, 0), Vec3(-0.5, 0.3, 0), Vec3(0, 0, 0), Vec3(0, 1, 0)};
  const CcdPoints e1 = {Vec3(0, 0.3, 0), Vec3(0.5, 0.3, 0), Vec3(0, 0, 0), Vec3(0, 1, 0)};
  const EdgeEdgeHit ee = EdgeEdgeCcd(e0, e1, {h});
  ASSERT_TRUE(ee.hit);
  EXPECT_NEAR(ee.toi, 0.5 - h, 1e-9);
  EXPECT_NEAR(ee.s, 1.0, 1e-12);
  EXPECT_NEAR(ee.u, 0.3, 1e-12);
}

TEST(CcdTest, DegenerateTrianglesAndParallelEdges) {
  const double h = 1e-3;
  // A triangle collapsed onto the segment [0, 1] x {0} x {0}: the vertex passes through it at
  // t = 0.5 along (0.5, 0.5 - t, 1 - 2 t), at distance |0.5 - t| sqrt(5): first within h at
  // t = 0.5 - h / sqrt(5).
  CcdPoints x0 = {Vec3(0.5, 0.5, 1), Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.5, 0, 0)};
  CcdPoints x1 = {Vec3(0.5, -0.5, -1), Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.5, 0, 0)};
  VertexTriangleHit hit = VertexTriangleCcd(x0, x1, {h});
  ASSERT_TRUE(hit.hit);
  EXPECT_NEAR(hit.toi, 0.5 - h / std::sqrt(5.0), 1e-9);
  EXPECT_NEAR(hit.normal.norm(), 1.0, 1e-12);
  // Passing 2 h beside it: no hit.
  x0[0].x() = x1[0].x() = 1.0 + 2 * h;
  EXPECT_FALSE(VertexTriangleCcd(x0, x1, {h}).hit);
  // A triangle collapsed to a point, the vertex passing through it.
  x0 = {Vec3(0.2, 0.2, 1), Vec3(0.2, 0.2, 0), Vec3(0.2, 0.2, 0), Vec3(0.2, 0.2, 0)};
  x1 = {Vec3(0.2, 0.2, -1), Vec3(0.2, 0.2, 0), Vec3(0.2, 0.2, 0), Vec3(0.2, 0.2, 0)};
  hit = VertexTriangleCcd(x0, x1, {h});
  ASSERT_TRUE(hit.hit);
  EXPECT_NEAR(hit.toi, 0.5 - h / 2, 1e-9);
  EXPECT_NEAR((hit.normal - Vec3(0, 0, 1)).norm(), 0.0, 1e-12);
  // Parallel edges (their cubic is identically zero) closing from 1 to -1 apart across each
  // other: within h at t = (1 - h) / 2.
  const CcdPoints p0 = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.5, 1, 0), Vec3(1.5, 1, 0)};
  const CcdPoints p1 = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.5, -1, 0), Vec3(1.5, -1, 0)};
  const EdgeEdgeHit ee = EdgeEdgeCcd(p0, p1, {h});
  ASSERT_TRUE(ee.hit);
  EXPECT_NEAR(ee.toi, (1 - h) / 2, 1e-9);
  EXPECT_NEAR((ee.normal - Vec3(0, -1, 0)).norm(), 0.0, 1e-9);  // from f toward e
  // A zero-length edge (a point) through a segment.
  const CcdPoints z0 = {Vec3(0.5, 0.5, 1), Vec3(0.5, 0.5, 1), Vec3(0, 0.5, 0), Vec3(1, 0.5, 0)};
  const CcdPoints z1 = {Vec3(0.5, 0.5, -1), Vec3(0.5, 0.5, -1), Vec3(0, 0.5, 0), Vec3(1, 0.5, 0)};
  const EdgeEdgeHit zz = EdgeEdgeCcd(z0, z1, {h});
  ASSERT_TRUE(zz.hit);
  EXPECT_NEAR(zz.toi, 0.5 - h / 2, 1e-9);
}

TEST(CcdTest, TouchingAtTheEndsAndRootsNearThem) {
  const double h = 1e-6;
  CcdPoints x0, x1;
  // Lands exactly on the face at t = 1.
  VertexOverBase(Vec3(0.2, 0.3, 1), Vec3(0.2, 0.3, 0), &x0, &x1);
  VertexTriangleHit hit = VertexTriangleCcd(x0, x1, {h});
  ASSERT_TRUE(hit.hit);
  EXPECT_GT(hit.toi, 1 - 1e-12);
  // Stops 1e-9 above it: never coplanar (no collision), but within h (separation) near the end.
  VertexOverBase(Vec3(0.2, 0.3, 1), Vec3(0.2, 0.3, 1e-9), &x0, &x1);
  EXPECT_FALSE(VertexTriangleCcd(x0, x1, {h}).hit);
  hit = VertexTriangleSeparation(x0, x1, {h});
  ASSERT_TRUE(hit.hit);
  EXPECT_NEAR(hit.toi, (1 - h) / (1 - 1e-9), 1e-12);
  // Starts on the face, and starts 1e-12 above it moving down.
  VertexOverBase(Vec3(0.2, 0.3, 0), Vec3(0.2, 0.3, -1), &x0, &x1);
  hit = VertexTriangleCcd(x0, x1, {h});
  ASSERT_TRUE(hit.hit);
  EXPECT_EQ(hit.toi, 0.0);
  EXPECT_NEAR((hit.normal - Vec3(0, 0, 1)).norm(), 0.0, 1e-12);  // against the motion
  VertexOverBase(Vec3(0.2, 0.3, 1e-12), Vec3(0.2, 0.3, -1), &x0, &x1);
  hit = VertexTriangleCcd(x0, x1, {h});
  ASSERT_TRUE(hit.hit);
  EXPECT_LT(hit.toi, 2e-12);
  // Crosses 1e-12 before the end.
  VertexOverBase(Vec3(0.2, 0.3, 1), Vec3(0.2, 0.3, -1e-12), &x0, &x1);
  hit = VertexTriangleCcd(x0, x1, {h});
  ASSERT_TRUE(hit.hit);
  EXPECT_NEAR(hit.toi, 1.0 / (1.0 + 1e-12), 1e-14);
}

// A triangle moving and turning so that its plane touches a vertex's path at t* = 0.4 with the
// vertex inside it (a double root of the cubic), then the vertex moved by `offset` along the
// normal at t*: one side gives two nearby roots (a crossing and back), the other none.
void DoubleRootCase(double offset, CcdPoints* x0, CcdPoints* x1) {
  const double ts = 0.4;
  const Vec3 a0(0, 0, 0), b0(1, 0, 0.3), c0(0, 1, -0.2);
  const Vec3 va(0.1, 0.0, 0.2), vb(-0.2, 0.1, 0.9), vc(0.0, -0.1, -0.6);
  const Vec3 ab = (b0 + ts * vb) - (a0 + ts * va), ac = (c0 + ts * vc) - (a0 + ts * va);
  const Vec3 n = ab.cross(ac);
  const Vec3 dn = (vb - va).cross(ac) + ab.cross(vc - va);  // dN/dt at t*
  const Vec3 rel = 0.3 * ab + 0.3 * ac;                     // the vertex relative to a at t*
  // P'(t*) = dN . rel + N . (vp - va) = 0.
  Vec3 w(0.05, -0.1, 0.02);
  w -= ((w.dot(n) + dn.dot(rel)) / n.squaredNorm()) * n;
  const Vec3 vp = va + w;
  const Vec3 x = a0 + ts * va + rel + offset * n.normalized();
  *x0 = {x - ts * vp, a0, b0, c0};
  *x1 = {x + (1 - ts) * vp, a0 + va, b0 + vb, c0 + vc};
}

TEST(CcdTest, DoubleAndNearlyDoubleRoots) {
  const double h = 1e-6;
  CcdPoints x0, x1;
  // The touch itself (a root of multiplicity two, up to rounding) is a contact.
  DoubleRootCase(0.0, &x0, &x1);
  VertexTriangleHit hit = VertexTriangleCcd(x0, x1, {h});
  ASSERT_TRUE(hit.hit);
  EXPECT_NEAR(hit.toi, 0.4, 1e-6);
  EXPECT_LE(hit.distance_m, h);
  // 1e-9 to either side: exactly one side crosses the plane (twice); the other never reaches it.
  int crossing_sides = 0;
  for (double offset : {1e-9, -1e-9}) {
    DoubleRootCase(offset, &x0, &x1);
    const CoplanarityCubic cubic = MakeCoplanarityCubic(
        x0[2] - x0[1], x1[2] - x1[1], x0[3] - x0[1], x1[3] - x1[1], x0[0] - x0[1], x1[0] - x1[1]);
    const double at = EvaluateCoplanarity(cubic, 0.4).value;
    const double before = EvaluateCoplanarity(cubic, 0.3).value;
    const bool crosses = at * before < 0.0;
    crossing_sides += crosses;
    hit = VertexTriangleCcd(x0, x1, {h});
    EXPECT_EQ(hit.hit, crosses) << offset;
    if (crosses) {
      EXPECT_NEAR(hit.toi, 0.4, 1e-3);
    }
    // Either way the vertex passes within 1e-9 < h of the triangle.
    EXPECT_TRUE(VertexTriangleSeparation(x0, x1, {h}).hit) << offset;
  }
  EXPECT_EQ(crossing_sides, 1);
}

// ---------------------------------------------------------------------------------------------
// Randomized differential test against a sampled reference.
//
// Inputs are dyadic (multiples of 2^-20 in [-2, 2]) and the reference samples times k 2^-m, so
// the sampled positions x0 + t (x1 - x0) are exact and Orient3D gives the exact sign of the exact
// coplanarity P at each sample. The spacing 2^-m is chosen with speed * 2^-m <= h / 4 (speed: the
// Lipschitz constant of the distance), so the distance changes by at most h / 4 between samples.
// The reference then proves (it cannot be wrong) that:
// - a collision must be reported, no later than t_k, when P(t_k) = 0 exactly and d(t_k) <= h;
// - a collision must be reported, no later than t_{k+1}, when P changes sign strictly between t_k
//   and t_{k+1}: an exact root t* lies between, where d(t*) <= (d_k + d_{k+1} + speed dt) / 2;
//   required when that bound is <= h;
// - for the minimal-separation variant: a hit no later than t_k when d(t_k) <= h, and no hit at
//   all when every d_k exceeds h (1 + slack) + speed dt / 2.
// Every reported hit is checked: distance at toi <= h (1 + slack), |P(toi)| within the cubic's
// rounding bound (the collision variant), and nothing the reference proves came earlier.
// ---------------------------------------------------------------------------------------------

double Dyadic20(double v) { return std::ldexp(std::round(std::ldexp(v, 20)), -20); }
Vec3 Dyadic20(const Vec3& v) { return Vec3(Dyadic20(v.x()), Dyadic20(v.y()), Dyadic20(v.z())); }

enum class Kind { kVertexTriangle, kEdgeEdge };

struct Sample {
  double t;
  int sign;  // exact sign of P(t)
  double d;  // distance at t
};

std::vector<Sample> SampleMotion(Kind kind, const CcdPoints& x0, const CcdPoints& x1, double h,
                                 double speed, int* log2_samples) {
  int m = 0;
  while (m < 16 && speed * std::ldexp(1.0, -m) > h / 4) ++m;
  *log2_samples = m;
  std::vector<Sample> out;
  for (int k = 0; k <= (1 << m); ++k) {
    const double t = std::ldexp(k, -m);
    CcdPoints p;
    for (int i = 0; i < 4; ++i) p[i] = x0[i] + t * (x1[i] - x0[i]);  // exact (dyadic)
    Sample s{t, 0, 0.0};
    if (kind == Kind::kVertexTriangle) {
      s.sign = Orient3D(p[1], p[2], p[3], p[0]);
      s.d = std::sqrt(ClosestPointOnTriangle(p[0], p[1], p[2], p[3]).distance_sq);
    } else {
      s.sign = Orient3D(p[0], p[1], p[2], p[3]);
      s.d = std::sqrt(ClosestPointsOfSegments(p[0], p[1], p[2], p[3]).distance_sq);
    }
    out.push_back(s);
  }
  return out;
}

struct Tally {
  int cases = 0;
  int must_hit = 0;
  int misses = 0;
  int late = 0;
  int bad_hits = 0;
  int capped = 0;
  int sep_must_hit = 0;
  int sep_misses = 0;
  int sep_false = 0;
};

void CheckCase(Kind kind, const CcdPoints& x0, const CcdPoints& x1, double h, Tally* tally,
               const std::string& label) {
  const double speed = kind == Kind::kVertexTriangle ? VertexTriangleRelativeSpeed(x0, x1)
                                                     : EdgeEdgeRelativeSpeed(x0, x1);
  int m = 0;
  const std::vector<Sample> ref = SampleMotion(kind, x0, x1, h, speed, &m);
  const double dt = std::ldexp(1.0, -m);
  ASSERT_LE(speed * dt, h / 4) << label << ": motion too fast for the sampled reference";
  const double margin = 1e-12;  // the samples' distances carry rounding errors of ~1e-16 m

  // The earliest time the reference proves a collision must be reported by.
  double must_by = 2.0;
  for (size_t k = 0; k < ref.size() && must_by > 1.0; ++k) {
    if (ref[k].sign == 0 && ref[k].d <= h - margin) must_by = ref[k].t;
    if (k + 1 < ref.size() && ref[k].sign * ref[k + 1].sign < 0 &&
        (ref[k].d + ref[k + 1].d + speed * dt) / 2 <= h - margin) {
      must_by = ref[k + 1].t;
    }
  }
  const CcdOptions options{h};
  double toi = 2.0, distance = 0.0;
  bool hit = false, capped = false;
  CoplanarityCubic cubic;
  if (kind == Kind::kVertexTriangle) {
    const VertexTriangleHit r = VertexTriangleCcd(x0, x1, options);
    hit = r.hit, capped = r.capped, toi = r.toi, distance = r.distance_m;
    cubic = MakeCoplanarityCubic(x0[2] - x0[1], x1[2] - x1[1], x0[3] - x0[1], x1[3] - x1[1],
                                 x0[0] - x0[1], x1[0] - x1[1]);
    if (r.hit) {
      EXPECT_NEAR(r.normal.norm(), 1.0, 1e-9) << label;
      EXPECT_NEAR(r.barycentric.sum(), 1.0, 1e-12) << label;
      EXPECT_GE(r.barycentric.minCoeff(), -1e-12) << label;
    }
  } else {
    const EdgeEdgeHit r = EdgeEdgeCcd(x0, x1, options);
    hit = r.hit, capped = r.capped, toi = r.toi, distance = r.distance_m;
    cubic = MakeCoplanarityCubic(x0[1] - x0[0], x1[1] - x1[0], x0[3] - x0[2], x1[3] - x1[2],
                                 x0[2] - x0[0], x1[2] - x1[0]);
    if (r.hit) {
      EXPECT_NEAR(r.normal.norm(), 1.0, 1e-9) << label;
      EXPECT_TRUE(r.s >= 0 && r.s <= 1 && r.u >= 0 && r.u <= 1) << label;
    }
  }
  ++tally->cases;
  tally->capped += capped;
  if (must_by <= 1.0) {
    ++tally->must_hit;
    if (!hit) {
      ++tally->misses;
      ADD_FAILURE() << label << ": missed a collision the reference proves by t = " << must_by;
    } else if (toi > must_by + 1e-12) {
      ++tally->late;
      ADD_FAILURE() << label << ": reported at " << toi << ", the reference proves one by "
                    << must_by;
    }
  }
  if (hit && !capped) {
    // A real near-contact: within h, and coplanar up to rounding (an interval's first time lies
    // a few time tolerances outside the band |P| <= bound, as P's own evaluation noise (a fraction
    // of the bound) placed it).
    const CubicValue at = EvaluateCoplanarity(cubic, toi);
    const bool ok = distance <= h * (1 + kCcdDistanceSlack) + margin &&
                    std::abs(at.value) <= 1.5 * cubic.error_bound + 1e-13 * std::abs(at.slope);
    if (!ok) {
      ++tally->bad_hits;
      ADD_FAILURE() << label << ": hit at " << toi << " distance " << distance << " P "
                    << EvaluateCoplanarity(cubic, toi).value << " bound " << cubic.error_bound;
    }
  }

  // Minimal separation.
  double sep_by = 2.0, min_d = 1e300;
  for (const Sample& s : ref) {
    if (s.d <= h - margin && sep_by > 1.0) sep_by = s.t;
    min_d = std::min(min_d, s.d);
  }
  bool sep_hit = false;
  double sep_toi = 2.0, sep_distance = 0.0;
  bool sep_capped = false;
  if (kind == Kind::kVertexTriangle) {
    const VertexTriangleHit r = VertexTriangleSeparation(x0, x1, options);
    sep_hit = r.hit, sep_toi = r.toi, sep_distance = r.distance_m, sep_capped = r.capped;
  } else {
    const EdgeEdgeHit r = EdgeEdgeSeparation(x0, x1, options);
    sep_hit = r.hit, sep_toi = r.toi, sep_distance = r.distance_m, sep_capped = r.capped;
  }
  tally->capped += sep_capped;
  if (sep_by <= 1.0) {
    ++tally->sep_must_hit;
    if (!sep_hit || sep_toi > sep_by + 1e-12) {
      ++tally->sep_misses;
      ADD_FAILURE() << label << ": separation missed or late (" << sep_hit << ", " << sep_toi
                    << ") by " << sep_by;
    }
  }
  if (sep_hit && !sep_capped &&
      (sep_distance > h * (1 + kCcdDistanceSlack) + margin ||
       min_d > h * (1 + kCcdDistanceSlack) + speed * dt / 2 + margin)) {
    ++tally->sep_false;
    ADD_FAILURE() << label << ": separation hit at distance " << sep_distance << ", sampled min "
                  << min_d;
  }
  // The collision variant's hits are within h too, so the separation variant hits no later.
  if (hit && !capped && (!sep_hit || sep_toi > toi + 1e-12)) {
    ADD_FAILURE() << label << ": collision at " << toi << " but separation at " << sep_toi;
  }
}

// Random dyadic cases of several kinds, each built around a hard situation.
struct CaseMaker {
  std::mt19937_64 rng;
  double scale = 1.0;  // all positions multiplied by this (a power of two: stays dyadic)
  explicit CaseMaker(uint64_t seed) : rng(seed) {}
  double U(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); }
  Vec3 P(double r) { return Vec3(U(-r, r), U(-r, r), U(-r, r)); }
  Vec3 Unit() {
    std::normal_distribution<double> g(0, 1);
    return Vec3(g(rng), g(rng), g(rng)).normalized();
  }
  // A motion with the configuration `at` (4 points) at time ts and random velocities of size v.
  void Around(const CcdPoints& at, double ts, double v, CcdPoints* x0, CcdPoints* x1) {
    for (int i = 0; i < 4; ++i) {
      const Vec3 vel = P(v);
      (*x0)[i] = Dyadic20(scale * (at[i] - ts * vel));
      (*x1)[i] = Dyadic20(scale * (at[i] + (1 - ts) * vel));
    }
  }
};

// Projects all eight positions onto a random plane through the origin, then rounds them: the
// motion is coplanar up to the 2^-20 grid (the cubic small but not zero).
void FlattenOntoTiltedPlane(CaseMaker* mk, CcdPoints* x0, CcdPoints* x1) {
  const Vec3 n = mk->Unit();
  for (CcdPoints* x : {x0, x1}) {
    for (Vec3& p : *x) p = Dyadic20(Vec3(p - p.dot(n) * n));
  }
}

void MakeVertexTriangleCase(int kind, double h, CaseMaker* mk, CcdPoints* x0, CcdPoints* x1) {
  CaseMaker& m = *mk;
  const double ts = kind == 6 ? (m.U(0, 1) < 0.5 ? 0.0 : 1.0) : m.U(0, 1);
  CcdPoints at = {m.P(0.5), m.P(0.5), m.P(0.5), m.P(0.5)};
  double w1 = m.U(0, 1), w2 = m.U(0, 1);
  if (w1 + w2 > 1) w1 = 1 - w1, w2 = 1 - w2;
  switch (kind) {
    case 0:  // random
      m.Around(at, ts, 0.6, x0, x1);
      return;
    case 1:  // the vertex on the triangle at ts (inside, on an edge or at a corner)
    case 6:  // ... at t = 0 or t = 1
      if (m.U(0, 1) < 0.2) w2 = 0;
      if (m.U(0, 1) < 0.1) w1 = 0;
      at[0] = at[1] + w1 * (at[2] - at[1]) + w2 * (at[3] - at[1]);
      m.Around(at, ts, 0.6, x0, x1);
      return;
    case 2:  // near miss: a random offset of up to 2 h from the triangle at ts
      at[0] = at[1] + w1 * (at[2] - at[1]) + w2 * (at[3] - at[1]) + m.U(0, 2 * h) * m.Unit();
      m.Around(at, ts, 0.6, x0, x1);
      return;
    case 3:  // coplanar motion in z = 0 (the cubic is exactly zero)
      m.Around(at, ts, 0.6, x0, x1);
      for (int i = 0; i < 4; ++i) (*x0)[i].z() = (*x1)[i].z() = 0.0;
      return;
    case 4:  // degenerate triangle: c the midpoint of a and b (or equal to a) throughout
      at[0] = at[1] + w1 * (at[2] - at[1]);
      m.Around(at, ts, 0.6, x0, x1);
      for (CcdPoints* x : {x0, x1}) {
        (*x)[3] = m.U(0, 1) < 0.5 ? Vec3((*x)[1]) : Vec3(0.5 * ((*x)[1] + (*x)[2]));
      }
      if ((*x0)[3] != (*x0)[1] && (*x1)[3] == (*x1)[1]) (*x1)[3] = 0.5 * ((*x1)[1] + (*x1)[2]);
      if ((*x0)[3] == (*x0)[1] && (*x1)[3] != (*x1)[1]) (*x1)[3] = (*x1)[1];
      return;
    case 7:  // nearly coplanar: everything in a tilted plane through the origin, rounded
      m.Around(at, ts, 0.6, x0, x1);
      FlattenOntoTiltedPlane(mk, x0, x1);
      return;
    case 5:  // small and far: the configuration at 1/64 of the size, offset by (1, 1, 1)
    default: {
      at[0] = at[1] + w1 * (at[2] - at[1]) + w2 * (at[3] - at[1]);
      m.Around(at, ts, 0.6, x0, x1);
      for (int i = 0; i < 4; ++i) {
        (*x0)[i] = Dyadic20((*x0)[i] / 64 + Vec3(1, 1, 1));
        (*x1)[i] = Dyadic20((*x1)[i] / 64 + Vec3(1, 1, 1));
      }
      return;
    }
  }
}

void MakeEdgeEdgeCase(int kind, double h, CaseMaker* mk, CcdPoints* x0, CcdPoints* x1) {
  CaseMaker& m = *mk;
  const double ts = kind == 6 ? (m.U(0, 1) < 0.5 ? 0.0 : 1.0) : m.U(0, 1);
  CcdPoints at = {m.P(0.5), m.P(0.5), m.P(0.5), m.P(0.5)};
  const double s = m.U(0, 1) < 0.15 ? 1.0 : m.U(0, 1);
  const double u = m.U(0, 1) < 0.15 ? 0.0 : m.U(0, 1);
  const Vec3 x = at[0] + s * (at[1] - at[0]);
  const Vec3 dir = m.P(0.5);
  switch (kind) {
    case 0:  // random
      m.Around(at, ts, 0.6, x0, x1);
      return;
    case 1:  // the edges meet at ts
    case 6:  // ... at t = 0 or t = 1
      at[2] = x - u * dir, at[3] = x + (1 - u) * dir;
      m.Around(at, ts, 0.6, x0, x1);
      return;
    case 2: {  // near miss by up to 2 h
      const Vec3 off = m.U(0, 2 * h) * m.Unit();
      at[2] = x - u * dir + off, at[3] = x + (1 - u) * dir + off;
      m.Around(at, ts, 0.6, x0, x1);
      return;
    }
    case 3:  // coplanar motion in z = 0
      m.Around(at, ts, 0.6, x0, x1);
      for (int i = 0; i < 4; ++i) (*x0)[i].z() = (*x1)[i].z() = 0.0;
      return;
    case 4: {  // parallel edges throughout (f = e scaled and moved), or e of zero length
      m.Around(at, ts, 0.6, x0, x1);
      const double k = m.U(0, 1) < 0.5 ? 0.5 : 2.0;
      const bool point = m.U(0, 1) < 0.3;
      for (CcdPoints* y : {x0, x1}) {
        if (point) {
          (*y)[1] = (*y)[0];
        } else {
          (*y)[3] = Dyadic20((*y)[2] + k * ((*y)[1] - (*y)[0]));
        }
      }
      return;
    }
    case 7:  // nearly coplanar: everything in a tilted plane through the origin, rounded
      m.Around(at, ts, 0.6, x0, x1);
      FlattenOntoTiltedPlane(mk, x0, x1);
      return;
    case 5:  // small and far
    default:
      at[2] = x - u * dir, at[3] = x + (1 - u) * dir;
      m.Around(at, ts, 0.6, x0, x1);
      for (int i = 0; i < 4; ++i) {
        (*x0)[i] = Dyadic20((*x0)[i] / 64 + Vec3(1, 1, 1));
        (*x1)[i] = Dyadic20((*x1)[i] / 64 + Vec3(1, 1, 1));
      }
      return;
  }
}

void RunDifferential(Kind kind, int per_kind, uint64_t seed) {
  CaseMaker maker(seed);
  Tally tally;
  const char* name = kind == Kind::kVertexTriangle ? "vertex-triangle" : "edge-edge";
  for (int k = 0; k < 8; ++k) {
    for (int i = 0; i < per_kind; ++i) {
      const double h = std::ldexp(1.0, -6 - (i % 3) * 2);  // 1/64, 1/256, 1/1024
      const double hk = k == 5 ? h / 64 : h;               // the small cases scale h too
      CcdPoints x0, x1;
      if (kind == Kind::kVertexTriangle) {
        MakeVertexTriangleCase(k, hk, &maker, &x0, &x1);
      } else {
        MakeEdgeEdgeCase(k, hk, &maker, &x0, &x1);
      }
      CheckCase(kind, x0, x1, hk, &tally,
                std::string(name) + " kind " + std::to_string(k) + " case " + std::to_string(i));
      if (::testing::Test::HasFailure()) return;
    }
  }
  // Zero misses, and the reference demanded plenty of hits.
  EXPECT_EQ(tally.misses, 0);
  EXPECT_EQ(tally.late, 0);
  EXPECT_EQ(tally.bad_hits, 0);
  EXPECT_EQ(tally.sep_misses, 0);
  EXPECT_EQ(tally.sep_false, 0);
  // A capped report (the advancement's step cap, on a long oblique approach toward h) is a
  // conservative hit before any contact (checked above as never late); it must stay rare.
  EXPECT_LE(tally.capped, tally.cases / 200);
  EXPECT_GT(tally.must_hit, tally.cases / 5);
  EXPECT_GT(tally.sep_must_hit, tally.cases / 4);
  std::printf(
      "%s: %d cases, %d collisions proven by the reference (%d missed), %d separation "
      "hits proven (%d missed), %d capped\n",
      name, tally.cases, tally.must_hit, tally.misses, tally.sep_must_hit, tally.sep_misses,
      tally.capped);
}

// 250 cases of each kind (60 under a sanitizer, tests/test_env.h: the same code paths).
int32_t CasesPerKind() { return testing::Sanitized() ? 60 : 250; }

TEST(CcdTest, VertexTriangleNeverMissesAgainstSampledReference) {
  RunDifferential(Kind::kVertexTriangle, CasesPerKind(), 2201);
}

TEST(CcdTest, EdgeEdgeNeverMissesAgainstSampledReference) {
  RunDifferential(Kind::kEdgeEdge, CasesPerKind(), 2202);
}

}  // namespace
}  // namespace felt
