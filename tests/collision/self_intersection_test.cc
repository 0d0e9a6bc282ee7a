// The exact predicates and the exact triangle-triangle test: closed forms, near-degenerate inputs a
// plain floating-point determinant gets wrong, a differential test against an edges-both-ways
// reference on random, integer-grid (degenerate) and touching inputs, invariances, and the mesh
// counter on flat, rotated and folded grids.
#include "collision/self_intersection.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <random>

#include "collision/self_predicates.h"

namespace felt {
namespace {

using Tri = std::array<Vec3, 3>;

// Reference: two closed triangles meet iff an edge of one meets the other triangle (non-coplanar:
// the ends of the overlap of their intervals on the planes' common line lie on edges; coplanar
// or degenerate: an edge of the contained one lies in the other).
bool ReferenceIntersect(const Tri& t, const Tri& u) {
  for (int i = 0; i < 3; ++i) {
    if (SegmentIntersectsTriangle(t[i], t[(i + 1) % 3], u[0], u[1], u[2])) return true;
    if (SegmentIntersectsTriangle(u[i], u[(i + 1) % 3], t[0], t[1], t[2])) return true;
  }
  return false;
}

bool Intersect(const Tri& t, const Tri& u) {
  return TrianglesIntersect(t[0], t[1], t[2], u[0], u[1], u[2]);
}

TEST(SelfPredicatesTest, SignsOfSimpleCases) {
  const Vec3 o(0, 0, 0), ex(1, 0, 0), ey(0, 1, 0), ez(0, 0, 1);
  EXPECT_EQ(Orient3D(o, ex, ey, ez), 1);
  EXPECT_EQ(Orient3D(o, ey, ex, ez), -1);
  EXPECT_EQ(Orient3D(o, ex, ey, Vec3(5, -3, 0)), 0);
  EXPECT_EQ(Orient3D(o, ex, Vec3(2, 0, 0), ez), 0);  // collinear base
  EXPECT_EQ(Orient2D(o, ex, ey, 2), 1);
  EXPECT_EQ(Orient2D(o, ey, ez, 0), 1);
  EXPECT_EQ(Orient2D(o, ez, ex, 1), 1);
  EXPECT_EQ(Orient2D(o, ex, ey, 0), 0);
  EXPECT_TRUE(ExactlyCollinear(o, ex, Vec3(-7, 0, 0)));
  EXPECT_TRUE(ExactlyCollinear(ex, ex, ey));
  EXPECT_FALSE(ExactlyCollinear(o, ex, Vec3(3, 1e-300, 0)));
}

// Points a few ulps off the line y = x (Shewchuk 1997, Figure 1): the exact orientation of
// (0.5 + i u, 0.5 + j u), (12, 12), (24, 24) with u = 2^-53 is sign(j - i) (the determinant is
// 12 (j - i) u), which a floating-point determinant gets wrong for many (i, j).
TEST(SelfPredicatesTest, NearlyCollinearPointsAreExact) {
  const double u = 0x1p-53;
  const Vec3 q(12, 12, 0), r(24, 24, 0);
  // The plane through (12, 12, 0), (24, 24, 0), (0, 0, 1) is x = y; its normal is (12, -12, 0).
  const Vec3 top(0, 0, 1);
  int naive_wrong = 0;
  for (int i = 0; i < 64; ++i) {
    for (int j = 0; j < 64; ++j) {
      const Vec3 p(0.5 + i * u, 0.5 + j * u, 0.0);
      const int expect = (j > i) - (j < i);
      ASSERT_EQ(Orient2D(p, q, r, 2), expect) << i << " " << j;
      ASSERT_EQ(Orient3D(q, r, top, Vec3(p.x(), p.y(), 0.3)), -expect) << i << " " << j;
      const double naive = (q.x() - p.x()) * (r.y() - p.y()) - (q.y() - p.y()) * (r.x() - p.x());
      if ((naive > 0) - (naive < 0) != expect) ++naive_wrong;
    }
  }
  EXPECT_GT(naive_wrong, 0);  // the case is hard: plain doubles get some of them wrong
}

TEST(SelfPredicatesTest, PermutationsAgreeOnNearlyCoplanarPoints) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int k = 0; k < 2000; ++k) {
    // Three random points and a fourth in their plane up to rounding (a rounded affine
    // combination), then moved by a few ulps or not at all.
    const Vec3 a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng)), c(u(rng), u(rng), u(rng));
    const double s = u(rng), t = u(rng);
    Vec3 d = a + s * (b - a) + t * (c - a);
    if (k % 3 == 1) d.z() = std::nextafter(d.z(), 2.0);
    const int o = Orient3D(a, b, c, d);
    ASSERT_EQ(Orient3D(b, c, a, d), o);
    ASSERT_EQ(Orient3D(b, a, c, d), -o);
    ASSERT_EQ(Orient3D(a, b, d, c), -o);
    ASSERT_EQ(Orient3D(d, b, c, a), -o);
    // Scaling by a power of two is exact and keeps the sign.
    ASSERT_EQ(Orient3D(0x1p-7 * a, 0x1p-7 * b, 0x1p-7 * c, 0x1p-7 * d), o);
    for (int axis = 0; axis < 3; ++axis) {
      const int o2 = Orient2D(a, b, d, axis);
      ASSERT_EQ(Orient2D(b, d, a, axis), o2);
      ASSERT_EQ(Orient2D(b, a, d, axis), -o2);
    }
  }
}

TEST(SelfIntersectionTest, ClosedFormCases) {
  const Tri base = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  // A vertical triangle through the face.
  EXPECT_TRUE(Intersect(base, {Vec3(0.2, 0.2, -1), Vec3(0.2, 0.2, 1), Vec3(0.3, 0.1, 1)}));
  // The same one moved beyond the hypotenuse.
  EXPECT_FALSE(Intersect(base, {Vec3(0.7, 0.7, -1), Vec3(0.7, 0.7, 1), Vec3(0.8, 0.6, 1)}));
  // Parallel planes.
  EXPECT_FALSE(Intersect(base, {Vec3(0, 0, 1e-300), Vec3(1, 0, 1e-300), Vec3(0, 1, 1e-300)}));
  // A vertex resting on the face touches; a hair above it does not.
  EXPECT_TRUE(Intersect(base, {Vec3(0.25, 0.25, 0), Vec3(0, 0, 1), Vec3(1, 1, 1)}));
  EXPECT_FALSE(Intersect(base, {Vec3(0.25, 0.25, 0x1p-60), Vec3(0, 0, 1), Vec3(1, 1, 1)}));
  // A vertex exactly on an edge of the base, the rest above it.
  EXPECT_TRUE(Intersect(base, {Vec3(0.5, 0, 0), Vec3(0.5, -1, 1), Vec3(0.5, 1, 1)}));
  // Edge on edge: an edge of a triangle in the plane x = 0.5 crosses the base's edge y = 0 at
  // (0.5, 0, 0), the rest of it on the side y < 0; moved by 1e-9 m toward -y it misses.
  EXPECT_TRUE(Intersect(base, {Vec3(0.5, -0.5, -0.5), Vec3(0.5, 0.5, 0.5), Vec3(0.5, -1, 1)}));
  EXPECT_FALSE(Intersect(
      base, {Vec3(0.5, -0.5 - 1e-9, -0.5), Vec3(0.5, 0.5 - 1e-9, 0.5), Vec3(0.5, -1, 1)}));
  // Coplanar: overlapping, contained, touching at a vertex, disjoint.
  EXPECT_TRUE(Intersect(base, {Vec3(0.5, 0.5, 0), Vec3(-0.5, 0.5, 0), Vec3(0.5, -0.5, 0)}));
  EXPECT_TRUE(Intersect(base, {Vec3(0.1, 0.1, 0), Vec3(0.2, 0.1, 0), Vec3(0.1, 0.2, 0)}));
  EXPECT_TRUE(Intersect(base, {Vec3(1, 0, 0), Vec3(2, 0, 0), Vec3(2, 1, 0)}));
  EXPECT_FALSE(Intersect(base, {Vec3(0.6, 0.6, 0), Vec3(2, 0.6, 0), Vec3(0.6, 2, 0)}));
  // Coplanar sharing a whole edge with opposite sides (a flat grid's two halves of a cell).
  EXPECT_TRUE(Intersect(base, {Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)}));
  // Degenerate triangles: a segment piercing the face, a point on it, a point off it.
  EXPECT_TRUE(Intersect(base, {Vec3(0.2, 0.2, -1), Vec3(0.2, 0.2, 1), Vec3(0.2, 0.2, 0.5)}));
  EXPECT_TRUE(Intersect(base, {Vec3(0.2, 0.3, 0), Vec3(0.2, 0.3, 0), Vec3(0.2, 0.3, 0)}));
  EXPECT_FALSE(
      Intersect(base, {Vec3(0.2, 0.3, 1e-12), Vec3(0.2, 0.3, 1e-12), Vec3(0.2, 0.3, 1e-12)}));
  // Two degenerate triangles: crossing segments, and parallel disjoint ones.
  EXPECT_TRUE(Intersect({Vec3(0, 0, 0), Vec3(2, 2, 0), Vec3(1, 1, 0)},
                        {Vec3(0, 2, 0), Vec3(2, 0, 0), Vec3(2, 0, 0)}));
  EXPECT_FALSE(Intersect({Vec3(0, 0, 0), Vec3(2, 2, 0), Vec3(1, 1, 0)},
                         {Vec3(0, 1, 0), Vec3(2, 3, 0), Vec3(2, 3, 0)}));
  EXPECT_TRUE(Intersect({Vec3(0, 0, 0), Vec3(2, 2, 2), Vec3(1, 1, 1)},
                        {Vec3(2, 2, 2), Vec3(3, 3, 3), Vec3(3, 3, 3)}));  // collinear, touching
}

// Random triangles of a few kinds: general, on a small integer grid (many exact coplanarities,
// collinearities, shared and repeated points), and near-touching (a vertex placed on the other
// triangle up to rounding).
Tri RandomTriangle(std::mt19937_64& rng, int kind) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_int_distribution<int> g(0, 3);
  Tri t;
  for (Vec3& v : t) {
    v = kind == 1 ? Vec3(g(rng), g(rng), g(rng)) : Vec3(u(rng), u(rng), u(rng));
  }
  return t;
}

TEST(SelfIntersectionTest, MatchesEdgesBothWaysReferenceOnRandomAndDegenerateInputs) {
  std::mt19937_64 rng(22);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  int hits = 0, total = 0;
  for (int kind = 0; kind < 3; ++kind) {
    for (int k = 0; k < 20000; ++k) {
      Tri t = RandomTriangle(rng, kind);
      Tri s = RandomTriangle(rng, kind);
      if (kind == 2) {
        // Put one vertex of s on t (up to rounding) or on an edge of t.
        double a = u01(rng), b = u01(rng);
        if (a + b > 1) a = 1 - a, b = 1 - b;
        if (k % 2) b = 0;
        s[0] = t[0] + a * (t[1] - t[0]) + b * (t[2] - t[0]);
      }
      const bool expect = ReferenceIntersect(t, s);
      ASSERT_EQ(Intersect(t, s), expect) << kind << " " << k;
      // Invariances: order of the triangles, of their vertices, orientation.
      ASSERT_EQ(Intersect(s, t), expect);
      ASSERT_EQ(Intersect({t[1], t[2], t[0]}, {s[2], s[0], s[1]}), expect);
      ASSERT_EQ(Intersect({t[1], t[0], t[2]}, s), expect);
      ASSERT_EQ(Intersect(t, {s[0], s[2], s[1]}), expect);
      // Exact similarity: translation by integers and scaling by a power of two.
      Tri t2 = t, s2 = s;
      for (Vec3& v : t2) v = 0.25 * v + Vec3(3, -5, 1);
      for (Vec3& v : s2) v = 0.25 * v + Vec3(3, -5, 1);
      if (kind == 1) {
        ASSERT_EQ(Intersect(t2, s2), expect);
      }
      hits += expect;
      ++total;
    }
  }
  // Both outcomes are well represented.
  EXPECT_GT(hits, total / 10);
  EXPECT_LT(hits, total * 9 / 10);
}

// A grid of width x height vertices over [0, 1]^2 in the plane z = 0, rotated and shifted.
std::vector<Vec3> RotatedGrid(int32_t w, int32_t h, const Eigen::Matrix3d& rot, const Vec3& shift) {
  std::vector<Vec3> x;
  for (int32_t r = 0; r < h; ++r) {
    for (int32_t c = 0; c < w; ++c)
      x.push_back(rot * Vec3(c / (w - 1.0), r / (h - 1.0), 0) + shift);
  }
  return x;
}

TEST(SelfIntersectionTest, FlatGridsHaveNone) {
  const std::vector<Triangle> tris = MakeGridTriangles(17, 13);
  EXPECT_EQ(
      CountSelfIntersections(RotatedGrid(17, 13, Eigen::Matrix3d::Identity(), Vec3::Zero()), tris),
      0);
  // Rotated off the axes, so that the rounded vertices are no longer exactly coplanar.
  const Eigen::Matrix3d rot =
      (Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized())).toRotationMatrix();
  EXPECT_EQ(CountSelfIntersections(RotatedGrid(17, 13, rot, Vec3(0.1, -3, 7)), tris), 0);
}

// A 9-column grid folded into a Z: a flat bottom (z = 0), a vertical wall at y = 0.75, and a top
// layer that comes back over the bottom sloping down through it along the line y = y_c, z = 0.
// Shifted by 0.3 columns in x, the top layer crosses the bottom in one row of cells, whose
// triangles cut the line into intervals with breakpoints at column bounds and diagonal
// crossings; each pair of a top and a bottom interval that overlap is one intersecting pair.
struct FoldedGrid {
  int32_t width = 9;
  int32_t height = 0;
  std::vector<Vec3> x;
};

FoldedGrid MakeZFold(double top_drop_m) {
  FoldedGrid g;
  const double dx = 1.0 / 8, dy = 1.0 / 8, dz = 0.051;
  const int32_t bottom_rows = 7, wall_rows = 2, top_rows = 5;
  g.height = bottom_rows + wall_rows + top_rows;
  const double shift = 0.3 * dx;
  const double slope = top_drop_m;  // z lost per top row
  for (int32_t r = 0; r < g.height; ++r) {
    for (int32_t c = 0; c < g.width; ++c) {
      if (r < bottom_rows) {
        g.x.emplace_back(c * dx, r * dy, 0.0);
      } else if (r < bottom_rows + wall_rows) {
        const int32_t k = r - bottom_rows + 1;  // 1..wall_rows
        g.x.emplace_back(c * dx + shift * k / wall_rows, (bottom_rows - 1) * dy, k * dz);
      } else {
        const int32_t k = r - bottom_rows - wall_rows + 1;  // 1..top_rows
        g.x.emplace_back(c * dx + shift, (bottom_rows - 1 - k) * dy, wall_rows * dz - k * slope);
      }
    }
  }
  return g;
}

TEST(SelfIntersectionTest, ZFoldHasTheCountedPairs) {
  // The top layer loses 0.04 m per row from z = 0.102 at the wall: it crosses z = 0 at 2.55 rows
  // (lambda = 0.55 along its diagonals), at y = (6 - 2.55) / 8, mu = 0.45 into bottom row 3.
  const FoldedGrid g = MakeZFold(0.04);
  const std::vector<Triangle> tris = MakeGridTriangles(g.width, g.height);
  // Breakpoints on the crossing line, in columns, inside the common range (0.3, 8):
  // top column bounds c + 0.3 (c = 1..7), top diagonals c + 0.85 (c = 0..7), bottom column
  // bounds c (c = 1..7), bottom diagonals c + 0.45 (c = 0..7): 7 + 8 + 7 + 8 = 30, and one more
  // pair than breakpoints.
  int32_t breakpoints = 0;
  for (int c = 0; c <= 8; ++c) {
    for (double f : {0.3, 0.85, 0.0, 0.45}) {
      if (c + f > 0.3 && c + f < 8.0 && !(f == 0.3 && c == 0)) ++breakpoints;
    }
  }
  EXPECT_EQ(breakpoints, 30);
  EXPECT_EQ(CountSelfIntersections(g.x, tris), breakpoints + 1);
  // Every reported pair is one top and one bottom triangle, and the reference agrees pair by pair.
  const auto pairs = FindSelfIntersections(g.x, tris);
  ASSERT_EQ(static_cast<int64_t>(pairs.size()), breakpoints + 1);
  int64_t reference = 0;
  for (size_t i = 0; i < tris.size(); ++i) {
    for (size_t j = i + 1; j < tris.size(); ++j) {
      if (TrianglesShareVertex(tris[i], tris[j])) continue;
      const Tri t = {g.x[tris[i][0]], g.x[tris[i][1]], g.x[tris[i][2]]};
      const Tri s = {g.x[tris[j][0]], g.x[tris[j][1]], g.x[tris[j][2]]};
      reference += ReferenceIntersect(t, s);
    }
  }
  EXPECT_EQ(reference, breakpoints + 1);
  // Raised so that the top layer stays above the bottom (it reaches z = 0.102 - 5 * 0.02 > 0):
  // no pair.
  const FoldedGrid raised = MakeZFold(0.02);
  EXPECT_EQ(CountSelfIntersections(raised.x, tris), 0);
}

TEST(SelfIntersectionTest, DegenerateMeshMatchesReference) {
  // A crumpled 9 x 9 grid with collapsed vertices and repeated-index triangles.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const int32_t w = 9;
  std::vector<Vec3> x = RotatedGrid(w, w, Eigen::Matrix3d::Identity(), Vec3::Zero());
  for (Vec3& p : x) p += Vec3(u(rng), u(rng), 3 * u(rng)) * 0.08;
  x[GridIndex(w, 2, 4)] = x[GridIndex(w, 3, 4)];
  x[GridIndex(w, 5, 2)] = 0.5 * (x[GridIndex(w, 4, 2)] + x[GridIndex(w, 6, 2)]);
  std::vector<Triangle> tris = MakeGridTriangles(w, w);
  tris.push_back({0, 0, 1});
  tris.push_back({40, 40, 40});
  int64_t reference = 0;
  for (size_t i = 0; i < tris.size(); ++i) {
    for (size_t j = i + 1; j < tris.size(); ++j) {
      if (TrianglesShareVertex(tris[i], tris[j])) continue;
      const Tri t = {x[tris[i][0]], x[tris[i][1]], x[tris[i][2]]};
      const Tri s = {x[tris[j][0]], x[tris[j][1]], x[tris[j][2]]};
      reference += ReferenceIntersect(t, s);
    }
  }
  EXPECT_GT(reference, 0);  // crumpled hard enough to pass through itself
  EXPECT_EQ(CountSelfIntersections(x, tris), reference);
}

// The sort and sweep that finds the pairs to test misses none: on crumpled grids (ties in the
// boxes' lowest x included, and a NaN vertex, whose boxes have no order) FindSelfIntersections
// gives exactly the pairs, in order, of a loop over all pairs with the same exact test.
TEST(SelfIntersectionTest, SweepFindsWhatAllPairsFind) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 4; ++trial) {
    const int32_t w = 12;
    std::vector<Vec3> x = RotatedGrid(w, w, Eigen::Matrix3d::Identity(), Vec3::Zero());
    for (Vec3& p : x) p += Vec3(u(rng), u(rng), 3 * u(rng)) * 0.06;
    for (int32_t c = 0; c < w; ++c) x[GridIndex(w, c, 3)].x() = x[GridIndex(w, 0, 3)].x();
    if (trial >= 2) x[GridIndex(w, 6, 6)].y() = std::numeric_limits<double>::quiet_NaN();
    const std::vector<Triangle> tris = MakeGridTriangles(w, w);
    std::vector<std::pair<int32_t, int32_t>> all_pairs;
    for (int32_t i = 0; i < static_cast<int32_t>(tris.size()); ++i) {
      for (int32_t j = i + 1; j < static_cast<int32_t>(tris.size()); ++j) {
        if (TrianglesShareVertex(tris[i], tris[j])) continue;
        const Triangle& t = tris[i];
        const Triangle& v = tris[j];
        if (TrianglesIntersect(x[t[0]], x[t[1]], x[t[2]], x[v[0]], x[v[1]], x[v[2]])) {
          all_pairs.emplace_back(i, j);
        }
      }
    }
    EXPECT_GT(all_pairs.size(), 10u) << trial;  // crumpled hard enough
    EXPECT_EQ(FindSelfIntersections(x, tris), all_pairs) << trial;
    EXPECT_EQ(CountSelfIntersections(x, tris), static_cast<int64_t>(all_pairs.size())) << trial;
  }
}

}  // namespace
}  // namespace felt
