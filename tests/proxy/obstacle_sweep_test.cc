// The proxy's obstacle geometry (proxy/obstacle_sweep.h) against closed forms, and against a
// slow sampled reference on thousands of random motions.
#include "proxy/obstacle_sweep.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "tests/proxy/proxy_test_util.h"

namespace felt {
namespace {

using testing::Box;
using testing::Capsule;
using testing::Plane;
using testing::Sphere;
using testing::Table;

void ExpectVecNear(const Vec3& a, const Vec3& b, double tol) {
  EXPECT_NEAR((a - b).norm(), 0.0, tol) << "got " << a.transpose() << ", want " << b.transpose();
}

TEST(ObstacleSweepTest, ContactIdsAreNegativeAndInvertible) {
  for (int32_t k = 0; k < 100; ++k) {
    EXPECT_LT(ObstacleContactId(k), 0);
    EXPECT_TRUE(IsObstacleContactId(ObstacleContactId(k)));
    EXPECT_EQ(ObstacleIndexOf(ObstacleContactId(k)), k);
  }
  EXPECT_FALSE(IsObstacleContactId(0));
}

TEST(ObstacleSweepTest, ClosestPointOfEachShape) {
  // Box, outside at a corner region, outside at a face, inside (the nearest face).
  ObstaclePoint p = ClosestObstaclePoint(Table(), Vec3(0.4, 0.1, 0.3));
  ExpectVecNear(p.point_W_m, Vec3(0.3, 0.0, 0.2), 1e-15);
  ExpectVecNear(p.normal_W, Vec3(1, 1, 1).normalized(), 1e-15);
  EXPECT_NEAR(p.distance_m, std::sqrt(0.03), 1e-15);
  p = ClosestObstaclePoint(Table(), Vec3(0.1, 0.02, 0.0));
  ExpectVecNear(p.point_W_m, Vec3(0.1, 0.0, 0.0), 1e-15);
  ExpectVecNear(p.normal_W, Vec3::UnitY(), 0.0);
  p = ClosestObstaclePoint(Table(), Vec3(0.1, -0.01, 0.0));
  EXPECT_NEAR(p.distance_m, -0.01, 1e-15);
  ExpectVecNear(p.point_W_m, Vec3(0.1, 0.0, 0.0), 1e-15);
  // Capsule: radial from the axis; sphere; a tilted plane.
  p = ClosestObstaclePoint(Capsule(Vec3(-0.1, 0, 0), Vec3(0.1, 0, 0), 0.03), Vec3(0.05, 0, 0.1));
  ExpectVecNear(p.point_W_m, Vec3(0.05, 0, 0.03), 1e-15);
  EXPECT_NEAR(p.distance_m, 0.07, 1e-15);
  p = ClosestObstaclePoint(Sphere(Vec3(1, 2, 3), 0.5), Vec3(1, 2, 5));
  ExpectVecNear(p.point_W_m, Vec3(1, 2, 3.5), 1e-15);
  const Vec3 n = Vec3(1, 1, 0).normalized();
  p = ClosestObstaclePoint(Plane(Vec3::Zero(), n), Vec3(1, 0, 0));
  EXPECT_NEAR(p.distance_m, std::sqrt(0.5), 1e-15);
  ExpectVecNear(p.point_W_m, Vec3(0.5, -0.5, 0), 1e-15);
}

TEST(ObstacleSweepTest, SphereOntoPlaneHasTheExactTimeOfImpact) {
  // Falling 0.2 m onto y = 0 with r = 0.01: contact when the centre is at y = r, t = 0.09 / 0.2.
  const SweepContact c = SweepSphereObstacle(Vec3(0, 0.1, 0), Vec3(0, -0.1, 0), 0.01,
                                             Plane(Vec3::Zero(), Vec3::UnitY()));
  ASSERT_TRUE(c.hit);
  EXPECT_DOUBLE_EQ(c.toi, 0.45);
  ExpectVecNear(c.point, Vec3::Zero(), 1e-15);
  ExpectVecNear(c.normal, Vec3::UnitY(), 0.0);
  // Tilted plane, oblique motions: t = (d0 - r) / -(n . d).
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 1000; ++i) {
    const Vec3 n = Vec3(u(rng), u(rng), u(rng)).normalized();
    const Vec3 q(u(rng), u(rng), u(rng));
    const Vec3 p0 = q + n * (0.2 + 0.1 * std::abs(u(rng))) + 0.3 * Vec3(u(rng), u(rng), u(rng));
    const Vec3 p1 = p0 + Vec3(u(rng), u(rng), u(rng));
    const double r = 0.01;
    const double d0 = n.dot(p0 - q);
    const double dn = n.dot(p1 - p0);
    const SweepContact s = SweepSphereObstacle(p0, p1, r, Plane(q, n));
    if (d0 <= r) {
      // Starting in contact: a contact at once only when moving in.
      ASSERT_EQ(s.hit, dn < -kApproachCos * (p1 - p0).norm()) << i;
      if (s.hit) {
        EXPECT_EQ(s.toi, 0.0) << i;
      }
      continue;
    }
    const bool expect = dn < 0.0 && (d0 - r) / -dn <= 1.0;
    ASSERT_EQ(s.hit, expect) << i;
    if (expect) {
      EXPECT_NEAR(s.toi, (d0 - r) / -dn, 1e-12);
    }
  }
}

TEST(ObstacleSweepTest, TouchingSphereSlidesButIsStoppedWhenPushedIn) {
  const ObstacleSpec floor = Plane(Vec3::Zero(), Vec3::UnitY());
  const double r = 0.004;
  // Resting at y = r: sliding along the plane and leaving are free; pushing in hits at once.
  EXPECT_FALSE(SweepSphereObstacle(Vec3(0, r, 0), Vec3(1, r, 0), r, floor).hit);
  EXPECT_FALSE(SweepSphereObstacle(Vec3(0, r, 0), Vec3(0, 1, 0), r, floor).hit);
  const SweepContact in = SweepSphereObstacle(Vec3(0, r, 0), Vec3(0.1, -0.1, 0), r, floor);
  ASSERT_TRUE(in.hit);
  EXPECT_EQ(in.toi, 0.0);
  // The same on a box's top face and on a sphere.
  EXPECT_FALSE(SweepSphereObstacle(Vec3(0, r, 0), Vec3(0.1, r, 0.1), r, Table()).hit);
  EXPECT_TRUE(SweepSphereObstacle(Vec3(0, r, 0), Vec3(0, 0, 0), r, Table()).hit);
  EXPECT_FALSE(
      SweepSphereObstacle(Vec3(0, 0.1 + r, 0), Vec3(0, 0.2, 0), r, Sphere(Vec3::Zero(), 0.1)).hit);
}

TEST(ObstacleSweepTest, SphereOntoSphere) {
  // Centre to centre along -x: contact at distance R + r.
  const SweepContact c =
      SweepSphereObstacle(Vec3(0.5, 0, 0), Vec3(-0.5, 0, 0), 0.02, Sphere(Vec3::Zero(), 0.1));
  ASSERT_TRUE(c.hit);
  EXPECT_NEAR(c.toi, 0.38, 1e-15);
  ExpectVecNear(c.point, Vec3(0.1, 0, 0), 1e-15);
  ExpectVecNear(c.normal, Vec3::UnitX(), 1e-15);
  // Offset by h from the centre line: the entry is sqrt((R + r)^2 - h^2) before the centre.
  const double h = 0.05;
  const SweepContact o =
      SweepSphereObstacle(Vec3(0.5, h, 0), Vec3(-0.5, h, 0), 0.02, Sphere(Vec3::Zero(), 0.1));
  ASSERT_TRUE(o.hit);
  EXPECT_NEAR(o.toi, 0.5 - std::sqrt(0.12 * 0.12 - h * h), 1e-15);
  // Passing at R + r + 1 mm: no contact.
  EXPECT_FALSE(SweepSphereObstacle(Vec3(0.5, 0.121, 0), Vec3(-0.5, 0.121, 0), 0.02,
                                   Sphere(Vec3::Zero(), 0.1))
                   .hit);
}

TEST(ObstacleSweepTest, SphereOntoCapsuleSideAndEnd) {
  const ObstacleSpec cap = Capsule(Vec3(-0.1, 0, 0), Vec3(0.1, 0, 0), 0.03);
  const double r = 0.01;
  // Onto the side: stops at R + r above the axis.
  SweepContact c = SweepSphereObstacle(Vec3(0.02, 0.5, 0), Vec3(0.02, -0.5, 0), r, cap);
  ASSERT_TRUE(c.hit);
  EXPECT_NEAR(c.toi, 0.46, 1e-15);
  ExpectVecNear(c.point, Vec3(0.02, 0.03, 0), 1e-15);
  ExpectVecNear(c.normal, Vec3::UnitY(), 1e-15);
  // Along the axis onto the end: stops at R + r beyond b.
  c = SweepSphereObstacle(Vec3(0.5, 0, 0), Vec3(-0.5, 0, 0), r, cap);
  ASSERT_TRUE(c.hit);
  EXPECT_NEAR(c.toi, 0.36, 1e-15);
  ExpectVecNear(c.point, Vec3(0.13, 0, 0), 1e-15);
  // Past the end, offset 2 cm along the axis: onto the end ball, y = sqrt((R + r)^2 - 0.02^2).
  c = SweepSphereObstacle(Vec3(0.12, 0.5, 0), Vec3(0.12, -0.5, 0), r, cap);
  ASSERT_TRUE(c.hit);
  EXPECT_NEAR(c.toi, 0.5 - std::sqrt(0.04 * 0.04 - 0.02 * 0.02), 1e-15);
  ExpectVecNear(c.normal, Vec3(0.02, std::sqrt(0.04 * 0.04 - 0.02 * 0.02), 0) / 0.04, 1e-12);
  // Beyond the end ball: no contact.
  EXPECT_FALSE(SweepSphereObstacle(Vec3(0.141, 0.5, 0), Vec3(0.141, -0.5, 0), r, cap).hit);
}

TEST(ObstacleSweepTest, SphereOntoBoxFaceEdgeAndCorner) {
  const ObstacleSpec table = Table();
  const double r = 0.004;
  // Face: straight down onto the top.
  SweepContact c = SweepSphereObstacle(Vec3(0, 0.1, 0), Vec3(0, -0.1, 0), r, table);
  ASSERT_TRUE(c.hit);
  EXPECT_NEAR(c.toi, 0.48, 1e-15);
  ExpectVecNear(c.normal, Vec3::UnitY(), 0.0);
  // Edge (x = 0.3, y = 0, along z), approached diagonally in x-y: distance sqrt(2) (0.1 - s).
  c = SweepSphereObstacle(Vec3(0.4, 0.1, 0), Vec3(0.2, -0.1, 0), r, table);
  ASSERT_TRUE(c.hit);
  EXPECT_NEAR(c.toi, (0.1 - r / std::sqrt(2.0)) / 0.2, 1e-13);
  ExpectVecNear(c.point, Vec3(0.3, 0, 0), 1e-13);
  ExpectVecNear(c.normal, Vec3(1, 1, 0).normalized(), 1e-12);
  // Corner (0.3, 0, 0.2), approached along the diagonal: distance sqrt(3) (0.1 - s).
  c = SweepSphereObstacle(Vec3(0.4, 0.1, 0.3), Vec3(0.2, -0.1, 0.1), r, table);
  ASSERT_TRUE(c.hit);
  EXPECT_NEAR(c.toi, (0.1 - r / std::sqrt(3.0)) / 0.2, 1e-13);
  ExpectVecNear(c.point, Vec3(0.3, 0, 0.2), 1e-13);
  ExpectVecNear(c.normal, Vec3(1, 1, 1).normalized(), 1e-12);
  // Skimming 3 mm above the top toward the edge from outside: onto the edge cylinder, where
  // (x - 0.3)^2 + 0.003^2 = r^2. At 5 mm above it passes freely.
  c = SweepSphereObstacle(Vec3(0.5, 0.003, 0), Vec3(0.2, 0.003, 0), r, table);
  ASSERT_TRUE(c.hit);
  EXPECT_NEAR(c.toi, (0.2 - std::sqrt(r * r - 0.003 * 0.003)) / 0.3, 1e-13);
  EXPECT_FALSE(SweepSphereObstacle(Vec3(0.5, 0.005, 0), Vec3(0.2, 0.005, 0), r, table).hit);
}

// A start exactly on the grown box's top (y = r): the box distance |p - c| - h rounds just above
// r while the face slab's own test p.y <= hi.y + r finds the start inside the slab. It must count
// as touching (stopped at once when moving in), not as a start inside the slab that only meets
// the x slab at the end of the motion.
TEST(ObstacleSweepTest, StartOnTheGrownSurfaceWithRoundingIsTouching) {
  const double r = 0.004;
  const Vec3 p0(0.2, 0.004, 0.002);
  ASSERT_GT(ClosestObstaclePoint(Table(), p0).distance_m, r);  // the rounding this case needs
  const SweepContact c = SweepSphereObstacle(p0, Vec3(0.2006713, 0.0, 0.0020001), r, Table());
  ASSERT_TRUE(c.hit);
  EXPECT_EQ(c.toi, 0.0);
  EXPECT_FALSE(SweepSphereObstacle(p0, Vec3(0.25, 0.004, 0.002), r, Table()).hit);
}

// A thin wall is not tunnelled through by a long motion (a sampled test at the end points would).
TEST(ObstacleSweepTest, ThinObstaclesAreNotTunnelled) {
  const double r = 0.001;
  const ObstacleSpec wall = Box(Vec3(-0.1, -0.00025, -0.1), Vec3(0.1, 0.00025, 0.1));
  const SweepContact c = SweepSphereObstacle(Vec3(0, 0.01, 0), Vec3(0, -0.01, 0), r, wall);
  ASSERT_TRUE(c.hit);
  EXPECT_NEAR(c.toi, (0.01 - 0.00125) / 0.02, 1e-13);
  const ObstacleSpec rod = Capsule(Vec3(0, 0, -0.1), Vec3(0, 0, 0.1), 0.0002);
  EXPECT_TRUE(SweepSphereObstacle(Vec3(0, 0.01, 0), Vec3(0, -0.01, 0), r, rod).hit);
}

// Against a slow reference: the distance sampled finely along the motion. Before toi the sphere
// never overlaps by more than rounding; at toi it touches; without a hit it never overlaps.
TEST(ObstacleSweepTest, MatchesASampledReferenceOnRandomMotions) {
  std::mt19937_64 rng(2026);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const ObstacleSpec shapes[] = {
      Plane(Vec3(0, -0.05, 0), Vec3(0.2, 1, 0.1)),
      Sphere(Vec3(0.01, 0, -0.02), 0.07),
      Box(Vec3(-0.08, -0.03, -0.05), Vec3(0.06, 0.02, 0.09)),
      Capsule(Vec3(-0.05, -0.02, 0.01), Vec3(0.06, 0.03, -0.04), 0.03),
  };
  int hits = 0;
  for (int i = 0; i < 4000; ++i) {
    const ObstacleSpec& o = shapes[i % 4];
    const double r = 0.002 + 0.02 * std::abs(u(rng));
    Vec3 p0(0.2 * u(rng), 0.2 * u(rng), 0.2 * u(rng));
    if (ClosestObstaclePoint(o, p0).distance_m <= r) continue;  // starts overlapping
    const Vec3 p1 = p0 + 0.3 * Vec3(u(rng), u(rng), u(rng));
    const SweepContact c = SweepSphereObstacle(p0, p1, r, o);
    const double end = c.hit ? c.toi : 1.0;
    constexpr int kSamples = 400;
    for (int s = 0; s <= kSamples; ++s) {
      const double t = end * s / kSamples;
      ASSERT_GE(ClosestObstaclePoint(o, p0 + t * (p1 - p0)).distance_m, r - 1e-12)
          << "case " << i << " t " << t << " toi " << end;
    }
    if (c.hit) {
      ++hits;
      const Vec3 p = p0 + c.toi * (p1 - p0);
      ASSERT_NEAR(ClosestObstaclePoint(o, p).distance_m, r, 1e-12) << "case " << i;
      ASSERT_NEAR((p - c.point).norm(), r, 1e-12) << "case " << i;
      ASSERT_LT(c.normal.dot(p1 - p0), 0.0) << "case " << i;
    }
  }
  EXPECT_GT(hits, 300);  // the cases exercise contacts, not only misses
}

TEST(ObstacleSweepTest, EarliestOfSeveralObstacles) {
  const ObstacleSpec list[] = {Plane(Vec3(0, -0.05, 0), Vec3::UnitY()), Table(),
                               Sphere(Vec3(0, 0.2, 0), 0.01)};
  int32_t index = -7;
  const SweepContact c =
      SweepSphereObstacles(Vec3(0, 0.1, 0), Vec3(0, -0.1, 0), 0.004, list, &index);
  ASSERT_TRUE(c.hit);
  EXPECT_EQ(index, 1);  // the table's top before the floor below it
  index = -7;
  EXPECT_FALSE(SweepSphereObstacles(Vec3(0, 0.1, 0), Vec3(0, 0.15, 0), 0.004, list, &index).hit);
  EXPECT_EQ(index, -7);
}

}  // namespace
}  // namespace felt
