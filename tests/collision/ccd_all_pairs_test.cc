// The all-pairs continuous reference on meshes: the edge list, a flat grid moving rigidly (no
// collision), a sheet folded flat through itself (every vertex of the moving half hits), and a
// Z-folded grid pushed through itself, where every triangle pair that intersects at the end must
// be explained by a vertex-triangle or edge-edge collision of its primitives. The box prefilter
// changes nothing.
#include "collision/ccd_all_pairs.h"

#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <vector>

#include "collision/self_intersection.h"
#include "tests/collision/collision_test_util.h"

namespace felt {
namespace {

using testing::SpacedGrid;

bool SameHits(const std::vector<CcdPairHit>& a, const std::vector<CcdPairHit>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i].kind != b[i].kind || a[i].vertices != b[i].vertices || a[i].toi != b[i].toi) {
      return false;
    }
  }
  return true;
}

TEST(CcdAllPairsTest, MeshEdgesOfAGrid) {
  std::vector<Triangle> tris = MakeGridTriangles(3, 3);
  // (W - 1) H horizontal + W (H - 1) vertical + (W - 1)(H - 1) diagonal edges.
  EXPECT_EQ(MeshEdges(tris).size(), 16u);
  tris.push_back({0, 0, 4});  // a repeated index: only the edge (0, 4), already there
  const std::vector<MeshEdge> edges = MeshEdges(tris);
  EXPECT_EQ(edges.size(), 16u);
  for (const MeshEdge& e : edges) EXPECT_LT(e[0], e[1]);
}

TEST(CcdAllPairsTest, RigidlyMovingFlatGridHasNone) {
  const int32_t w = 7;
  const double step = 0.05, h = 0.1 * step;
  const std::vector<Triangle> tris = MakeGridTriangles(w, w);
  const std::vector<Vec3> x0 = SpacedGrid(w, w, step);
  std::vector<Vec3> x1 = x0;
  for (Vec3& p : x1) p += Vec3(0.3, -0.2, 0.5);
  for (bool separation : {false, true}) {
    AllPairsCcdOptions options;
    options.ccd.thickness_m = h;
    options.minimal_separation = separation;
    EXPECT_TRUE(AllPairsCcd(x0, x1, tris, options).empty()) << separation;
  }
}

// A w x rows grid (spacing `step`) whose first `bottom` rows lie in z = 0 and whose other rows are
// folded back over them about the hinge row, at angle `angle` (rad) from the bottom's plane, the
// folded half shifted by 0.37 columns along x. At angle pi the two halves lie flat on each other.
std::vector<Vec3> FoldedSheet(int32_t w, int32_t rows, int32_t bottom, double step, double angle) {
  std::vector<Vec3> x;
  const double hinge_y = (bottom - 1) * step;
  for (int32_t r = 0; r < rows; ++r) {
    for (int32_t c = 0; c < w; ++c) {
      if (r < bottom) {
        x.emplace_back(c * step, r * step, 0.0);
      } else {
        const double d = (r - bottom + 1) * step;  // distance from the hinge
        x.emplace_back((c + 0.37) * step, hinge_y + d * std::cos(angle), d * std::sin(angle));
      }
    }
  }
  return x;
}

TEST(CcdAllPairsTest, SheetFoldedFlatThroughItselfHitsEveryFoldedVertex) {
  const int32_t w = 8, rows = 10, bottom = 6;
  const double step = 0.05, h = 1e-3;
  const double pi = std::acos(-1.0);
  const std::vector<Triangle> tris = MakeGridTriangles(w, rows);
  // From 10 degrees open above the bottom half to 10 degrees below it: along the straight paths
  // every folded vertex reaches z = 0 at t = 0.5, over the bottom half (at most 4 rows from the
  // hinge, cos 10 deg * 4 < 5 rows).
  const std::vector<Vec3> x0 = FoldedSheet(w, rows, bottom, step, pi - 10 * pi / 180);
  const std::vector<Vec3> x1 = FoldedSheet(w, rows, bottom, step, pi + 10 * pi / 180);
  AllPairsCcdOptions options;
  options.ccd.thickness_m = h;
  const std::vector<CcdPairHit> hits = AllPairsCcd(x0, x1, tris, options);
  // Every vertex of the folded half beyond the hinge's neighbour row meets a bottom triangle
  // no later than t = 0.5, except the last column's, which the 0.37-column shift puts beyond the
  // bottom's edge.
  std::set<int32_t> hit_vertices;
  int32_t edge_edge = 0;
  for (const CcdPairHit& hit : hits) {
    EXPECT_FALSE(hit.capped);
    EXPECT_GE(hit.toi, 0.0);
    EXPECT_LE(hit.distance_m, h * (1 + kCcdDistanceSlack));
    EXPECT_NEAR(hit.normal.norm(), 1.0, 1e-9);
    EXPECT_NEAR(hit.weights[0] + hit.weights[1] + hit.weights[2] + hit.weights[3], 0.0, 1e-12);
    if (hit.kind == CcdPairHit::Kind::kEdgeEdge) {
      ++edge_edge;
    } else if (hit.first >= (bottom + 1) * w) {
      hit_vertices.insert(hit.first);
      EXPECT_LE(hit.toi, 0.5 + 1e-12);
      EXPECT_GT(hit.toi, 0.4);  // nothing is near at the start
    }
  }
  std::set<int32_t> expected;
  for (int32_t r = bottom + 1; r < rows; ++r) {
    for (int32_t c = 0; c + 1 < w; ++c) expected.insert(GridIndex(w, c, r));
  }
  EXPECT_EQ(hit_vertices, expected);
  EXPECT_GT(edge_edge, 0);
  // Same with the box prefilter; the separation variant finds every pair the collision test does.
  options.box_prefilter = true;
  EXPECT_TRUE(SameHits(AllPairsCcd(x0, x1, tris, options), hits));
  options.minimal_separation = true;
  const std::vector<CcdPairHit> near = AllPairsCcd(x0, x1, tris, options);
  size_t j = 0;
  for (const CcdPairHit& hit : hits) {
    while (j < near.size() && (near[j].kind != hit.kind || near[j].vertices != hit.vertices)) ++j;
    ASSERT_LT(j, near.size()) << "a collision pair missing from the separation hits";
    EXPECT_LE(near[j].toi, hit.toi + 1e-12);
  }
}

// The Z-fold of self_intersection_test.cc: a bottom in z = 0, a wall, and a top layer losing
// `drop` metres per row from z = 0.102, shifted by 0.3 columns.
std::vector<Vec3> ZFoldPositions(double drop) {
  std::vector<Vec3> x;
  const double dx = 1.0 / 8, dy = 1.0 / 8, dz = 0.051;
  for (int32_t r = 0; r < 14; ++r) {
    for (int32_t c = 0; c < 9; ++c) {
      if (r < 7) {
        x.emplace_back(c * dx, r * dy, 0.0);
      } else if (r < 9) {
        const int32_t k = r - 6;
        x.emplace_back(c * dx + 0.3 * dx * k / 2, 6 * dy, k * dz);
      } else {
        const int32_t k = r - 8;
        x.emplace_back(c * dx + 0.3 * dx, (6 - k) * dy, 2 * dz - k * drop);
      }
    }
  }
  return x;
}

TEST(CcdAllPairsTest, EveryIntersectionAtTheEndHasAPrimitiveCollision) {
  const std::vector<Triangle> tris = MakeGridTriangles(9, 14);
  const std::vector<Vec3> x0 = ZFoldPositions(0.02);  // above the bottom: no intersection
  const std::vector<Vec3> x1 = ZFoldPositions(0.04);  // through it: 31 pairs
  ASSERT_EQ(CountSelfIntersections(x0, tris), 0);
  const auto crossing = FindSelfIntersections(x1, tris);
  ASSERT_EQ(crossing.size(), 31u);
  AllPairsCcdOptions options;
  options.ccd.thickness_m = 1e-4;
  const std::vector<CcdPairHit> hits = AllPairsCcd(x0, x1, tris, options);
  const std::vector<MeshEdge> edges = MeshEdges(tris);
  // Two disjoint triangles that come to intersect first touch vertex-to-face or edge-to-edge, so
  // some primitive pair of theirs collides.
  for (const auto& [i, j] : crossing) {
    bool explained = false;
    for (const CcdPairHit& hit : hits) {
      std::set<int32_t> a, b;  // the two primitives' vertices
      if (hit.kind == CcdPairHit::Kind::kVertexTriangle) {
        a = {hit.vertices[0]};
        b = {hit.vertices[1], hit.vertices[2], hit.vertices[3]};
      } else {
        a = {hit.vertices[0], hit.vertices[1]};
        b = {hit.vertices[2], hit.vertices[3]};
      }
      const std::set<int32_t> ti(tris[i].begin(), tris[i].end());
      const std::set<int32_t> tj(tris[j].begin(), tris[j].end());
      const auto within = [](const std::set<int32_t>& s, const std::set<int32_t>& t) {
        for (int32_t v : s) {
          if (!t.count(v)) return false;
        }
        return true;
      };
      explained |= (within(a, ti) && within(b, tj)) || (within(a, tj) && within(b, ti));
    }
    EXPECT_TRUE(explained) << "triangles " << i << " and " << j;
  }
  options.box_prefilter = true;
  EXPECT_TRUE(SameHits(AllPairsCcd(x0, x1, tris, options), hits));
}

}  // namespace
}  // namespace felt
