#include "sim_loop/snapshot.h"

#include <gtest/gtest.h>

#include <random>

#include "proxy/reaction.h"
#include "tests/alloc_counter.h"
#include "tests/proxy/proxy_test_util.h"

namespace felt {
namespace {

using testing::FlatSheet;
using testing::Snap;

TEST(SnapshotTest, FillCopiesAndRepairsWithoutAllocating) {
  const testing::TestMesh mesh = FlatSheet(0.2, 17);
  for (CollisionStructureSpec::Kind kind :
       {CollisionStructureSpec::Kind::kBvh, CollisionStructureSpec::Kind::kSpatialHash,
        CollisionStructureSpec::Kind::kNaive}) {
    CollisionStructureSpec spec;
    spec.kind = kind;
    ClothSnapshot s = Snap(mesh, spec);
    std::vector<Vec3> x = mesh.x;
    std::vector<Vec3> v(x.size(), Vec3::Zero());
    for (size_t i = 0; i < x.size(); ++i) {
      x[i].z() = 0.05 * std::sin(20.0 * x[i].x());
      v[i] = Vec3(0, 0, i == 7 ? -2.0 : 0.5);
    }
    std::vector<Vec3> normals(x.size());
    ComputeVertexNormals(x, mesh.triangles, normals);
    AllocationGuard guard;
    FillSnapshot(x, v, normals, 42, 1.5, 0.016, &s);
    EXPECT_EQ(guard.allocations(), 0u);
    EXPECT_EQ(s.frame, 42u);
    EXPECT_EQ(s.time_s, 1.5);
    EXPECT_EQ(s.frame_dt_s, 0.016);
    EXPECT_EQ(s.max_speed_m_per_s, 2.0);
    EXPECT_EQ(s.x, x);
    EXPECT_EQ(s.normals, normals);
    // The structure answers for the new positions exactly as the naive reference does.
    const NaiveCollision naive(s.triangles);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-0.1, 0.1);
    for (int q = 0; q < 200; ++q) {
      const Vec3 p0(u(rng), u(rng), 0.1);
      const Vec3 p1(u(rng), u(rng), -0.1);
      const SweepHit a = SweepSphere(s.structure, s.x, p0, p1, 0.004);
      const SweepHit b = naive.SweepSphere(s.x, p0, p1, 0.004);
      ASSERT_EQ(a.hit, b.hit);
      EXPECT_EQ(a.toi, b.toi);
      EXPECT_EQ(a.triangle, b.triangle);
    }
  }
}

TEST(SnapshotTest, CopyAssignIntoASnapshotOfTheSameSizeDoesNotAllocate) {
  const testing::TestMesh mesh = FlatSheet(0.2, 17);
  ClothSnapshot a = Snap(mesh);
  ClothSnapshot b = Snap(mesh);
  std::vector<Vec3> x = mesh.x;
  for (Vec3& xi : x) xi.z() += 0.01;
  testing::Refill(x, std::vector<Vec3>(x.size(), Vec3::Zero()), 3, 0.05, 0.016, &a);
  AllocationGuard guard;
  b = a;
  EXPECT_EQ(guard.allocations(), 0u);
  EXPECT_EQ(b.x, a.x);
  EXPECT_EQ(b.frame, 3u);
  const SweepHit hit =
      SweepSphere(b.structure, b.x, Vec3(0.01, 0.01, 0.1), Vec3(0.01, 0.01, -0.1), 0.004);
  ASSERT_TRUE(hit.hit);
  EXPECT_NEAR(0.1 - 0.2 * hit.toi, 0.014, 1e-12);
  EXPECT_EQ(MaxDisplacement(a, Snap(mesh)), 0.01);
}

TEST(SnapshotTest, BadTrianglesAreRejected) {
  testing::TestMesh mesh = FlatSheet(0.2, 3);
  mesh.triangles.push_back({0, 1, 99});
  EXPECT_THROW(Snap(mesh), std::invalid_argument);
}

TEST(ReactionTest, SplitsOverParticlesAndAveragesOverTime) {
  ReactionAccumulator acc(8);
  const Triangle tri = {4, 5, 6};
  acc.AddForce(2, tri, Vec3(0.5, 0.25, 0.25), Vec3(0, 0, -4.0), 0.001);
  acc.AddTime(0.001);
  acc.AddTime(0.001);  // a tick without contact halves the average
  EXPECT_EQ(acc.size(), 3);
  const std::vector<ExternalForce> f = acc.Drain();
  ASSERT_EQ(f.size(), 3u);
  EXPECT_EQ(f[0].triangle, 2);
  EXPECT_EQ(f[0].barycentric, Vec3(1, 0, 0));
  EXPECT_NEAR((f[0].force_N - Vec3(0, 0, -1.0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((f[1].force_N - Vec3(0, 0, -0.5)).norm(), 0.0, 1e-15);
  EXPECT_EQ(f[2].barycentric, Vec3(0, 0, 1));
  EXPECT_EQ(acc.size(), 0);
  EXPECT_EQ(acc.time_s(), 0.0);
}

TEST(ReactionTest, OverflowKeepsTheTotal) {
  ReactionAccumulator acc(2);
  for (int t = 0; t < 5; ++t) {
    acc.AddForce(t, {3 * t, 3 * t + 1, 3 * t + 2}, Vec3(0.2, 0.3, 0.5), Vec3(1, 2, 3), 0.001);
  }
  acc.AddTime(0.001);
  EXPECT_GT(acc.overflows(), 0u);
  EXPECT_NEAR((acc.TotalImpulse() - 5 * 0.001 * Vec3(1, 2, 3)).norm(), 0.0, 1e-15);
  std::vector<ExternalForce> out(1);
  ASSERT_EQ(acc.DrainInto(out), 1);
  EXPECT_NEAR((out[0].force_N - 5 * Vec3(1, 2, 3)).norm(), 0.0, 1e-12);
}

// A frame whose contact ended before its last tick drains plain averaged forces. Into a slot
// that held the previous frame's contact spring (the server and RunLockstep reuse their buffers)
// it must write a plain force: a stale stiffness made the sim press the old sphere for a whole
// frame after the proxy had left (tests/proxy/table_slide_test.cc).
TEST(ReactionTest, PlainForceDrainedIntoASpringSlotIsPlain) {
  ReactionAccumulator acc;
  acc.SetContactSpring(4, Vec3(0.2, 0.3, 0.5), Vec3::UnitY(), Vec3(0, -0.02, 0), 400.0, 3.3, 0.03);
  acc.AddTime(0.001);
  std::vector<ExternalForce> out(2);
  ASSERT_EQ(acc.DrainInto(out), 1);
  ASSERT_GT(out[0].stiffness_N_per_m, 0.0);
  acc.AddForce(7, {10, 11, 12}, Vec3(1, 0, 0), Vec3(0, -1, 0), 0.001);
  acc.AddTime(0.001);
  ASSERT_EQ(acc.DrainInto(out), 1);
  const ExternalForce plain;
  EXPECT_EQ(out[0].triangle, 7);
  EXPECT_EQ(out[0].force_N, Vec3(0, -1, 0));
  EXPECT_EQ(out[0].stiffness_N_per_m, 0.0);
  EXPECT_EQ(out[0].radius_m, plain.radius_m);
  EXPECT_EQ(out[0].anchor_m, plain.anchor_m);
  EXPECT_EQ(out[0].normal, plain.normal);
  EXPECT_EQ(out[0].max_force_N, plain.max_force_N);
}

}  // namespace
}  // namespace felt
