// Closed forms and brute-force checks for the point/sphere-triangle kernels.
#include "collision/geometry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace felt {
namespace {

const Vec3 kA(0, 0, 0), kB(1, 0, 0), kC(0, 1, 0);

TEST(GeometryTest, ClosestPointRegionsHaveClosedForms) {
  // Face: straight below.
  TrianglePoint cp = ClosestPointOnTriangle(Vec3(0.2, 0.3, 0.7), kA, kB, kC);
  EXPECT_NEAR((cp.point - Vec3(0.2, 0.3, 0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((cp.barycentric - Vec3(0.5, 0.2, 0.3)).norm(), 0.0, 1e-15);
  EXPECT_NEAR(cp.distance_sq, 0.49, 1e-15);
  // Vertex a, b, c regions.
  EXPECT_EQ(ClosestPointOnTriangle(Vec3(-1, -2, 3), kA, kB, kC).barycentric, Vec3(1, 0, 0));
  EXPECT_EQ(ClosestPointOnTriangle(Vec3(3, -0.5, 1), kA, kB, kC).barycentric, Vec3(0, 1, 0));
  EXPECT_EQ(ClosestPointOnTriangle(Vec3(-0.1, 4, 0), kA, kB, kC).barycentric, Vec3(0, 0, 1));
  // Edge ab, ac, bc regions.
  cp = ClosestPointOnTriangle(Vec3(0.25, -2, 1), kA, kB, kC);
  EXPECT_NEAR((cp.barycentric - Vec3(0.75, 0.25, 0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR(cp.distance_sq, 5.0, 1e-15);
  cp = ClosestPointOnTriangle(Vec3(-3, 0.6, 0), kA, kB, kC);
  EXPECT_NEAR((cp.barycentric - Vec3(0.4, 0, 0.6)).norm(), 0.0, 1e-15);
  cp = ClosestPointOnTriangle(Vec3(1, 1, 0), kA, kB, kC);
  EXPECT_NEAR((cp.point - Vec3(0.5, 0.5, 0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR(cp.distance_sq, 0.5, 1e-15);
}

TEST(GeometryTest, ClosestPointBeatsDenseSamplingOnRandomAndDegenerateTriangles) {
  std::mt19937_64 rng(1);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int k = 0; k < 300; ++k) {
    Vec3 a(g(rng), g(rng), g(rng)), b(g(rng), g(rng), g(rng)), c(g(rng), g(rng), g(rng));
    if (k % 3 == 1) c = a + 0.37 * (b - a);  // collinear
    if (k % 3 == 2) b = a;                   // repeated vertex
    if (k % 30 == 2) c = a;                  // a single point
    const Vec3 p(g(rng), g(rng), g(rng));
    const TrianglePoint cp = ClosestPointOnTriangle(p, a, b, c);
    // Consistent outputs: barycentrics valid and reproduce the point.
    EXPECT_GE(cp.barycentric.minCoeff(), -1e-12);
    EXPECT_NEAR(cp.barycentric.sum(), 1.0, 1e-12);
    const Vec3 from_bary = cp.barycentric[0] * a + cp.barycentric[1] * b + cp.barycentric[2] * c;
    EXPECT_NEAR((from_bary - cp.point).norm(), 0.0, 1e-12);
    EXPECT_NEAR((p - cp.point).squaredNorm(), cp.distance_sq, 1e-12);
    // No sampled point of the triangle is nearer.
    const int n = 60;
    double best = 1e300;
    for (int i = 0; i <= n; ++i)
      for (int j = 0; i + j <= n; ++j) {
        const Vec3 q = a + (b - a) * (double(i) / n) + (c - a) * (double(j) / n);
        best = std::min(best, (p - q).squaredNorm());
      }
    EXPECT_LE(cp.distance_sq, best + 1e-12) << k;
    EXPECT_GE(cp.distance_sq, best - 0.05) << k;  // and sampling gets close to it
  }
}

TEST(GeometryTest, SweepHitsFaceEdgeAndVertexAtClosedFormTimes) {
  const double r = 0.1;
  // Face: straight down from z = 1 to z = -1: touches at z = r, t = (1 - r) / 2.
  SweepContact h = SweepSphereTriangle(Vec3(0.2, 0.2, 1), Vec3(0.2, 0.2, -1), r, kA, kB, kC);
  ASSERT_TRUE(h.hit);
  EXPECT_NEAR(h.toi, (1 - r) / 2, 1e-15);
  EXPECT_NEAR((h.normal - Vec3(0, 0, 1)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((h.point - Vec3(0.2, 0.2, 0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((h.barycentric - Vec3(0.6, 0.2, 0.2)).norm(), 0.0, 1e-15);
  // Edge ab from -y, in the plane: centre reaches y = -r at t = (1 - r) / 2.
  h = SweepSphereTriangle(Vec3(0.5, -1, 0), Vec3(0.5, 1, 0), r, kA, kB, kC);
  ASSERT_TRUE(h.hit);
  EXPECT_NEAR(h.toi, (1 - r) / 2, 1e-15);
  EXPECT_NEAR((h.normal - Vec3(0, -1, 0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((h.barycentric - Vec3(0.5, 0.5, 0)).norm(), 0.0, 1e-15);
  // Edge bc at 45 degrees above the plane: distance to the line x + y = 1, z = 0.
  const Vec3 out_dir = Vec3(1, 1, 1).normalized();
  const Vec3 mid(0.5, 0.5, 0);
  h = SweepSphereTriangle(mid + 2 * out_dir, mid - 2 * out_dir, r, kA, kB, kC);
  ASSERT_TRUE(h.hit);
  // The line passes through the edge point perpendicular to bc, so contact at distance r.
  EXPECT_NEAR(h.toi, (2 - r) / 4, 1e-14);
  // Vertex c approached along +y from above: |p(t) - c| = r.
  h = SweepSphereTriangle(Vec3(0, 3, 0.05), Vec3(0, 1, 0.05), r, kA, kB, kC);
  ASSERT_TRUE(h.hit);
  const double dy = std::sqrt(r * r - 0.05 * 0.05);
  EXPECT_NEAR(h.toi, (2 - dy) / 2, 1e-14);
  EXPECT_EQ(h.barycentric, Vec3(0, 0, 1));
  // Misses.
  EXPECT_FALSE(SweepSphereTriangle(Vec3(2, 2, 1), Vec3(2, 2, -1), r, kA, kB, kC).hit);
  EXPECT_FALSE(SweepSphereTriangle(Vec3(0.2, 0.2, 1), Vec3(0.2, 0.2, 0.2), r, kA, kB, kC).hit);
}

TEST(GeometryTest, SweepConventionForRestingAndOverlappingSpheres) {
  const double r = 0.1;
  const Vec3 rest(0.3, 0.3, r);
  // Resting at r: tangential and outward motion free, inward motion blocked at 0.
  EXPECT_FALSE(SweepSphereTriangle(rest, rest + Vec3(0.1, 0.05, 0), r, kA, kB, kC).hit);
  EXPECT_FALSE(SweepSphereTriangle(rest, rest + Vec3(0, 0, 0.5), r, kA, kB, kC).hit);
  EXPECT_FALSE(SweepSphereTriangle(rest, rest, r, kA, kB, kC).hit);
  SweepContact h = SweepSphereTriangle(rest, rest + Vec3(0.1, 0, -1e-6), r, kA, kB, kC);
  ASSERT_TRUE(h.hit);
  EXPECT_EQ(h.toi, 0.0);
  EXPECT_NEAR((h.normal - Vec3(0, 0, 1)).norm(), 0.0, 1e-15);
  // Deep overlap from below, moving further in: toi 0, normal toward the start side (-z).
  h = SweepSphereTriangle(Vec3(0.3, 0.3, -0.02), Vec3(0.3, 0.3, 0.5), r, kA, kB, kC);
  ASSERT_TRUE(h.hit);
  EXPECT_EQ(h.toi, 0.0);
  EXPECT_NEAR((h.normal - Vec3(0, 0, -1)).norm(), 0.0, 1e-15);
  // Centre exactly on the face: the normal opposes the motion.
  h = SweepSphereTriangle(Vec3(0.3, 0.3, 0), Vec3(0.3, 0.3, 0.5), r, kA, kB, kC);
  ASSERT_TRUE(h.hit);
  EXPECT_NEAR((h.normal - Vec3(0, 0, -1)).norm(), 0.0, 1e-15);
  // Resting beside an edge (in the plane) and sliding along it: free.
  EXPECT_FALSE(SweepSphereTriangle(Vec3(0.2, -r, 0), Vec3(0.9, -r, 0), r, kA, kB, kC).hit);
}

TEST(GeometryTest, SweepMatchesFineSamplingOnRandomCases) {
  // The reported toi has distance r, and no earlier sample is closer than r (no tunnelling).
  std::mt19937_64 rng(2);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int hits = 0;
  for (int k = 0; k < 400; ++k) {
    const Vec3 a(g(rng), g(rng), 0.1 * g(rng)), b(g(rng), g(rng), 0.1 * g(rng));
    const Vec3 c = k % 10 == 0 ? Vec3(a) : Vec3(g(rng), g(rng), 0.1 * g(rng));
    const Vec3 p0(g(rng), g(rng), 2 + g(rng)), p1(g(rng), g(rng), -2 + g(rng));
    const double r = 0.3 * u(rng);
    const SweepContact h = SweepSphereTriangle(p0, p1, r, a, b, c);
    const int n = 4000;
    double first = -1;
    for (int i = 0; i <= n; ++i) {
      const double t = double(i) / n;
      if (ClosestPointOnTriangle(p0 + t * (p1 - p0), a, b, c).distance_sq < r * r) {
        first = t;
        break;
      }
    }
    if (first >= 0) {
      ASSERT_TRUE(h.hit) << k;
      EXPECT_LE(h.toi, first + 1e-12) << k;
      EXPECT_GE(h.toi, first - 1.0 / n - 1e-12) << k;
    }
    if (h.hit) {
      ++hits;
      const Vec3 at = p0 + h.toi * (p1 - p0);
      EXPECT_NEAR(std::sqrt(ClosestPointOnTriangle(at, a, b, c).distance_sq), r, 1e-9) << k;
      EXPECT_NEAR(h.normal.norm(), 1.0, 1e-12);
      EXPECT_LT(h.normal.dot(p1 - p0), 0.0);
    }
  }
  EXPECT_GT(hits, 60);
}

TEST(GeometryTest, MovingTriangleMatchesClosedFormAndFineSampling) {
  // A triangle rising at 1 m per unit t into a static sphere at height 0.5: contact at 0.5 - r.
  const double r = 0.1;
  const Vec3 up(0, 0, 1);
  SweepContact h = MovingTriangleSphereContact(Vec3(0.2, 0.2, 0.5), Vec3(0.2, 0.2, 0.5), r, kA, kB,
                                               kC, kA + up, kB + up, kC + up);
  ASSERT_TRUE(h.hit);
  EXPECT_NEAR(h.toi, 0.4, 1e-6);
  EXPECT_NEAR((h.normal - Vec3(0, 0, 1)).norm(), 0.0, 1e-9);
  // The sphere moving down with the triangle moving up: they meet twice as fast.
  h = MovingTriangleSphereContact(Vec3(0.2, 0.2, 0.5), Vec3(0.2, 0.2, -0.5), r, kA, kB, kC, kA + up,
                                  kB + up, kC + up);
  ASSERT_TRUE(h.hit);
  EXPECT_NEAR(h.toi, 0.2, 1e-6);
  // Overlapping at t = 0 and separating: no contact; approaching: toi 0.
  EXPECT_FALSE(MovingTriangleSphereContact(Vec3(0.2, 0.2, 0.05), Vec3(0.2, 0.2, 0.05), r, kA, kB,
                                           kC, kA - up, kB - up, kC - up)
                   .hit);
  h = MovingTriangleSphereContact(Vec3(0.2, 0.2, 0.05), Vec3(0.2, 0.2, 0.05), r, kA, kB, kC,
                                  kA + up, kB + up, kC + up);
  ASSERT_TRUE(h.hit);
  EXPECT_EQ(h.toi, 0.0);

  // Random rotating and moving triangles against fine sampling.
  std::mt19937_64 rng(3);
  std::normal_distribution<double> g(0.0, 1.0);
  const MovingContactOptions opts;
  int hits = 0;
  for (int k = 0; k < 300; ++k) {
    const Vec3 a0(g(rng), g(rng), -1 + 0.2 * g(rng)), b0(g(rng), g(rng), -1 + 0.2 * g(rng)),
        c0v(g(rng), g(rng), -1 + 0.2 * g(rng));
    const Vec3 a1 = a0 + Vec3(0.3 * g(rng), 0.3 * g(rng), 2 + 0.3 * g(rng));
    const Vec3 b1 = b0 + Vec3(0.3 * g(rng), 0.3 * g(rng), 2 + 0.3 * g(rng));
    const Vec3 c1v = c0v + Vec3(0.3 * g(rng), 0.3 * g(rng), 2 + 0.3 * g(rng));
    const Vec3 s0(0.5 * g(rng), 0.5 * g(rng), 0.2 * g(rng));
    const Vec3 s1 = s0 + 0.3 * Vec3(g(rng), g(rng), g(rng));
    const double rr = 0.05 + 0.1 * std::abs(g(rng));
    const auto dist_at = [&](double t) {
      return std::sqrt(ClosestPointOnTriangle(s0 + t * (s1 - s0), a0 + t * (a1 - a0),
                                              b0 + t * (b1 - b0), c0v + t * (c1v - c0v))
                           .distance_sq);
    };
    const SweepContact m = MovingTriangleSphereContact(s0, s1, rr, a0, b0, c0v, a1, b1, c1v, opts);
    const int n = 5000;
    double first = -1;
    for (int i = 0; i <= n; ++i) {
      if (dist_at(double(i) / n) <= rr) {
        first = double(i) / n;
        break;
      }
    }
    if (first > 0) {
      ASSERT_TRUE(m.hit) << k;
      EXPECT_LE(m.toi, first + 1e-12) << k;  // never later than the first sampled contact
    }
    if (m.hit) {
      ++hits;
      EXPECT_LE(dist_at(m.toi), rr + opts.tolerance_m + 1e-12) << k;
      // No contact before toi: every earlier sample is farther than r.
      for (int i = 0; double(i) / n < m.toi; ++i) ASSERT_GT(dist_at(double(i) / n), rr) << k;
    }
  }
  EXPECT_GT(hits, 60);
}

}  // namespace
}  // namespace felt
