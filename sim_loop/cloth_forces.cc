// Forces of the mass-spring cloth (001_0f9f1b7fedff7723.txt §2, §6.1): gravity, viscous drag,

#include "base/check.h"
// springs with a dashpot along each spring, external point forces; and the energy diagnostics.

#include <algorithm>
#include <cmath>
#if defined(__x86_64__)
#include <immintrin.h>
#endif
#include <cstddef>
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

// The force of every spring of `family` into s[p] (the spring whose end i is particle p), and
// added to end i's force, f[p] += s[p], over the particle range [lo, hi): Hooke plus dashpot
// along the spring, 001 §2 (as AddSpringForces). Branch-free, so the compiler vectorises it;
// springs shorter than kMinSpringLength_m get 0.
void FamilySpringForces(const SoaViews& a, const SpringFamily& family, ptrdiff_t off, ptrdiff_t lo,
                        ptrdiff_t hi) {
  const double* __restrict x = a.x;
  const double* __restrict y = a.y;
  const double* __restrict z = a.z;
  const double* __restrict vx = a.vx;
  const double* __restrict vy = a.vy;
  const double* __restrict vz = a.vz;
  double* __restrict sx = a.sx;
  double* __restrict sy = a.sy;
  double* __restrict sz = a.sz;
  double* __restrict fx = a.fx;
  double* __restrict fy = a.fy;
  double* __restrict fz = a.fz;
  const double k = family.stiffness_N_per_m, c = family.damping_N_s_per_m;
  const double rest = family.rest_length_m;
  constexpr double kMinLength2 = kMinSpringLength_m * kMinSpringLength_m;
  for (ptrdiff_t p = lo; p < hi; ++p) {
    const ptrdiff_t q = p + off;
    const double dx = x[q] - x[p], dy = y[q] - y[p], dz = z[q] - z[p];
    const double len2 = dx * dx + dy * dy + dz * dz;
    const double live = len2 > kMinLength2 ? 1.0 : 0.0;
    const double len = std::sqrt(len2 > kMinLength2 ? len2 : kMinLength2);
    const double inv_len = 1.0 / len;
    const double rel_speed =
        ((vx[q] - vx[p]) * dx + (vy[q] - vy[p]) * dy + (vz[q] - vz[p]) * dz) * inv_len;
    const double scale = live * (k * (len - rest) + c * rel_speed) * inv_len;
    sx[p] = scale * dx;
    sy[p] = scale * dy;
    sz[p] = scale * dz;
    fx[p] += sx[p];
    fy[p] += sy[p];
    fz[p] += sz[p];
  }
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
__attribute__((target("avx2"), always_inline)) inline void SpringLanes(const SoaViews& a,
                                                                       const FamilyLanes& f,
                                                                       ptrdiff_t p, ptrdiff_t q,
                                                                       __m256d* sx, __m256d* sy,
                                                                       __m256d* sz) {
  const __m256d dx = _mm256_sub_pd(_mm256_loadu_pd(a.x + q), _mm256_loadu_pd(a.x + p));
  const __m256d dy = _mm256_sub_pd(_mm256_loadu_pd(a.y + q), _mm256_loadu_pd(a.y + p));
  const __m256d dz = _mm256_sub_pd(_mm256_loadu_pd(a.z + q), _mm256_loadu_pd(a.z + p));
  const __m256d len2 = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy)),
                                     _mm256_mul_pd(dz, dz));
  const __m256d live_mask = _mm256_cmp_pd(len2, f.min2, _CMP_GT_OQ);
  const __m256d live = _mm256_and_pd(live_mask, f.one);
  const __m256d len = _mm256_sqrt_pd(_mm256_blendv_pd(f.min2, len2, live_mask));
  const __m256d inv_len = _mm256_div_pd(f.one, len);
  const __m256d dvx = _mm256_sub_pd(_mm256_loadu_pd(a.vx + q), _mm256_loadu_pd(a.vx + p));
  const __m256d dvy = _mm256_sub_pd(_mm256_loadu_pd(a.vy + q), _mm256_loadu_pd(a.vy + p));
  const __m256d dvz = _mm256_sub_pd(_mm256_loadu_pd(a.vz + q), _mm256_loadu_pd(a.vz + p));
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
    SpringLanes(a, f, p, p + off, &sx, &sy, &sz);
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
    SpringLanes(a, f, p, q, &sx, &sy, &sz);
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
};

constexpr SpringKernels kPortableSpringKernels{FamilySpringForces, SubtractFrom, nullptr};
#if defined(__x86_64__)
constexpr SpringKernels kAvx2SpringKernels{FamilySpringForcesAvx2, SubtractFromAvx2,
                                           FamilySpringForcesBothEndsAvx2};
// AVX-512 has no spring kernels of its own: its entry is AVX2's.
constexpr SimdTable<SpringKernels> kSpringKernels{kPortableSpringKernels, kAvx2SpringKernels,
                                                  kAvx2SpringKernels};
#else
constexpr SimdTable<SpringKernels> kSpringKernels{kPortableSpringKernels, kPortableSpringKernels,
                                                  kPortableSpringKernels};
#endif

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

// Adds every spring of `family` to the forces: f_i += s, f_j -= s (grid stencil, no indices).
// Row by row over the columns [c_lo, c_hi) where springs start: every end i first (fused into the
// kernel), then every end j = i + off, so each particle's sum takes its terms in the same order
// as one pass of each over the whole grid. Where the level has a both-ends kernel and off >= 4,
// one pass does both ends in that same order per particle (FamilySpringForcesBothEndsAvx2).
void AddFamilyForces(const SpringKernels& kernels, const SoaViews& a, int32_t width, int32_t height,
                     const SpringFamily& family) {
  const int32_t c_lo = std::max(0, -family.dc), c_hi = width - std::max(0, family.dc);
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
  // a = g + F / m for free particles; pinned particles (inv_mass 0) do not accelerate.
  const Vec3 g = model.gravity_m_per_s2;
  const double* inv_mass = model.inv_mass_per_kg.data();
  const double* __restrict fx = soa.fx;
  const double* __restrict fy = soa.fy;
  const double* __restrict fz = soa.fz;
  double* __restrict out = a.data()->data();
  for (int32_t p = 0; p < n; ++p) {
    const double w = inv_mass[p];
    out[3 * p] = w > 0.0 ? g.x() + w * fx[p] : 0.0;
    out[3 * p + 1] = w > 0.0 ? g.y() + w * fy[p] : 0.0;
    out[3 * p + 2] = w > 0.0 ? g.z() + w * fz[p] : 0.0;
  }
  // Haptic contact springs at these positions (sim_loop/cloth_coupling.h), as accelerations:
  // every particle has mass model.particle_mass_kg and pinned ones take no share.
  AddCouplingForces(scratch->coupling, x, 1.0 / model.particle_mass_kg, out);
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
