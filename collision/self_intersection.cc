#include "collision/self_intersection.h"
// The implementations of collision/self_predicates.h and collision/self_intersection.h (one file:
// see docs/self_collision.md, "Build note").

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>
#include <vector>

#include "base/check.h"
#include "collision/self_predicates.h"

namespace felt {

// ----------------------------------------------------------------------------------------------
// collision/self_predicates.h
// ----------------------------------------------------------------------------------------------

namespace {

// Half an ulp of 1, Shewchuk's "epsilon" (1997).
constexpr double kPredEps = 0x1p-53;
// Error bounds of the floating-point evaluations below (Shewchuk 1997: orient3d's
// o3derrboundA and orient2d's ccwerrboundA), relative to the permanent of the determinant.
constexpr double kOrient3dBound = (7.0 + 56.0 * kPredEps) * kPredEps;
constexpr double kOrient2dBound = (3.0 + 16.0 * kPredEps) * kPredEps;

// A nonoverlapping expansion (Shewchuk 1997): the exact value is the sum of the components,
// stored by increasing magnitude without zeros, so its sign is the sign of the last component.
// The capacity covers the largest expansion formed here (the 3x3 determinant: at most 192).
struct Expansion {
  static constexpr int kCapacity = 256;
  std::array<double, kCapacity> c;
  int n = 0;
  void Push(double v) {
    FELT_CHECK(n < kCapacity);
    if (v != 0.0) c[n++] = v;
  }
  int Sign() const { return n == 0 ? 0 : (c[n - 1] > 0.0 ? 1 : -1); }
};

// x + y == a + b exactly, x = fl(a + b) (Knuth's TwoSum; Shewchuk 1997, Theorem 7).
void ExactSum(double a, double b, double* x, double* y) {
  *x = a + b;
  const double bv = *x - a;
  const double av = *x - bv;
  *y = (a - av) + (b - bv);
}

// x + y == a * b exactly, x = fl(a b): the fused multiply-add gives the rounding error exactly.
void ExactProduct(double a, double b, double* x, double* y) {
  *x = a * b;
  *y = std::fma(a, b, -*x);
}

// The exact difference a - b as an expansion of at most two components.
Expansion DiffExpansion(double a, double b) {
  double x, y;
  ExactSum(a, -b, &x, &y);
  Expansion e;
  e.Push(y);
  e.Push(x);
  return e;
}

// e += b (Shewchuk 1997, Grow-Expansion with zero elimination; in place, since at most one
// component is written per component read).
void GrowExpansion(Expansion* e, double b) {
  double q = b;
  int out = 0;
  for (int i = 0; i < e->n; ++i) {
    double h;
    ExactSum(q, e->c[i], &q, &h);
    if (h != 0.0) e->c[out++] = h;
  }
  e->n = out;
  e->Push(q);
}

// e + f, one component of f at a time (Shewchuk 1997, Expansion-Sum).
Expansion SumExpansion(const Expansion& e, const Expansion& f) {
  Expansion s = e;
  for (int j = 0; j < f.n; ++j) GrowExpansion(&s, f.c[j]);
  return s;
}

// e * b (Shewchuk 1997, Scale-Expansion with zero elimination; TwoSum in place of FastTwoSum,
// which gives the same two results without FastTwoSum's precondition).
Expansion ScaleExpansion(const Expansion& e, double b) {
  Expansion s;
  if (e.n == 0 || b == 0.0) return s;
  double q, h;
  ExactProduct(e.c[0], b, &q, &h);
  s.Push(h);
  for (int i = 1; i < e.n; ++i) {
    double hi, lo, sum;
    ExactProduct(e.c[i], b, &hi, &lo);
    ExactSum(q, lo, &sum, &h);
    s.Push(h);
    ExactSum(hi, sum, &q, &h);
    s.Push(h);
  }
  s.Push(q);
  return s;
}

// e * f, as the sum of e scaled by each component of f.
Expansion MulExpansion(const Expansion& e, const Expansion& f) {
  Expansion p;
  for (int j = 0; j < f.n; ++j) p = SumExpansion(p, ScaleExpansion(e, f.c[j]));
  return p;
}

Expansion NegExpansion(Expansion e) {
  for (int i = 0; i < e.n; ++i) e.c[i] = -e.c[i];
  return e;
}

// Exact sign of u_i v_j - u_j v_i for two difference vectors given as expansions.
Expansion Cross2(const Expansion& ui, const Expansion& uj, const Expansion& vi,
                 const Expansion& vj) {
  return SumExpansion(MulExpansion(ui, vj), NegExpansion(MulExpansion(uj, vi)));
}

// Exact sign of det[a - d, b - d, c - d] (Shewchuk's orient3d, positive when d lies below the
// plane of a, b, c seen counter-clockwise from above).
int Orient3dExactSign(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  std::array<Expansion, 3> ad, bd, cd;
  for (int k = 0; k < 3; ++k) {
    ad[k] = DiffExpansion(a[k], d[k]);
    bd[k] = DiffExpansion(b[k], d[k]);
    cd[k] = DiffExpansion(c[k], d[k]);
  }
  // Cofactor expansion along the z components.
  const Expansion t0 = MulExpansion(ad[2], Cross2(bd[0], bd[1], cd[0], cd[1]));
  const Expansion t1 = MulExpansion(bd[2], Cross2(cd[0], cd[1], ad[0], ad[1]));
  const Expansion t2 = MulExpansion(cd[2], Cross2(ad[0], ad[1], bd[0], bd[1]));
  return SumExpansion(SumExpansion(t0, t1), t2).Sign();
}

}  // namespace

int Orient3D(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  // Floating-point filter (Shewchuk 1997, orient3d with its bound A), on det[a-d, b-d, c-d],
  // which is -((b - a) x (c - a)) . (d - a).
  const double adx = a.x() - d.x(), ady = a.y() - d.y(), adz = a.z() - d.z();
  const double bdx = b.x() - d.x(), bdy = b.y() - d.y(), bdz = b.z() - d.z();
  const double cdx = c.x() - d.x(), cdy = c.y() - d.y(), cdz = c.z() - d.z();
  const double bdxcdy = bdx * cdy, cdxbdy = cdx * bdy;
  const double cdxady = cdx * ady, adxcdy = adx * cdy;
  const double adxbdy = adx * bdy, bdxady = bdx * ady;
  const double det = adz * (bdxcdy - cdxbdy) + bdz * (cdxady - adxcdy) + cdz * (adxbdy - bdxady);
  const double permanent = (std::abs(bdxcdy) + std::abs(cdxbdy)) * std::abs(adz) +
                           (std::abs(cdxady) + std::abs(adxcdy)) * std::abs(bdz) +
                           (std::abs(adxbdy) + std::abs(bdxady)) * std::abs(cdz);
  const double bound = kOrient3dBound * permanent;
  if (det > bound) return -1;
  if (-det > bound) return 1;
  // Every product is exactly zero (no underflow assumed): the determinant is exactly zero.
  if (permanent == 0.0) return 0;
  return -Orient3dExactSign(a, b, c, d);
}

int Orient2D(const Vec3& a, const Vec3& b, const Vec3& c, int axis) {
  FELT_CHECK(axis >= 0 && axis <= 2);
  const int i = (axis + 1) % 3;
  const int j = (axis + 2) % 3;
  // Floating-point filter (Shewchuk 1997, orient2d with its bound A) on
  // (a_i - c_i)(b_j - c_j) - (a_j - c_j)(b_i - c_i), which equals ((b - a) x (c - a))[axis].
  const double left = (a[i] - c[i]) * (b[j] - c[j]);
  const double right = (a[j] - c[j]) * (b[i] - c[i]);
  const double det = left - right;
  const double permanent = std::abs(left) + std::abs(right);
  const double bound = kOrient2dBound * permanent;
  if (det > bound) return 1;
  if (-det > bound) return -1;
  if (permanent == 0.0) return 0;
  // Exact: the same expression with expansions.
  const Expansion exact = Cross2(DiffExpansion(a[i], c[i]), DiffExpansion(a[j], c[j]),
                                 DiffExpansion(b[i], c[i]), DiffExpansion(b[j], c[j]));
  return exact.Sign();
}

bool ExactlyCollinear(const Vec3& a, const Vec3& b, const Vec3& c) {
  return Orient2D(a, b, c, 0) == 0 && Orient2D(a, b, c, 1) == 0 && Orient2D(a, b, c, 2) == 0;
}

// ----------------------------------------------------------------------------------------------
// collision/self_intersection.h
// ----------------------------------------------------------------------------------------------

namespace {

// An axis along which the non-collinear triangle (a, b, c) projects onto a non-degenerate
// triangle (its normal's component there is exactly non-zero), preferring the normal's largest
// component; -1 when the three points are exactly collinear.
int FaithfulAxis(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 n = (b - a).cross(c - a).cwiseAbs();
  std::array<int, 3> order = {0, 1, 2};
  std::sort(order.begin(), order.end(), [&](int i, int j) { return n[i] > n[j]; });
  for (int k : order) {
    if (Orient2D(a, b, c, k) != 0) return k;
  }
  return -1;
}

// True when r lies in the closed box of p and q on the two coordinates of the projection along
// `axis` (for an r collinear with p and q in that projection: r on the closed segment).
bool InProjectedBox(const Vec3& p, const Vec3& q, const Vec3& r, int axis) {
  for (int k = 0; k < 3; ++k) {
    if (k == axis) continue;
    if (r[k] < std::min(p[k], q[k]) || r[k] > std::max(p[k], q[k])) return false;
  }
  return true;
}

// Closed segments [p, q] and [a, b] in the projection along `axis` share a point (the classic
// orientation test, with the collinear and touching cases decided by the boxes).
bool SegmentsIntersect2D(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, int axis) {
  const int o1 = Orient2D(p, q, a, axis);
  const int o2 = Orient2D(p, q, b, axis);
  const int o3 = Orient2D(a, b, p, axis);
  const int o4 = Orient2D(a, b, q, axis);
  if (o1 * o2 < 0 && o3 * o4 < 0) return true;
  if (o1 == 0 && InProjectedBox(p, q, a, axis)) return true;
  if (o2 == 0 && InProjectedBox(p, q, b, axis)) return true;
  if (o3 == 0 && InProjectedBox(a, b, p, axis)) return true;
  if (o4 == 0 && InProjectedBox(a, b, q, axis)) return true;
  return false;
}

// p lies in the closed triangle (a, b, c), non-degenerate in the projection along `axis`.
bool PointInTriangle2D(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, int axis) {
  const int o1 = Orient2D(a, b, p, axis);
  const int o2 = Orient2D(b, c, p, axis);
  const int o3 = Orient2D(c, a, p, axis);
  return (o1 >= 0 && o2 >= 0 && o3 >= 0) || (o1 <= 0 && o2 <= 0 && o3 <= 0);
}

// The closed segment [p, q] meets the closed triangle (a, b, c), all in one plane that projects
// faithfully along `axis`: an end inside, or the segment crossing an edge.
bool SegmentTriangle2D(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c,
                       int axis) {
  return PointInTriangle2D(p, a, b, c, axis) || PointInTriangle2D(q, a, b, c, axis) ||
         SegmentsIntersect2D(p, q, a, b, axis) || SegmentsIntersect2D(p, q, b, c, axis) ||
         SegmentsIntersect2D(p, q, c, a, axis);
}

// Two coplanar non-degenerate triangles that project faithfully along `axis` share a point: a
// vertex of one lies in the other, or two edges cross (if neither holds, the boundaries are
// disjoint and neither contains the other).
bool TrianglesIntersect2D(const std::array<Vec3, 3>& t, const std::array<Vec3, 3>& u, int axis) {
  for (int i = 0; i < 3; ++i) {
    if (PointInTriangle2D(t[i], u[0], u[1], u[2], axis)) return true;
    if (PointInTriangle2D(u[i], t[0], t[1], t[2], axis)) return true;
  }
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (SegmentsIntersect2D(t[i], t[(i + 1) % 3], u[j], u[(j + 1) % 3], axis)) return true;
    }
  }
  return false;
}

// Rotates triangle t (and its vertices' plane signs s) so that t[0] is alone on its closed side of
// the other triangle's plane: after an optional negation of every sign (*flip), s[0] >= 0 and
// s[1], s[2] <= 0. A vertex off the plane is preferred as t[0]; a vertex on the plane is t[0] only
// when the other two lie strictly on one side. Signs must not be all equal and non-zero, nor all
// zero (Guigue & Devillers 2003: the permutation that isolates one vertex).
void IsolateApex(std::array<Vec3, 3>* t, std::array<int, 3>* s, bool* flip) {
  for (int pass = 0; pass < 2; ++pass) {
    for (int r = 0; r < 3; ++r) {
      const int i = r, j = (r + 1) % 3, k = (r + 2) % 3;
      const int si = (*s)[i];
      const bool isolated = pass == 0 ? si != 0 && si * (*s)[j] <= 0 && si * (*s)[k] <= 0
                                      : si == 0 && (*s)[j] == (*s)[k] && (*s)[j] != 0;
      if (!isolated) continue;
      std::rotate(t->begin(), t->begin() + i, t->end());
      std::rotate(s->begin(), s->begin() + i, s->end());
      *flip = pass == 0 ? si < 0 : (*s)[1] > 0;
      return;
    }
  }
  FELT_CHECK(false);  // unreachable for the sign patterns allowed above
}

bool AllSameStrictSign(const std::array<int, 3>& s) {
  return (s[0] > 0 && s[1] > 0 && s[2] > 0) || (s[0] < 0 && s[1] < 0 && s[2] < 0);
}

}  // namespace

bool SegmentsIntersect(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b) {
  if (Orient3D(p, q, a, b) != 0) return false;
  // Coplanar: project along an axis faithful to any non-collinear triple of the four points.
  const std::array<std::array<const Vec3*, 3>, 4> triples = {
      {{&p, &q, &a}, {&p, &q, &b}, {&a, &b, &p}, {&a, &b, &q}}};
  for (const auto& tr : triples) {
    const int axis = FaithfulAxis(*tr[0], *tr[1], *tr[2]);
    if (axis >= 0) return SegmentsIntersect2D(p, q, a, b, axis);
  }
  // All four on one line: compare the intervals on a coordinate along which the line advances.
  for (int k = 0; k < 3; ++k) {
    if (p[k] == q[k] && q[k] == a[k] && a[k] == b[k]) continue;
    return std::max(std::min(p[k], q[k]), std::min(a[k], b[k])) <=
           std::min(std::max(p[k], q[k]), std::max(a[k], b[k]));
  }
  return true;  // all four are one point
}

bool SegmentIntersectsTriangle(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b,
                               const Vec3& c) {
  // A degenerate triangle is the union of its edges.
  if (ExactlyCollinear(a, b, c)) {
    return SegmentsIntersect(p, q, a, b) || SegmentsIntersect(p, q, b, c) ||
           SegmentsIntersect(p, q, c, a);
  }
  const int sp = Orient3D(a, b, c, p);
  const int sq = Orient3D(a, b, c, q);
  if (sp * sq > 0) return false;
  // In the triangle's plane: the 2D test.
  if (sp == 0 && sq == 0) return SegmentTriangle2D(p, q, a, b, c, FaithfulAxis(a, b, c));
  // The segment meets the plane at one point, inside the triangle when the line pq passes on the
  // same side of the three edges (the signed volumes of pq with each edge agree).
  const int s1 = Orient3D(p, q, a, b);
  const int s2 = Orient3D(p, q, b, c);
  const int s3 = Orient3D(p, q, c, a);
  return (s1 >= 0 && s2 >= 0 && s3 >= 0) || (s1 <= 0 && s2 <= 0 && s3 <= 0);
}

bool TrianglesIntersect(const Vec3& a1, const Vec3& b1, const Vec3& c1, const Vec3& a2,
                        const Vec3& b2, const Vec3& c2) {
  // Degenerate triangles: their edges against the other triangle.
  if (ExactlyCollinear(a1, b1, c1)) {
    return SegmentIntersectsTriangle(a1, b1, a2, b2, c2) ||
           SegmentIntersectsTriangle(b1, c1, a2, b2, c2) ||
           SegmentIntersectsTriangle(c1, a1, a2, b2, c2);
  }
  if (ExactlyCollinear(a2, b2, c2)) {
    return SegmentIntersectsTriangle(a2, b2, a1, b1, c1) ||
           SegmentIntersectsTriangle(b2, c2, a1, b1, c1) ||
           SegmentIntersectsTriangle(c2, a2, a1, b1, c1);
  }
  // Each triangle against the other's plane: strictly on one side means no contact.
  std::array<int, 3> s1 = {Orient3D(a2, b2, c2, a1), Orient3D(a2, b2, c2, b1),
                           Orient3D(a2, b2, c2, c1)};
  if (AllSameStrictSign(s1)) return false;
  std::array<int, 3> s2 = {Orient3D(a1, b1, c1, a2), Orient3D(a1, b1, c1, b2),
                           Orient3D(a1, b1, c1, c2)};
  if (AllSameStrictSign(s2)) return false;
  std::array<Vec3, 3> t1 = {a1, b1, c1};
  std::array<Vec3, 3> t2 = {a2, b2, c2};
  // Coplanar (a non-degenerate triangle with its three vertices on the other's plane spans it).
  if (s1[0] == 0 && s1[1] == 0 && s1[2] == 0) {
    return TrianglesIntersect2D(t1, t2, FaithfulAxis(a1, b1, c1));
  }
  // Guigue & Devillers 2003: with p1 alone on the positive side of T2's plane and p2 alone on
  // the positive side of T1's plane (swapping the other two vertices of a triangle reverses its
  // plane), both triangles cross the planes' common line in intervals [i, j] (on p1q1, p1r1) and
  // [k, l] (on p2q2, p2r2); they overlap when k is not past j and i is not past l, which are the
  // signs of two orientations.
  bool flip1 = false, flip2 = false;
  IsolateApex(&t1, &s1, &flip1);
  IsolateApex(&t2, &s2, &flip2);
  if (flip1) std::swap(t2[1], t2[2]);
  if (flip2) std::swap(t1[1], t1[2]);
  return Orient3D(t1[0], t1[1], t2[0], t2[1]) <= 0 && Orient3D(t1[0], t1[2], t2[2], t2[0]) <= 0;
}

bool TrianglesShareVertex(const Triangle& t, const Triangle& u) {
  for (int32_t i : t) {
    for (int32_t j : u) {
      if (i == j) return true;
    }
  }
  return false;
}

namespace {

// Calls visit(i, j) for every intersecting non-adjacent pair i < j, in no set order. Every pair
// whose closed boxes overlap is tested exactly, found by a sort and sweep along x (Baraff 1992's
// sweep on one axis: with the boxes in order of their lowest x, the boxes that overlap box k along
// x and come after it are the run that starts before box k's highest x), so the pairs tested are
// those an all-pairs loop over the boxes would test, at O(n log n + overlaps) instead of O(n^2).
// A box with a NaN coordinate has no place in the order: it is tested against every box.
template <class Visit>
void ForEachSelfIntersection(std::span<const Vec3> x, std::span<const Triangle> triangles,
                             Visit&& visit) {
  // Closed boxes of the triangles (exact: min and max of the coordinates).
  std::vector<std::pair<Vec3, Vec3>> boxes(triangles.size());
  std::vector<int32_t> order, unordered;
  for (size_t i = 0; i < triangles.size(); ++i) {
    const Triangle& t = triangles[i];
    for (int32_t v : t) FELT_CHECK(v >= 0 && static_cast<size_t>(v) < x.size());
    boxes[i].first = x[t[0]].cwiseMin(x[t[1]]).cwiseMin(x[t[2]]);
    boxes[i].second = x[t[0]].cwiseMax(x[t[1]]).cwiseMax(x[t[2]]);
    const bool nan = boxes[i].first.array().isNaN().any() || boxes[i].second.array().isNaN().any();
    (nan ? unordered : order).push_back(static_cast<int32_t>(i));
  }
  const auto test = [&](int32_t a, int32_t b) {
    const int32_t i = std::min(a, b), j = std::max(a, b);
    if (TrianglesShareVertex(triangles[i], triangles[j])) return;
    const auto& bi = boxes[i];
    const auto& bj = boxes[j];
    if ((bi.second.array() < bj.first.array()).any() ||
        (bj.second.array() < bi.first.array()).any()) {
      return;
    }
    const Triangle& t = triangles[i];
    const Triangle& u = triangles[j];
    if (TrianglesIntersect(x[t[0]], x[t[1]], x[t[2]], x[u[0]], x[u[1]], x[u[2]])) visit(i, j);
  };
  std::sort(order.begin(), order.end(), [&](int32_t a, int32_t b) {
    return boxes[a].first.x() < boxes[b].first.x() ||
           (boxes[a].first.x() == boxes[b].first.x() && a < b);
  });
  for (size_t k = 0; k < order.size(); ++k) {
    const double high_x = boxes[order[k]].second.x();
    for (size_t m = k + 1; m < order.size() && boxes[order[m]].first.x() <= high_x; ++m) {
      test(order[k], order[m]);
    }
  }
  for (size_t k = 0; k < unordered.size(); ++k) {
    for (const int32_t other : order) test(unordered[k], other);
    for (size_t m = k + 1; m < unordered.size(); ++m) test(unordered[k], unordered[m]);
  }
}

}  // namespace

std::vector<std::pair<int32_t, int32_t>> FindSelfIntersections(
    std::span<const Vec3> x, std::span<const Triangle> triangles) {
  std::vector<std::pair<int32_t, int32_t>> pairs;
  ForEachSelfIntersection(x, triangles, [&](int32_t i, int32_t j) { pairs.emplace_back(i, j); });
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

int64_t CountSelfIntersections(std::span<const Vec3> x, std::span<const Triangle> triangles) {
  int64_t count = 0;
  ForEachSelfIntersection(x, triangles, [&](int32_t, int32_t) { ++count; });
  return count;
}

}  // namespace felt
