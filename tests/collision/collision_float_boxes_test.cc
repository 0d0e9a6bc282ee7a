// The AABB trees store float32 boxes rounded outward (PackedAabb). These tests aim at that
// rounding: every box must contain what it bounds with no tolerance, at any scale (1 km offsets
// with 0.1 mm cells, coordinates near zero, beyond float's range), and every query must still
// answer exactly as the naive reference, including points exactly on vertices, edges and the
// surface and spheres that graze an edge at exactly their radius. (That the AVX2 and portable
// repair passes give the same bits is simd_kernels_test.cc's.)
#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

#include "collision/collision_structure.h"
#include "tests/collision/collision_test_util.h"
#include "tests/test_env.h"

namespace felt {
namespace {

using testing::MakeTestCloths;
using testing::TestCloth;

// True if every stored box contains its triangle's vertices (leaves) or its children's boxes,
// compared in double with no tolerance.
bool BoxesContain(const Bvh& h, std::span<const Vec3> x, std::string* why) {
  const BvhTopology& t = h.topology();
  for (int32_t i = 0; i < t.num_nodes(); ++i) {
    const Aabb b = h.aabb(i);
    if (t.is_leaf(i)) {
      for (int32_t v : h.triangles()[h.order()[t.begin[i]]]) {
        if ((x[v].array() < b.lo.array()).any() || (x[v].array() > b.hi.array()).any()) {
          *why = "leaf " + std::to_string(i) + " misses vertex " + std::to_string(v);
          return false;
        }
      }
    }
    for (int32_t k = 0; k < t.num_children[i]; ++k) {
      const Aabb c = h.aabb(t.first_child[i] + k);
      if ((c.lo.array() < b.lo.array()).any() || (c.hi.array() > b.hi.array()).any()) {
        *why = "node " + std::to_string(i) + " misses child " + std::to_string(k);
        return false;
      }
    }
  }
  return true;
}

// A test cloth moved to `offset` [m] and scaled so that its [0, 1] square spans `size` [m].
TestCloth Placed(const TestCloth& c, double offset, double size) {
  TestCloth out = c;
  for (Vec3& p : out.x) p = Vec3::Constant(offset) + size * p;
  return out;
}

std::vector<CollisionStructureSpec> AabbSpecs(double inflation_m) {
  std::vector<CollisionStructureSpec> specs;
  for (int32_t arity : {2, 4})
    for (BvhRepair m : {BvhRepair::kBottomUp, BvhRepair::kBottomUpQueue, BvhRepair::kTopDown,
                        BvhRepair::kRebuild})
      for (double d : {0.0, inflation_m})
        specs.push_back(
            {CollisionStructureSpec::Kind::kBvh, {BoundingVolume::kAabb, arity, m, d}, {}});
  return specs;
}

TEST(CollisionFloatBoxesTest, BoxesContainTheirContentsAtEveryScale) {
  const auto cloths = MakeTestCloths(15, 3);
  // (offset, size) [m]: unit, 1 km away with 0.1 mm cells, tiny, subnormal in float, near and
  // beyond float's largest value, and far negative.
  const std::vector<std::pair<double, double>> placements = {
      {0.0, 1.0},     {1e3, 14e-4},   {-1e3, 14e-4}, {0.0, 1e-30},  {0.0, 1e-40},
      {1e-40, 1e-44}, {3.3e38, 1e36}, {1e39, 1e37},  {-1e39, 1e37}, {-3.4e38, 1e20}};
  for (const auto& [offset, size] : placements) {
    for (const TestCloth& base : cloths) {
      const TestCloth c = Placed(base, offset, size);
      for (const CollisionStructureSpec& spec : AabbSpecs(0.1 * size)) {
        // Built at the cloth's own shape, then repaired to a shifted copy and back.
        Bvh h(c.triangles, c.x, spec.bvh);
        const std::string what = c.name + " offset " + std::to_string(offset) + " size " +
                                 std::to_string(size) + " " + CollisionStructureName(spec);
        std::string why;
        EXPECT_TRUE(BoxesContain(h, c.x, &why)) << what << ": " << why;
        std::vector<Vec3> shifted = c.x;
        for (Vec3& p : shifted) p += Vec3(0.3, -0.2, 0.1) * size;
        h.Repair(shifted);
        EXPECT_TRUE(BoxesContain(h, shifted, &why)) << what << " shifted: " << why;
        h.Repair(c.x);
        EXPECT_TRUE(BoxesContain(h, c.x, &why)) << what << " back: " << why;
        h.RepairSwept(shifted, c.x);
        EXPECT_TRUE(BoxesContain(h, shifted, &why)) << what << " swept old: " << why;
        EXPECT_TRUE(BoxesContain(h, c.x, &why)) << what << " swept new: " << why;
      }
    }
  }
}

// A query point at an exact feature of a random triangle, or at exactly r from one.
Vec3 FeaturePoint(const TestCloth& c, double r, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const auto& tris = *c.triangles;
  const Triangle& t = tris[std::uniform_int_distribution<size_t>(0, tris.size() - 1)(rng)];
  const Vec3 &a = c.x[t[0]], &b = c.x[t[1]], &cc = c.x[t[2]];
  const Vec3 axis = Vec3::Unit(std::uniform_int_distribution<int>(0, 2)(rng));
  double s = u(rng), w = u(rng);
  if (s + w > 1) s = 1 - s, w = 1 - w;
  switch (std::uniform_int_distribution<int>(0, 5)(rng)) {
    case 0:
      return a;  // exactly a vertex
    case 1:
      return 0.5 * (a + b);  // an edge's midpoint
    case 2:
      return a + s * (b - a) + w * (cc - a);  // on the surface (up to rounding)
    case 3:
      return a + r * axis;  // at r from a vertex along an axis: grazes the leaf box's face
    case 4:
      return a + u(rng) * (b - a) + r * axis;  // grazing an edge
    default:
      return a + s * (b - a) + w * (cc - a) + (2 * u(rng) - 1) * 2 * r * axis;
  }
}

TEST(CollisionFloatBoxesTest, QueriesMatchNaiveAtLargeOffsetsAndTinyCells) {
  std::mt19937_64 rng(21);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<PointContact> ref_buf(4096), got_buf(4096);
  int64_t nonempty = 0, hits = 0;
  // 1 km from the origin with 0.1 mm cells: a float ulp there (61 us) is most of a cell.
  for (const auto& [offset, size] :
       std::vector<std::pair<double, double>>{{1e3, 14e-4}, {-1e3, 14e-4}, {0.0, 14e-4}}) {
    const double cell = size / 14.0;
    const double radii[] = {0.0, 0.1 * cell, cell, 5 * cell};
    std::vector<CollisionStructureSpec> specs = AabbSpecs(0.2 * cell);
    specs.insert(specs.begin(), {CollisionStructureSpec::Kind::kNaive, {}, {}});
    for (const TestCloth& base : MakeTestCloths(15, 4)) {
      const TestCloth c = Placed(base, offset, size);
      std::vector<CollisionStructure> st;
      for (const CollisionStructureSpec& spec : specs) {
        st.push_back(MakeCollisionStructure(spec, c.triangles, Placed(base, offset, size).x));
        Repair(st.back(), c.x);
      }
      // Under a sanitizer 60 queries per cloth (tests/test_env.h): the same code paths.
      const int queries = testing::Sanitized() ? 60 : 300;
      for (int q = 0; q < queries; ++q) {
        const double r = radii[q % 4];
        const Vec3 p = FeaturePoint(c, r, rng);
        const std::string where =
            c.name + " offset " + std::to_string(offset) + " query " + std::to_string(q);
        const WithinResult ref_r = TrianglesWithin(st[0], c.x, p, r, ref_buf);
        nonempty += ref_r.found > 0 ? 1 : 0;
        for (size_t s = 1; s < st.size(); ++s) {
          const WithinResult got_r = TrianglesWithin(st[s], c.x, p, r, got_buf);
          ASSERT_EQ(ref_r.found, got_r.found) << where << " " << CollisionStructureName(specs[s]);
        }
        // A sweep from p through the cloth: a tick's worth, a few cells, or 10 m.
        const Vec3 dir = Vec3(g(rng), g(rng), g(rng)).normalized();
        const double len = q % 3 == 0 ? 0.2 * cell : q % 3 == 1 ? 3 * cell : 10.0;
        const Vec3 p0 = p - 0.5 * len * dir, p1 = p + 0.5 * len * dir;
        const SweepHit ref = SweepSphere(st[0], c.x, p0, p1, r);
        hits += ref.hit ? 1 : 0;
        for (size_t s = 1; s < st.size(); ++s) {
          const SweepHit got = SweepSphere(st[s], c.x, p0, p1, r);
          const std::string what = where + " " + CollisionStructureName(specs[s]);
          ASSERT_EQ(ref.hit, got.hit) << what;
          if (!ref.hit) continue;
          EXPECT_EQ(ref.toi, got.toi) << what;
          EXPECT_EQ(ref.triangle, got.triangle) << what;
          EXPECT_EQ(ref.point_m, got.point_m) << what;
        }
      }
    }
  }
  const int64_t scale = testing::Sanitized() ? 5 : 1;  // 60 queries per cloth instead of 300
  EXPECT_GT(nonempty, 1000 / scale);
  EXPECT_GT(hits, 1000 / scale);
}

}  // namespace
}  // namespace felt
