#include "collision/self_predicates.h"

#include <array>
#include <cmath>

#include "base/check.h"

namespace felt {
namespace {

// Half an ulp of 1, Shewchuk's "epsilon" (1997, §2.1).
constexpr double kPredEps = 0x1p-53;
// Error bounds of the floating-point evaluations below (Shewchuk 1997, §4.3: orient3d's
// o3derrboundA and orient2d's ccwerrboundA), relative to the permanent of the determinant.
constexpr double kOrient3dBound = (7.0 + 56.0 * kPredEps) * kPredEps;
constexpr double kOrient2dBound = (3.0 + 16.0 * kPredEps) * kPredEps;

// A nonoverlapping expansion (Shewchuk 1997, §2.2): the exact value is the sum of the components,
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

}  // namespace felt
