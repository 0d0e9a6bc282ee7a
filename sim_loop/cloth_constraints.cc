// What is enforced after each substep: Provot's deformation constraints, the obstacles, the pins.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include "base/simd.h"
#include "sim_loop/cloth.h"
#include "sim_loop/cloth_internal.h"

namespace felt {
namespace {

// The flat kernels read a std::vector<Vec3> as 3 n packed doubles.
static_assert(sizeof(Vec3) == 3 * sizeof(double));

// Provot stops sweeping once the worst excess in a sweep is below this fraction of the limit.
constexpr float kProvotConverged = 1e-3f;
// Each violated constraint is shortened by this multiple of its excess: 1 is plain projection
// (Provot 1995); above 1, projected successive over-relaxation (Cryer 1971; Macklin, Mueller,
// Chentanez & Kim 2014, §4.2). With row and column multiresolution families only, 1.5 carried a
// correction faster down the chains that hold a hanging cloth (64 x 64 two-corner curtain, 10
// sweeps: release peak 1.169 -> about 1.13). With the diagonal families too, plain projection is
// best: 64 x 64 curtain, 2 sweeps per substep, structural / shear stretch once settled 1.1145 /
// 1.1088 at 1.7, 1.1100 / 1.1057 at 1.5, 1.1068 / 1.1038 at 1.3, 1.1042 / 1.1023 at 1.0 (and
// 1.1042 / 1.1022 at 0.9).
constexpr float kProvotRelaxation = 1.0f;
// (1 + kProvotConverged)^2: a pair is loose if its squared length exceeds this times its limit's.
constexpr float kLoose2 = (1.0f + kProvotConverged) * (1.0f + kProvotConverged);
// Sphere-tracing steps along a substep's path before it is taken as a graze.
constexpr int kMaxMarchSteps = 48;

// Removes the velocity into the surface with normal `n` and applies Coulomb friction: the
// tangential speed drops by at most mu times the normal speed removed (sticking if it would
// reverse).
void ContactVelocity(const Vec3& n, double mu, Vec3* v) {
  const double vn = v->dot(n);
  if (vn >= 0.0) return;
  Vec3 vt = *v - vn * n;
  if (mu > 0.0) {
    const double vt_len = vt.norm();
    const double drop = -mu * vn;
    vt = vt_len <= drop ? Vec3(Vec3::Zero()) : Vec3(vt * (1.0 - drop / vt_len));
  }
  *v = vt;
}

// The first point of the segment a -> b whose distance to the obstacle is <= margin, by sphere
// tracing (every shape's distance is exact outside, so each step is safe). False if none.
bool FirstContact(const ObstacleSpec& o, const Vec3& a, const Vec3& b, Vec3* hit, Vec3* normal) {
  const Vec3 d = b - a;
  const double len = d.norm();
  if (!(len > 0.0)) return false;
  const Vec3 dir = d / len;
  double t = 0.0;
  for (int i = 0; i < kMaxMarchSteps && t <= len; ++i) {
    const Vec3 p = a + t * dir;
    const double gap = ObstacleDistance(o, p, normal) - o.margin_m;
    if (gap <= 1e-9) {
      *hit = p;
      return true;
    }
    t += gap;
  }
  return false;
}

// Positions of ApplyProvot in structure-of-arrays form, single precision, metres from the first
// particle (see ApplyProvot), and each particle's movability (1 free, 0 pinned:
// ClothModel::provot_movable).
struct ProvotSoa {
  float* x;
  float* y;
  float* z;
  const float* w;
};

// Provot 1995 (000_25210a744b053ca5.txt slides 9-10) on one pair p, q: a pair longer than its limit
// is shortened by kProvotRelaxation times its excess, split equally between its free ends (the
// free end alone if the other is pinned). Branch-free; the same operations in the same order as
// ProjectLanes, so both give the same bits. Returns true if the pair was loose (over the limit by
// more than kProvotConverged). `max2` is the squared limit, `loose2` kLoose2 times it
// (ProvotLimits).
inline bool ProjectPair(const ProvotSoa& a, ptrdiff_t p, ptrdiff_t q, float max2, float loose2) {
  const float dx = a.x[q] - a.x[p], dy = a.y[q] - a.y[p], dz = a.z[q] - a.z[p];
  const float len2 = dx * dx + dy * dy + dz * dz;
  // (len - max) / len without a square root: (len^2 - max^2) / (len^2 + max^2), one Newton step
  // for the square root from len = max (Jakobsen 2001, "Advanced Character Physics"): the same to
  // first order, 4.5 % more at 10 % over the limit.
  const float over = len2 - max2;
  const float excess = over > 0.0f ? over : 0.0f;
  const float wp = a.w[p], wq = a.w[q];
  // 1 / (number of free ends): 0.5 for two, 1 for one (and moot for none: both weights are 0).
  const float share = 1.0f - 0.5f * (wp * wq);
  const float s = kProvotRelaxation * excess / (len2 + max2) * share;
  const float sp = wp * s, sq = wq * s;
  a.x[p] += sp * dx;
  a.y[p] += sp * dy;
  a.z[p] += sp * dz;
  a.x[q] -= sq * dx;
  a.y[q] -= sq * dy;
  a.z[q] -= sq * dz;
  return len2 > loose2;
}

// Pairs (p, p + off) for p in [lo, hi); the two ranges must not overlap.
bool ProjectRun(const ProvotSoa& a, ptrdiff_t lo, ptrdiff_t hi, ptrdiff_t off, float max2,
                float loose2) {
  bool loose = false;
  for (ptrdiff_t p = lo; p < hi; ++p) loose = ProjectPair(a, p, p + off, max2, loose2) || loose;
  return loose;
}

// Pairs (c + k, c + k + dc) for c = lo, lo + 2 dc, ... and k < dc, c + k < hi (a strided run).
bool ProjectStrided(const ProvotSoa& a, ptrdiff_t lo, ptrdiff_t hi, ptrdiff_t dc, float max2,
                    float loose2) {
  bool loose = false;
  for (ptrdiff_t c = lo; c < hi; c += 2 * dc) {
    for (ptrdiff_t p = c; p < std::min(c + dc, hi); ++p) {
      loose = ProjectPair(a, p, p + dc, max2, loose2) || loose;
    }
  }
  return loose;
}

// One Gauss-Seidel sweep over a family's runs, one pair at a time. Returns true if any pair was
// loose.
bool SweepFamilyPortable(const ProvotSoa& a, int32_t width, const ProvotFamily& f) {
  const ProvotLimits lim = ProvotLimitsOf(f);
  const ptrdiff_t off = static_cast<ptrdiff_t>(f.dr) * width + f.dc;
  bool loose = false;
  for (const ProvotFamily::Run& run : f.runs) {
    if (f.strided()) {
      loose = ProjectStrided(a, run.lo, run.hi, f.dc, lim.max2, lim.loose2) || loose;
    } else {
      loose = ProjectRun(a, run.lo, run.hi, off, lim.max2, lim.loose2) || loose;
    }
  }
  return loose;
}

// Long range attachments of particles [lo, hi), one rank: each particle p outside the ball of
// radius max_len[p] around particle pin[p] back onto it (Kim, Chentanez & Mueller 2012).
void ProjectAttachments(const ProvotSoa& a, const int32_t* pin, const float* max_len, size_t lo,
                        size_t hi) {
  for (size_t p = lo; p < hi; ++p) {
    ProjectIntoBall(a.x, a.y, a.z, p, static_cast<size_t>(pin[p]), max_len[p]);
  }
}

// ProjectAttachments of every particle [0, n), rank after rank (`ranks` ranks of n entries each).
void ProjectAttachmentsPortable(const ProvotSoa& a, const int32_t* pin, const float* max_len,
                                size_t n, size_t ranks) {
  for (size_t k = 0; k < ranks; ++k) ProjectAttachments(a, pin + k * n, max_len + k * n, 0, n);
}

// The conversion kernels of a level without vector ones: they leave every particle to
// ApplyProvot's scalar loops (0 particles done).
size_t NoVectorToProvotSoa(const double*, size_t, const ProvotSoa&) { return 0; }
size_t NoVectorFromProvotSoa(const ProvotSoa&, size_t, double, const double*, double*, double*) {
  return 0;
}

#if defined(__x86_64__)
// Eight pairs at once: ProjectPair on registers (p ends px.., q ends qx..), updated in place.
// Returns the lanes' loose mask.
__attribute__((target("avx2"), always_inline)) inline __m256 ProjectLanes(
    __m256* px, __m256* py, __m256* pz, __m256* qx, __m256* qy, __m256* qz, __m256 wp, __m256 wq,
    __m256 max2, __m256 loose2) {
  const __m256 dx = _mm256_sub_ps(*qx, *px);
  const __m256 dy = _mm256_sub_ps(*qy, *py);
  const __m256 dz = _mm256_sub_ps(*qz, *pz);
  const __m256 len2 = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(dx, dx), _mm256_mul_ps(dy, dy)),
                                    _mm256_mul_ps(dz, dz));
  const __m256 excess = _mm256_max_ps(_mm256_sub_ps(len2, max2), _mm256_setzero_ps());
  const __m256 share = _mm256_sub_ps(_mm256_set1_ps(1.0f),
                                     _mm256_mul_ps(_mm256_set1_ps(0.5f), _mm256_mul_ps(wp, wq)));
  const __m256 s =
      _mm256_mul_ps(_mm256_div_ps(_mm256_mul_ps(_mm256_set1_ps(kProvotRelaxation), excess),
                                  _mm256_add_ps(len2, max2)),
                    share);
  const __m256 sp = _mm256_mul_ps(wp, s), sq = _mm256_mul_ps(wq, s);
  *px = _mm256_add_ps(*px, _mm256_mul_ps(sp, dx));
  *py = _mm256_add_ps(*py, _mm256_mul_ps(sp, dy));
  *pz = _mm256_add_ps(*pz, _mm256_mul_ps(sp, dz));
  *qx = _mm256_sub_ps(*qx, _mm256_mul_ps(sq, dx));
  *qy = _mm256_sub_ps(*qy, _mm256_mul_ps(sq, dy));
  *qz = _mm256_sub_ps(*qz, _mm256_mul_ps(sq, dz));
  return _mm256_cmp_ps(len2, loose2, _CMP_GT_OQ);
}

// The lane shuffles that split two loads of eight particles of a row (c .. c + 15) into the eight
// pairs (c, c + kDc) of one colour, p ends and q ends, and join them back. kDc = 1: the even
// particles against the odd ones; kDc = 2: the first two of every four against the last two;
// kDc = 4: the first four of every eight against the last four; kDc = 8: the first eight against
// the last eight. The lane order does not matter: the pairs are independent.
template <int kDc>
struct PairShuffle;

template <>
struct PairShuffle<1> {
  __attribute__((target("avx2"), always_inline)) static __m256 P(__m256 lo, __m256 hi) {
    return _mm256_shuffle_ps(lo, hi, _MM_SHUFFLE(2, 0, 2, 0));  // c, c + 2, c + 8, c + 10 | ..
  }
  __attribute__((target("avx2"), always_inline)) static __m256 Q(__m256 lo, __m256 hi) {
    return _mm256_shuffle_ps(lo, hi, _MM_SHUFFLE(3, 1, 3, 1));  // c + 1, c + 3, c + 9, ..
  }
  __attribute__((target("avx2"), always_inline)) static __m256 Lo(__m256 p, __m256 q) {
    return _mm256_unpacklo_ps(p, q);  // c .. c + 7
  }
  __attribute__((target("avx2"), always_inline)) static __m256 Hi(__m256 p, __m256 q) {
    return _mm256_unpackhi_ps(p, q);  // c + 8 .. c + 15
  }
};

template <>
struct PairShuffle<2> {
  __attribute__((target("avx2"), always_inline)) static __m256 P(__m256 lo, __m256 hi) {
    return _mm256_shuffle_ps(lo, hi, _MM_SHUFFLE(1, 0, 1, 0));  // c, c + 1, c + 8, c + 9 | ..
  }
  __attribute__((target("avx2"), always_inline)) static __m256 Q(__m256 lo, __m256 hi) {
    return _mm256_shuffle_ps(lo, hi, _MM_SHUFFLE(3, 2, 3, 2));  // c + 2, c + 3, c + 10, ..
  }
  __attribute__((target("avx2"), always_inline)) static __m256 Lo(__m256 p, __m256 q) {
    return _mm256_shuffle_ps(p, q, _MM_SHUFFLE(1, 0, 1, 0));  // c .. c + 7
  }
  __attribute__((target("avx2"), always_inline)) static __m256 Hi(__m256 p, __m256 q) {
    return _mm256_shuffle_ps(p, q, _MM_SHUFFLE(3, 2, 3, 2));  // c + 8 .. c + 15
  }
};

template <>
struct PairShuffle<4> {
  __attribute__((target("avx2"), always_inline)) static __m256 P(__m256 lo, __m256 hi) {
    return _mm256_permute2f128_ps(lo, hi, 0x20);  // c .. c + 3 | c + 8 .. c + 11
  }
  __attribute__((target("avx2"), always_inline)) static __m256 Q(__m256 lo, __m256 hi) {
    return _mm256_permute2f128_ps(lo, hi, 0x31);  // c + 4 .. c + 7 | c + 12 .. c + 15
  }
  __attribute__((target("avx2"), always_inline)) static __m256 Lo(__m256 p, __m256 q) {
    return _mm256_permute2f128_ps(p, q, 0x20);  // c .. c + 7
  }
  __attribute__((target("avx2"), always_inline)) static __m256 Hi(__m256 p, __m256 q) {
    return _mm256_permute2f128_ps(p, q, 0x31);  // c + 8 .. c + 15
  }
};

template <>
struct PairShuffle<8> {
  __attribute__((target("avx2"), always_inline)) static __m256 P(__m256 lo, __m256) {
    return lo;  // c .. c + 7
  }
  __attribute__((target("avx2"), always_inline)) static __m256 Q(__m256, __m256 hi) {
    return hi;  // c + 8 .. c + 15
  }
  __attribute__((target("avx2"), always_inline)) static __m256 Lo(__m256 p, __m256) { return p; }
  __attribute__((target("avx2"), always_inline)) static __m256 Hi(__m256, __m256 q) { return q; }
};

// Lane offsets, from the step's first particle c, of the p end of each pair PairShuffle<kDc>::P
// puts in a lane: a pair takes part in a step's last, partial group if its p end is in the run.
template <int kDc>
__attribute__((target("avx2"), always_inline)) inline __m256i PairStarts() {
  if constexpr (kDc == 1) return _mm256_setr_epi32(0, 2, 8, 10, 4, 6, 12, 14);
  if constexpr (kDc == 2) return _mm256_setr_epi32(0, 1, 8, 9, 4, 5, 12, 13);
  if constexpr (kDc == 4) return _mm256_setr_epi32(0, 1, 2, 3, 8, 9, 10, 11);
  return _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
}

// Lanes k of eight whose offset[k] < count, as a mask (all bits set in a taken lane).
__attribute__((target("avx2"), always_inline)) inline __m256 LanesBelow(__m256i offsets,
                                                                        ptrdiff_t count) {
  return _mm256_castsi256_ps(_mm256_cmpgt_epi32(
      _mm256_set1_epi32(static_cast<int>(std::min<ptrdiff_t>(count, 1 << 30))), offsets));
}

// Projects eight pairs in registers and keeps the result only in the lanes of `take` (the others
// keep their bits exactly, so storing all eight lanes back writes their own values). Returns the
// taken lanes' loose mask.
__attribute__((target("avx2"), always_inline)) inline __m256 ProjectTaken(
    __m256 take, __m256* px, __m256* py, __m256* pz, __m256* qx, __m256* qy, __m256* qz, __m256 wp,
    __m256 wq, __m256 max2, __m256 loose2) {
  __m256 p[3] = {*px, *py, *pz}, q[3] = {*qx, *qy, *qz};
  const __m256 loose = ProjectLanes(&p[0], &p[1], &p[2], &q[0], &q[1], &q[2], wp, wq, max2, loose2);
  *px = _mm256_blendv_ps(*px, p[0], take);
  *py = _mm256_blendv_ps(*py, p[1], take);
  *pz = _mm256_blendv_ps(*pz, p[2], take);
  *qx = _mm256_blendv_ps(*qx, q[0], take);
  *qy = _mm256_blendv_ps(*qy, q[1], take);
  *qz = _mm256_blendv_ps(*qz, q[2], take);
  return _mm256_and_ps(loose, take);
}

// NothingToProject16 on eight pairs (AVX2): true if projecting the lanes of `take` would change
// no coordinate's value (each taken pair at most its limit, not NaN).
__attribute__((target("avx2"), always_inline)) inline bool NothingToProject(
    __m256 take, __m256 px, __m256 py, __m256 pz, __m256 qx, __m256 qy, __m256 qz, __m256 max2) {
  const __m256 dx = _mm256_sub_ps(qx, px);
  const __m256 dy = _mm256_sub_ps(qy, py);
  const __m256 dz = _mm256_sub_ps(qz, pz);
  const __m256 len2 = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(dx, dx), _mm256_mul_ps(dy, dy)),
                                    _mm256_mul_ps(dz, dz));
  const __m256 over = _mm256_cmp_ps(len2, max2, _CMP_NLE_UQ);
  return _mm256_movemask_ps(_mm256_and_ps(over, take)) == 0;
}

// The strided runs of a family along a row with dc = kDc (1, 2, 4 or 8), sixteen particles and
// eight pairs per step (PairShuffle); a run's last, partial step projects only the pairs that start
// in the run (ProjectTaken; its loads may reach up to 15 floats past the run, inside
// ProvotSoaStride's padding). Returns the lanes' loose mask.
template <int kDc>
__attribute__((target("avx2"))) __m256 SweepShuffledRunsAvx2(const ProvotSoa& a,
                                                             const ProvotFamily& f,
                                                             const ProvotLimits& lim) {
  using S = PairShuffle<kDc>;
  const __m256 max2 = _mm256_set1_ps(lim.max2), loose2 = _mm256_set1_ps(lim.loose2);
  float* const coords[3] = {a.x, a.y, a.z};
  const float* __restrict w = a.w;
  // Movability of a run without pins: every end moves (the same values the loads would give).
  const __m256 one = _mm256_set1_ps(1.0f);
  const __m256i lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  __m256 loose = _mm256_setzero_ps();
  for (const ProvotFamily::Run& run : f.runs) {
    for (ptrdiff_t c = run.lo; c < run.hi; c += 16) {
      // Full step: the last pair starts at c + 15 - kDc, below run.hi.
      const bool full = c + 15 < run.hi + kDc;
      __m256 p[3], q[3];
      for (int k = 0; k < 3; ++k) {
        const __m256 lo = _mm256_loadu_ps(coords[k] + c), hi = _mm256_loadu_ps(coords[k] + c + 8);
        p[k] = S::P(lo, hi);
        q[k] = S::Q(lo, hi);
      }
      const __m256 take = full ? _mm256_castsi256_ps(_mm256_set1_epi32(-1))
                               : LanesBelow(PairStarts<kDc>(), run.hi - c);
      if (NothingToProject(take, p[0], p[1], p[2], q[0], q[1], q[2], max2)) continue;
      __m256 w0 = one, w1 = one;
      if (run.pinned) {
        // Only the run's particles, [c, run.hi + kDc): movability has no padding.
        const ptrdiff_t count = run.hi + kDc - c;
        w0 = _mm256_maskload_ps(w + c, _mm256_castps_si256(LanesBelow(lanes, count)));
        w1 = _mm256_maskload_ps(w + c + 8, _mm256_castps_si256(LanesBelow(lanes, count - 8)));
      }
      const __m256 wp = S::P(w0, w1), wq = S::Q(w0, w1);
      if (full) {
        loose = _mm256_or_ps(
            loose, ProjectLanes(&p[0], &p[1], &p[2], &q[0], &q[1], &q[2], wp, wq, max2, loose2));
      } else {
        loose = _mm256_or_ps(loose, ProjectTaken(take, &p[0], &p[1], &p[2], &q[0], &q[1], &q[2], wp,
                                                 wq, max2, loose2));
      }
      for (int k = 0; k < 3; ++k) {
        _mm256_storeu_ps(coords[k] + c, S::Lo(p[k], q[k]));
        _mm256_storeu_ps(coords[k] + c + 8, S::Hi(p[k], q[k]));
      }
    }
  }
  return loose;
}

// SweepFamilyPortable eight pairs at a time (the same operations in the same order per pair, no
// fused multiply-add: the same bits).
__attribute__((target("avx2"))) bool SweepFamilyAvx2(const ProvotSoa& a, int32_t width,
                                                     const ProvotFamily& f) {
  const ProvotLimits lim = ProvotLimitsOf(f);
  if (f.strided()) {
    switch (f.dc) {
      case 1:
        return _mm256_movemask_ps(SweepShuffledRunsAvx2<1>(a, f, lim)) != 0;
      case 2:
        return _mm256_movemask_ps(SweepShuffledRunsAvx2<2>(a, f, lim)) != 0;
      case 4:
        return _mm256_movemask_ps(SweepShuffledRunsAvx2<4>(a, f, lim)) != 0;
      case 8:
        return _mm256_movemask_ps(SweepShuffledRunsAvx2<8>(a, f, lim)) != 0;
      default:
        return SweepFamilyPortable(a, width, f);  // not reached: strided() is 1, 2, 4, 8
    }
  }
  const __m256 max2 = _mm256_set1_ps(lim.max2), loose2 = _mm256_set1_ps(lim.loose2);
  float* __restrict x = a.x;
  float* __restrict y = a.y;
  float* __restrict z = a.z;
  const float* __restrict w = a.w;
  // Movability of a run without pins: every end moves (the same values the loads would give).
  const __m256 one = _mm256_set1_ps(1.0f);
  const __m256i lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  __m256 loose = _mm256_setzero_ps();
  // Contiguous ends: p in the run, q = p + off in another row or run. A run's last, partial group
  // projects only its pairs (ProjectTaken; loads up to 7 floats past the run, in the padding).
  // Where off < 8 the two ends' lanes overlap: the q ends are stored last, so a p lane that is
  // also a taken q end ends with the q result, and an untaken lane writes back its own bits.
  const ptrdiff_t off = static_cast<ptrdiff_t>(f.dr) * width + f.dc;
  for (const ProvotFamily::Run& run : f.runs) {
    for (ptrdiff_t p = run.lo; p < run.hi; p += 8) {
      const ptrdiff_t q = p + off;
      __m256 px = _mm256_loadu_ps(x + p), py = _mm256_loadu_ps(y + p);
      __m256 pz = _mm256_loadu_ps(z + p), qx = _mm256_loadu_ps(x + q);
      __m256 qy = _mm256_loadu_ps(y + q), qz = _mm256_loadu_ps(z + q);
      __m256 wp = one, wq = one;
      const __m256 take = LanesBelow(lanes, run.hi - p);
      if (NothingToProject(take, px, py, pz, qx, qy, qz, max2)) continue;
      if (run.pinned) {
        wp = _mm256_maskload_ps(w + p, _mm256_castps_si256(take));
        wq = _mm256_maskload_ps(w + q, _mm256_castps_si256(take));
      }
      if (p + 8 <= run.hi) {
        loose =
            _mm256_or_ps(loose, ProjectLanes(&px, &py, &pz, &qx, &qy, &qz, wp, wq, max2, loose2));
      } else {
        loose = _mm256_or_ps(
            loose, ProjectTaken(take, &px, &py, &pz, &qx, &qy, &qz, wp, wq, max2, loose2));
      }
      _mm256_storeu_ps(x + p, px);
      _mm256_storeu_ps(y + p, py);
      _mm256_storeu_ps(z + p, pz);
      _mm256_storeu_ps(x + q, qx);
      _mm256_storeu_ps(y + q, qy);
      _mm256_storeu_ps(z + q, qz);
    }
  }
  return _mm256_movemask_ps(loose) != 0;
}

// AVX-512F brings fused multiply-add, which GCC would contract a * b + c into (GNU mode's
// -ffp-contract=fast): these kernels must round every operation as ProjectPair does.
#pragma GCC push_options
#pragma GCC optimize("fp-contract=off")

// ProjectLanes on sixteen pairs (AVX-512F): the same operations in the same order, so the same
// bits. Returns the lanes' loose mask.
__attribute__((target("avx512f"), always_inline)) inline __mmask16 ProjectLanes16(
    __m512* px, __m512* py, __m512* pz, __m512* qx, __m512* qy, __m512* qz, __m512 wp, __m512 wq,
    __m512 max2, __m512 loose2) {
  const __m512 dx = _mm512_sub_ps(*qx, *px);
  const __m512 dy = _mm512_sub_ps(*qy, *py);
  const __m512 dz = _mm512_sub_ps(*qz, *pz);
  const __m512 len2 = _mm512_add_ps(_mm512_add_ps(_mm512_mul_ps(dx, dx), _mm512_mul_ps(dy, dy)),
                                    _mm512_mul_ps(dz, dz));
  // (maskz with every lane: _mm512_max_ps's undefined source trips GCC 12's uninitialised warning)
  const __m512 excess =
      _mm512_maskz_max_ps(__mmask16{0xFFFF}, _mm512_sub_ps(len2, max2), _mm512_setzero_ps());
  const __m512 share = _mm512_sub_ps(_mm512_set1_ps(1.0f),
                                     _mm512_mul_ps(_mm512_set1_ps(0.5f), _mm512_mul_ps(wp, wq)));
  const __m512 s =
      _mm512_mul_ps(_mm512_div_ps(_mm512_mul_ps(_mm512_set1_ps(kProvotRelaxation), excess),
                                  _mm512_add_ps(len2, max2)),
                    share);
  const __m512 sp = _mm512_mul_ps(wp, s), sq = _mm512_mul_ps(wq, s);
  *px = _mm512_add_ps(*px, _mm512_mul_ps(sp, dx));
  *py = _mm512_add_ps(*py, _mm512_mul_ps(sp, dy));
  *pz = _mm512_add_ps(*pz, _mm512_mul_ps(sp, dz));
  *qx = _mm512_sub_ps(*qx, _mm512_mul_ps(sq, dx));
  *qy = _mm512_sub_ps(*qy, _mm512_mul_ps(sq, dy));
  *qz = _mm512_sub_ps(*qz, _mm512_mul_ps(sq, dz));
  return _mm512_cmp_ps_mask(len2, loose2, _CMP_GT_OQ);
}

// True if projecting the taken lanes of sixteen pairs would change no coordinate's value, so a
// sweep may skip them (most steps of the coarse families; 57 % of all steps across rows in
// curtain_128): each pair is at most its limit (ordered: not NaN, so its differences are finite),
// which makes ProjectLanes16's share exactly +0, and a move of +0 or -0 keeps every value. It may
// change a zero's sign (-0.0 + +0 is +0.0), but no result sees that sign: lengths square it away,
// a coordinate can only hold -0.0 if it began as -0.0 (a sum is -0.0 only if both terms are), and
// such a coordinate's move back to the state, a - (-0.0), is +0 for a = +-0 alike. So the state,
// the loose flags and the worklist's scan get the same bits (provot_sweep_skip_test.cc); only the
// single-precision positions may differ, in the sign of a zero. (Testing for -0.0 in the six
// coordinates as well, to keep even those bits, cost 13 % of ApplyProvot's sweeps on curtain_128.)
__attribute__((target("avx512f"), always_inline)) inline bool NothingToProject16(
    __mmask16 take, __m512 px, __m512 py, __m512 pz, __m512 qx, __m512 qy, __m512 qz, __m512 max2) {
  const __m512 dx = _mm512_sub_ps(qx, px);
  const __m512 dy = _mm512_sub_ps(qy, py);
  const __m512 dz = _mm512_sub_ps(qz, pz);
  const __m512 len2 = _mm512_add_ps(_mm512_add_ps(_mm512_mul_ps(dx, dx), _mm512_mul_ps(dy, dy)),
                                    _mm512_mul_ps(dz, dz));
  return _mm512_mask_cmp_ps_mask(take, len2, max2, _CMP_NLE_UQ) == 0;
}

// SweepFamilyAvx2's loop over contiguous ends sixteen pairs at a time, for the families across
// rows (dr > 0): their runs lie in one row, so a run is no longer than its offset and the taken
// lanes of a step are independent pairs. A run's last, partial step keeps the untaken lanes' bits
// (loads up to 15 floats past the run, inside ProvotSoaStride's padding; the q ends are stored
// last, as in SweepFamilyAvx2).
__attribute__((target("avx512f"))) bool SweepAcrossRowsAvx512(const ProvotSoa& a, int32_t width,
                                                              const ProvotFamily& f) {
  const ProvotLimits lim = ProvotLimitsOf(f);
  const __m512 max2 = _mm512_set1_ps(lim.max2), loose2 = _mm512_set1_ps(lim.loose2);
  float* __restrict x = a.x;
  float* __restrict y = a.y;
  float* __restrict z = a.z;
  const float* __restrict w = a.w;
  const __m512 one = _mm512_set1_ps(1.0f);
  __mmask16 loose = 0;
  const ptrdiff_t off = static_cast<ptrdiff_t>(f.dr) * width + f.dc;
  for (const ProvotFamily::Run& run : f.runs) {
    for (ptrdiff_t p = run.lo; p < run.hi; p += 16) {
      const ptrdiff_t q = p + off;
      const ptrdiff_t count = run.hi - p;
      const __mmask16 take =
          count >= 16 ? __mmask16{0xFFFF} : static_cast<__mmask16>((1u << count) - 1u);
      __m512 px = _mm512_loadu_ps(x + p), py = _mm512_loadu_ps(y + p);
      __m512 pz = _mm512_loadu_ps(z + p), qx = _mm512_loadu_ps(x + q);
      __m512 qy = _mm512_loadu_ps(y + q), qz = _mm512_loadu_ps(z + q);
      if (NothingToProject16(take, px, py, pz, qx, qy, qz, max2)) continue;
      __m512 wp = one, wq = one;
      if (run.pinned) {
        wp = _mm512_maskz_loadu_ps(take, w + p);
        wq = _mm512_maskz_loadu_ps(take, w + q);
      }
      __m512 np[3] = {px, py, pz}, nq[3] = {qx, qy, qz};
      loose |= static_cast<__mmask16>(
          ProjectLanes16(&np[0], &np[1], &np[2], &nq[0], &nq[1], &nq[2], wp, wq, max2, loose2) &
          take);
      _mm512_storeu_ps(x + p, _mm512_mask_blend_ps(take, px, np[0]));
      _mm512_storeu_ps(y + p, _mm512_mask_blend_ps(take, py, np[1]));
      _mm512_storeu_ps(z + p, _mm512_mask_blend_ps(take, pz, np[2]));
      _mm512_storeu_ps(x + q, _mm512_mask_blend_ps(take, qx, nq[0]));
      _mm512_storeu_ps(y + q, _mm512_mask_blend_ps(take, qy, nq[1]));
      _mm512_storeu_ps(z + q, _mm512_mask_blend_ps(take, qz, nq[2]));
    }
  }
  return loose != 0;
}
#pragma GCC pop_options

// Four packed (x, y, z) float triples a = [x0 y0 z0 x1], b = [y1 z1 x2 y2], c = [z2 x3 y3 z3] as
// x = [x0 x1 x2 x3], y, z, and back.
__attribute__((target("avx2"), always_inline)) inline void TriplesToLanes(__m128 a, __m128 b,
                                                                          __m128 c, __m128* x,
                                                                          __m128* y, __m128* z) {
  *x = _mm_shuffle_ps(a, _mm_shuffle_ps(b, c, _MM_SHUFFLE(1, 1, 2, 2)), _MM_SHUFFLE(2, 0, 3, 0));
  *y = _mm_shuffle_ps(_mm_shuffle_ps(a, b, _MM_SHUFFLE(0, 0, 1, 1)),
                      _mm_shuffle_ps(b, c, _MM_SHUFFLE(2, 2, 3, 3)), _MM_SHUFFLE(2, 0, 2, 0));
  *z = _mm_shuffle_ps(_mm_shuffle_ps(a, b, _MM_SHUFFLE(1, 1, 2, 2)),
                      _mm_shuffle_ps(c, c, _MM_SHUFFLE(3, 3, 0, 0)), _MM_SHUFFLE(2, 0, 2, 0));
}

__attribute__((target("avx2"), always_inline)) inline void LanesToTriples(__m128 x, __m128 y,
                                                                          __m128 z, __m128* a,
                                                                          __m128* b, __m128* c) {
  *a = _mm_shuffle_ps(_mm_shuffle_ps(x, y, _MM_SHUFFLE(0, 0, 0, 0)),
                      _mm_shuffle_ps(z, x, _MM_SHUFFLE(1, 1, 0, 0)), _MM_SHUFFLE(2, 0, 2, 0));
  *b = _mm_shuffle_ps(_mm_shuffle_ps(y, z, _MM_SHUFFLE(1, 1, 1, 1)),
                      _mm_shuffle_ps(x, y, _MM_SHUFFLE(2, 2, 2, 2)), _MM_SHUFFLE(2, 0, 2, 0));
  *c = _mm_shuffle_ps(_mm_shuffle_ps(z, x, _MM_SHUFFLE(3, 3, 2, 2)),
                      _mm_shuffle_ps(y, z, _MM_SHUFFLE(3, 3, 3, 3)), _MM_SHUFFLE(2, 0, 2, 0));
}

// ApplyProvot's conversion into the single-precision arrays four particles a step: the same
// subtraction and rounding per coordinate. Returns how many particles it did (the rest are
// ApplyProvot's scalar loop's).
__attribute__((target("avx2"))) size_t ToProvotSoaAvx2(const double* __restrict xo, size_t n,
                                                       const ProvotSoa& a) {
  const __m256d oa = _mm256_setr_pd(xo[0], xo[1], xo[2], xo[0]);
  const __m256d ob = _mm256_setr_pd(xo[1], xo[2], xo[0], xo[1]);
  const __m256d oc = _mm256_setr_pd(xo[2], xo[0], xo[1], xo[2]);
  size_t p = 0;
  for (; p + 4 <= n; p += 4) {
    const double* t = xo + 3 * p;
    __m128 x, y, z;
    TriplesToLanes(_mm256_cvtpd_ps(_mm256_sub_pd(_mm256_loadu_pd(t), oa)),
                   _mm256_cvtpd_ps(_mm256_sub_pd(_mm256_loadu_pd(t + 4), ob)),
                   _mm256_cvtpd_ps(_mm256_sub_pd(_mm256_loadu_pd(t + 8), oc)), &x, &y, &z);
    _mm_storeu_ps(a.x + p, x);
    _mm_storeu_ps(a.y + p, y);
    _mm_storeu_ps(a.z + p, z);
  }
  return p;
}

// ApplyProvot's conversion back four particles a step: the same operations per coordinate, so
// the same bits. Returns how many particles it did (the rest are ApplyProvot's scalar loop's).
__attribute__((target("avx2"))) size_t FromProvotSoaAvx2(const ProvotSoa& a, size_t n, double inv_h,
                                                         const double* origin,
                                                         double* __restrict xo,
                                                         double* __restrict vo) {
  const __m256d oa = _mm256_setr_pd(origin[0], origin[1], origin[2], origin[0]);
  const __m256d ob = _mm256_setr_pd(origin[1], origin[2], origin[0], origin[1]);
  const __m256d oc = _mm256_setr_pd(origin[2], origin[0], origin[1], origin[2]);
  const __m256d ih = _mm256_set1_pd(inv_h);
  size_t p = 0;
  for (; p + 4 <= n; p += 4) {
    double* t = xo + 3 * p;
    double* u = vo + 3 * p;
    __m128 na, nb, nc;
    LanesToTriples(_mm_loadu_ps(a.x + p), _mm_loadu_ps(a.y + p), _mm_loadu_ps(a.z + p), &na, &nb,
                   &nc);
    const __m256d xa = _mm256_loadu_pd(t), xb = _mm256_loadu_pd(t + 4), xc = _mm256_loadu_pd(t + 8);
    const __m256d ma =
        _mm256_sub_pd(_mm256_cvtps_pd(na), _mm256_cvtps_pd(_mm256_cvtpd_ps(_mm256_sub_pd(xa, oa))));
    const __m256d mb =
        _mm256_sub_pd(_mm256_cvtps_pd(nb), _mm256_cvtps_pd(_mm256_cvtpd_ps(_mm256_sub_pd(xb, ob))));
    const __m256d mc =
        _mm256_sub_pd(_mm256_cvtps_pd(nc), _mm256_cvtps_pd(_mm256_cvtpd_ps(_mm256_sub_pd(xc, oc))));
    _mm256_storeu_pd(t, _mm256_add_pd(xa, ma));
    _mm256_storeu_pd(t + 4, _mm256_add_pd(xb, mb));
    _mm256_storeu_pd(t + 8, _mm256_add_pd(xc, mc));
    _mm256_storeu_pd(u, _mm256_add_pd(_mm256_loadu_pd(u), _mm256_mul_pd(ih, ma)));
    _mm256_storeu_pd(u + 4, _mm256_add_pd(_mm256_loadu_pd(u + 4), _mm256_mul_pd(ih, mb)));
    _mm256_storeu_pd(u + 8, _mm256_add_pd(_mm256_loadu_pd(u + 8), _mm256_mul_pd(ih, mc)));
  }
  return p;
}

// ProjectAttachmentsPortable eight particles a step: the same operations per lane (a correctly
// rounded square root and division, no fused multiply-add), so the same bits. Every rank of a step
// is done before the next step: a particle's ranks still run in order, and the pins they read never
// move (a pin is attached to itself with limit 0), so the order across particles does not matter;
// the step's positions are loaded and stored once. Eight particles that share a pin (all but the
// steps where the nearest pin changes) read it by a broadcast instead of a gather.
__attribute__((target("avx2"))) void ProjectAttachmentsAvx2(const ProvotSoa& a, const int32_t* pin,
                                                            const float* max_len, size_t n,
                                                            size_t ranks) {
  size_t p = 0;
  for (; p + 8 <= n; p += 8) {
    __m256 px = _mm256_loadu_ps(a.x + p), py = _mm256_loadu_ps(a.y + p),
           pz = _mm256_loadu_ps(a.z + p);
    bool moved = false;
    for (size_t k = 0; k < ranks; ++k) {
      const int32_t* rank_pin = pin + k * n;
      const __m256i q = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(rank_pin + p));
      const int32_t q0 = rank_pin[p];
      __m256 qx, qy, qz;
      if (_mm256_movemask_epi8(_mm256_cmpeq_epi32(q, _mm256_set1_epi32(q0))) == -1) {
        qx = _mm256_set1_ps(a.x[q0]);
        qy = _mm256_set1_ps(a.y[q0]);
        qz = _mm256_set1_ps(a.z[q0]);
      } else {
        qx = _mm256_i32gather_ps(a.x, q, 4);
        qy = _mm256_i32gather_ps(a.y, q, 4);
        qz = _mm256_i32gather_ps(a.z, q, 4);
      }
      const __m256 dx = _mm256_sub_ps(px, qx);
      const __m256 dy = _mm256_sub_ps(py, qy);
      const __m256 dz = _mm256_sub_ps(pz, qz);
      const __m256 len2 = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(dx, dx), _mm256_mul_ps(dy, dy)),
                                        _mm256_mul_ps(dz, dz));
      const __m256 ml = _mm256_loadu_ps(max_len + k * n + p);
      // Moved where not len2 <= max^2 (NaN included), as the scalar test.
      const __m256 move = _mm256_cmp_ps(len2, _mm256_mul_ps(ml, ml), _CMP_NLE_UQ);
      if (_mm256_movemask_ps(move) == 0) continue;
      moved = true;
      const __m256 len = _mm256_sqrt_ps(len2);
      const __m256 scale = _mm256_div_ps(_mm256_sub_ps(len, ml), len);
      px = _mm256_blendv_ps(px, _mm256_sub_ps(px, _mm256_mul_ps(scale, dx)), move);
      py = _mm256_blendv_ps(py, _mm256_sub_ps(py, _mm256_mul_ps(scale, dy)), move);
      pz = _mm256_blendv_ps(pz, _mm256_sub_ps(pz, _mm256_mul_ps(scale, dz)), move);
    }
    if (!moved) continue;
    _mm256_storeu_ps(a.x + p, px);
    _mm256_storeu_ps(a.y + p, py);
    _mm256_storeu_ps(a.z + p, pz);
  }
  for (size_t k = 0; k < ranks; ++k) ProjectAttachments(a, pin + k * n, max_len + k * n, p, n);
}
#endif

// ApplyProvot's kernels of one level (SimdTable); every level gives the same bits
// (simd_kernels_test.cc, and cloth_provot_test.cc against a naive Gauss-Seidel).
struct ProvotSimdKernels {
  // The state's packed positions xo [3 n] into the single-precision arrays, a first run of
  // particles; returns how many (ApplyProvot's scalar loop does the rest).
  size_t (*to_soa)(const double* xo, size_t n, const ProvotSoa& a);
  // Every rank of long range attachments over particles [0, n) (ProjectAttachments): `ranks`
  // ranks of n pins and limits each.
  void (*attachments)(const ProvotSoa& a, const int32_t* pin, const float* max_len, size_t n,
                      size_t ranks);
  // One Gauss-Seidel sweep over a family along a row (dr = 0; SweepFamilyPortable).
  bool (*sweep_along_rows)(const ProvotSoa& a, int32_t width, const ProvotFamily& f);
  // One Gauss-Seidel sweep over a family across rows (dr > 0; SweepFamilyPortable).
  bool (*sweep_across_rows)(const ProvotSoa& a, int32_t width, const ProvotFamily& f);
  // The moves back into the state, positions and velocities, a first run of particles; returns
  // how many (ApplyProvot's scalar loop does the rest).
  size_t (*from_soa)(const ProvotSoa& a, size_t n, double inv_h, const double* origin, double* xo,
                     double* vo);
};

constexpr ProvotSimdKernels kPortableProvotKernels{NoVectorToProvotSoa, ProjectAttachmentsPortable,
                                                   SweepFamilyPortable, SweepFamilyPortable,
                                                   NoVectorFromProvotSoa};
#if defined(__x86_64__)
constexpr ProvotSimdKernels kAvx2ProvotKernels{ToProvotSoaAvx2, ProjectAttachmentsAvx2,
                                               SweepFamilyAvx2, SweepFamilyAvx2, FromProvotSoaAvx2};
// AVX-512F only for the families across rows; the rest as AVX2.
constexpr ProvotSimdKernels kAvx512ProvotKernels{ToProvotSoaAvx2, ProjectAttachmentsAvx2,
                                                 SweepFamilyAvx2, SweepAcrossRowsAvx512,
                                                 FromProvotSoaAvx2};
constexpr SimdTable<ProvotSimdKernels> kProvotKernels{kPortableProvotKernels, kAvx2ProvotKernels,
                                                      kAvx512ProvotKernels};
#else
constexpr SimdTable<ProvotSimdKernels> kProvotKernels{
    kPortableProvotKernels, kPortableProvotKernels, kPortableProvotKernels};
#endif

}  // namespace

double ObstacleDistance(const ObstacleSpec& o, const Vec3& p, Vec3* normal) {
  if (const auto* plane = std::get_if<PlaneSpec>(&o.shape)) {
    *normal = plane->normal;
    return plane->normal.dot(p - plane->point_m);
  }
  if (const auto* sphere = std::get_if<SphereSpec>(&o.shape)) {
    const Vec3 d = p - sphere->center_m;
    const double len = d.norm();
    *normal = len > 0.0 ? Vec3(d / len) : Vec3(Vec3::UnitY());
    return len - sphere->radius_m;
  }
  if (const auto* box = std::get_if<BoxSpec>(&o.shape)) {
    // Exact box distance: q = |p - centre| - half extent per axis.
    const Vec3 centre = 0.5 * (box->min_m + box->max_m);
    const Vec3 half = 0.5 * (box->max_m - box->min_m);
    const Vec3 rel = p - centre;
    const Vec3 q = rel.cwiseAbs() - half;
    const Vec3 sign(rel.x() < 0.0 ? -1.0 : 1.0, rel.y() < 0.0 ? -1.0 : 1.0,
                    rel.z() < 0.0 ? -1.0 : 1.0);
    const Vec3 outside = q.cwiseMax(0.0);
    const double out_len = outside.norm();
    if (out_len > 0.0) {
      *normal = sign.cwiseProduct(outside) / out_len;
      return out_len;
    }
    // Inside: the nearest face.
    Eigen::Index axis = 0;
    const double depth = q.maxCoeff(&axis);
    *normal = Vec3::Zero();
    (*normal)[axis] = sign[axis];
    return depth;
  }
  const auto& capsule = std::get<CapsuleSpec>(o.shape);
  // Distance to the closest point of the segment a-b, less the radius.
  const Vec3 ab = capsule.b_m - capsule.a_m;
  const double ab2 = ab.squaredNorm();
  const double t = ab2 > 0.0 ? std::clamp((p - capsule.a_m).dot(ab) / ab2, 0.0, 1.0) : 0.0;
  const Vec3 d = p - (capsule.a_m + t * ab);
  const double len = d.norm();
  *normal = len > 0.0 ? Vec3(d / len) : Vec3(Vec3::UnitY());
  return len - capsule.radius_m;
}

ProvotLimits ProvotLimitsOf(const ProvotFamily& f) {
  const float max_len = static_cast<float>(f.sweep_length_m);
  const float max2 = max_len * max_len;
  return {max2, kLoose2 * max2};
}

void ApplyProvot(const ClothModel& model, double h_s, ClothState* state) {
  // The kernels of the level in use, picked once per call.
  const ProvotSimdKernels& kernels = PickSimd(kProvotKernels);
  const size_t n = static_cast<size_t>(model.num_particles());
  // x, y, z each on a 64-byte line (ProvotSoaIn).
  ClothState::Scratch& scratch = *state->scratch;
  const ProvotSoaArrays arrays = ProvotSoaIn(&scratch.provot_soa, n);
  const ProvotSoa a{arrays.x, arrays.y, arrays.z, model.provot_movable.data()};
  // Into structure-of-arrays, single precision, relative to the first particle (so the precision
  // does not depend on where the cloth is in the world): ~6e-8 of the cloth's size, 1e-4 of a
  // 64 x 64 curtain's spacing against the 1e-3 convergence tolerance.
  double* __restrict xo = state->x.data()->data();
  const double origin[3] = {xo[0], xo[1], xo[2]};
  const double ox = origin[0], oy = origin[1], oz = origin[2];
  for (size_t p = kernels.to_soa(xo, n, a); p < n; ++p) {
    a.x[p] = static_cast<float>(xo[3 * p] - ox);
    a.y[p] = static_cast<float>(xo[3 * p + 1] - oy);
    a.z[p] = static_cast<float>(xo[3 * p + 2] - oz);
  }
  // Long range attachments first: each free particle back into the ball around its pins (Kim,
  // Chentanez & Mueller 2012), nearest first; the pins are kinematic, so only the particle moves.
  if (model.attachment_ranks > 0) {
    kernels.attachments(a, model.attachment_pin.data(), model.attachment_max_m.data(), n,
                        static_cast<size_t>(model.attachment_ranks));
  }
  // Sweeps over the families, coarse to fine (the coarse ones in the first provot_coarse_sweeps
  // only); converged once no pair of a sweep was more than kProvotConverged over its limit.
  for (int32_t sweep = 0; sweep < model.provot_iterations; ++sweep) {
    bool loose = false;
    for (const ProvotFamily& family : model.provot_families) {
      // The multiresolution families in the first provot_coarse_sweeps sweeps only.
      if (family.level > 1 && sweep >= model.provot_coarse_sweeps) continue;
      const auto sweep_family =
          family.dr > 0 ? kernels.sweep_across_rows : kernels.sweep_along_rows;
      loose = sweep_family(a, model.width, family) || loose;
    }
    if (!loose) break;
  }
  // Back to the state as the move each particle made (exact in double; 0 for one not moved, so
  // its position keeps every bit); velocities follow, v += dx / h, so (x, v) stay consistent.
  const double inv_h = 1.0 / h_s;
  double* __restrict vo = state->v.data()->data();
  for (size_t p = kernels.from_soa(a, n, inv_h, origin, xo, vo); p < n; ++p) {
    const double mx =
        static_cast<double>(a.x[p]) - static_cast<double>(static_cast<float>(xo[3 * p] - ox));
    const double my =
        static_cast<double>(a.y[p]) - static_cast<double>(static_cast<float>(xo[3 * p + 1] - oy));
    const double mz =
        static_cast<double>(a.z[p]) - static_cast<double>(static_cast<float>(xo[3 * p + 2] - oz));
    xo[3 * p] += mx;
    xo[3 * p + 1] += my;
    xo[3 * p + 2] += mz;
    vo[3 * p] += inv_h * mx;
    vo[3 * p + 1] += inv_h * my;
    vo[3 * p + 2] += inv_h * mz;
  }
  // The springs the sweeps left over their limits, exactly (ProvotSpec::finish).
  ApplyLimitWorklist(model, h_s, state);
}

void ApplyObstacles(const ClothModel& model, double h_s, ClothState* state) {
  const auto& obstacles = model.obstacles;
  const Vec3* x_start = state->scratch->x_start.data();
  for (int32_t p = 0; p < model.num_particles(); ++p) {
    if (model.inv_mass_per_kg[p] == 0.0) continue;
    bool touched = false;
    for (const ObstacleSpec& o : obstacles) {
      Vec3& x = state->x[p];
      Vec3 normal;
      const double phi = ObstacleDistance(o, x, &normal);
      const Vec3 start = x_start[p];
      // The distance is 1-Lipschitz: a path that ends farther out than its length cannot have
      // touched the margin shell, the common case, decided without a second distance.
      const double path = (x - start).norm();
      if (phi - o.margin_m >= path) continue;
      Vec3 n_start, hit;
      const double phi_start = ObstacleDistance(o, start, &n_start);
      // Started clearly outside the shell (not resting on it): the first contact along the path
      // is where the particle meets the obstacle, so a fast particle cannot tunnel through a thin
      // one or exit on its far side.
      const bool start_clear = phi_start - o.margin_m > 1e-9;
      // Resting on or starting inside the shell, the particle is held by the face it started on:
      // the shell's tangent plane there (normal n_start, margin - phi_start out from the start).
      // The shell is convex, so it lies wholly behind that plane, and a point projected onto the
      // plane is outside it. `behind` < 0: the end lies behind the plane by that much.
      const double behind = phi_start + n_start.dot(x - start) - o.margin_m;
      if (phi >= o.margin_m) {
        if (start_clear) {
          if (phi_start + phi - 2.0 * o.margin_m > path) continue;
          if (!FirstContact(o, start, x, &hit, &normal)) continue;
          x = hit;
        } else {
          // Ended outside, having started on the shell: it left (in front of the plane, or round
          // an edge), or it went through the obstacle and out of a far side, which the path back
          // from the end tells by meeting the shell farther than the margin from the start
          // (Bridson, Fedkiw & Anderson 2002: contacts are resolved along the whole path, not at
          // its end). A light particle under a frame's held push travels metres in one substep
          // (TableSlideTest).
          if (behind >= 0.0 || !FirstContact(o, x, start, &hit, &normal) ||
              (hit - start).norm() <= o.margin_m + 1e-6) {
            continue;
          }
          x -= behind * n_start;
          normal = n_start;
        }
      } else if (start_clear && FirstContact(o, start, x, &hit, &normal)) {
        x = hit;
      } else if (start_clear || normal.dot(n_start) > 0.0) {
        // Out to the nearest surface plus margin.
        x += (o.margin_m - phi) * normal;
      } else {
        // Started on the shell and ended deep inside, nearest to another face (or the far side):
        // back onto the plane of the face it started on, not out of the one nearest the end.
        x -= behind * n_start;
        normal = n_start;
      }
      ContactVelocity(normal, o.friction, &state->v[p]);
      touched = true;
    }
    if (touched) SyncVerletHistory(model, p, h_s, state);
  }
}

void ApplyPins(const ClothModel& model, double t_s, ClothState* state) {
  for (size_t k = 0; k < model.pinned.size(); ++k) {
    const int32_t p = model.pinned[k];
    if (model.pin_scripted[k]) {
      const PinMotionSpec& motion = model.pin_motion[k];
      state->x[p] = model.rest_position_m[p] + PinOffset(motion, t_s);
      state->v[p] = PinVelocity(motion, t_s);
    } else {
      state->x[p] = model.rest_position_m[p];
      state->v[p].setZero();
    }
  }
}

}  // namespace felt
