// Forces of the mass-spring cloth (001_0f9f1b7fedff7723.txt §2, §6.1): gravity, viscous drag,

#include "base/check.h"
// springs with a dashpot along each spring, external point forces; and the energy diagnostics.

#include <algorithm>
#include <array>
#include <cmath>
#if defined(__x86_64__)
#include <immintrin.h>
#endif
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "base/simd.h"
#include "sim_loop/cloth.h"
#include "sim_loop/cloth_internal.h"

namespace felt {
namespace {

// The flat kernels read a std::vector<Vec3> as 3 n packed doubles.
static_assert(sizeof(Vec3) == 3 * sizeof(double));

}  // namespace

void AddSpringForces(const ClothModel& model, std::span<const Vec3> x, std::span<const Vec3> v,
                     std::span<Vec3> f) {
  FELT_CHECK(x.size() == v.size() && x.size() == f.size());
  // Flat loop over raw coordinates (a Vec3 is three packed doubles): no Eigen temporaries, and
  // restrict tells the compiler x, v and f do not alias, so it keeps the loads in registers.
  const double* __restrict xp = x.data()->data();
  const double* __restrict vp = v.data()->data();
  double* __restrict fp = f.data()->data();
  const Spring* __restrict springs = model.springs.data();
  const size_t count = model.springs.size();
  constexpr double kMinLength2 = kMinSpringLength_m * kMinSpringLength_m;
  for (size_t k = 0; k < count; ++k) {
    // Hooke plus dashpot along the unit direction u from i to j:
    // f_i = (k (l - L) + c (v_j - v_i) . u) u, f_j = -f_i (001 §2; 000 slide 5).
    const Spring& s = springs[k];
    const size_t i = 3 * static_cast<size_t>(s.i), j = 3 * static_cast<size_t>(s.j);
    const double dx = xp[j] - xp[i], dy = xp[j + 1] - xp[i + 1], dz = xp[j + 2] - xp[i + 2];
    const double len2 = dx * dx + dy * dy + dz * dz;
    if (!(len2 > kMinLength2)) continue;
    const double len = std::sqrt(len2);
    const double inv_len = 1.0 / len;
    const double rel_speed =
        ((vp[j] - vp[i]) * dx + (vp[j + 1] - vp[i + 1]) * dy + (vp[j + 2] - vp[i + 2]) * dz) *
        inv_len;
    // Force magnitude over length, so that force = scale * d.
    const double scale =
        (s.stiffness_N_per_m * (len - s.rest_length_m) + s.damping_N_s_per_m * rel_speed) * inv_len;
    const double fx = scale * dx, fy = scale * dy, fz = scale * dz;
    fp[i] += fx;
    fp[i + 1] += fy;
    fp[i + 2] += fz;
    fp[j] -= fx;
    fp[j + 1] -= fy;
    fp[j + 2] -= fz;
  }
}

namespace {

// The particles' positions, velocities and forces as structure-of-arrays views into
// scratch.soa (6 arrays of coordinates in, 3 of forces, 3 of per-spring forces of one family),
// SoaStride(n) doubles apart.
struct SoaViews {
  double *x, *y, *z, *vx, *vy, *vz, *fx, *fy, *fz, *sx, *sy, *sz;
};

SoaViews Views(std::vector<double>* soa, size_t particles) {
  double* b = soa->data();
  const size_t n = SoaStride(particles);
  return {b,         b + n,     b + 2 * n, b + 3 * n, b + 4 * n,  b + 5 * n,
          b + 6 * n, b + 7 * n, b + 8 * n, b + 9 * n, b + 10 * n, b + 11 * n};
}

// The columns [c_lo, c_hi) where a family's springs start (end i) on a grid `width` wide: those
// whose end j, dc columns on, is on the grid too.
std::pair<int32_t, int32_t> FamilyColumns(const SpringFamily& family, int32_t width) {
  return {std::max(0, -family.dc), width - std::max(0, family.dc)};
}

// A spring family's constants as the portable kernels use them.
struct FamilyConstants {
  double k, c, rest;
};

// The force (sx, sy, sz) of the spring with end i at p of `a` and end j at q of `b`: Hooke plus
// dashpot along it, 001 §2 (as AddSpringForces); 0 for a spring shorter than kMinSpringLength_m.
// Branch-free, so that the loops calling it vectorise.
inline void SpringAt(const SoaViews& a, const SoaViews& b, const FamilyConstants& f, ptrdiff_t p,
                     ptrdiff_t q, double* sx, double* sy, double* sz) {
  constexpr double kMinLength2 = kMinSpringLength_m * kMinSpringLength_m;
  const double dx = b.x[q] - a.x[p], dy = b.y[q] - a.y[p], dz = b.z[q] - a.z[p];
  const double len2 = dx * dx + dy * dy + dz * dz;
  const double live = len2 > kMinLength2 ? 1.0 : 0.0;
  const double len = std::sqrt(len2 > kMinLength2 ? len2 : kMinLength2);
  const double inv_len = 1.0 / len;
  const double rel_speed =
      ((b.vx[q] - a.vx[p]) * dx + (b.vy[q] - a.vy[p]) * dy + (b.vz[q] - a.vz[p]) * dz) * inv_len;
  const double scale = live * (f.k * (len - f.rest) + f.c * rel_speed) * inv_len;
  *sx = scale * dx;
  *sy = scale * dy;
  *sz = scale * dz;
}

FamilyConstants ConstantsOf(const SpringFamily& family) {
  return {family.stiffness_N_per_m, family.damping_N_s_per_m, family.rest_length_m};
}

// The force of every spring of `family` into s[p] (the spring whose end i is particle p), and
// added to end i's force, f[p] += s[p], over the particle range [lo, hi) (SpringAt).
void FamilySpringForces(const SoaViews& a, const SpringFamily& family, ptrdiff_t off, ptrdiff_t lo,
                        ptrdiff_t hi) {
  const FamilyConstants f = ConstantsOf(family);
  for (ptrdiff_t p = lo; p < hi; ++p) {
    double sx, sy, sz;
    SpringAt(a, a, f, p, p + off, &sx, &sy, &sz);
    a.sx[p] = sx;
    a.sy[p] = sy;
    a.sz[p] = sz;
    a.fx[p] += sx;
    a.fy[p] += sy;
    a.fz[p] += sz;
  }
}

// The force of every spring of `family` with end i at column p in [lo, hi) of row view `a` and
// end j at column p + dc of row view `b` into (sx, sy, sz)[p - lo] (SpringAt), nothing else
// (StreamAccelerations' rows).
void FamilySpringRow(const SoaViews& a, const SoaViews& b, const SpringFamily& family, ptrdiff_t dc,
                     ptrdiff_t lo, ptrdiff_t hi, double* __restrict sx, double* __restrict sy,
                     double* __restrict sz) {
  const FamilyConstants f = ConstantsOf(family);
  for (ptrdiff_t p = lo; p < hi; ++p) {
    SpringAt(a, b, f, p, p + dc, &sx[p - lo], &sy[p - lo], &sz[p - lo]);
  }
}

// Splits n packed (x, y, z) triples into three arrays, and sets f = e - drag v per coordinate.
void SplitState(const double* __restrict x, const double* __restrict v, const double* __restrict e,
                double drag, size_t n, const SoaViews& a) {
  double* __restrict ox = a.x;
  double* __restrict oy = a.y;
  double* __restrict oz = a.z;
  double* __restrict ovx = a.vx;
  double* __restrict ovy = a.vy;
  double* __restrict ovz = a.vz;
  double* __restrict fx = a.fx;
  double* __restrict fy = a.fy;
  double* __restrict fz = a.fz;
  for (size_t p = 0; p < n; ++p) {
    ox[p] = x[3 * p];
    oy[p] = x[3 * p + 1];
    oz[p] = x[3 * p + 2];
    ovx[p] = v[3 * p];
    ovy[p] = v[3 * p + 1];
    ovz[p] = v[3 * p + 2];
    fx[p] = e[3 * p] - drag * v[3 * p];
    fy[p] = e[3 * p + 1] - drag * v[3 * p + 1];
    fz[p] = e[3 * p + 2] - drag * v[3 * p + 2];
  }
}

// One term of a row's force sums (StreamAccelerations): a family's springs as end i (added) or
// as end j (subtracted), for the row's columns [lo, hi); x[p], y[p], z[p] is column p's.
struct RowTerm {
  const double* x;
  const double* y;
  const double* z;
  int32_t lo, hi;
  bool subtract;
};

// Column p's force F (fx, fy, fz) plus its terms, in order.
inline void SumTerms(const RowTerm* terms, size_t count, ptrdiff_t p, double* fx, double* fy,
                     double* fz) {
  for (size_t t = 0; t < count; ++t) {
    const RowTerm& term = terms[t];
    if (p < term.lo || p >= term.hi) continue;
    if (term.subtract) {
      *fx -= term.x[p];
      *fy -= term.y[p];
      *fz -= term.z[p];
    } else {
      *fx += term.x[p];
      *fy += term.y[p];
      *fz += term.z[p];
    }
  }
}

// The columns [lo, hi) of a row of `width` that every one of the `count` terms covers.
std::pair<ptrdiff_t, ptrdiff_t> ColumnsEveryTermCovers(const RowTerm* terms, size_t count,
                                                       int32_t width) {
  ptrdiff_t lo = 0, hi = width;
  for (size_t t = 0; t < count; ++t) {
    lo = std::max<ptrdiff_t>(lo, terms[t].lo);
    hi = std::min<ptrdiff_t>(hi, terms[t].hi);
  }
  return {lo, hi};
}

// One axis of a = g + w F for inverse mass w, force F and gravity g; 0 for a pinned particle
// (w = 0), which does not accelerate.
inline double AxisAcceleration(double w, double g, double f) { return w > 0.0 ? g + w * f : 0.0; }

// a = g + F / m for the `count` particles of `soa` (F in its fx, fy, fz), inverse masses
// inv_mass, into out (xyz per particle); pinned particles (inv_mass 0) do not accelerate.
void AccelerationsOf(const Vec3& g, const double* __restrict inv_mass, const SoaViews& soa,
                     size_t count, double* __restrict out) {
  const double* __restrict fx = soa.fx;
  const double* __restrict fy = soa.fy;
  const double* __restrict fz = soa.fz;
  for (size_t p = 0; p < count; ++p) {
    const double w = inv_mass[p];
    out[3 * p] = AxisAcceleration(w, g.x(), fx[p]);
    out[3 * p + 1] = AxisAcceleration(w, g.y(), fy[p]);
    out[3 * p + 2] = AxisAcceleration(w, g.z(), fz[p]);
  }
}

// A row's accelerations, a = g + F / m (0 for pinned particles, inv_mass 0), into accel (xyz per
// particle), F being row.fx, fy, fz plus `terms` in order, for columns [lo, hi).
void FinishRowColumns(const RowTerm* terms, size_t count, const SoaViews& row,
                      const double* inv_mass, const Vec3& g, ptrdiff_t lo, ptrdiff_t hi,
                      double* accel) {
  for (ptrdiff_t p = lo; p < hi; ++p) {
    double fx = row.fx[p], fy = row.fy[p], fz = row.fz[p];
    SumTerms(terms, count, p, &fx, &fy, &fz);
    const double w = inv_mass[p];
    accel[3 * p] = AxisAcceleration(w, g.x(), fx);
    accel[3 * p + 1] = AxisAcceleration(w, g.y(), fy);
    accel[3 * p + 2] = AxisAcceleration(w, g.z(), fz);
  }
}

// FinishRowColumns over the whole row of `width` columns (the portable kernel).
void FinishRow(const RowTerm* terms, size_t count, const SoaViews& row, const double* inv_mass,
               const Vec3& g, int32_t width, double* accel) {
  FinishRowColumns(terms, count, row, inv_mass, g, 0, width, accel);
}

// f[k] -= s[k] for k < count (restrict parameters: the compiler vectorises it).
void SubtractFrom(double* __restrict f, const double* __restrict s, ptrdiff_t count) {
  for (ptrdiff_t k = 0; k < count; ++k) f[k] -= s[k];
}

#if defined(__x86_64__)
// A spring family's constants in AVX2 lanes.
struct FamilyLanes {
  __m256d k, c, rest, min2, one;
};

__attribute__((target("avx2"), always_inline)) inline FamilyLanes LanesOf(
    const SpringFamily& family) {
  constexpr double kMinLength2 = kMinSpringLength_m * kMinSpringLength_m;
  return {_mm256_set1_pd(family.stiffness_N_per_m), _mm256_set1_pd(family.damping_N_s_per_m),
          _mm256_set1_pd(family.rest_length_m), _mm256_set1_pd(kMinLength2), _mm256_set1_pd(1.0)};
}

// The forces s of the four springs with end i at p .. p + 3 and end j at q = p + off .. q + 3:
// FamilySpringForces' operations in the same order, no fused multiply-add (the same bits).
// End i's coordinates come from `a` at p, end j's from `b` at q.
__attribute__((target("avx2"), always_inline)) inline void SpringLanes(
    const SoaViews& a, const SoaViews& b, const FamilyLanes& f, ptrdiff_t p, ptrdiff_t q,
    __m256d* sx, __m256d* sy, __m256d* sz) {
  const __m256d dx = _mm256_sub_pd(_mm256_loadu_pd(b.x + q), _mm256_loadu_pd(a.x + p));
  const __m256d dy = _mm256_sub_pd(_mm256_loadu_pd(b.y + q), _mm256_loadu_pd(a.y + p));
  const __m256d dz = _mm256_sub_pd(_mm256_loadu_pd(b.z + q), _mm256_loadu_pd(a.z + p));
  const __m256d len2 = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy)),
                                     _mm256_mul_pd(dz, dz));
  const __m256d live_mask = _mm256_cmp_pd(len2, f.min2, _CMP_GT_OQ);
  const __m256d live = _mm256_and_pd(live_mask, f.one);
  const __m256d len = _mm256_sqrt_pd(_mm256_blendv_pd(f.min2, len2, live_mask));
  const __m256d inv_len = _mm256_div_pd(f.one, len);
  const __m256d dvx = _mm256_sub_pd(_mm256_loadu_pd(b.vx + q), _mm256_loadu_pd(a.vx + p));
  const __m256d dvy = _mm256_sub_pd(_mm256_loadu_pd(b.vy + q), _mm256_loadu_pd(a.vy + p));
  const __m256d dvz = _mm256_sub_pd(_mm256_loadu_pd(b.vz + q), _mm256_loadu_pd(a.vz + p));
  const __m256d rel_speed =
      _mm256_mul_pd(_mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(dvx, dx), _mm256_mul_pd(dvy, dy)),
                                  _mm256_mul_pd(dvz, dz)),
                    inv_len);
  const __m256d magnitude =
      _mm256_add_pd(_mm256_mul_pd(f.k, _mm256_sub_pd(len, f.rest)), _mm256_mul_pd(f.c, rel_speed));
  const __m256d scale = _mm256_mul_pd(_mm256_mul_pd(live, magnitude), inv_len);
  *sx = _mm256_mul_pd(scale, dx);
  *sy = _mm256_mul_pd(scale, dy);
  *sz = _mm256_mul_pd(scale, dz);
}

// FamilySpringForces four springs at a time with AVX2 (the build targets baseline x86-64, whose
// SSE2 has no 4-wide double; kSpringKernels picks this where the CPU has AVX2): the same bits as
// the portable loop.
__attribute__((target("avx2"))) void FamilySpringForcesAvx2(const SoaViews& a,
                                                            const SpringFamily& family,
                                                            ptrdiff_t off, ptrdiff_t lo,
                                                            ptrdiff_t hi) {
  const FamilyLanes f = LanesOf(family);
  ptrdiff_t p = lo;
  for (; p + 4 <= hi; p += 4) {
    __m256d sx, sy, sz;
    SpringLanes(a, a, f, p, p + off, &sx, &sy, &sz);
    _mm256_storeu_pd(a.sx + p, sx);
    _mm256_storeu_pd(a.sy + p, sy);
    _mm256_storeu_pd(a.sz + p, sz);
    _mm256_storeu_pd(a.fx + p, _mm256_add_pd(_mm256_loadu_pd(a.fx + p), sx));
    _mm256_storeu_pd(a.fy + p, _mm256_add_pd(_mm256_loadu_pd(a.fy + p), sy));
    _mm256_storeu_pd(a.fz + p, _mm256_add_pd(_mm256_loadu_pd(a.fz + p), sz));
  }
  if (p < hi) FamilySpringForces(a, family, off, p, hi);
}

// FamilySpringForcesAvx2 and the end-j pass of AddFamilyForces in one, for off >= 4 (a step's four
// j ends are never its own i ends). The springs go from the highest i down, so that each particle
// still takes its term as end i (when i = p) before its term as end j (when i = p - off, later):
// the same order, so the same bits, as the two passes. Saves storing s and reading it back.
__attribute__((target("avx2"))) void FamilySpringForcesBothEndsAvx2(const SoaViews& a,
                                                                    const SpringFamily& family,
                                                                    ptrdiff_t off, ptrdiff_t lo,
                                                                    ptrdiff_t hi) {
  const FamilyLanes f = LanesOf(family);
  const ptrdiff_t vector_end = lo + (hi - lo) / 4 * 4;
  // The tail first (the highest i): its end-i terms, then its end-j terms (fewer than four
  // springs, so none of their j ends is one of their i ends).
  if (vector_end < hi) {
    FamilySpringForces(a, family, off, vector_end, hi);
    SubtractFrom(a.fx + vector_end + off, a.sx + vector_end, hi - vector_end);
    SubtractFrom(a.fy + vector_end + off, a.sy + vector_end, hi - vector_end);
    SubtractFrom(a.fz + vector_end + off, a.sz + vector_end, hi - vector_end);
  }
  for (ptrdiff_t p = vector_end - 4; p >= lo; p -= 4) {
    const ptrdiff_t q = p + off;
    __m256d sx, sy, sz;
    SpringLanes(a, a, f, p, q, &sx, &sy, &sz);
    _mm256_storeu_pd(a.fx + p, _mm256_add_pd(_mm256_loadu_pd(a.fx + p), sx));
    _mm256_storeu_pd(a.fy + p, _mm256_add_pd(_mm256_loadu_pd(a.fy + p), sy));
    _mm256_storeu_pd(a.fz + p, _mm256_add_pd(_mm256_loadu_pd(a.fz + p), sz));
    _mm256_storeu_pd(a.fx + q, _mm256_sub_pd(_mm256_loadu_pd(a.fx + q), sx));
    _mm256_storeu_pd(a.fy + q, _mm256_sub_pd(_mm256_loadu_pd(a.fy + q), sy));
    _mm256_storeu_pd(a.fz + q, _mm256_sub_pd(_mm256_loadu_pd(a.fz + q), sz));
  }
}

// SubtractFrom four at a time with AVX2 (the same bits).
__attribute__((target("avx2"))) void SubtractFromAvx2(double* __restrict f,
                                                      const double* __restrict s, ptrdiff_t count) {
  ptrdiff_t k = 0;
  for (; k + 4 <= count; k += 4) {
    _mm256_storeu_pd(f + k, _mm256_sub_pd(_mm256_loadu_pd(f + k), _mm256_loadu_pd(s + k)));
  }
  for (; k < count; ++k) f[k] -= s[k];
}

// FamilySpringRow four springs at a time with AVX2 (the same bits).
__attribute__((target("avx2"))) void FamilySpringRowAvx2(const SoaViews& a, const SoaViews& b,
                                                         const SpringFamily& family, ptrdiff_t dc,
                                                         ptrdiff_t lo, ptrdiff_t hi, double* sx,
                                                         double* sy, double* sz) {
  const FamilyLanes f = LanesOf(family);
  ptrdiff_t p = lo;
  for (; p + 4 <= hi; p += 4) {
    __m256d lx, ly, lz;
    SpringLanes(a, b, f, p, p + dc, &lx, &ly, &lz);
    _mm256_storeu_pd(sx + (p - lo), lx);
    _mm256_storeu_pd(sy + (p - lo), ly);
    _mm256_storeu_pd(sz + (p - lo), lz);
  }
  if (p < hi) {
    FamilySpringRow(a, b, family, dc, p, hi, sx + (p - lo), sy + (p - lo), sz + (p - lo));
  }
}

// Four particles' packed (x, y, z) triples, t[0 .. 11], as lanes x, y, z.
__attribute__((target("avx2"), always_inline)) inline void TriplesToLanesPd(const double* t,
                                                                            __m256d* x, __m256d* y,
                                                                            __m256d* z) {
  const __m256d a = _mm256_loadu_pd(t), b = _mm256_loadu_pd(t + 4), c = _mm256_loadu_pd(t + 8);
  const __m256d p = _mm256_permute2f128_pd(a, b, 0x30);  // x0 y0 | x2 y2
  const __m256d q = _mm256_permute2f128_pd(a, c, 0x21);  // z0 x1 | z2 x3
  const __m256d r = _mm256_permute2f128_pd(b, c, 0x30);  // y1 z1 | y3 z3
  *x = _mm256_shuffle_pd(p, q, 0b1010);
  *y = _mm256_shuffle_pd(p, r, 0b0101);
  *z = _mm256_shuffle_pd(q, r, 0b1010);
}

// Lanes x, y, z as four particles' packed (x, y, z) triples into t[0 .. 11].
__attribute__((target("avx2"), always_inline)) inline void LanesToTriplesPd(__m256d x, __m256d y,
                                                                            __m256d z, double* t) {
  const __m256d p = _mm256_shuffle_pd(x, y, 0b0000);  // x0 y0 | x2 y2
  const __m256d q = _mm256_shuffle_pd(z, x, 0b1010);  // z0 x1 | z2 x3
  const __m256d r = _mm256_shuffle_pd(y, z, 0b1111);  // y1 z1 | y3 z3
  _mm256_storeu_pd(t, _mm256_permute2f128_pd(p, q, 0x20));
  _mm256_storeu_pd(t + 4, _mm256_permute2f128_pd(r, p, 0x30));
  _mm256_storeu_pd(t + 8, _mm256_permute2f128_pd(q, r, 0x31));
}

// SplitState four particles at a time with AVX2 (the same bits).
__attribute__((target("avx2"))) void SplitRowAvx2(const double* x, const double* v, const double* e,
                                                  double drag, size_t count, const SoaViews& a) {
  const __m256d d = _mm256_set1_pd(drag);
  size_t p = 0;
  for (; p + 4 <= count; p += 4) {
    __m256d lx, ly, lz, lvx, lvy, lvz, ex, ey, ez;
    TriplesToLanesPd(x + 3 * p, &lx, &ly, &lz);
    TriplesToLanesPd(v + 3 * p, &lvx, &lvy, &lvz);
    TriplesToLanesPd(e + 3 * p, &ex, &ey, &ez);
    _mm256_storeu_pd(a.x + p, lx);
    _mm256_storeu_pd(a.y + p, ly);
    _mm256_storeu_pd(a.z + p, lz);
    _mm256_storeu_pd(a.vx + p, lvx);
    _mm256_storeu_pd(a.vy + p, lvy);
    _mm256_storeu_pd(a.vz + p, lvz);
    _mm256_storeu_pd(a.fx + p, _mm256_sub_pd(ex, _mm256_mul_pd(d, lvx)));
    _mm256_storeu_pd(a.fy + p, _mm256_sub_pd(ey, _mm256_mul_pd(d, lvy)));
    _mm256_storeu_pd(a.fz + p, _mm256_sub_pd(ez, _mm256_mul_pd(d, lvz)));
  }
  if (p < count) {
    const SoaViews rest{a.x + p,  a.y + p,  a.z + p,  a.vx + p, a.vy + p, a.vz + p,
                        a.fx + p, a.fy + p, a.fz + p, nullptr,  nullptr,  nullptr};
    SplitState(x + 3 * p, v + 3 * p, e + 3 * p, drag, count - p, rest);
  }
}

// a = g + F / m for four particles with inverse masses inv_mass[0 .. 3] (0 where pinned: a = 0),
// F in lanes fx, fy, fz, into accel[0 .. 11] (xyz per particle).
__attribute__((target("avx2"), always_inline)) inline void StoreAccelerations(
    const Vec3& g, const double* inv_mass, __m256d fx, __m256d fy, __m256d fz, double* accel) {
  const __m256d w = _mm256_loadu_pd(inv_mass);
  const __m256d free = _mm256_cmp_pd(w, _mm256_setzero_pd(), _CMP_GT_OQ);
  LanesToTriplesPd(_mm256_and_pd(free, _mm256_add_pd(_mm256_set1_pd(g.x()), _mm256_mul_pd(w, fx))),
                   _mm256_and_pd(free, _mm256_add_pd(_mm256_set1_pd(g.y()), _mm256_mul_pd(w, fy))),
                   _mm256_and_pd(free, _mm256_add_pd(_mm256_set1_pd(g.z()), _mm256_mul_pd(w, fz))),
                   accel);
}

// Lanes p .. p + 3 that lie in [lo, hi), as a blend mask.
__attribute__((target("avx2"), always_inline)) inline __m256d LanesIn(ptrdiff_t p, ptrdiff_t lo,
                                                                      ptrdiff_t hi) {
  const __m256i lane = _mm256_add_epi64(_mm256_set1_epi64x(p), _mm256_set_epi64x(3, 2, 1, 0));
  const __m256i in = _mm256_and_si256(_mm256_cmpgt_epi64(lane, _mm256_set1_epi64x(lo - 1)),
                                      _mm256_cmpgt_epi64(_mm256_set1_epi64x(hi), lane));
  return _mm256_castsi256_pd(in);
}

// sum + (s[0 .. 3] with its sign bits flipped by `negate`) in the lanes of `in`, sum elsewhere.
__attribute__((target("avx2"), always_inline)) inline __m256d AddWhere(__m256d sum, const double* s,
                                                                       __m256d negate, __m256d in) {
  return _mm256_blendv_pd(sum, _mm256_add_pd(sum, _mm256_xor_pd(_mm256_loadu_pd(s), negate)), in);
}

// FinishRow with AVX2 (the same bits), eight columns a step from column 0: a step every term
// covers adds them all; a step at an edge of the row adds each term where it covers the column
// only (a blend: the other lanes keep their sum; their loads stay inside the stream's ring); the
// last width % 8 columns as FinishRowColumns. A subtracted term is added negated (its sign bit
// flipped): IEEE 754 defines x - y as x + (-y), so the bits are the same, without a branch.
__attribute__((target("avx2"))) void FinishRowAvx2(const RowTerm* terms, size_t count,
                                                   const SoaViews& row, const double* inv_mass,
                                                   const Vec3& g, int32_t width, double* accel) {
  const auto [lo, hi] = ColumnsEveryTermCovers(terms, count, width);
  __m256d negate[2 * kMaxSpringFamilies];
  FELT_CHECK(count <= 2 * kMaxSpringFamilies);
  for (size_t t = 0; t < count; ++t) {
    negate[t] = terms[t].subtract ? _mm256_set1_pd(-0.0) : _mm256_setzero_pd();
  }
  ptrdiff_t p = 0;
  for (; p + 8 <= width; p += 8) {
    __m256d ax = _mm256_loadu_pd(row.fx + p), ay = _mm256_loadu_pd(row.fy + p),
            az = _mm256_loadu_pd(row.fz + p), bx = _mm256_loadu_pd(row.fx + p + 4),
            by = _mm256_loadu_pd(row.fy + p + 4), bz = _mm256_loadu_pd(row.fz + p + 4);
    if (p >= lo && p + 8 <= hi) {
      // Each term's pointers are loaded once for two vectors.
      for (size_t t = 0; t < count; ++t) {
        const double* tx = terms[t].x + p;
        const double* ty = terms[t].y + p;
        const double* tz = terms[t].z + p;
        const __m256d m = negate[t];
        ax = _mm256_add_pd(ax, _mm256_xor_pd(_mm256_loadu_pd(tx), m));
        ay = _mm256_add_pd(ay, _mm256_xor_pd(_mm256_loadu_pd(ty), m));
        az = _mm256_add_pd(az, _mm256_xor_pd(_mm256_loadu_pd(tz), m));
        bx = _mm256_add_pd(bx, _mm256_xor_pd(_mm256_loadu_pd(tx + 4), m));
        by = _mm256_add_pd(by, _mm256_xor_pd(_mm256_loadu_pd(ty + 4), m));
        bz = _mm256_add_pd(bz, _mm256_xor_pd(_mm256_loadu_pd(tz + 4), m));
      }
    } else {
      for (size_t t = 0; t < count; ++t) {
        const RowTerm& term = terms[t];
        const __m256d m = negate[t];
        const __m256d in_a = LanesIn(p, term.lo, term.hi), in_b = LanesIn(p + 4, term.lo, term.hi);
        ax = AddWhere(ax, term.x + p, m, in_a);
        ay = AddWhere(ay, term.y + p, m, in_a);
        az = AddWhere(az, term.z + p, m, in_a);
        bx = AddWhere(bx, term.x + p + 4, m, in_b);
        by = AddWhere(by, term.y + p + 4, m, in_b);
        bz = AddWhere(bz, term.z + p + 4, m, in_b);
      }
    }
    StoreAccelerations(g, inv_mass + p, ax, ay, az, accel + 3 * p);
    StoreAccelerations(g, inv_mass + p + 4, bx, by, bz, accel + 3 * p + 12);
  }
  FinishRowColumns(terms, count, row, inv_mass, g, p, width, accel);
}

// AVX-512F brings fused multiply-add, which GCC would contract a * b + c into (GNU mode's
// -ffp-contract=fast): this kernel must round every operation as SpringAt does.
#pragma GCC push_options
#pragma GCC optimize("fp-contract=off")
// GCC 12's _mm512_sqrt_pd passes _mm512_undefined_pd() as its unused merge source, which
// -Wmaybe-uninitialized reports as read uninitialised.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

// FamilySpringRow eight springs at a time with AVX-512F: SpringLanes' operations in the same
// order (the same bits). Its gain is not the width (a 512-bit square root or division costs what
// two 256-bit ones do on the AMD and Intel hosts) but depth: the loop is bound by the latency of
// the square root and the division, and twice the springs per instruction keep twice as many of
// them in flight in the reorder buffer.
__attribute__((target("avx512f"))) void FamilySpringRowAvx512(const SoaViews& a, const SoaViews& b,
                                                              const SpringFamily& family,
                                                              ptrdiff_t dc, ptrdiff_t lo,
                                                              ptrdiff_t hi, double* sx, double* sy,
                                                              double* sz) {
  constexpr double kMinLength2 = kMinSpringLength_m * kMinSpringLength_m;
  const __m512d k = _mm512_set1_pd(family.stiffness_N_per_m);
  const __m512d c = _mm512_set1_pd(family.damping_N_s_per_m);
  const __m512d rest = _mm512_set1_pd(family.rest_length_m);
  const __m512d min2 = _mm512_set1_pd(kMinLength2), one = _mm512_set1_pd(1.0);
  // Local copies of the row pointers: the stores through sx, sy, sz cannot alias them.
  const double *ax = a.x, *ay = a.y, *az = a.z, *avx = a.vx, *avy = a.vy, *avz = a.vz;
  const double *bx = b.x + dc, *by = b.y + dc, *bz = b.z + dc, *bvx = b.vx + dc, *bvy = b.vy + dc,
               *bvz = b.vz + dc;
  // Eight springs a step; the last step masked to the springs left (masked-off lanes load zeros,
  // compute a dead spring and store nothing).
  for (ptrdiff_t p = lo; p < hi; p += 8) {
    const __mmask8 m =
        hi - p >= 8 ? static_cast<__mmask8>(0xff) : static_cast<__mmask8>((1u << (hi - p)) - 1u);
    auto load = [m](const double* q) { return _mm512_maskz_loadu_pd(m, q); };
    const __m512d dx = _mm512_sub_pd(load(bx + p), load(ax + p));
    const __m512d dy = _mm512_sub_pd(load(by + p), load(ay + p));
    const __m512d dz = _mm512_sub_pd(load(bz + p), load(az + p));
    const __m512d len2 = _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(dx, dx), _mm512_mul_pd(dy, dy)),
                                       _mm512_mul_pd(dz, dz));
    const __mmask8 live = _mm512_cmp_pd_mask(len2, min2, _CMP_GT_OQ);
    const __m512d len = _mm512_sqrt_pd(_mm512_mask_blend_pd(live, min2, len2));
    const __m512d inv_len = _mm512_div_pd(one, len);
    const __m512d dvx = _mm512_sub_pd(load(bvx + p), load(avx + p));
    const __m512d dvy = _mm512_sub_pd(load(bvy + p), load(avy + p));
    const __m512d dvz = _mm512_sub_pd(load(bvz + p), load(avz + p));
    const __m512d rel_speed =
        _mm512_mul_pd(_mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(dvx, dx), _mm512_mul_pd(dvy, dy)),
                                    _mm512_mul_pd(dvz, dz)),
                      inv_len);
    const __m512d magnitude =
        _mm512_add_pd(_mm512_mul_pd(k, _mm512_sub_pd(len, rest)), _mm512_mul_pd(c, rel_speed));
    // live * magnitude as SpringLanes computes it: 1.0 * m or 0.0 * m (0 times a finite
    // magnitude is +0 or -0 by its sign, which a masked zero would not keep).
    const __m512d live_one = _mm512_maskz_mov_pd(live, one);
    const __m512d scale = _mm512_mul_pd(_mm512_mul_pd(live_one, magnitude), inv_len);
    _mm512_mask_storeu_pd(sx + (p - lo), m, _mm512_mul_pd(scale, dx));
    _mm512_mask_storeu_pd(sy + (p - lo), m, _mm512_mul_pd(scale, dy));
    _mm512_mask_storeu_pd(sz + (p - lo), m, _mm512_mul_pd(scale, dz));
  }
}

// A term's value at s[0 .. 7], its sign bits flipped by negate_bits (AVX-512F).
__attribute__((target("avx512f"), always_inline)) inline __m512d TermAt(const double* s,
                                                                        __m512i negate_bits) {
  return _mm512_castsi512_pd(
      _mm512_xor_si512(_mm512_castpd_si512(_mm512_loadu_pd(s)), negate_bits));
}

// FinishRowAvx2 eight columns a vector with AVX-512F (the same bits): half the instructions for
// a pass bound by its loads.
__attribute__((target("avx512f"))) void FinishRowAvx512(const RowTerm* terms, size_t count,
                                                        const SoaViews& row, const double* inv_mass,
                                                        const Vec3& g, int32_t width,
                                                        double* accel) {
  const auto [lo, hi] = ColumnsEveryTermCovers(terms, count, width);
  __m512i negate[2 * kMaxSpringFamilies];
  FELT_CHECK(count <= 2 * kMaxSpringFamilies);
  for (size_t t = 0; t < count; ++t) {
    negate[t] = _mm512_set1_epi64(terms[t].subtract ? INT64_MIN : 0);
  }
  const __m512i lanes = _mm512_set_epi64(7, 6, 5, 4, 3, 2, 1, 0);
  ptrdiff_t p = 0;
  for (; p + 8 <= width; p += 8) {
    __m512d fx = _mm512_loadu_pd(row.fx + p), fy = _mm512_loadu_pd(row.fy + p),
            fz = _mm512_loadu_pd(row.fz + p);
    if (p >= lo && p + 8 <= hi) {
      for (size_t t = 0; t < count; ++t) {
        const RowTerm& term = terms[t];
        fx = _mm512_add_pd(fx, TermAt(term.x + p, negate[t]));
        fy = _mm512_add_pd(fy, TermAt(term.y + p, negate[t]));
        fz = _mm512_add_pd(fz, TermAt(term.z + p, negate[t]));
      }
    } else {
      // At an edge: each term only in the columns it covers (the other lanes keep their sum).
      const __m512i column = _mm512_add_epi64(_mm512_set1_epi64(p), lanes);
      for (size_t t = 0; t < count; ++t) {
        const RowTerm& term = terms[t];
        const __mmask8 in =
            _mm512_cmp_epi64_mask(column, _mm512_set1_epi64(term.lo), _MM_CMPINT_NLT) &
            _mm512_cmp_epi64_mask(column, _mm512_set1_epi64(term.hi), _MM_CMPINT_LT);
        fx = _mm512_mask_add_pd(fx, in, fx, TermAt(term.x + p, negate[t]));
        fy = _mm512_mask_add_pd(fy, in, fy, TermAt(term.y + p, negate[t]));
        fz = _mm512_mask_add_pd(fz, in, fz, TermAt(term.z + p, negate[t]));
      }
    }
    StoreAccelerations(g, inv_mass + p, _mm512_castpd512_pd256(fx), _mm512_castpd512_pd256(fy),
                       _mm512_castpd512_pd256(fz), accel + 3 * p);
    StoreAccelerations(g, inv_mass + p + 4, _mm512_extractf64x4_pd(fx, 1),
                       _mm512_extractf64x4_pd(fy, 1), _mm512_extractf64x4_pd(fz, 1),
                       accel + 3 * p + 12);
  }
  FinishRowColumns(terms, count, row, inv_mass, g, p, width, accel);
}

#pragma GCC diagnostic pop
#pragma GCC pop_options
#endif

// The spring kernels of one level (SimdTable): AVX2 where the level has it, else the portable
// loops; every level gives the same bits (simd_kernels_test.cc).
struct SpringKernels {
  // The forces of a family's springs with end i in [lo, hi) into s, and added to end i
  // (FamilySpringForces).
  void (*end_i)(const SoaViews& a, const SpringFamily& family, ptrdiff_t off, ptrdiff_t lo,
                ptrdiff_t hi);
  // f[k] -= s[k] for k < count (SubtractFrom).
  void (*subtract)(double* f, const double* s, ptrdiff_t count);
  // Both ends in one pass for off >= 4 (FamilySpringForcesBothEndsAvx2); null: two passes.
  void (*both_ends)(const SoaViews& a, const SpringFamily& family, ptrdiff_t off, ptrdiff_t lo,
                    ptrdiff_t hi);
  // The forces of a family's springs with end i at columns [lo, hi) of row a and end j dc
  // columns on in row b into (sx, sy, sz)[p - lo] alone (FamilySpringRow).
  void (*row)(const SoaViews& a, const SoaViews& b, const SpringFamily& family, ptrdiff_t dc,
              ptrdiff_t lo, ptrdiff_t hi, double* sx, double* sy, double* sz);
  // A row's particles into its structure-of-arrays slot, F = external - drag v (SplitState).
  void (*split_row)(const double* x, const double* v, const double* e, double drag, size_t count,
                    const SoaViews& a);
  // A row's force sums and accelerations (FinishRow).
  void (*finish_row)(const RowTerm* terms, size_t count, const SoaViews& row,
                     const double* inv_mass, const Vec3& g, int32_t width, double* accel);
};

constexpr SpringKernels kPortableSpringKernels{FamilySpringForces, SubtractFrom, nullptr,
                                               FamilySpringRow,    SplitState,   FinishRow};
#if defined(__x86_64__)
constexpr SpringKernels kAvx2SpringKernels{
    FamilySpringForcesAvx2, SubtractFromAvx2, FamilySpringForcesBothEndsAvx2,
    FamilySpringRowAvx2,    SplitRowAvx2,     FinishRowAvx2};
// AVX-512: AVX2's kernels but the row of springs and the row's sums (FamilySpringRowAvx512,
// FinishRowAvx512).
constexpr SpringKernels kAvx512SpringKernels{
    FamilySpringForcesAvx2, SubtractFromAvx2, FamilySpringForcesBothEndsAvx2,
    FamilySpringRowAvx512,  SplitRowAvx2,     FinishRowAvx512};
constexpr SimdTable<SpringKernels> kSpringKernels{kPortableSpringKernels, kAvx2SpringKernels,
                                                  kAvx512SpringKernels};
#else
constexpr SimdTable<SpringKernels> kSpringKernels{kPortableSpringKernels, kPortableSpringKernels,
                                                  kPortableSpringKernels};
#endif

// Adds every spring of `family` to the forces: f_i += s, f_j -= s (grid stencil, no indices).
// Row by row over the columns [c_lo, c_hi) where springs start: every end i first (fused into the
// kernel), then every end j = i + off, so each particle's sum takes its terms in the same order
// as one pass of each over the whole grid. Where the level has a both-ends kernel and off >= 4,
// one pass does both ends in that same order per particle (FamilySpringForcesBothEndsAvx2).
void AddFamilyForces(const SpringKernels& kernels, const SoaViews& a, int32_t width, int32_t height,
                     const SpringFamily& family) {
  const auto [c_lo, c_hi] = FamilyColumns(family, width);
  const int32_t rows = height - family.dr;
  if (rows <= 0 || c_hi <= c_lo) return;
  const ptrdiff_t off = static_cast<ptrdiff_t>(family.dr) * width + family.dc;
  if (off >= 4 && kernels.both_ends != nullptr) {
    // Both ends in one pass, from the last row and column down (FamilySpringForcesBothEndsAvx2).
    for (int32_t r = rows - 1; r >= 0; --r) {
      const ptrdiff_t row = static_cast<ptrdiff_t>(r) * width;
      kernels.both_ends(a, family, off, row + c_lo, row + c_hi);
    }
    return;
  }
  for (int32_t r = 0; r < rows; ++r) {
    const ptrdiff_t row = static_cast<ptrdiff_t>(r) * width;
    kernels.end_i(a, family, off, row + c_lo, row + c_hi);
  }
  const ptrdiff_t count = c_hi - c_lo;
  for (int32_t r = 0; r < rows; ++r) {
    const ptrdiff_t lo = static_cast<ptrdiff_t>(r) * width + c_lo;
    kernels.subtract(a.fx + lo + off, a.sx + lo, count);
    kernels.subtract(a.fy + lo + off, a.sy + lo, count);
    kernels.subtract(a.fz + lo + off, a.sz + lo, count);
  }
}

}  // namespace

void ComputeAccelerations(const ClothModel& model, std::span<const Vec3> x, std::span<const Vec3> v,
                          ClothState::Scratch* scratch, std::span<Vec3> a) {
  const int32_t n = model.num_particles();
  const double drag = model.drag_N_s_per_m;
  const Vec3* ext = scratch->external_N.data();
  const SoaViews soa = Views(&scratch->soa, static_cast<size_t>(n));
  // Into structure-of-arrays; external forces and viscous drag F = -c v (001 §6.1).
  SplitState(x.data()->data(), v.data()->data(), ext->data(), drag, static_cast<size_t>(n), soa);
  // Springs, one family (type and direction) at a time over whole rows, with the kernels of the
  // level in use (picked once per call).
  const SpringKernels& kernels = PickSimd(kSpringKernels);
  for (const SpringFamily& family : model.spring_families) {
    AddFamilyForces(kernels, soa, model.width, model.height, family);
  }
  double* out = a.data()->data();
  AccelerationsOf(model.gravity_m_per_s2, model.inv_mass_per_kg.data(), soa, static_cast<size_t>(n),
                  out);
  // Haptic contact springs at these positions (sim_loop/cloth_coupling.h), as accelerations:
  // every particle has mass model.particle_mass_kg and pinned ones take no share.
  AddCouplingForces(scratch->coupling, x, 1.0 / model.particle_mass_kg, out);
}

size_t StreamScratchSize(const ClothModel& model) {
  int32_t max_dr = 0;
  for (const SpringFamily& f : model.spring_families) max_dr = std::max(max_dr, f.dr);
  const size_t depth = static_cast<size_t>(max_dr) + 2;
  // Per slot of the ring: 9 rows of particles (x, y, z, v, F) and 3 per family (its springs);
  // then two rows of accelerations; each SoaStride(width) apart (no two 4 KiB apart), and 8
  // doubles to align the start to a cache line.
  return (depth * (9 + 3 * model.spring_families.size()) + 6) *
             SoaStride(static_cast<size_t>(model.width)) +
         8;
}

void StreamAccelerations(const ClothModel& model, std::span<const Vec3> x, std::span<const Vec3> v,
                         ClothState::Scratch* scratch, AcceleratedRows sink) {
  const int32_t width = model.width, height = model.height;
  const size_t n = static_cast<size_t>(model.num_particles());
  FELT_CHECK(x.size() == n && v.size() == n && sink.rows != nullptr);
  FELT_CHECK(scratch->stream_rows.size() >= StreamScratchSize(model));
  const double drag = model.drag_N_s_per_m;
  const double* xp = x.data()->data();
  const double* vp = v.data()->data();
  const double* ep = scratch->external_N.data()->data();
  const SpringKernels& kernels = PickSimd(kSpringKernels);
  const std::vector<SpringFamily>& families = model.spring_families;
  const size_t num_fam = families.size();
  FELT_CHECK(num_fam <= kMaxSpringFamilies);
  int32_t max_dr = 0;
  for (const SpringFamily& f : families) max_dr = std::max(max_dr, f.dr);
  // A ring of `depth` row slots: slot r % depth holds row r's x, y, z, v and F = external - drag
  // v (+ springs once the row is finished), then each family's springs with end i in row r (x, y,
  // z rows, by end i's column). Row r is finished one iteration after its springs are made, and
  // handed to the sink one row behind too: everything a finish or an update loads was then
  // stored a row earlier, never still in the store buffer (a load that spans a wider or
  // misaligned pending store cannot be forwarded from it and waits: 20 % of the frame at 128 x
  // 128 when the update ran on the row just finished).
  const size_t depth = static_cast<size_t>(max_dr) + 2;
  const size_t w = static_cast<size_t>(width);
  const size_t ws = SoaStride(w);  // doubles from one row array to the next (no 4K aliasing)
  double* const base = OnCacheLine(scratch->stream_rows.data());
  const size_t slot_size = (9 + 3 * num_fam) * ws;
  auto slot = [&](int32_t r) {
    double* b = base + (static_cast<size_t>(r) % depth) * slot_size;
    return SoaViews{b,          b + ws,     b + 2 * ws, b + 3 * ws, b + 4 * ws, b + 5 * ws,
                    b + 6 * ws, b + 7 * ws, b + 8 * ws, nullptr,    nullptr,    nullptr};
  };
  // Family k's springs of row r: column p's at [p], [p + ws], [p + 2 ws].
  auto springs = [&](size_t k, int32_t r) {
    return base + (static_cast<size_t>(r) % depth) * slot_size + (9 + 3 * k) * ws;
  };
  // Two rows of accelerations, xyz per particle, alternating.
  auto accel = [&](int32_t r) {
    return base + depth * slot_size + static_cast<size_t>(r % 2) * 3 * ws;
  };
  std::array<RowTerm, 2 * kMaxSpringFamilies> terms;
  // The contact springs first, at the positions before any row moves: their accelerations by row.
  const bool coupled = scratch->coupling.count > 0;
  if (coupled) {
    CouplingTermsByRow(scratch->coupling, x, 1.0 / model.particle_mass_kg, width,
                       &scratch->coupling_rows);
  }
  // Rows [0, split) are in their slots, with F = external - drag v (001 §6.1).
  int32_t split = 0;
  for (int32_t r = 0; r <= height; ++r) {
    if (r < height) {
      // The springs with end i in row r reach rows up to r + max_dr.
      for (const int32_t need = std::min(height, r + max_dr + 1); split < need; ++split) {
        const size_t lo = static_cast<size_t>(split) * w;
        kernels.split_row(xp + 3 * lo, vp + 3 * lo, ep + 3 * lo, drag, w, slot(split));
      }
      // Every family's springs with end i in row r.
      for (size_t k = 0; k < num_fam; ++k) {
        const SpringFamily& f = families[k];
        const auto [c_lo, c_hi] = FamilyColumns(f, width);
        if (r >= height - f.dr || c_hi <= c_lo) continue;
        double* s = springs(k, r) + c_lo;
        kernels.row(slot(r), slot(r + f.dr), f, f.dc, c_lo, c_hi, s, s + ws, s + 2 * ws);
      }
    }
    if (r == 0) continue;
    // Row q = r - 1's forces are complete: per particle, family by family, its term as end i,
    // then as end j (of the spring from row q - dr), ComputeAccelerations' order.
    const int32_t q = r - 1;
    size_t num_terms = 0;
    for (size_t k = 0; k < num_fam; ++k) {
      const SpringFamily& f = families[k];
      const auto [c_lo, c_hi] = FamilyColumns(f, width);
      if (c_hi <= c_lo) continue;
      if (q < height - f.dr) {
        const double* s = springs(k, q);
        terms[num_terms++] = {s, s + ws, s + 2 * ws, c_lo, c_hi, false};
      }
      if (q >= f.dr) {
        const double* s = springs(k, q - f.dr) - f.dc;  // end j's column p: the spring at p - dc
        terms[num_terms++] = {s, s + ws, s + 2 * ws, c_lo + f.dc, c_hi + f.dc, true};
      }
    }
    const size_t row = static_cast<size_t>(q) * w;
    double* out = accel(q);
    kernels.finish_row(terms.data(), num_terms, slot(q), model.inv_mass_per_kg.data() + row,
                       model.gravity_m_per_s2, width, out);
    if (coupled) {
      const CouplingTermRows& c = scratch->coupling_rows;
      const auto uq = static_cast<size_t>(q);
      for (int32_t t = c.row_start[uq]; t < c.row_start[uq + 1]; ++t) {
        const CouplingTerm& term = c.sorted[static_cast<size_t>(t)];
        double* o = out + 3 * (static_cast<size_t>(term.particle) - row);
        o[0] += term.value.x();
        o[1] += term.value.y();
        o[2] += term.value.z();
      }
    }
    sink.rows(sink.context, q, out);
  }
}

double MaxStretch(const ClothModel& model, const ClothState& state) {
  return MaxStretchOf(model, state, SpringType::kStructural);
}

double MaxStretchOf(const ClothModel& model, const ClothState& state, SpringType type) {
  double worst = 1.0;
  bool any = false;
  for (const Spring& s : model.springs) {
    if (s.type != type) continue;
    const double ratio = (state.x[s.j] - state.x[s.i]).norm() / s.rest_length_m;
    worst = any ? std::max(worst, ratio) : ratio;
    any = true;
  }
  return any ? worst : 1.0;
}

double TotalEnergy(const ClothModel& model, const ClothState& state) {
  const Vec3& g = model.gravity_m_per_s2;
  const double m = model.particle_mass_kg;
  double kinetic = 0.0, gravity = 0.0, elastic = 0.0;
  for (int32_t p = 0; p < model.num_particles(); ++p) {
    if (model.inv_mass_per_kg[p] > 0.0) kinetic += 0.5 * m * state.v[p].squaredNorm();
    // Potential of a uniform field: U = -m g . x.
    gravity -= m * g.dot(state.x[p]);
  }
  for (const Spring& s : model.springs) {
    const double stretch = (state.x[s.j] - state.x[s.i]).norm() - s.rest_length_m;
    elastic += 0.5 * s.stiffness_N_per_m * stretch * stretch;
  }
  return kinetic + gravity + elastic;
}

}  // namespace felt
