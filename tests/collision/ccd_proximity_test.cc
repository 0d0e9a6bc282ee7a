// Segment-segment closest points: closed forms (crossing, skew, parallel, collinear, zero-length,
// nearly parallel) and a dense-sampling bound on random and degenerate segments.
#include "collision/ccd_proximity.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace felt {
namespace {

void ExpectConsistent(const SegmentsClosest& c, const Vec3& p0, const Vec3& p1, const Vec3& q0,
                      const Vec3& q1) {
  EXPECT_GE(c.s, 0.0);
  EXPECT_LE(c.s, 1.0);
  EXPECT_GE(c.u, 0.0);
  EXPECT_LE(c.u, 1.0);
  EXPECT_NEAR((c.point_a - (p0 + c.s * (p1 - p0))).norm(), 0.0, 1e-15);
  EXPECT_NEAR((c.point_b - (q0 + c.u * (q1 - q0))).norm(), 0.0, 1e-15);
  EXPECT_NEAR(c.distance_sq, (c.point_a - c.point_b).squaredNorm(), 1e-15);
}

TEST(CcdProximityTest, SegmentClosedForms) {
  // Crossing at their midpoints.
  SegmentsClosest c =
      ClosestPointsOfSegments(Vec3(0, 0, 0), Vec3(2, 2, 0), Vec3(0, 2, 0), Vec3(2, 0, 0));
  EXPECT_NEAR(c.distance_sq, 0.0, 1e-30);
  EXPECT_NEAR(c.s, 0.5, 1e-15);
  EXPECT_NEAR(c.u, 0.5, 1e-15);
  // Skew and perpendicular, 0.3 apart, at s = 0.25 and u = 0.75.
  c = ClosestPointsOfSegments(Vec3(0, 0, 0), Vec3(4, 0, 0), Vec3(1, -3, 0.3), Vec3(1, 1, 0.3));
  EXPECT_NEAR(std::sqrt(c.distance_sq), 0.3, 1e-15);
  EXPECT_NEAR(c.s, 0.25, 1e-15);
  EXPECT_NEAR(c.u, 0.75, 1e-15);
  // The closest point beyond an end: clamped.
  c = ClosestPointsOfSegments(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(3, -1, 1), Vec3(3, 1, 1));
  EXPECT_NEAR(c.distance_sq, 4.0 + 1.0, 1e-14);
  EXPECT_EQ(c.s, 1.0);
  EXPECT_NEAR(c.u, 0.5, 1e-15);
  // Parallel, overlapping: distance 0.5 wherever they overlap.
  const Vec3 p0(0, 0, 0), p1(2, 0, 0), q0(1, 0.5, 0), q1(3, 0.5, 0);
  c = ClosestPointsOfSegments(p0, p1, q0, q1);
  EXPECT_NEAR(c.distance_sq, 0.25, 1e-15);
  ExpectConsistent(c, p0, p1, q0, q1);
  // Parallel, disjoint end to end, and collinear overlapping.
  c = ClosestPointsOfSegments(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(3, 0, 0), Vec3(5, 0, 0));
  EXPECT_NEAR(c.distance_sq, 4.0, 1e-15);
  EXPECT_EQ(c.s, 1.0);
  EXPECT_EQ(c.u, 0.0);
  c = ClosestPointsOfSegments(Vec3(0, 0, 0), Vec3(2, 0, 0), Vec3(5, 0, 0), Vec3(1, 0, 0));
  EXPECT_EQ(c.distance_sq, 0.0);
  // Zero-length segments: point to segment, point to point.
  c = ClosestPointsOfSegments(Vec3(1, 1, 0), Vec3(1, 1, 0), Vec3(0, 0, 0), Vec3(2, 0, 0));
  EXPECT_NEAR(c.distance_sq, 1.0, 1e-15);
  EXPECT_NEAR(c.u, 0.5, 1e-15);
  c = ClosestPointsOfSegments(Vec3(1, 1, 0), Vec3(1, 1, 0), Vec3(1, 2, 0), Vec3(1, 2, 0));
  EXPECT_NEAR(c.distance_sq, 1.0, 1e-15);
}

TEST(CcdProximityTest, NearlyParallelCrossingSegmentsMeet) {
  // Two unit segments crossing at their midpoints at angles down to 1e-9 rad: the distance is 0
  // (a boundary-only answer would be about half the angle).
  for (double angle : {1e-3, 1e-5, 1e-7, 1e-9}) {
    const Vec3 d(std::cos(angle), std::sin(angle), 0.0);
    const Vec3 c0(0.3, 0.2, 0.1);
    const SegmentsClosest c = ClosestPointsOfSegments(c0 - Vec3(0.5, 0, 0), c0 + Vec3(0.5, 0, 0),
                                                      c0 - 0.5 * d, c0 + 0.5 * d);
    EXPECT_LT(std::sqrt(c.distance_sq), 1e-12) << angle;
  }
}

TEST(CcdProximityTest, BeatsDenseSamplingOnRandomAndDegenerateSegments) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int k = 0; k < 400; ++k) {
    Vec3 p0(g(rng), g(rng), g(rng)), p1(g(rng), g(rng), g(rng));
    Vec3 q0(g(rng), g(rng), g(rng)), q1(g(rng), g(rng), g(rng));
    if (k % 5 == 1) q1 = q0 + 0.7 * (p1 - p0);                              // parallel
    if (k % 5 == 2) q1 = q0 + (p1 - p0) + 1e-9 * Vec3(g(rng), g(rng), 0);   // nearly parallel
    if (k % 5 == 3) p1 = p0;                                                // a point
    if (k % 10 == 4) q0 = p0 + 0.5 * (p1 - p0), q1 = p0 + 2.0 * (p1 - p0);  // collinear
    const SegmentsClosest c = ClosestPointsOfSegments(p0, p1, q0, q1);
    ExpectConsistent(c, p0, p1, q0, q1);
    const int n = 200;
    double best = 1e300;
    for (int i = 0; i <= n; ++i) {
      for (int j = 0; j <= n; ++j) {
        const Vec3 a = p0 + (p1 - p0) * (double(i) / n);
        const Vec3 b = q0 + (q1 - q0) * (double(j) / n);
        best = std::min(best, (a - b).squaredNorm());
      }
    }
    EXPECT_LE(c.distance_sq, best + 1e-12) << k;
    EXPECT_GE(c.distance_sq, best - 0.05) << k;
  }
}

}  // namespace
}  // namespace felt
