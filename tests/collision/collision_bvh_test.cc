// BVH shape and repair invariants (001_0f9f1b7fedff7723.txt §6.3) and spatial-hash bookkeeping.
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>

#include "collision/bvh.h"
#include "collision/spatial_hash.h"
#include "tests/collision/collision_test_util.h"

namespace felt {
namespace {

using testing::FlatGrid;
using testing::MakeTestCloths;

TEST(BvhTopologyTest, BreadthFirstArraysWithParentsBeforeChildren) {
  for (int32_t arity : {2, 4}) {
    for (int32_t n : {1, 2, 3, 5, 162, 721, 4802}) {
      const BvhTopology t = BvhTopology::Make(n, arity);
      int32_t leaves = 0;
      for (int32_t i = 0; i < t.num_nodes(); ++i) {
        if (i > 0) {
          ASSERT_LT(t.parent[i], i);
          ASSERT_GE(t.parent[i], t.parent[i - 1]);  // breadth-first: parents never decrease
        }
        if (t.is_leaf(i)) {
          ++leaves;
          ASSERT_EQ(t.end[i] - t.begin[i], 1);
          continue;
        }
        // Children consecutive, ranges partition the parent's range.
        ASSERT_LE(t.num_children[i], arity);
        int32_t at = t.begin[i];
        for (int32_t k = 0; k < t.num_children[i]; ++k) {
          const int32_t child = t.first_child[i] + k;
          ASSERT_EQ(t.parent[child], i);
          ASSERT_EQ(t.begin[child], at);
          at = t.end[child];
        }
        ASSERT_EQ(at, t.end[i]);
      }
      EXPECT_EQ(leaves, n);
      EXPECT_EQ(static_cast<int32_t>(t.leaves_desc.size()), n);
      EXPECT_TRUE(std::is_sorted(t.leaves_desc.rbegin(), t.leaves_desc.rend()));
      // The flat sweep's arrays: each slot's leaf, and every internal node once, deepest first.
      ASSERT_EQ(static_cast<int32_t>(t.leaf_of_slot.size()), n);
      for (int32_t s = 0; s < n; ++s) ASSERT_EQ(t.begin[t.leaf_of_slot[s]], s);
      EXPECT_EQ(static_cast<int32_t>(t.internal_desc.size()), t.num_internal);
      EXPECT_TRUE(std::is_sorted(t.internal_desc.rbegin(), t.internal_desc.rend()));
      for (int32_t i : t.internal_desc) ASSERT_FALSE(t.is_leaf(i));
      if (arity == 2) {
        EXPECT_EQ(t.num_nodes(), 2 * n - 1);
      }
    }
  }
}

// True if every stored volume contains its triangle's (leaf) or its children's volumes.
bool VolumesNest(const Bvh& h, std::span<const Vec3> x) {
  const BvhTopology& t = h.topology();
  const double eps = 1e-12;
  for (int32_t i = 0; i < t.num_nodes(); ++i) {
    std::vector<Vec3> pts;
    if (t.is_leaf(i)) {
      for (int32_t v : h.triangles()[h.order()[t.begin[i]]]) pts.push_back(x[v]);
    }
    if (!h.aabbs().empty()) {
      // Float boxes are rounded outward: they must contain their contents with no tolerance.
      const Aabb b = h.aabb(i);
      for (const Vec3& p : pts) {
        if (((p - b.lo).array() < 0.0).any() || ((b.hi - p).array() < 0.0).any()) return false;
      }
      for (int32_t k = 0; k < t.num_children[i]; ++k) {
        const Aabb c = h.aabb(t.first_child[i] + k);
        if (((c.lo - b.lo).array() < 0.0).any() || ((b.hi - c.hi).array() < 0.0).any()) {
          return false;
        }
      }
    } else {
      const BoundingSphere& s = h.spheres()[i];
      for (const Vec3& p : pts) {
        if ((p - s.center).norm() > s.radius + eps) return false;
      }
      for (int32_t k = 0; k < t.num_children[i]; ++k) {
        const BoundingSphere& c = h.spheres()[t.first_child[i] + k];
        if ((c.center - s.center).norm() + c.radius > s.radius + eps) return false;
      }
    }
  }
  return true;
}

bool SameVolumes(const Bvh& a, const Bvh& b) {
  if (a.aabbs().size() != b.aabbs().size() || a.spheres().size() != b.spheres().size()) {
    return false;
  }
  for (size_t i = 0; i < a.aabbs().size(); ++i) {
    const int32_t n = static_cast<int32_t>(i);
    if (a.aabb(n).lo != b.aabb(n).lo || a.aabb(n).hi != b.aabb(n).hi) return false;
  }
  for (size_t i = 0; i < a.spheres().size(); ++i) {
    if (a.spheres()[i].center != b.spheres()[i].center ||
        a.spheres()[i].radius != b.spheres()[i].radius) {
      return false;
    }
  }
  return true;
}

// A sequence of shapes: the test cloths in turn, plus a partial motion that moves one corner.
std::vector<std::vector<Vec3>> Shapes(int32_t w) {
  std::vector<std::vector<Vec3>> shapes;
  for (const auto& c : MakeTestCloths(w, 9)) {
    if (c.name != "degenerate") shapes.push_back(c.x);
  }
  std::vector<Vec3> corner = shapes.back();
  for (int32_t r = 0; r < 4; ++r)
    for (int32_t c = 0; c < 4; ++c) corner[GridIndex(w, c, r)].z() += 0.05;
  shapes.push_back(corner);
  shapes.push_back(corner);  // no motion at all
  return shapes;
}

TEST(BvhRepairTest, BottomUpRefitsEachParentOnceAndEqualsRefitFromScratch) {
  const int32_t w = 23;
  const auto tris = std::make_shared<const std::vector<Triangle>>(MakeGridTriangles(w, w));
  const std::vector<Vec3> rest = FlatGrid(w, w);
  for (BoundingVolume v : {BoundingVolume::kSphere, BoundingVolume::kAabb}) {
    for (int32_t arity : {2, 4}) {
      for (double d : {0.0, 0.01}) {
        Bvh bottom_up(tris, rest, {v, arity, BvhRepair::kBottomUp, d});
        Bvh top_down(tris, rest, {v, arity, BvhRepair::kTopDown, d});
        Bvh queue(tris, rest, {v, arity, BvhRepair::kBottomUpQueue, d});
        Bvh scratch = bottom_up;
        ASSERT_EQ(&bottom_up.topology(), &scratch.topology());  // shape shared by copies
        const BvhTopology& t = bottom_up.topology();
        const int32_t leaves = static_cast<int32_t>(t.leaves_desc.size());
        int32_t step = 0;
        for (const std::vector<Vec3>& x : Shapes(w)) {
          const RepairStats bu = bottom_up.Repair(x);
          const RepairStats td = top_down.Repair(x);
          const RepairStats qu = queue.Repair(x);
          const std::string what = "volume " + std::to_string(static_cast<int>(v)) + " arity " +
                                   std::to_string(arity) + " d " + std::to_string(d) + " step " +
                                   std::to_string(step++);
          // Same decisions as the recursive refit, which visits every node exactly once: so the
          // array-based repair refits each parent at most once.
          EXPECT_EQ(bu.leaves_refit, leaves) << what;
          EXPECT_EQ(bu.parents_refit, td.parents_refit) << what;
          EXPECT_EQ(bu.node_updates, td.node_updates) << what;
          EXPECT_LE(bu.parents_refit, t.num_internal) << what;
          // The flat sweep and 001's queue make the same decisions.
          EXPECT_EQ(qu.leaves_refit, leaves) << what;
          EXPECT_EQ(qu.parents_refit, td.parents_refit) << what;
          EXPECT_EQ(qu.node_updates, td.node_updates) << what;
          EXPECT_TRUE(SameVolumes(bottom_up, top_down)) << what;
          EXPECT_TRUE(SameVolumes(queue, top_down)) << what;
          EXPECT_TRUE(VolumesNest(bottom_up, x)) << what;
          if (d == 0.0) {
            // Exact mode: identical to recomputing every volume from scratch.
            scratch.RefitAll(x);
            EXPECT_TRUE(SameVolumes(bottom_up, scratch)) << what;
          }
        }
        // The last step did not move anything: nothing updated.
        EXPECT_EQ(bottom_up.Repair(Shapes(w).back()).node_updates, 0);
      }
    }
  }
}

TEST(BvhRepairTest, SweptRepairsAgreeBetweenSweepQueueAndTopDown) {
  const auto cloths = MakeTestCloths(19, 6);
  for (BoundingVolume v : {BoundingVolume::kSphere, BoundingVolume::kAabb}) {
    for (int32_t arity : {2, 4}) {
      for (double d : {0.0, 0.01}) {
        Bvh sweep(cloths[0].triangles, cloths[0].x, {v, arity, BvhRepair::kBottomUp, d});
        Bvh queue(cloths[0].triangles, cloths[0].x, {v, arity, BvhRepair::kBottomUpQueue, d});
        Bvh top_down(cloths[0].triangles, cloths[0].x, {v, arity, BvhRepair::kTopDown, d});
        for (size_t i = 1; i < cloths.size(); ++i) {
          if (cloths[i].name == "degenerate" || cloths[i - 1].name == "degenerate") continue;
          // Swept between two shapes, then a plain repair at the second.
          for (int pass = 0; pass < 2; ++pass) {
            const auto run = [&](Bvh& h) {
              return pass == 0 ? h.RepairSwept(cloths[i - 1].x, cloths[i].x)
                               : h.Repair(cloths[i].x);
            };
            const RepairStats a = run(sweep);
            const RepairStats b = run(queue);
            const RepairStats c = run(top_down);
            const std::string what = cloths[i].name + " pass " + std::to_string(pass);
            EXPECT_EQ(a.node_updates, b.node_updates) << what;
            EXPECT_EQ(a.parents_refit, b.parents_refit) << what;
            EXPECT_EQ(a.node_updates, c.node_updates) << what;
            EXPECT_TRUE(SameVolumes(sweep, queue)) << what;
            EXPECT_TRUE(SameVolumes(sweep, top_down)) << what;
            EXPECT_TRUE(VolumesNest(sweep, cloths[i].x)) << what;
          }
        }
      }
    }
  }
}

TEST(BvhRepairTest, ExactRepairOfAGlobalMotionRefitsEveryNodeOnce) {
  const int32_t w = 17;
  const auto tris = std::make_shared<const std::vector<Triangle>>(MakeGridTriangles(w, w));
  std::vector<Vec3> x = FlatGrid(w, w);
  for (int32_t arity : {2, 4}) {
    for (BvhRepair m : {BvhRepair::kBottomUp, BvhRepair::kBottomUpQueue}) {
      Bvh h(tris, x, {BoundingVolume::kAabb, arity, m, 0.0});
      std::vector<Vec3> moved = x;
      for (Vec3& p : moved) p += Vec3(0.01, -0.02, 0.03);
      const RepairStats s = h.Repair(moved);
      EXPECT_EQ(s.parents_refit, h.topology().num_internal);
      EXPECT_EQ(s.node_updates, h.num_nodes());
    }
  }
}

TEST(BvhRepairTest, InflationSkipsMotionSmallerThanTheMargin) {
  const int32_t w = 17;
  const auto tris = std::make_shared<const std::vector<Triangle>>(MakeGridTriangles(w, w));
  const std::vector<Vec3> x = FlatGrid(w, w);
  const double d = 0.01;
  for (BoundingVolume v : {BoundingVolume::kSphere, BoundingVolume::kAabb}) {
    Bvh h(tris, x, {v, 4, BvhRepair::kBottomUp, d});
    std::vector<Vec3> moved = x;
    for (Vec3& p : moved) p.z() += 0.4 * d;
    EXPECT_EQ(h.Repair(moved).node_updates, 0);
    EXPECT_TRUE(VolumesNest(h, moved));
    for (Vec3& p : moved) p.z() += 0.8 * d;  // now beyond the margin
    const RepairStats s = h.Repair(moved);
    EXPECT_EQ(s.node_updates, h.num_nodes());
    EXPECT_TRUE(VolumesNest(h, moved));
  }
}

TEST(BvhRepairTest, RebuildKeepsAPermutationAndValidVolumes) {
  const auto cloths = MakeTestCloths(21, 4);
  const std::vector<Vec3> rest = FlatGrid(21, 21);
  for (BoundingVolume v : {BoundingVolume::kSphere, BoundingVolume::kAabb}) {
    for (int32_t arity : {2, 4}) {
      Bvh h(cloths[0].triangles, rest, {v, arity, BvhRepair::kRebuild, 0.0});
      for (const auto& c : cloths) {
        if (c.name == "degenerate") continue;
        const RepairStats s = h.Repair(c.x);
        EXPECT_EQ(s.node_updates, h.num_nodes());
        std::vector<int32_t> order(h.order().begin(), h.order().end());
        std::sort(order.begin(), order.end());
        std::vector<int32_t> expected(order.size());
        std::iota(expected.begin(), expected.end(), 0);
        EXPECT_EQ(order, expected);
        EXPECT_TRUE(VolumesNest(h, c.x)) << c.name;
      }
    }
  }
}

TEST(BvhRepairTest, SweptRepairBoundsBothSnapshots) {
  const auto cloths = MakeTestCloths(21, 4);
  for (BoundingVolume v : {BoundingVolume::kSphere, BoundingVolume::kAabb}) {
    Bvh h(cloths[0].triangles, cloths[0].x, {v, 2, BvhRepair::kBottomUp, 0.0});
    EXPECT_FALSE(h.covers_motion());
    h.RepairSwept(cloths[1].x, cloths[2].x);
    EXPECT_TRUE(h.covers_motion());
    EXPECT_TRUE(VolumesNest(h, cloths[1].x));
    EXPECT_TRUE(VolumesNest(h, cloths[2].x));
    h.Repair(cloths[2].x);
    EXPECT_FALSE(h.covers_motion());
  }
}

TEST(SpatialHashTest, CellSizeIsTheAverageEdgeAndEveryTriangleIsHashed) {
  const auto c = MakeTestCloths(21, 4)[0];
  SpatialHash h(c.triangles, c.x);
  // Edges 0.05 and diagonals 0.05 sqrt(2): average (2 + sqrt(2)) / 3 x 0.05.
  EXPECT_NEAR(h.cell_size_m(), (2 + std::sqrt(2.0)) / 3 * 0.05, 1e-15);
  EXPECT_GE(h.table_size(), 4 * static_cast<int32_t>(c.triangles->size()));
  EXPECT_EQ(h.num_oversized(), 0);
  EXPECT_GE(h.num_entries(), static_cast<int32_t>(c.triangles->size()));
  // A huge triangle goes to the always-tested list, and is still found.
  std::vector<Vec3> x = c.x;
  x[0] = Vec3(-3, -3, 0);
  const RepairStats s = h.Repair(x);
  EXPECT_EQ(h.num_oversized(), 2);  // the two triangles at vertex 0
  EXPECT_EQ(s.entries, h.num_entries());
  std::vector<PointContact> buf(16);
  const WithinResult r = h.TrianglesWithin(x, Vec3(-2, -2, 0.001), 0.01, buf);
  // (-2, -2) lies on the stretched diagonal edge shared by both.
  EXPECT_EQ(r.found, 2);
}

}  // namespace
}  // namespace felt
