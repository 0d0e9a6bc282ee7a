// What is enforced after each substep: Provot's deformation constraints, the obstacles, the pins.

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include "sim_loop/cloth.h"
#include "sim_loop/cloth_internal.h"
#include "sim_loop/cpu_features.h"

namespace felt {
namespace {

// The flat kernels read a std::vector<Vec3> as 3 n packed doubles.
static_assert(sizeof(Vec3) == 3 * sizeof(double));

// Provot stops sweeping once the worst excess in a sweep is below this fraction of the limit.
constexpr double kProvotConverged = 1e-3;
// Each violated constraint is shortened by this multiple of its excess, ending it up to 50 % of
// the excess below the limit: projected successive over-relaxation (Cryer 1971), as position-based
// solvers use it (Macklin, Mueller, Chentanez & Kim 2014, §4.2). Gauss-Seidel with plain
// projection (1.0) carries a correction only slowly down the chains of constraints that hold a
// hanging cloth; measured on the two-corner curtain (10 sweeps, first second after release), 1.5
// lowers the peak stretch from 1.154 to 1.131 at 32 x 32, from 1.169 to about 1.13 at 64 x 64, at
// the same cost. An inequality constraint left below its limit is inactive, so nothing is pushed.
constexpr double kProvotOverRelaxation = 1.5;
// (1 + kProvotConverged)^2: a pair is loose if its squared length exceeds this times its limit's.
constexpr double kLoose2 = (1.0 + kProvotConverged) * (1.0 + kProvotConverged);
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

// Set by UsePortableProvotKernels: the sweeps ignore AVX2.
std::atomic<bool> g_provot_portable{false};

// Positions of ApplyProvot in structure-of-arrays form, and each particle's movability (1 free,
// 0 pinned: ClothModel::provot_movable).
struct ProvotSoa {
  double* x;
  double* y;
  double* z;
  const double* w;
};

// Provot 1995 (000_25210a744b053ca5.txt slides 9-10) on one pair p, q: a pair longer than its limit
// is shortened by kProvotOverRelaxation times its excess, split equally between its free ends (the
// free end alone if the other is pinned). Branch-free; the same operations in the same order as
// ProjectLanes, so both give the same bits. Returns true if the pair was loose (over the limit by
// more than kProvotConverged).
inline bool ProjectPair(const ProvotSoa& a, ptrdiff_t p, ptrdiff_t q, double max_len,
                        double loose2) {
  const double dx = a.x[q] - a.x[p], dy = a.y[q] - a.y[p], dz = a.z[q] - a.z[p];
  const double len2 = dx * dx + dy * dy + dz * dz;
  const double max2 = max_len * max_len;
  // (len - max) / len without a square root: (len^2 - max^2) / (len^2 + max^2), one Newton step
  // for the square root from len = max (Jakobsen 2001, "Advanced Character Physics"): the same to
  // first order, 4.5 % more at 10 % over the limit.
  const double over = len2 - max2;
  const double excess = over > 0.0 ? over : 0.0;
  const double wp = a.w[p], wq = a.w[q];
  // 1 / (number of free ends): 0.5 for two, 1 for one (and moot for none: both weights are 0).
  const double share = 1.0 - 0.5 * (wp * wq);
  const double s = kProvotOverRelaxation * excess / (len2 + max2) * share;
  const double sp = wp * s, sq = wq * s;
  a.x[p] += sp * dx;
  a.y[p] += sp * dy;
  a.z[p] += sp * dz;
  a.x[q] -= sq * dx;
  a.y[q] -= sq * dy;
  a.z[q] -= sq * dz;
  return len2 > loose2;
}

// Pairs (p, p + off) for p in [lo, hi); the two ranges must not overlap.
bool ProjectRun(const ProvotSoa& a, ptrdiff_t lo, ptrdiff_t hi, ptrdiff_t off, double max_len,
                double loose2) {
  bool loose = false;
  for (ptrdiff_t p = lo; p < hi; ++p) loose = ProjectPair(a, p, p + off, max_len, loose2) || loose;
  return loose;
}

// Pairs (c, c + 1) for c = lo, lo + 2, ... < hi.
bool ProjectNeighbours(const ProvotSoa& a, ptrdiff_t lo, ptrdiff_t hi, double max_len,
                       double loose2) {
  bool loose = false;
  for (ptrdiff_t c = lo; c < hi; c += 2) loose = ProjectPair(a, c, c + 1, max_len, loose2) || loose;
  return loose;
}

// Pairs (c, c + 2) for c in {lo, lo + 1} + 4 k, c < hi.
bool ProjectSecondNeighbours(const ProvotSoa& a, ptrdiff_t lo, ptrdiff_t hi, double max_len,
                             double loose2) {
  bool loose = false;
  for (ptrdiff_t c = lo; c < hi; c += 4) {
    loose = ProjectPair(a, c, c + 2, max_len, loose2) || loose;
    if (c + 1 < hi) loose = ProjectPair(a, c + 1, c + 3, max_len, loose2) || loose;
  }
  return loose;
}

// One Gauss-Seidel sweep over a family's runs, one pair at a time. Returns true if any pair was
// loose.
bool SweepFamilyPortable(const ProvotSoa& a, int32_t width, const ProvotFamily& f) {
  const double loose2 = kLoose2 * f.max_length_m * f.max_length_m;
  const ptrdiff_t off = static_cast<ptrdiff_t>(f.dr) * width + f.dc;
  bool loose = false;
  for (const ProvotFamily::Run& run : f.runs) {
    if (f.dr == 0 && f.dc == 1) {
      loose = ProjectNeighbours(a, run.lo, run.hi, f.max_length_m, loose2) || loose;
    } else if (f.dr == 0 && f.dc == 2) {
      loose = ProjectSecondNeighbours(a, run.lo, run.hi, f.max_length_m, loose2) || loose;
    } else {
      loose = ProjectRun(a, run.lo, run.hi, off, f.max_length_m, loose2) || loose;
    }
  }
  return loose;
}

#if defined(__x86_64__)
// Four pairs at once: ProjectPair on registers (p ends px.., q ends qx..), updated in place.
// Returns the lanes' loose mask.
__attribute__((target("avx2"), always_inline)) inline __m256d ProjectLanes(
    __m256d* px, __m256d* py, __m256d* pz, __m256d* qx, __m256d* qy, __m256d* qz, __m256d wp,
    __m256d wq, __m256d max2, __m256d loose2) {
  const __m256d dx = _mm256_sub_pd(*qx, *px);
  const __m256d dy = _mm256_sub_pd(*qy, *py);
  const __m256d dz = _mm256_sub_pd(*qz, *pz);
  const __m256d len2 = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy)),
                                     _mm256_mul_pd(dz, dz));
  const __m256d excess = _mm256_max_pd(_mm256_sub_pd(len2, max2), _mm256_setzero_pd());
  const __m256d share =
      _mm256_sub_pd(_mm256_set1_pd(1.0), _mm256_mul_pd(_mm256_set1_pd(0.5), _mm256_mul_pd(wp, wq)));
  const __m256d s =
      _mm256_mul_pd(_mm256_div_pd(_mm256_mul_pd(_mm256_set1_pd(kProvotOverRelaxation), excess),
                                  _mm256_add_pd(len2, max2)),
                    share);
  const __m256d sp = _mm256_mul_pd(wp, s), sq = _mm256_mul_pd(wq, s);
  *px = _mm256_add_pd(*px, _mm256_mul_pd(sp, dx));
  *py = _mm256_add_pd(*py, _mm256_mul_pd(sp, dy));
  *pz = _mm256_add_pd(*pz, _mm256_mul_pd(sp, dz));
  *qx = _mm256_sub_pd(*qx, _mm256_mul_pd(sq, dx));
  *qy = _mm256_sub_pd(*qy, _mm256_mul_pd(sq, dy));
  *qz = _mm256_sub_pd(*qz, _mm256_mul_pd(sq, dz));
  return _mm256_cmp_pd(len2, loose2, _CMP_GT_OQ);
}

// The lane shuffles that split two loads of eight particles of a row into the four pairs (c,
// c + kDc) of one colour, p ends and q ends; the same shuffles join them back. kDc = 1: the even
// lanes against the odd ones; kDc = 2: the low halves against the high halves. The lane order
// does not matter: the pairs are independent.
template <int kDc>
struct PairShuffle;

template <>
struct PairShuffle<1> {
  __attribute__((target("avx2"), always_inline)) static __m256d First(__m256d a, __m256d b) {
    return _mm256_unpacklo_pd(a, b);  // c, c + 4, c + 2, c + 6 (split) / c .. c + 3 (join)
  }
  __attribute__((target("avx2"), always_inline)) static __m256d Second(__m256d a, __m256d b) {
    return _mm256_unpackhi_pd(a, b);  // c + 1, c + 5, c + 3, c + 7 / c + 4 .. c + 7
  }
};

template <>
struct PairShuffle<2> {
  __attribute__((target("avx2"), always_inline)) static __m256d First(__m256d a, __m256d b) {
    return _mm256_permute2f128_pd(a, b, 0x20);  // c, c + 1, c + 4, c + 5 / c .. c + 3
  }
  __attribute__((target("avx2"), always_inline)) static __m256d Second(__m256d a, __m256d b) {
    return _mm256_permute2f128_pd(a, b, 0x31);  // c + 2, c + 3, c + 6, c + 7 / c + 4 .. c + 7
  }
};

// The runs of a family along a row with dc = kDc (1 or 2), eight particles and four pairs per
// step (PairShuffle), the rest one pair at a time; sets *tail if a pair of the rest was loose.
// Returns the lanes' loose mask.
template <int kDc>
__attribute__((target("avx2"))) __m256d SweepShuffledRunsAvx2(const ProvotSoa& a,
                                                              const ProvotFamily& f, __m256d max2,
                                                              __m256d loose2, bool* tail) {
  using S = PairShuffle<kDc>;
  const double loose2_s = kLoose2 * f.max_length_m * f.max_length_m;
  double* const coords[3] = {a.x, a.y, a.z};
  const double* __restrict w = a.w;
  // Movability of a run without pins: every end moves (the same values the loads would give).
  const __m256d one = _mm256_set1_pd(1.0);
  __m256d loose = _mm256_setzero_pd();
  for (const ProvotFamily::Run& run : f.runs) {
    ptrdiff_t c = run.lo;
    // The step's last pair starts at c + 7 - kDc, which must be below run.hi.
    for (; c + 7 < run.hi + kDc; c += 8) {
      __m256d p[3], q[3];
      for (int k = 0; k < 3; ++k) {
        const __m256d lo = _mm256_loadu_pd(coords[k] + c), hi = _mm256_loadu_pd(coords[k] + c + 4);
        p[k] = S::First(lo, hi);
        q[k] = S::Second(lo, hi);
      }
      const __m256d w0 = run.pinned ? _mm256_loadu_pd(w + c) : one;
      const __m256d w1 = run.pinned ? _mm256_loadu_pd(w + c + 4) : one;
      loose = _mm256_or_pd(loose, ProjectLanes(&p[0], &p[1], &p[2], &q[0], &q[1], &q[2],
                                               S::First(w0, w1), S::Second(w0, w1), max2, loose2));
      for (int k = 0; k < 3; ++k) {
        _mm256_storeu_pd(coords[k] + c, S::First(p[k], q[k]));
        _mm256_storeu_pd(coords[k] + c + 4, S::Second(p[k], q[k]));
      }
    }
    if (c < run.hi) {
      const bool rest = kDc == 1 ? ProjectNeighbours(a, c, run.hi, f.max_length_m, loose2_s)
                                 : ProjectSecondNeighbours(a, c, run.hi, f.max_length_m, loose2_s);
      *tail = rest || *tail;
    }
  }
  return loose;
}

// SweepFamilyPortable four pairs at a time (the same operations in the same order per pair, no
// fused multiply-add: the same bits).
__attribute__((target("avx2"))) bool SweepFamilyAvx2(const ProvotSoa& a, int32_t width,
                                                     const ProvotFamily& f) {
  const double max2_s = f.max_length_m * f.max_length_m;
  const double loose2_s = kLoose2 * max2_s;
  const __m256d max2 = _mm256_set1_pd(max2_s), loose2 = _mm256_set1_pd(loose2_s);
  double* __restrict x = a.x;
  double* __restrict y = a.y;
  double* __restrict z = a.z;
  const double* __restrict w = a.w;
  // Movability of a run without pins: every end moves (the same values the loads would give).
  const __m256d one = _mm256_set1_pd(1.0);
  __m256d loose = _mm256_setzero_pd();
  bool tail = false;
  if (f.dr == 0 && f.dc == 1) {
    loose = SweepShuffledRunsAvx2<1>(a, f, max2, loose2, &tail);
  } else if (f.dr == 0 && f.dc == 2) {
    loose = SweepShuffledRunsAvx2<2>(a, f, max2, loose2, &tail);
  } else {
    // Contiguous ends: p in the run, q = p + off in another row or run.
    const ptrdiff_t off = static_cast<ptrdiff_t>(f.dr) * width + f.dc;
    for (const ProvotFamily::Run& run : f.runs) {
      ptrdiff_t p = run.lo;
      for (; p + 4 <= run.hi; p += 4) {
        const ptrdiff_t q = p + off;
        __m256d px = _mm256_loadu_pd(x + p), py = _mm256_loadu_pd(y + p);
        __m256d pz = _mm256_loadu_pd(z + p), qx = _mm256_loadu_pd(x + q);
        __m256d qy = _mm256_loadu_pd(y + q), qz = _mm256_loadu_pd(z + q);
        loose = _mm256_or_pd(
            loose,
            ProjectLanes(&px, &py, &pz, &qx, &qy, &qz, run.pinned ? _mm256_loadu_pd(w + p) : one,
                         run.pinned ? _mm256_loadu_pd(w + q) : one, max2, loose2));
        _mm256_storeu_pd(x + p, px);
        _mm256_storeu_pd(y + p, py);
        _mm256_storeu_pd(z + p, pz);
        _mm256_storeu_pd(x + q, qx);
        _mm256_storeu_pd(y + q, qy);
        _mm256_storeu_pd(z + q, qz);
      }
      if (p < run.hi) tail = ProjectRun(a, p, run.hi, off, f.max_length_m, loose2_s) || tail;
    }
  }
  return _mm256_movemask_pd(loose) != 0 || tail;
}

// True if this CPU runs AVX2 and the tests have not asked for the portable loops.
bool ProvotUsesAvx2() { return CpuHasAvx2() && !g_provot_portable.load(std::memory_order_relaxed); }
#endif

// One Gauss-Seidel sweep over a family: AVX2 where the CPU has it, else the portable loop.
bool SweepFamily(const ProvotSoa& a, int32_t width, const ProvotFamily& f) {
#if defined(__x86_64__)
  if (ProvotUsesAvx2()) return SweepFamilyAvx2(a, width, f);
#endif
  return SweepFamilyPortable(a, width, f);
}

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

void UsePortableProvotKernels(bool portable) {
  g_provot_portable.store(portable, std::memory_order_relaxed);
}

void ApplyProvot(const ClothModel& model, double h_s, ClothState* state) {
  const size_t n = static_cast<size_t>(model.num_particles());
  const size_t stride = SoaStride(n);
  double* soa = state->scratch->provot_soa.data();
  const ProvotSoa a{soa, soa + stride, soa + 2 * stride, model.provot_movable.data()};
  double* __restrict bx = soa + 3 * stride;
  double* __restrict by = soa + 4 * stride;
  double* __restrict bz = soa + 5 * stride;
  // Into structure-of-arrays, and a copy of where the particles started.
  const double* __restrict x = state->x.data()->data();
  for (size_t p = 0; p < n; ++p) {
    a.x[p] = bx[p] = x[3 * p];
    a.y[p] = by[p] = x[3 * p + 1];
    a.z[p] = bz[p] = x[3 * p + 2];
  }
  // Long range attachments first: each free particle back into the ball around its pin (Kim,
  // Chentanez & Mueller 2012); the pin is kinematic, so only the particle moves.
  for (const PinAttachment& at : model.attachments) {
    const size_t p = static_cast<size_t>(at.particle), q = static_cast<size_t>(at.pin);
    const double dx = a.x[p] - a.x[q], dy = a.y[p] - a.y[q], dz = a.z[p] - a.z[q];
    const double len2 = dx * dx + dy * dy + dz * dz;
    if (len2 <= at.max_length_m * at.max_length_m) continue;
    const double len = std::sqrt(len2);
    const double scale = (len - at.max_length_m) / len;
    a.x[p] -= scale * dx;
    a.y[p] -= scale * dy;
    a.z[p] -= scale * dz;
  }
  // Sweeps over every family, coarse to fine; converged once no pair of a sweep was more than
  // kProvotConverged over its limit.
  for (int32_t sweep = 0; sweep < model.spec.provot.iterations; ++sweep) {
    bool loose = false;
    for (const ProvotFamily& family : model.provot_families) {
      loose = SweepFamily(a, model.width, family) || loose;
    }
    if (!loose) break;
  }
  // Back to the state; velocities follow the positions, v += dx / h, so (x, v) stay consistent.
  const double inv_h = 1.0 / h_s;
  double* __restrict xo = state->x.data()->data();
  double* __restrict vo = state->v.data()->data();
  for (size_t p = 0; p < n; ++p) {
    xo[3 * p] = a.x[p];
    xo[3 * p + 1] = a.y[p];
    xo[3 * p + 2] = a.z[p];
    vo[3 * p] += inv_h * (a.x[p] - bx[p]);
    vo[3 * p + 1] += inv_h * (a.y[p] - by[p]);
    vo[3 * p + 2] += inv_h * (a.z[p] - bz[p]);
  }
}

void ApplyObstacles(const ClothModel& model, double h_s, ClothState* state) {
  const auto& obstacles = model.spec.cloth.obstacles;
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
  const auto& pins = model.spec.cloth.pins;
  for (size_t k = 0; k < model.pinned.size(); ++k) {
    const int32_t p = model.pinned[k];
    if (model.pin_scripted[k]) {
      const PinMotionSpec& motion = pins[model.pin_spec[k]].motion;
      state->x[p] = model.rest_position_m[p] + PinOffset(motion, t_s);
      state->v[p] = PinVelocity(motion, t_s);
    } else {
      state->x[p] = model.rest_position_m[p];
      state->v[p].setZero();
    }
  }
}

}  // namespace felt
