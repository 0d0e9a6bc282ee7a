// The stretch limiter's finishing pass (ProvotSpec::finish): after Provot's sweeps, a worklist of
// the spring constraints still over their limits, projected exactly in double precision, each
// projection re-queuing only the springs it pushed over, until none is over.
//
// Why a worklist, and why the sweeps' headroom (measured on the two-corner curtain, 120 frames
// from release, curtain_128.toml's settings otherwise; probe CPU ms per frame at 64 x 64 on the
// AMD host):
// Gauss-Seidel sweeps stall in taut patches where every pair sits at its limit (the release peak
// of bench/results/stability.md), and so does a worklist on its own: with the sweeps aiming at the
// limit itself, it ran out of a budget of 64 projections per particle in nearly every substep and
// still left 1.104 (64 x 64, 150 ms a frame). With the sweeps aiming 1 % below the limit
// (ProvotSpec::sweep_headroom) the springs they leave over it sit in small patches with room
// around them, and the worklist settles them in about 10 projections per substep at 64 x 64 (1.92
// ms against 1.71 without it); the structural maximum is then 1.10 after every substep at 10-128.

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

// A violated pair is projected to this fraction below its limit, not onto it: the slack keeps a
// neighbour's later projection from pushing it back over by a rounding error, which would queue it
// again and again. 1e-6 (with the sweeps' 1 % headroom): 64 x 64 released flat, 498k projections
// over 120 frames; 1e-3: 46k. With scenes/curtain_128.toml's settings (one sweep 2 % under the
// limit), `felt bench cloth --scene scenes/curtain_128.toml`, projections per substep at 64 / 128:
// 1e-3 839 / 929, 5e-3 - / 519, 1e-2 366 / 433, 2e-2 - / 442 (3e-2: 650 at 128). 1e-2 in five
// interleaved pairs against 1e-3 (AMD EPYC, session 33): frame median 0.94 of 1e-3's at 128 x 128
// (0.78-0.98), 0.82 at 64 x 64 (0.62-0.88); the cloth settles at most 0.07 % shorter.
constexpr double kWorklistSlack = 1e-2;
// Projections per substep at most, per particle: the real-time bound. Unconverged substeps are
// counted (ClothCounters::limiter_unconverged); none with scenes/curtain_128.toml's settings at
// grids 10-128.
constexpr size_t kWorklistBudgetPerParticle = 64;
// The single-precision scan queues a pair longer than (1 - this) times its limit, and the exact
// test in double decides. ApplyProvot's positions are relative to the first particle, rounded to
// 6e-8 of the cloth's extent: a length error of about 1.2e-7 (N - 1) of the spacing on an N-wide
// grid, 5e-4 at the largest grid (4096), below this margin.
constexpr float kCandidateMargin = 2e-3f;

// Grid neighbours: particle e's index and its column and row.
struct LimiterEnd {
  int32_t index;
  int32_t col;
  int32_t row;
};

// The sweeps' single-precision positions (scratch.provot_soa) as the scan reads them.
struct LimiterSoa {
  const float* x;
  const float* y;
  const float* z;
};

// True if a pair (p, p + off), p in [lo, hi), has a squared length above near2 (ordered: a NaN
// length is not above), in single precision.
bool AnyNearPortable(const LimiterSoa& a, ptrdiff_t lo, ptrdiff_t hi, ptrdiff_t off, float near2) {
  int any = 0;
  for (ptrdiff_t p = lo; p < hi; ++p) {
    const ptrdiff_t q = p + off;
    const float dx = a.x[q] - a.x[p], dy = a.y[q] - a.y[p], dz = a.z[q] - a.z[p];
    any |= dx * dx + dy * dy + dz * dz > near2 ? 1 : 0;
  }
  return any != 0;
}

#if defined(__x86_64__)
// AnyNearPortable eight pairs a step (the same operations per pair, so the same answer). A run's
// last, partial step loads up to 7 floats past it, inside ProvotSoaStride's padding, and masks
// those lanes out of the test.
__attribute__((target("avx2"))) bool AnyNearAvx2(const LimiterSoa& a, ptrdiff_t lo, ptrdiff_t hi,
                                                 ptrdiff_t off, float near2) {
  const __m256 n2 = _mm256_set1_ps(near2);
  const __m256i lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  __m256 any = _mm256_setzero_ps();
  for (ptrdiff_t p = lo; p < hi; p += 8) {
    const ptrdiff_t q = p + off;
    const __m256 dx = _mm256_sub_ps(_mm256_loadu_ps(a.x + q), _mm256_loadu_ps(a.x + p));
    const __m256 dy = _mm256_sub_ps(_mm256_loadu_ps(a.y + q), _mm256_loadu_ps(a.y + p));
    const __m256 dz = _mm256_sub_ps(_mm256_loadu_ps(a.z + q), _mm256_loadu_ps(a.z + p));
    const __m256 len2 = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(dx, dx), _mm256_mul_ps(dy, dy)),
                                      _mm256_mul_ps(dz, dz));
    const __m256 in_run = _mm256_castsi256_ps(_mm256_cmpgt_epi32(
        _mm256_set1_epi32(static_cast<int>(std::min<ptrdiff_t>(hi - p, 8))), lanes));
    any = _mm256_or_ps(any, _mm256_and_ps(in_run, _mm256_cmp_ps(len2, n2, _CMP_GT_OQ)));
  }
  return _mm256_movemask_ps(any) != 0;
}

// AnyNearPortable sixteen pairs a step (AVX-512F, the same operations per pair); a run's last,
// partial step loads only its own lanes.
#pragma GCC push_options
#pragma GCC optimize("fp-contract=off")
__attribute__((target("avx512f"))) bool AnyNearAvx512(const LimiterSoa& a, ptrdiff_t lo,
                                                      ptrdiff_t hi, ptrdiff_t off, float near2) {
  const __m512 n2 = _mm512_set1_ps(near2);
  __mmask16 any = 0;
  for (ptrdiff_t p = lo; p < hi; p += 16) {
    const ptrdiff_t q = p + off;
    const ptrdiff_t count = hi - p;
    const __mmask16 take =
        count >= 16 ? __mmask16{0xFFFF} : static_cast<__mmask16>((1u << count) - 1u);
    const __m512 dx =
        _mm512_sub_ps(_mm512_maskz_loadu_ps(take, a.x + q), _mm512_maskz_loadu_ps(take, a.x + p));
    const __m512 dy =
        _mm512_sub_ps(_mm512_maskz_loadu_ps(take, a.y + q), _mm512_maskz_loadu_ps(take, a.y + p));
    const __m512 dz =
        _mm512_sub_ps(_mm512_maskz_loadu_ps(take, a.z + q), _mm512_maskz_loadu_ps(take, a.z + p));
    const __m512 len2 = _mm512_add_ps(_mm512_add_ps(_mm512_mul_ps(dx, dx), _mm512_mul_ps(dy, dy)),
                                      _mm512_mul_ps(dz, dz));
    any |= _mm512_mask_cmp_ps_mask(take, len2, n2, _CMP_GT_OQ);
  }
  return any != 0;
}
#pragma GCC pop_options

constexpr SimdTable<bool (*)(const LimiterSoa&, ptrdiff_t, ptrdiff_t, ptrdiff_t, float)>
    kAnyNearKernels{AnyNearPortable, AnyNearAvx2, AnyNearAvx512};
#else
constexpr SimdTable<bool (*)(const LimiterSoa&, ptrdiff_t, ptrdiff_t, ptrdiff_t, float)>
    kAnyNearKernels{AnyNearPortable, AnyNearPortable, AnyNearPortable};
#endif

}  // namespace

void ApplyLimitWorklist(const ClothModel& model, double h_s, ClothState* state) {
  ClothState::Scratch& s = *state->scratch;
  const size_t num_fam = model.limit_families.size();
  if (num_fam == 0) return;
  const int32_t w = model.width, ht = model.height;
  const size_t n = static_cast<size_t>(model.num_particles());
  double* __restrict x = state->x.data()->data();
  double* __restrict v = state->v.data()->data();
  const double* inv_m = model.inv_mass_per_kg.data();
  const double inv_h = 1.0 / h_s;
  uint8_t* queued = s.limit_queued.data();
  int32_t* ring = s.limit_ring.data();
  const size_t cap = s.limit_ring.size();
  size_t head = 0, count = 0;
  uint8_t* logged = s.limit_logged.data();
  int32_t* log_index = s.limit_log_index.data();
  double* log_xv = s.limit_log_xv.data();
  size_t logs = 0;
  // A free particle's state before the worklist's first move of it, into the undo log.
  const auto log = [&](int32_t p) {
    if (logged[p]) return;
    logged[p] = 1;
    log_index[logs] = p;
    for (int32_t a = 0; a < 3; ++a) {
      log_xv[6 * logs + a] = x[3 * p + a];
      log_xv[6 * logs + 3 + a] = v[3 * p + a];
    }
    ++logs;
  };

  // Over its limit in double: the squared length above the squared limit.
  const auto over = [&](const LimitFamily& lf, int32_t p) {
    const int32_t q = p + lf.off;
    const double dx = x[3 * q] - x[3 * p], dy = x[3 * q + 1] - x[3 * p + 1],
                 dz = x[3 * q + 2] - x[3 * p + 2];
    return dx * dx + dy * dy + dz * dz > lf.max2_m2;
  };
  // The ring's wrap by a compare, not a division (head, count <= cap).
  const auto wrap = [cap](size_t i) { return i >= cap ? i - cap : i; };
  const auto push = [&](size_t f, int32_t p) {
    const size_t id = f * n + static_cast<size_t>(p);
    if (queued[id]) return;
    queued[id] = 1;
    ring[wrap(head + count)] = static_cast<int32_t>(id);
    ++count;
  };

  // Every pair over its limit into the worklist: a row at a time, a vectorised test on the sweeps'
  // single-precision positions (scratch.provot_soa, still those of the sweeps' end) whether any
  // pair of the row is near or over its limit, then the exact test in double on that row's pairs.
  const ProvotSoaArrays arrays = ProvotSoaIn(&s.provot_soa, n);
  const LimiterSoa soa{arrays.x, arrays.y, arrays.z};
  const auto any_near = PickSimd(kAnyNearKernels);
  for (size_t f = 0; f < num_fam; ++f) {
    const LimitFamily& lf = model.limit_families[f];
    const float near = static_cast<float>(lf.max_m) * (1.0f - kCandidateMargin);
    const float near2 = near * near;
    const int32_t c_lo = std::max(0, -lf.dc), c_hi = w - std::max(0, lf.dc);
    for (int32_t r = 0; r + lf.dr < ht; ++r) {
      const int32_t lo = r * w + c_lo, hi = r * w + c_hi;
      if (!any_near(soa, lo, hi, lf.off, near2)) continue;
      for (int32_t p = lo; p < hi; ++p) {
        if (over(lf, p)) push(f, p);
      }
    }
  }
  state->counters.limiter_initial += count;

  // Project until none is over (or the budget is spent); each projection re-queues the pairs at
  // its two ends that it pushed over their limits.
  size_t budget = kWorklistBudgetPerParticle * n;
  while (count > 0 && budget > 0) {
    const size_t id = static_cast<size_t>(ring[head]);
    head = wrap(head + 1);
    --count;
    queued[id] = 0;
    // The family and end i of pair id = f n + p, by subtraction (at most four families).
    size_t f = 0, pi = id;
    while (pi >= n) {
      pi -= n;
      ++f;
    }
    const LimitFamily& lf = model.limit_families[f];
    const int32_t p = static_cast<int32_t>(pi);
    const int32_t q = p + lf.off;
    const double dx = x[3 * q] - x[3 * p], dy = x[3 * q + 1] - x[3 * p + 1],
                 dz = x[3 * q + 2] - x[3 * p + 2];
    const double len2 = dx * dx + dy * dy + dz * dz;
    if (!(len2 > lf.max2_m2)) continue;
    const double wp = inv_m[p] > 0.0 ? 1.0 : 0.0, wq = inv_m[q] > 0.0 ? 1.0 : 0.0;
    if (wp + wq == 0.0) continue;
    --budget;
    // Provot 1995's projection, exact: shortened to just under the limit, the move split equally
    // between the free ends (the free end alone if the other is pinned), as in ApplyProvot; the
    // velocities take the move / h, so (x, v) stay consistent.
    if (wp > 0.0) log(p);
    if (wq > 0.0) log(q);
    const double len = std::sqrt(len2);
    const double k = (len - lf.max_m * (1.0 - kWorklistSlack)) / (len * (wp + wq));
    const double mp = wp * k, mq = wq * k;
    x[3 * p] += mp * dx;
    x[3 * p + 1] += mp * dy;
    x[3 * p + 2] += mp * dz;
    x[3 * q] -= mq * dx;
    x[3 * q + 1] -= mq * dy;
    x[3 * q + 2] -= mq * dz;
    v[3 * p] += inv_h * (mp * dx);
    v[3 * p + 1] += inv_h * (mp * dy);
    v[3 * p + 2] += inv_h * (mp * dz);
    v[3 * q] -= inv_h * (mq * dx);
    v[3 * q + 1] -= inv_h * (mq * dy);
    v[3 * q + 2] -= inv_h * (mq * dz);
    ++state->counters.limiter_projections;
    // The pairs at both moved ends that are now over: each end as end i, then as end j. End j's
    // column and row are end i's plus the family's offsets (both ends are on the grid).
    const int32_t p_row = p / w, p_col = p - p_row * w;
    for (const LimiterEnd e :
         {LimiterEnd{p, p_col, p_row}, LimiterEnd{q, p_col + lf.dc, p_row + lf.dr}}) {
      if (inv_m[e.index] == 0.0) continue;
      for (size_t g = 0; g < num_fam; ++g) {
        const LimitFamily& lg = model.limit_families[g];
        const int32_t ci = e.col + lg.dc, ri = e.row + lg.dr;
        if (ci >= 0 && ci < w && ri < ht && over(lg, e.index)) push(g, e.index);
        const int32_t cj = e.col - lg.dc, rj = e.row - lg.dr;
        if (cj >= 0 && cj < w && rj >= 0 && over(lg, e.index - lg.off)) {
          push(g, e.index - lg.off);
        }
      }
    }
  }
  // A worklist that ran out of budget is undone: every particle it moved goes back to the sweeps'
  // result, and the substep is counted. Measured on scenes/self_rail_twist.toml, whose rail
  // carries a pin further from the others than the cloth reaches (1.22 times the rest length at
  // the end even without self-collision): the worklist ran out in every substep from frame 88, and
  // the half-finished projections it left, repeated each substep against the self-collision
  // response, stretched a spring to 32 times its rest length at 58 m/s by frame 123. Undone, the
  // scene's structural maximum is 1.44 (the sweeps alone, provot.finish = false: 1.46).
  const bool undo = count > 0;
  if (undo) ++state->counters.limiter_unconverged;
  while (count > 0) {
    queued[static_cast<size_t>(ring[head])] = 0;
    head = wrap(head + 1);
    --count;
  }
  for (size_t k = 0; k < logs; ++k) {
    const int32_t p = log_index[k];
    logged[p] = 0;
    if (!undo) continue;
    for (int32_t a = 0; a < 3; ++a) {
      x[3 * p + a] = log_xv[6 * k + a];
      v[3 * p + a] = log_xv[6 * k + 3 + a];
    }
  }
}

}  // namespace felt
