#include "sim_loop/cloth_patch.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <stdexcept>
#include <string>

#include "base/simd.h"
#include "sim_loop/cloth_coupling.h"
#include "sim_loop/cloth_internal.h"

namespace felt {
namespace {

// True if windows a and b overlap or come within two particles of each other (a bend spring joins
// particles two apart), so their particles interact.
bool WindowsMeet(const PatchWindow& a, const PatchWindow& b) {
  return a.col0 <= b.col1 + 2 && b.col0 <= a.col1 + 2 && a.row0 <= b.row1 + 2 &&
         b.row0 <= a.row1 + 2;
}

// The bounding rectangle of a and b.
PatchWindow Bounding(const PatchWindow& a, const PatchWindow& b) {
  return {std::min(a.col0, b.col0), std::min(a.row0, b.row0), std::max(a.col1, b.col1),
          std::max(a.row1, b.row1)};
}

bool SameWindow(const PatchWindow& a, const PatchWindow& b) {
  return a.col0 == b.col0 && a.row0 == b.row0 && a.col1 == b.col1 && a.row1 == b.row1;
}

// The dense arrays (ClothPatch::dense_, double), stride_ entries each.
enum DenseArray : int32_t {
  kX = 0,         // positions x, y, z, m (3 arrays)
  kV = 3,         // velocities, m/s (3)
  kALast = 6,     // the last substep's accelerations, m/s^2 (3)
  kDriveX = 9,    // the drive's positions, m (3)
  kDriveV = 12,   // the drive's velocities, m/s (3)
  kInvMass = 15,  // 1 / mass, 1/kg
  kFree = 16,     // 1 free, 0 driven
  kRestart = 17,  // 1: leapfrog restarts from v
  kDenseArrays = 18,
};
// The single-precision arrays (ClothPatch::single_), stride_ entries each.
enum SingleArray : int32_t {
  kP = 0,         // positions, m from the window's first particle (3)
  kU = 3,         // velocities, m/s (3)
  kF = 6,         // forces, N (3)
  kT = 9,         // one family's pair forces (3)
  kMovable = 12,  // 1 free, 0 driven
  kMask = 13,     // 5 arrays, dc = -2..2: 1 where column c + dc lies in the window
  kSingleArrays = 18,
};

// One window's single-precision arrays at its first local index (the kernels' view).
struct WindowSoa {
  float* p[3];
  const float* u[3];
  float* f[3];
  float* t[3];
  const float* movable;
  const float* mask[5];  // by dc + 2
  int32_t count = 0;     // entries (rows x pitch, padding included)
  int32_t pitch = 0;     // entries per row: its particles, and one of padding if they are odd
};

// A spring family's pairs in a window: end i at local l in [l0, l1), end j at l + off.
struct SpringPass {
  int32_t l0, l1, off, dc;
  float stiffness, damping, rest;
};

// Per pair c < count of one spring family (i ends at xi.., j ends at xj.., single precision): the
// force on the i end into t (f_j = -f_i), Hooke plus the dashpot along the unit direction u from
// i to j, f_i = (k (l - L) + c (v_j - v_i) . u) u (001 §2, as AddSpringForces), times the pair's
// mask m (0 for a pair that would wrap from a row's end to the next row). A spring shorter than
// 1e-10 m exerts nothing. Branch-free, so the compiler vectorises it (GCC honours __restrict on
// parameters, which inlining keeps).
[[gnu::always_inline]] inline void SpringRun(
    int32_t count, const float* __restrict xi, const float* __restrict yi,
    const float* __restrict zi, const float* __restrict xj, const float* __restrict yj,
    const float* __restrict zj, const float* __restrict vxi, const float* __restrict vyi,
    const float* __restrict vzi, const float* __restrict vxj, const float* __restrict vyj,
    const float* __restrict vzj, const float* __restrict m, float stiffness, float damping,
    float rest, float* __restrict tx, float* __restrict ty, float* __restrict tz) {
  for (int32_t c = 0; c < count; ++c) {
    const float dx = xj[c] - xi[c], dy = yj[c] - yi[c], dz = zj[c] - zi[c];
    const float len2 = dx * dx + dy * dy + dz * dz;
    const float len = std::sqrt(len2);
    const float live = len2 > 1e-20f ? 1.0f : 0.0f;
    const float inv = live * m[c] / std::max(len, 1e-10f);
    const float rel =
        ((vxj[c] - vxi[c]) * dx + (vyj[c] - vyi[c]) * dy + (vzj[c] - vzi[c]) * dz) * inv;
    const float scale = (stiffness * (len - rest) + damping * rel) * inv;
    tx[c] = scale * dx;
    ty[c] = scale * dy;
    tz[c] = scale * dz;
  }
}

// a[c] += sign * t[c] for c < count, per coordinate (a run of pair forces onto their ends).
[[gnu::always_inline]] inline void AddRun(int32_t count, float sign, const float* __restrict tx,
                                          const float* __restrict ty, const float* __restrict tz,
                                          float* __restrict ax, float* __restrict ay,
                                          float* __restrict az) {
  for (int32_t c = 0; c < count; ++c) {
    ax[c] += sign * tx[c];
    ay[c] += sign * ty[c];
    az[c] += sign * tz[c];
  }
}

// Every spring family's forces on one window into w.f (cleared first): each family's pair forces
// (SpringRun) into w.t over the window's rows as one flat run, then added to the i ends and
// subtracted from the j ends.
[[gnu::always_inline]] inline void SpringForcesBody(const WindowSoa& w, const SpringPass* passes,
                                                    int32_t num_passes) {
  std::fill(w.f[0], w.f[0] + w.count, 0.0f);
  std::fill(w.f[1], w.f[1] + w.count, 0.0f);
  std::fill(w.f[2], w.f[2] + w.count, 0.0f);
  for (int32_t k = 0; k < num_passes; ++k) {
    const SpringPass s = passes[k];
    const int32_t i = s.l0, j = s.l0 + s.off, count = s.l1 - s.l0;
    SpringRun(count, w.p[0] + i, w.p[1] + i, w.p[2] + i, w.p[0] + j, w.p[1] + j, w.p[2] + j,
              w.u[0] + i, w.u[1] + i, w.u[2] + i, w.u[0] + j, w.u[1] + j, w.u[2] + j,
              w.mask[s.dc + 2] + i, s.stiffness, s.damping, s.rest, w.t[0], w.t[1], w.t[2]);
    AddRun(count, 1.0f, w.t[0], w.t[1], w.t[2], w.f[0] + i, w.f[1] + i, w.f[2] + i);
    AddRun(count, -1.0f, w.t[0], w.t[1], w.t[2], w.f[0] + j, w.f[1] + j, w.f[2] + j);
  }
}

// A Provot family's pairs in a window: i ends in local rows [row0, row1] and columns [col0, col1],
// j ends dr rows and dc columns on.
struct ProvotPass {
  int32_t row0, row1, col0, col1, dc, dr;
  float max_len, inv_max2;
};

// The length the patch's sweeps hold a Provot family's pairs to, m: the patch's sweep length
// (ProvotFamily::patch_sweep_length_m, (1 - provot.patch_sweep_headroom) times the limit; unset,
// the sim's sweep length, (1 - provot.sweep_headroom) times it), not the limit itself. The sim's
// sweeps aim there and its finishing worklist only takes what they leave over the limit, so the
// 60 Hz cloth that drives a window's rings sits at the sweep length wherever it is taut; free
// particles held to the limit instead could stretch 1 % further than the rings around them, a
// softer cloth than the one the truth steps. Measured (felt compare, 64 x 64 curtain, truth=on
// against snapshot=patch at 60 Hz, hard traces seeds 1-5): pin_drag 0.384 -> 0.134 N RMS worst,
// handwriting 0.239 -> 0.107 N; the same sweeps aimed at 0.995 or 0.985 of the limit, or six sweeps
// instead of three, were worse (docs/proxy.md).
double PatchSweepLength(const ProvotFamily& family) { return family.patch_sweep_length_m; }

// Pairs longer than their limit left more than 1e-3 over it by a sweep count as loose.
constexpr float kLoose = (1.0f + 1e-3f) * (1.0f + 1e-3f);

// One pair of ProvotRun, ends i and j (positions updated in place), movabilities mi,
// mj (1 free, 0 driven, times the pair's mask): shortened to max_len if longer, each end moving by
// its share m / (m_i + m_j) of the cut. Returns 1 if the pair has a free end and was more than
// 1e-3 over its limit (kLoose), else 0. Branch-free.
[[gnu::always_inline]] inline int32_t ProjectLane(float& xi, float& yi, float& zi, float& xj,
                                                  float& yj, float& zj, float mi, float mj,
                                                  float max_len, float inv_max2) {
  const float dx = xj - xi, dy = yj - yi, dz = zj - zi;
  const float len2 = dx * dx + dy * dy + dz * dz;
  const float both = mi + mj;
  const float ratio = len2 * inv_max2;
  const bool moves = both > 0.0f;
  const float over = static_cast<float>((ratio > 1.0f) & moves);
  const float len = std::sqrt(len2);
  const float cut = over * (len - max_len) / (std::max(len, 1e-10f) * std::max(both, 1.0f));
  const float si = cut * mi, sj = cut * mj;
  xi += si * dx;
  yi += si * dy;
  zi += si * dz;
  xj -= sj * dx;
  yj -= sj * dy;
  zj -= sj * dz;
  return static_cast<int32_t>((ratio > kLoose) & moves);
}

// The lanes of a block (ProvotRun with kLanes = kBlock).
constexpr int32_t kBlock = 16;

// Provot 1995 (000 slide 9) over independent pairs, end i of pair c at index c * kStride of xi..,
// end j at c * kStride of xj..: a pair longer than max_len is shortened to it, each end moving by
// its share of the cut (movabilities m_i, m_j: 1 free, 0 driven, times the pair's mask; shares
// m_i / (m_i + m_j)); ProjectLane. With kLanes = 0 the pairs are c < count. With kLanes > 0 they
// are one block of kLanes of which the first `count` are real: a loop of constant length, which
// the compiler turns into whole vectors with no scalar remainder (one AVX-512 vector, two AVX2
// ones for kBlock); the lanes past `count` get movability 0 and write back what they read, so the
// arrays must be readable kLanes entries on (ClothPatch pads them) and the i and j blocks must
// not overlap (a row offset of at least kLanes). Returns the pairs with a free end left more than
// 1e-3 over (kLoose). Branch-free.
template <int32_t kStride, int32_t kLanes = 0>
[[gnu::always_inline]] inline int32_t ProvotRun(
    int32_t count, float* __restrict xi, float* __restrict yi, float* __restrict zi,
    float* __restrict xj, float* __restrict yj, float* __restrict zj,
    const float* __restrict movable_i, const float* __restrict movable_j,
    const float* __restrict mask, float max_len, float inv_max2) {
  int32_t loose = 0;
  const int32_t pairs = kLanes > 0 ? kLanes : count;
  for (int32_t c = 0; c < pairs; ++c) {
    const int32_t k = c * kStride;
    const float lane = kLanes > 0 ? mask[k] * static_cast<float>(c < count) : mask[k];
    loose += ProjectLane(xi[k], yi[k], zi[k], xj[k], yj[k], zj[k], lane * movable_i[k],
                         lane * movable_j[k], max_len, inv_max2);
  }
  return loose;
}

// One row r of an across-row pass: in blocks of kBlock, or in a narrow window one loop.
// Returns the pairs left loose.
[[gnu::always_inline]] inline int32_t ProvotRow(const WindowSoa& w, const ProvotPass& s,
                                                int32_t r) {
  float* const px = w.p[0];
  float* const py = w.p[1];
  float* const pz = w.p[2];
  const float* const mv = w.movable;
  const float* const mask = w.mask[s.dc + 2];
  const int32_t off = s.dr * w.pitch + s.dc, count = s.col1 - s.col0 + 1;
  const int32_t first = r * w.pitch + s.col0;
  if (off < kBlock) {
    const int32_t i = first, j = first + off;
    return ProvotRun<1>(count, px + i, py + i, pz + i, px + j, py + j, pz + j, mv + i, mv + j,
                        mask + i, s.max_len, s.inv_max2);
  }
  int32_t loose = 0;
  for (int32_t c = 0; c < count; c += kBlock) {
    const int32_t i = first + c, j = i + off;
    loose += ProvotRun<1, kBlock>(count - c, px + i, py + i, pz + i, px + j, py + j, pz + j, mv + i,
                                  mv + j, mask + i, s.max_len, s.inv_max2);
  }
  return loose;
}

// One Gauss-Seidel sweep of Provot's limits over a window's families; returns the pairs left
// loose (ProvotRun). A family across rows (dr > 0) is swept row by row, in order (a correction
// travels down the window within one sweep, as the sim's sweeps): the pairs of one row share no
// particle, in blocks of kBlock (ProvotRow) where the window is wide enough, else one loop. The
// structural family along a row (dr = 0, dc = 1) is swept in two colours over the window's rows
// as one flat run, the pairs (l, l + 1) with l - l0 even, then odd: each colour's pairs share no
// particle, and a pair that would wrap past a row's end has mask 0. Every loop is a loop over
// independent pairs, which the compiler vectorises; any other family is swept pair by pair.
[[gnu::always_inline]] inline int32_t ProvotBody(const WindowSoa& w, const ProvotPass* passes,
                                                 int32_t num_passes) {
  float* const px = w.p[0];
  float* const py = w.p[1];
  float* const pz = w.p[2];
  const float* const mv = w.movable;
  int32_t loose = 0;
  for (int32_t k = 0; k < num_passes;) {
    const ProvotPass s = passes[k];
    const float* const mask = w.mask[s.dc + 2];
    if (s.dr == 0 && s.dc == 1) {
      // An even pitch keeps each colour to one column parity on every row.
      const int32_t l0 = s.row0 * w.pitch + s.col0, l1 = s.row1 * w.pitch + s.col1 + 1;
      for (int32_t colour = 0; colour < 2; ++colour) {
        const int32_t i = l0 + colour, pairs = (l1 - i + 1) / 2;
        loose += ProvotRun<2>(pairs, px + i, py + i, pz + i, px + i + 1, py + i + 1, pz + i + 1,
                              mv + i, mv + i + 1, mask + i, s.max_len, s.inv_max2);
      }
      ++k;
      continue;
    }
    if (s.dr == 0) {  // another family along a row (not a level-1 family): pair by pair
      for (int32_t r = s.row0; r <= s.row1; ++r) {
        for (int32_t i = r * w.pitch + s.col0; i <= r * w.pitch + s.col1; ++i) {
          const int32_t j = i + s.dc;
          loose += ProvotRun<1>(1, px + i, py + i, pz + i, px + j, py + j, pz + j, mv + i, mv + j,
                                mask + i, s.max_len, s.inv_max2);
        }
      }
      ++k;
      continue;
    }
    // Consecutive passes across one row (dr = 1) over the same rows, pipelined: at step t, pass
    // g of the group sweeps row t - 2 g. Pass g's row q needs pass g - 1's rows q - 1 .. q + 1
    // (done at earlier steps) and touches rows q, q + 1, which no later row of an earlier pass
    // touches; so each pair sees exactly what it sees when the passes run one after the other,
    // and the rows of one step, two apart, are independent chains whose latencies overlap.
    int32_t group = 1;
    while (k + group < num_passes && passes[k + group].dr == 1 && s.dr == 1 &&
           passes[k + group].row0 == s.row0 && passes[k + group].row1 == s.row1) {
      ++group;
    }
    for (int32_t t = s.row0; t <= s.row1 + 2 * (group - 1); ++t) {
      for (int32_t g = 0; g < group; ++g) {
        const int32_t r = t - 2 * g;
        if (r >= s.row0 && r <= s.row1) loose += ProvotRow(w, passes[k + g], r);
      }
    }
    k += group;
  }
  return loose;
}

// One substep's integration of every window particle (IntegrateBody).
struct IntegrateArgs {
  double* x[3];
  double* v[3];
  double* a_last[3];
  const double* drive_x[3];
  const double* drive_v[3];
  const double* inv_mass;
  const float* f[3];
  const double* movable;  // 1 free, 0 driven
  double* restart;        // 1: restarts from v
  int32_t count;
  double h, h_old;     // this substep and the last one, s
  double drive_tau_s;  // the drive's time at the substep's end, s after its snapshot
  double beta;         // the driven particles' easing fraction
  double drag;         // N s / m
  double g[3];         // m/s^2
};

// One coordinate of IntegrateBody.
[[gnu::always_inline]] inline void IntegrateAxis(
    int32_t count, double* __restrict x, double* __restrict v, double* __restrict al,
    const double* __restrict dx, const double* __restrict dv, const float* __restrict f,
    const double* __restrict im, const double* __restrict mv, const double* __restrict rs, double h,
    double kick, double back, double tau, double beta, double drag, double g) {
  const double half = 0.5 * h;
  for (int32_t l = 0; l < count; ++l) {
    const double acc = im[l] * (static_cast<double>(f[l]) - drag * v[l]) + g;
    const double v_half = rs[l] > 0.0 ? v[l] + half * acc : v[l] + (kick * acc - back * al[l]);
    const double moved = x[l] + h * dv[l];
    const double target = dx[l] + tau * dv[l];
    const bool free = mv[l] > 0.0;
    x[l] = free ? x[l] + h * v_half : moved + beta * (target - moved);
    v[l] = free ? v_half + half * acc : dv[l];
    al[l] = free ? acc : al[l];
  }
}

// Free particles: leapfrog Verlet, kick-drift-kick with variable steps, as sim_loop's
// LeapfrogVerlet (001 §3.5): a = (f - drag v) / m + g, v_{n+1/2} = v_{n-1/2} + (h_old + h)/2 a_n,
// x_{n+1} = x_n + h v_{n+1/2}, the state keeping v_{n+1} = v_{n+1/2} + h/2 a_n; a particle
// restarts from v (v + h/2 a). Driven particles move with the drive's velocity and close the
// fraction beta of their distance to the drive at drive_tau_s (ClothPatch::Step). Branch-free.
[[gnu::always_inline]] inline void IntegrateBody(const IntegrateArgs& a) {
  const double kick = 0.5 * (a.h_old + a.h), back = 0.5 * a.h_old;
  for (int32_t axis = 0; axis < 3; ++axis) {
    IntegrateAxis(a.count, a.x[axis], a.v[axis], a.a_last[axis], a.drive_x[axis], a.drive_v[axis],
                  a.f[axis], a.inv_mass, a.movable, a.restart, a.h, kick, back, a.drive_tau_s,
                  a.beta, a.drag, a.g[axis]);
  }
  double* const rs = a.restart;
  for (int32_t l = 0; l < a.count; ++l) rs[l] *= 1.0 - a.movable[l];
}

// How many of x[0..count) are infinite or NaN (all exponent bits set, IEEE 754 binary64), as
// integer operations, which vectorise.
[[gnu::always_inline]] inline int64_t CountNonFiniteBody(const double* __restrict x, size_t count) {
  constexpr uint64_t kExponent = 0x7ff0000000000000ULL;
  int64_t bad = 0;
  for (size_t l = 0; l < count; ++l) {
    bad += static_cast<int64_t>((std::bit_cast<uint64_t>(x[l]) & kExponent) == kExponent);
  }
  return bad;
}

// The largest squared distance [m^2] between (x, y, z)[l] and (dx, dy, dz)[l], l < count. A
// non-negative double's bits order as an integer's, so the maximum is an integer one, which
// vectorises.
[[gnu::always_inline]] inline double MaxDistance2Body(int32_t count, const double* __restrict x,
                                                      const double* __restrict y,
                                                      const double* __restrict z,
                                                      const double* __restrict dx,
                                                      const double* __restrict dy,
                                                      const double* __restrict dz) {
  int64_t most = 0;
  for (int32_t l = 0; l < count; ++l) {
    const double ex = x[l] - dx[l], ey = y[l] - dy[l], ez = z[l] - dz[l];
    most = std::max(most, std::bit_cast<int64_t>(ex * ex + ey * ey + ez * ez));
  }
  return std::bit_cast<double>(most);
}

// The kernels at each vector level (base/simd.h): the same source compiled for the level's
// instruction set, so every level gives the same bits (no contraction: -ffp-contract=off).
struct PatchKernels {
  void (*spring_forces)(const WindowSoa&, const SpringPass*, int32_t);
  int32_t (*provot)(const WindowSoa&, const ProvotPass*, int32_t);
  void (*integrate)(const IntegrateArgs&);
  int64_t (*non_finite)(const double*, size_t);
  double (*max_distance2)(int32_t, const double*, const double*, const double*, const double*,
                          const double*, const double*);
};

#define FELT_PATCH_KERNELS(SUFFIX, ATTRIBUTE)                                                \
  ATTRIBUTE void SpringForces##SUFFIX(const WindowSoa& w, const SpringPass* p, int32_t n) {  \
    SpringForcesBody(w, p, n);                                                               \
  }                                                                                          \
  ATTRIBUTE int32_t Provot##SUFFIX(const WindowSoa& w, const ProvotPass* p, int32_t n) {     \
    return ProvotBody(w, p, n);                                                              \
  }                                                                                          \
  ATTRIBUTE void Integrate##SUFFIX(const IntegrateArgs& a) { IntegrateBody(a); }             \
  ATTRIBUTE int64_t NonFinite##SUFFIX(const double* x, size_t n) {                           \
    return CountNonFiniteBody(x, n);                                                         \
  }                                                                                          \
  ATTRIBUTE double MaxDistance2##SUFFIX(int32_t n, const double* x, const double* y,         \
                                        const double* z, const double* dx, const double* dy, \
                                        const double* dz) {                                  \
    return MaxDistance2Body(n, x, y, z, dx, dy, dz);                                         \
  }

FELT_PATCH_KERNELS(Portable, )
constexpr PatchKernels kPortablePatchKernels{SpringForcesPortable, ProvotPortable,
                                             IntegratePortable, NonFinitePortable,
                                             MaxDistance2Portable};
#if defined(__x86_64__)
FELT_PATCH_KERNELS(Avx2, __attribute__((target("avx2"))))
FELT_PATCH_KERNELS(Avx512, __attribute__((target("avx512f,prefer-vector-width=512"))))
constexpr SimdTable<PatchKernels> kPatchKernels{
    kPortablePatchKernels,
    PatchKernels{SpringForcesAvx2, ProvotAvx2, IntegrateAvx2, NonFiniteAvx2, MaxDistance2Avx2},
    PatchKernels{SpringForcesAvx512, ProvotAvx512, IntegrateAvx512, NonFiniteAvx512,
                 MaxDistance2Avx512}};
#else
constexpr SimdTable<PatchKernels> kPatchKernels{kPortablePatchKernels, kPortablePatchKernels,
                                                kPortablePatchKernels};
#endif
#undef FELT_PATCH_KERNELS

// The pairs (c, r)-(c + dc, r + dr) whose i ends lie in local rows [ra, rb] of a window of
// rows with `pitch` entries per row, every column (the pairs that would wrap past a row's end have
// mask 0), as one flat run: i ends at local [l0, l1), j ends at l + off, clipped to the window.
struct PairRun {
  int32_t l0, l1, off;
};
PairRun RowRun(int32_t rows, int32_t pitch, int32_t dc, int32_t dr, int32_t ra, int32_t rb) {
  PairRun run;
  run.off = dr * pitch + dc;
  run.l0 = std::max(ra * pitch, -run.off);
  run.l1 = std::min((rb + 1) * pitch, rows * pitch - run.off);
  return run;
}

// out[3 c + 0, 1, 2] = x[c], y[c], z[c] for c < count (a row of the dense arrays into the
// per-particle ones).
void Interleave(int32_t count, const double* __restrict x, const double* __restrict y,
                const double* __restrict z, double* __restrict out) {
  for (int32_t c = 0; c < count; ++c) {
    out[3 * c] = x[c];
    out[3 * c + 1] = y[c];
    out[3 * c + 2] = z[c];
  }
}

// Entries per row of a window's dense arrays: its columns, made even (ProvotBody's colours).
int32_t PitchOf(const PatchWindow& win) {
  const int32_t cols = win.col1 - win.col0 + 1;
  return cols + (cols & 1);
}

// Window k's single-precision arrays (WindowSoa) from the patch's block.
WindowSoa WindowArrays(float* single, size_t stride, int32_t base, const PatchWindow& win) {
  WindowSoa w;
  const auto at = [&](int32_t array) { return single + array * stride + base; };
  for (int32_t a = 0; a < 3; ++a) {
    w.p[a] = at(kP + a);
    w.u[a] = at(kU + a);
    w.f[a] = at(kF + a);
    w.t[a] = at(kT + a);
  }
  w.movable = at(kMovable);
  for (int32_t m = 0; m < 5; ++m) w.mask[m] = at(kMask + m);
  w.pitch = PitchOf(win);
  w.count = (win.row1 - win.row0 + 1) * w.pitch;
  return w;
}

}  // namespace

// A long range attachment inside a window (ClothPatch::BuildAttachments): the free particle at
// local index `local` stays within max_m of the pin at local index `pin`.
struct PatchAttachment {
  int32_t local = 0;
  int32_t pin = 0;
  float max_m = 0.0f;  // (1 + max_elongation) * rest distance, m (single precision, as the sim's)
};

// One window's spring and constraint passes, built by Layout from the window's shape (PairRange)
// and used by every substep until the windows change.
struct WindowPasses {
  std::array<SpringPass, 16> springs;
  int32_t num_springs = 0;
  std::array<ProvotPass, 16> provot;
  int32_t num_provot = 0;
};

ClothPatch::ClothPatch(const ClothModel& model, int32_t radius, int32_t max_windows, int32_t follow)
    : model_(model),
      radius_(radius),
      recentre_(follow),
      springs_(std::make_unique<CouplingSprings>()),
      spheres_(kMaxCouplingSprings),
      guard_cells_(kMaxCouplingSprings),
      guard_count_(kMaxCouplingSprings, 0) {
  if (radius < kMinPatchRadius || radius > kMaxPatchRadius) {
    throw std::invalid_argument(
        "proxy.patch_radius: must be in [" + std::to_string(kMinPatchRadius) + ", " +
        std::to_string(kMaxPatchRadius) + "], got " + std::to_string(radius));
  }
  if (follow < 1 || follow > radius) {
    throw std::invalid_argument("proxy.patch_follow: must be in [1, " + std::to_string(radius) +
                                "], got " + std::to_string(follow));
  }
  if (max_windows < 1) {
    throw std::invalid_argument("ClothPatch: max_windows must be >= 1, got " +
                                std::to_string(max_windows));
  }
  // Leapfrog at the cloth's nominal substep (chosen stable for the cloth's integrator); for another
  // integrator, within half of leapfrog's own stable step (the auto substeps' default safety).
  const double h_nominal = 1.0 / (model.frame_rate_hz * model.substeps);
  h_max_s_ = h_nominal;
  if (model.integrator != IntegratorKind::kLeapfrogVerlet) {
    h_max_s_ = std::min(h_nominal, 0.5 * StableStep(model, IntegratorKind::kLeapfrogVerlet));
  }
  const size_t n = static_cast<size_t>(model.num_particles());
  windows_.resize(static_cast<size_t>(max_windows));
  next_windows_.resize(static_cast<size_t>(max_windows));
  anchors_.assign(static_cast<size_t>(max_windows), -1);
  linger_s_.assign(static_cast<size_t>(max_windows), 0.0);
  role_.assign(n, PatchRole::kOutside);
  next_role_.assign(n, PatchRole::kOutside);
  for (std::vector<Vec3>* a : {&x_, &v_, &x_before_, &a_last_}) a->assign(n, Vec3::Zero());
  restart_.assign(n, 1);
  // The triangles around each particle (for NormalAt), compressed rows.
  vertex_tri_start_.assign(n + 1, 0);
  for (const Triangle& t : model.triangles) {
    for (int32_t corner : t) ++vertex_tri_start_[static_cast<size_t>(corner) + 1];
  }
  for (size_t p = 0; p < n; ++p) vertex_tri_start_[p + 1] += vertex_tri_start_[p];
  vertex_tris_.resize(static_cast<size_t>(vertex_tri_start_[n]));
  std::vector<int32_t> fill(vertex_tri_start_.begin(), vertex_tri_start_.end() - 1);
  for (size_t t = 0; t < model.triangles.size(); ++t) {
    for (int32_t corner : model.triangles[t]) {
      vertex_tris_[static_cast<size_t>(fill[static_cast<size_t>(corner)]++)] =
          static_cast<int32_t>(t);
    }
  }
  // The dense arrays hold the largest layout, the whole cloth (merged windows may grow to it) with
  // a padding entry on each row of each window, and room for a block's overrun (ProvotRun).
  const size_t most = n + static_cast<size_t>(max_windows) * static_cast<size_t>(model.height);
  stride_ = (most + 15) / 16 * 16 + 2 * 16;
  base_.assign(static_cast<size_t>(max_windows) + 1, 0);
  passes_.resize(static_cast<size_t>(max_windows));
  global_.assign(stride_, -1);
  local_.assign(n, -1);
  dense_.assign(kDenseArrays * stride_, 0.0);
  single_.assign(kSingleArrays * stride_, 0.0f);
  f_.assign(3 * n, 0.0);
  for (size_t i = 0; i < model.provot_families.size(); ++i) {
    if (model.provot_families[i].level == 1) level1_.push_back(static_cast<int32_t>(i));
  }
  attach_.resize(model.attachments.size());
  attach_base_.assign(static_cast<size_t>(max_windows) + 1, 0);
}

ClothPatch::~ClothPatch() = default;

template <typename Visit>
void ClothPatch::ForEachParticle(Visit&& visit) const {
  const int32_t w = model_.width;
  for (size_t k = 0; k < window_count_; ++k) {
    const PatchWindow& win = windows_[k];
    for (int32_t r = win.row0; r <= win.row1; ++r) {
      for (int32_t c = win.col0; c <= win.col1; ++c) visit(r * w + c);
    }
  }
}

void ClothPatch::MarkRoles(std::span<const PatchWindow> windows, PatchRole* roles) const {
  const int32_t w = model_.width, h = model_.height;
  for (const PatchWindow& win : windows) {
    for (int32_t r = win.row0; r <= win.row1; ++r) {
      for (int32_t c = win.col0; c <= win.col1; ++c) {
        const int32_t p = r * w + c;
        // The outer two rings are driven, except where the window ends on the cloth's own edge.
        const bool ring =
            (c - win.col0 < 2 && win.col0 > 0) || (win.col1 - c < 2 && win.col1 < w - 1) ||
            (r - win.row0 < 2 && win.row0 > 0) || (win.row1 - r < 2 && win.row1 < h - 1);
        roles[p] = ring || model_.inv_mass_per_kg[p] == 0.0 ? PatchRole::kDriven : PatchRole::kFree;
      }
    }
  }
}

double ClothPatch::DriftFromDrive(const PatchWindow& window, const ClothSnapshot& drive,
                                  double tau_s) const {
  double max2 = 0.0;
  const int32_t w = model_.width;
  for (int32_t r = window.row0; r <= window.row1; ++r) {
    for (int32_t c = window.col0; c <= window.col1; ++c) {
      const int32_t p = r * w + c;
      if (role_[p] != PatchRole::kFree) continue;
      max2 = std::max(max2, (x_[p] - drive.x[p] - tau_s * drive.v[p]).squaredNorm());
    }
  }
  return std::sqrt(max2);
}

void ClothPatch::Flush() {
  // The dense state back into the per-particle arrays (x_ and v_ are written by every step).
  for (int32_t l = 0; l < locals_; ++l) {
    const int32_t p = global_[l];
    if (p < 0) continue;
    for (int32_t a = 0; a < 3; ++a) a_last_[p][a] = D(kALast + a)[l];
    restart_[p] = D(kRestart)[l] > 0.0 ? 1 : 0;
  }
}

void ClothPatch::BuildPasses(const PatchWindow& win, WindowPasses* out) const {
  // Each spring family over the window's rows where a pair has a free end (PairRange) as one flat
  // run (RowRun); each level-1 Provot family over its pairs with a free end. Families joining
  // particles more than two columns apart have no mask and are not built (none are).
  const int32_t rows = win.row1 - win.row0 + 1, pitch = PitchOf(win);
  out->num_springs = 0;
  for (const SpringFamily& fam : model_.spring_families) {
    const PatchWindow range = PairRange(win, fam.dc, fam.dr);
    if (range.empty() || std::abs(fam.dc) > 2 ||
        out->num_springs == static_cast<int32_t>(out->springs.size())) {
      continue;
    }
    const PairRun run =
        RowRun(rows, pitch, fam.dc, fam.dr, range.row0 - win.row0, range.row1 - win.row0);
    if (run.l1 <= run.l0) continue;
    out->springs[static_cast<size_t>(out->num_springs++)] =
        SpringPass{run.l0,
                   run.l1,
                   run.off,
                   fam.dc,
                   static_cast<float>(fam.stiffness_N_per_m),
                   static_cast<float>(fam.damping_N_s_per_m),
                   static_cast<float>(fam.rest_length_m)};
  }
  out->num_provot = 0;
  for (int32_t index : level1_) {
    const ProvotFamily& fam = model_.provot_families[static_cast<size_t>(index)];
    const PatchWindow range = PairRange(win, fam.dc, fam.dr);
    if (range.empty() || std::abs(fam.dc) > 2 ||
        out->num_provot == static_cast<int32_t>(out->provot.size())) {
      continue;
    }
    const auto max_len = static_cast<float>(PatchSweepLength(fam));
    out->provot[static_cast<size_t>(out->num_provot++)] = ProvotPass{range.row0 - win.row0,
                                                                     range.row1 - win.row0,
                                                                     range.col0 - win.col0,
                                                                     range.col1 - win.col0,
                                                                     fam.dc,
                                                                     fam.dr,
                                                                     max_len,
                                                                     1.0f / (max_len * max_len)};
  }
}

void ClothPatch::Layout() {
  // The windows' particles into the dense arrays, window by window, row by row, each row padded
  // to an even pitch (PitchOf) by an entry that is no particle (global_ -1, all zero, mask 0).
  for (int32_t l = 0; l < locals_; ++l) {
    if (global_[l] >= 0) local_[global_[l]] = -1;
  }
  const int32_t w = model_.width;
  int32_t next = 0;
  for (size_t k = 0; k < window_count_; ++k) {
    const PatchWindow& win = windows_[k];
    base_[k] = next;
    const int32_t cols = win.col1 - win.col0 + 1, pitch = PitchOf(win);
    for (int32_t r = win.row0; r <= win.row1; ++r) {
      for (int32_t col = 0; col < pitch; ++col) {
        const int32_t l = next + (r - win.row0) * pitch + col;
        const bool real = col < cols;
        const int32_t p = real ? r * w + win.col0 + col : -1;
        global_[l] = p;
        const bool free = real && role_[p] == PatchRole::kFree;
        for (int32_t a = 0; a < 3; ++a) {
          D(kX + a)[l] = real ? x_[p][a] : 0.0;
          D(kV + a)[l] = real ? v_[p][a] : 0.0;
          D(kALast + a)[l] = real ? a_last_[p][a] : 0.0;
          D(kDriveX + a)[l] = 0.0;
          D(kDriveV + a)[l] = 0.0;
        }
        D(kInvMass)[l] = real ? model_.inv_mass_per_kg[p] : 0.0;
        F(kMovable)[l] = free ? 1.0f : 0.0f;
        D(kFree)[l] = free ? 1.0 : 0.0;
        D(kRestart)[l] = !real || restart_[p] ? 1.0 : 0.0;
        for (int32_t dc = -2; dc <= 2; ++dc) {
          F(kMask + dc + 2)[l] = real && col + dc >= 0 && col + dc < cols ? 1.0f : 0.0f;
        }
        if (real) local_[p] = l;
      }
    }
    next += (win.row1 - win.row0 + 1) * pitch;
    BuildPasses(win, &passes_[k]);
  }
  base_[window_count_] = next;
  locals_ = next;
  drive_loaded_ = false;
  BuildAttachments();
}

void ClothPatch::BuildAttachments() {
  // The model's attachments (its dense ranks, ClothModel::attachment_pin, in rank order) of each
  // window's free particles whose pin lies in the same window. A pin outside it reaches the window
  // through the driven rings, which follow the 60 Hz cloth that holds its attachments; a pin inside
  // has only the window's few sweeps to hold the particles near it (the slow propagation the
  // attachments exist for: Kim, Chentanez & Mueller 2012).
  const size_t n = static_cast<size_t>(model_.num_particles());
  int32_t next = 0;
  for (size_t k = 0; k < window_count_; ++k) {
    attach_base_[k] = next;
    const int32_t first = base_[k], last = base_[k + 1];
    for (int32_t l = first; l < last; ++l) {
      const int32_t p = global_[l];
      if (p < 0 || !(D(kFree)[l] > 0.0)) continue;
      for (int32_t r = 0; r < model_.attachment_ranks; ++r) {
        const size_t slot = static_cast<size_t>(r) * n + static_cast<size_t>(p);
        const int32_t q = local_[model_.attachment_pin[slot]];
        if (q < first || q >= last) continue;  // outside this window
        attach_[static_cast<size_t>(next++)] = {l, q, model_.attachment_max_m[slot]};
      }
    }
  }
  attach_base_[window_count_] = next;
}

void ClothPatch::LoadDrive(const ClothSnapshot& drive) {
  // The drive's state by local index, once per snapshot and layout.
  if (drive_loaded_ && drive_ == &drive && drive_frame_ == drive.frame) return;
  for (int32_t l = 0; l < locals_; ++l) {
    const int32_t p = global_[l];
    if (p < 0) continue;
    for (int32_t a = 0; a < 3; ++a) {
      D(kDriveX + a)[l] = drive.x[p][a];
      D(kDriveV + a)[l] = drive.v[p][a];
    }
  }
  drive_ = &drive;
  drive_frame_ = drive.frame;
  drive_loaded_ = true;
}

void ClothPatch::StorePositions(Vec3* x) const {
  for (int32_t l = 0; l < locals_; ++l) {
    if (global_[l] >= 0) x[global_[l]] = Vec3(D(kX)[l], D(kX + 1)[l], D(kX + 2)[l]);
  }
}

void ClothPatch::Place(std::span<const int32_t> centres, const ClothSnapshot& drive, double tau_s,
                       double dt_s) {
  tau_s = std::min(tau_s, drive_horizon_s_);
  const int32_t w = model_.width, h = model_.height, n = model_.num_particles();
  const auto window_of = [&](int32_t anchor) {
    const int32_t ac = anchor % w, ar = anchor / w;
    return PatchWindow{std::max(0, ac - radius_), std::max(0, ar - radius_),
                       std::min(w - 1, ac + radius_), std::min(h - 1, ar + radius_)};
  };
  // Each slot's anchor follows its centre with hysteresis; without a centre it lingers until its
  // patch has gone back to the drive (or for at most kPatchMaxLinger_s).
  size_t count = 0;
  for (size_t s = 0; s < anchors_.size(); ++s) {
    const int32_t c = s < centres.size() ? centres[s] : -1;
    const int32_t a = anchors_[s];
    if (c < 0 || c >= n) {
      if (a < 0) continue;
      linger_s_[s] += dt_s;
      if (linger_s_[s] > kPatchMaxLinger_s ||
          DriftFromDrive(window_of(a), drive, tau_s) <= kPatchReleaseDistance_m) {
        anchors_[s] = -1;
        continue;
      }
    } else {
      linger_s_[s] = 0.0;
      const bool keep =
          a >= 0 && std::abs(a % w - c % w) < recentre_ && std::abs(a / w - c / w) < recentre_;
      if (!keep) anchors_[s] = c;
    }
    next_windows_[count++] = window_of(anchors_[s]);
  }
  // Merge windows that meet, until none do.
  for (bool merged = true; merged;) {
    merged = false;
    for (size_t i = 0; i < count && !merged; ++i) {
      for (size_t j = i + 1; j < count && !merged; ++j) {
        if (!WindowsMeet(next_windows_[i], next_windows_[j])) continue;
        next_windows_[i] = Bounding(next_windows_[i], next_windows_[j]);
        next_windows_[j] = next_windows_[--count];
        ++counters_.merges;
        merged = true;
      }
    }
  }
  bool same = count == window_count_;
  for (size_t i = 0; same && i < count; ++i) same = SameWindow(next_windows_[i], windows_[i]);
  if (same) return;
  ++counters_.placements;
  Flush();

  // New roles; entering particles start from the drive, particles turning free restart.
  const std::span<const PatchWindow> next(next_windows_.data(), count);
  MarkRoles(next, next_role_.data());
  for (const PatchWindow& win : next) {
    for (int32_t r = win.row0; r <= win.row1; ++r) {
      for (int32_t c = win.col0; c <= win.col1; ++c) {
        const int32_t p = r * w + c;
        if (role_[p] == PatchRole::kOutside) {
          x_[p] = drive.x[p] + tau_s * drive.v[p];
          v_[p] = drive.v[p];
          x_before_[p] = x_[p];
          a_last_[p] = Vec3::Zero();
          restart_[p] = 1;
        } else if (next_role_[p] == PatchRole::kFree && role_[p] != PatchRole::kFree) {
          restart_[p] = 1;
        }
      }
    }
  }
  ForEachParticle([&](int32_t p) { role_[p] = PatchRole::kOutside; });
  for (size_t i = 0; i < count; ++i) windows_[i] = next_windows_[i];
  window_count_ = count;
  ForEachParticle([&](int32_t p) {
    role_[p] = next_role_[p];
    next_role_[p] = PatchRole::kOutside;
  });
  Layout();
}

bool ClothPatch::SpringInside(const ExternalForce& e) const {
  // The spring's candidates are the triangles of the 3 x 3 cells around its triangle's cell
  // (cloth_coupling.cc): their corners are the 4 x 4 particles from one row and column before it.
  const int32_t cells_per_row = model_.width - 1;
  if (e.triangle < 0 || e.triangle >= static_cast<int32_t>(model_.triangles.size())) return false;
  const int32_t cell = e.triangle / 2;
  const int32_t row = cell / cells_per_row, col = cell % cells_per_row;
  for (int32_t r = std::max(0, row - 1); r <= std::min(model_.height - 1, row + 2); ++r) {
    for (int32_t c = std::max(0, col - 1); c <= std::min(model_.width - 1, col + 2); ++c) {
      if (role_[r * model_.width + c] == PatchRole::kOutside) return false;
    }
  }
  return true;
}

PatchWindow ClothPatch::PairRange(const PatchWindow& win, int32_t dc, int32_t dr) const {
  // The free particles of a window lie in its interior rectangle: the window less its driven
  // rings, except along the cloth's own edge (pins inside are checked pair by pair). The pairs
  // (c, r)-(c + dc, r + dr) with an end in it and both in the window start in this range.
  const int32_t w = model_.width, h = model_.height;
  const int32_t fc0 = win.col0 > 0 ? win.col0 + 2 : win.col0;
  const int32_t fc1 = win.col1 < w - 1 ? win.col1 - 2 : win.col1;
  const int32_t fr0 = win.row0 > 0 ? win.row0 + 2 : win.row0;
  const int32_t fr1 = win.row1 < h - 1 ? win.row1 - 2 : win.row1;
  PatchWindow out;
  out.col0 = std::max({win.col0, win.col0 - dc, std::min(fc0, fc0 - dc)});
  out.col1 = std::min({win.col1, win.col1 - dc, std::max(fc1, fc1 - dc)});
  out.row0 = std::max(win.row0, fr0 - dr);
  out.row1 = std::min(win.row1 - dr, fr1);
  return out;
}

void ClothPatch::SubstepForces(std::span<const Vec3> positions) {
  // The windows' positions (m from each window's first particle) and velocities in single
  // precision, then every spring family's forces (SpringForcesBody, the window's passes from
  // BuildPasses), then the contact springs (sim_loop/cloth_coupling.h).
  const PatchKernels& kernels = PickSimd(kPatchKernels);
  for (size_t k = 0; k < window_count_; ++k) {
    const PatchWindow& win = windows_[k];
    const int32_t base = base_[k];
    WindowSoa w = WindowArrays(single_.data(), stride_, base, win);
    for (int32_t a = 0; a < 3; ++a) {
      const double* __restrict x = D(kX + a) + base;
      const double* __restrict v = D(kV + a) + base;
      float* __restrict px = w.p[a];
      float* __restrict pv = F(kU + a) + base;
      const double o = x[0];
      for (int32_t l = 0; l < w.count; ++l) {
        px[l] = static_cast<float>(x[l] - o);
        pv[l] = static_cast<float>(v[l]);
      }
    }
    const WindowPasses& passes = passes_[k];
    kernels.spring_forces(w, passes.springs.data(), passes.num_springs);
  }
  if (springs_->count == 0) return;
  // The contact springs at `positions` (the substep's start, by particle); AddCouplingForces
  // writes only their candidates' corners, which are read back and re-zeroed.
  AddCouplingForces(*springs_, positions, 1.0, f_.data());
  for (int32_t s = 0; s < springs_->count; ++s) {
    const CouplingSpring& spring = springs_->springs[static_cast<size_t>(s)];
    for (int32_t t = 0; t < spring.num_candidates; ++t) {
      for (int32_t p : spring.candidates[static_cast<size_t>(t)]) {
        const int32_t l = local_[p];
        for (int32_t a = 0; a < 3; ++a) {
          if (l >= 0) F(kF + a)[l] += static_cast<float>(f_[3 * p + a]);
          f_[3 * p + a] = 0.0;
        }
      }
    }
  }
}

void ClothPatch::ApplyProvotToWindows(double h) {
  // Provot 1995 (000 slide 9): a pair longer than its sweep length (PatchSweepLength) is shortened
  // to it, both ends moving by equal shares, a driven end not at all (as a pin), sweeps until none
  // was more than 1e-3 over it (as ApplyProvot, in single precision like it); the velocity follows
  // the particle's whole move / h. The sweeps: ProvotBody.
  const PatchKernels& kernels = PickSimd(kPatchKernels);
  const double inv_h = 1.0 / h;
  for (size_t k = 0; k < window_count_; ++k) {
    const PatchWindow& win = windows_[k];
    const int32_t base = base_[k];
    WindowSoa w = WindowArrays(single_.data(), stride_, base, win);
    for (int32_t a = 0; a < 3; ++a) {
      const double* __restrict x = D(kX + a) + base;
      float* __restrict px = w.p[a];
      const double o = x[0];
      for (int32_t l = 0; l < w.count; ++l) px[l] = static_cast<float>(x[l] - o);
    }
    // The attachments to the window's pins first, as ApplyProvot (Kim, Chentanez & Mueller 2012:
    // each particle back into the ball around its pin; ProjectAttachments' arithmetic).
    for (int32_t i = attach_base_[k]; i < attach_base_[k + 1]; ++i) {
      const PatchAttachment& at = attach_[static_cast<size_t>(i)];
      ProjectIntoBall(w.p[0], w.p[1], w.p[2], static_cast<size_t>(at.local - base),
                      static_cast<size_t>(at.pin - base), at.max_m);
    }
    const WindowPasses& passes = passes_[k];
    for (int32_t it = 0; it < model_.patch_provot_iterations; ++it) {
      if (kernels.provot(w, passes.provot.data(), passes.num_provot) == 0) break;
    }
    // Back as each particle's move (exact in double; zero for a particle not moved).
    for (int32_t a = 0; a < 3; ++a) {
      double* __restrict x = D(kX + a) + base;
      double* __restrict v = D(kV + a) + base;
      const float* __restrict px = w.p[a];
      const double o = x[0];
      for (int32_t l = 0; l < w.count; ++l) {
        const double move =
            static_cast<double>(px[l]) - static_cast<double>(static_cast<float>(x[l] - o));
        x[l] += move;
        v[l] += inv_h * move;
      }
    }
  }
}

void ClothPatch::ApplyObstaclesToWindows() {
  // Projection to the margin shell along the distance's gradient; the inward normal velocity is
  // removed and the particle restarts from its velocity (no sweep and no friction: the patch's
  // steps are 1 ms, and the sim's frame resolves the obstacles fully).
  for (int32_t l = 0; l < locals_; ++l) {
    if (!(D(kFree)[l] > 0.0)) continue;
    Vec3 x(D(kX)[l], D(kX + 1)[l], D(kX + 2)[l]);
    Vec3 v(D(kV)[l], D(kV + 1)[l], D(kV + 2)[l]);
    bool moved = false;
    for (const ObstacleSpec& o : model_.obstacles) {
      Vec3 n;
      const double phi = ObstacleDistance(o, x, &n);
      if (!(phi < o.margin_m)) continue;
      x += (o.margin_m - phi) * n;
      const double vn = v.dot(n);
      if (vn < 0.0) v -= vn * n;
      moved = true;
    }
    if (!moved) continue;
    for (int32_t a = 0; a < 3; ++a) {
      D(kX + a)[l] = x[a];
      D(kV + a)[l] = v[a];
    }
    D(kRestart)[l] = 1.0;
  }
}

static_assert(kMaxGuardCells == 256, "ClothPatch::guard_cells_ holds kMaxGuardCells a sphere");

void ClothPatch::GatherGuardCells() {
  // Each spring's sphere and the cells near it at the step's start (x_before_: every window
  // particle), the reach grown by one spacing for the step's motion (a particle moving a spacing
  // within a haptic tick, 8 m/s at 64 x 64, is past any hand; the sim's guard still holds then).
  const auto at_start = [&](int32_t p) -> const Vec3& { return x_before_[p]; };
  for (int32_t k = 0; k < springs_->count; ++k) {
    spheres_[k] = CouplingSphereAt(model_, springs_->springs[k], x_before_);
    guard_count_[k] = 0;
    if (!spheres_[k].valid) continue;
    int32_t dropped = 0;
    std::array<int32_t, kMaxGuardCells>& cells = guard_cells_[k];
    const int32_t count = GuardCellsNear(model_, spheres_[k], windows(), at_start, &cells, &dropped,
                                         model_.spacing_m);
    counters_.guard_dropped_cells += static_cast<uint64_t>(dropped);
    // Only cells whose four corners are in a window: the others' triangles are not the patch's.
    const int32_t w = model_.width;
    int32_t kept = 0;
    for (int32_t i = 0; i < count; ++i) {
      const int32_t cell = cells[i], p00 = GuardCellCorner(w, cell);
      if (local_[p00] >= 0 && local_[p00 + 1] >= 0 && local_[p00 + w] >= 0 &&
          local_[p00 + w + 1] >= 0) {
        cells[kept++] = cell;
      }
    }
    guard_count_[k] = kept;
  }
}

void ClothPatch::ApplySphereGuardsToWindows() {
  // The sim's guard (ApplySphereGuards) on the cells GatherGuardCells found, read from the dense
  // state: their corners are copied to x_ and v_ first; every particle but a pinned one is
  // movable, the driven rings too (left to their drive, the flap at x = -35 mm of
  // LayeredCloth.DISABLED_AFoldNeverClosesOnTheProxyFartherAfield closed through the proxy in
  // the patch); what it moved goes back to the dense state, leapfrog restarting from its velocity.
  // The spheres are the step's (the proxy moves little within a haptic tick).
  const auto load = [&](int32_t p) {
    const int32_t l = local_[p];
    x_[p] = Vec3(D(kX)[l], D(kX + 1)[l], D(kX + 2)[l]);
    v_[p] = Vec3(D(kV)[l], D(kV + 1)[l], D(kV + 2)[l]);
  };
  const int32_t w = model_.width;
  for (int32_t k = 0; k < springs_->count; ++k) {
    const CouplingSphere& sphere = spheres_[k];
    for (int32_t i = 0; i < guard_count_[k]; ++i) {
      const int32_t cell = guard_cells_[k][i], p00 = GuardCellCorner(w, cell);
      for (const int32_t p : {p00, p00 + 1, p00 + w, p00 + w + 1}) load(p);
      counters_.guard_pushes += static_cast<uint64_t>(GuardSphereCell(
          model_, sphere, cell, x_before_, x_, v_,
          [&](int32_t p) { return model_.inv_mass_per_kg[p] > 0.0; },
          [&](int32_t p) {
            const int32_t l = local_[p];
            for (int32_t a = 0; a < 3; ++a) {
              D(kX + a)[l] = x_[p][a];
              D(kV + a)[l] = v_[p][a];
            }
            D(kRestart)[l] = 1.0;
          }));
    }
  }
}

bool ClothPatch::AllFinite() const {
  int64_t bad = 0;
  const PatchKernels& kernels = PickSimd(kPatchKernels);
  for (int32_t a = 0; a < 6; ++a)
    bad += kernels.non_finite(D(kX + a), static_cast<size_t>(locals_));
  return bad == 0;
}

void ClothPatch::RestartFromDrive(double tau_s) {
  for (int32_t l = 0; l < locals_; ++l) {
    for (int32_t a = 0; a < 3; ++a) {
      D(kX + a)[l] = D(kDriveX + a)[l] + tau_s * D(kDriveV + a)[l];
      D(kV + a)[l] = D(kDriveV + a)[l];
    }
    D(kRestart)[l] = 1.0;
  }
  StorePositions(x_before_.data());
}

Vec3 ClothPatch::NormalAt(int32_t p) const {
  Vec3 n = Vec3::Zero();
  for (int32_t k = vertex_tri_start_[p]; k < vertex_tri_start_[p + 1]; ++k) {
    const Triangle& t = model_.triangles[static_cast<size_t>(vertex_tris_[k])];
    n += (x_[t[1]] - x_[t[0]]).cross(x_[t[2]] - x_[t[0]]);
  }
  const double len = n.norm();
  return len > 0.0 ? Vec3(n / len) : Vec3::Zero();
}

PatchStepResult ClothPatch::Step(std::span<const ExternalForce> external, double dt_s,
                                 const ClothSnapshot& drive, double tau_s) {
  PatchStepResult out;
  if (window_count_ == 0 || !(dt_s > 0.0)) return out;
  ++counters_.steps;
  // x_ holds the step's start (every window particle: written by the last step or by Place):
  // it becomes x_before_, and x_ is written again below.
  std::swap(x_, x_before_);
  LoadDrive(drive);

  // Substeps no longer than the patch's nominal one, shortened for a stiff contact spring
  // (CouplingSubsteps: Colgate, Stanley & Brown 1995).
  const int32_t plain = std::max(1, static_cast<int32_t>(std::ceil(dt_s / h_max_s_ - 1e-9)));
  const int32_t substeps = CouplingSubsteps(model_, external, dt_s, plain);
  const double h = dt_s / substeps;
  BeginCouplingFrame(springs_.get());
  for (const ExternalForce& e : external) {
    if (!(e.stiffness_N_per_m > 0.0)) continue;
    if (!SpringInside(e)) {
      ++counters_.springs_outside;
      continue;
    }
    AddCouplingSpring(model_, e, h, x_before_, springs_.get(), &counters_.coupling);
  }
  const PatchKernels& kernels = PickSimd(kPatchKernels);
  // The step's start from the drive's snapshot (DistanceFromDrive: now or at the step's start).
  double max2 = kernels.max_distance2(locals_, D(kX), D(kX + 1), D(kX + 2), D(kDriveX),
                                      D(kDriveX + 1), D(kDriveX + 2));
  const bool provot = model_.provot_enabled && !level1_.empty();
  const bool guard =
      model_.self_collision_enabled && model_.self_collision_guard_proxy && springs_->count > 0;
  if (guard) GatherGuardCells();
  IntegrateArgs args;
  for (int32_t a = 0; a < 3; ++a) {
    args.x[a] = D(kX + a);
    args.v[a] = D(kV + a);
    args.a_last[a] = D(kALast + a);
    args.drive_x[a] = D(kDriveX + a);
    args.drive_v[a] = D(kDriveV + a);
    args.f[a] = F(kF + a);
    args.g[a] = model_.gravity_m_per_s2[a];
  }
  args.inv_mass = D(kInvMass);
  args.movable = D(kFree);
  args.restart = D(kRestart);
  args.count = locals_;
  args.h = h;
  // Each driven particle closes the fraction beta = h / (T + h) of its distance to the drive
  // (backward Euler of x' = v + (target - x) / T, unconditionally stable), T = kPatchDriveTime_s.
  args.beta = h / (kPatchDriveTime_s + h);
  args.drag = model_.drag_N_s_per_m;
  for (int32_t s = 0; s < substeps; ++s) {
    // The contact springs read positions by particle: the step's start is x_before_; later
    // substeps write x_ first.
    if (s > 0) {
      AdvanceCouplingSprings(s * h, springs_.get());
      if (springs_->count > 0) StorePositions(x_.data());
    }
    // Forces at the substep's start (the driven particles where they are), then the driven
    // particles to the substep's end, where the constraints see them.
    SubstepForces(s == 0 ? x_before_ : x_);
    args.h_old = h_last_s_ > 0.0 ? h_last_s_ : h;
    args.drive_tau_s = std::min(tau_s - dt_s + (s + 1) * h, drive_horizon_s_);
    kernels.integrate(args);
    h_last_s_ = h;
    if (provot) ApplyProvotToWindows(h);
    if (!model_.obstacles.empty()) ApplyObstaclesToWindows();
    if (guard) ApplySphereGuardsToWindows();
  }
  if (!AllFinite()) {
    ++counters_.nan_events;
    RestartFromDrive(std::min(tau_s, drive_horizon_s_));
    max2 = 0.0;  // the step now starts where it ends (x_before_ = x_)
    out.recovered = true;
  }
  // The state the proxy reads, row by row, and the largest distance from the drive's snapshot.
  const int32_t w = model_.width;
  for (size_t k = 0; k < window_count_; ++k) {
    const PatchWindow& win = windows_[k];
    const int32_t cols = win.col1 - win.col0 + 1, pitch = PitchOf(win);
    for (int32_t r = win.row0; r <= win.row1; ++r) {
      const int32_t l = base_[k] + (r - win.row0) * pitch, p = r * w + win.col0;
      Interleave(cols, D(kX) + l, D(kX + 1) + l, D(kX + 2) + l, x_[p].data());
      Interleave(cols, D(kV) + l, D(kV + 1) + l, D(kV + 2) + l, v_[p].data());
    }
  }
  max2 = std::max(max2, kernels.max_distance2(locals_, D(kX), D(kX + 1), D(kX + 2), D(kDriveX),
                                              D(kDriveX + 1), D(kDriveX + 2)));
  drive_distance_m_ = std::sqrt(max2);
  out.substeps = substeps;
  out.springs = springs_->count;
  return out;
}

double ClothPatch::MaxDistanceFrom(const ClothSnapshot& s) const {
  double max2 = 0.0;
  ForEachParticle([&](int32_t p) {
    max2 = std::max({max2, (x_[p] - s.x[p]).squaredNorm(), (x_before_[p] - s.x[p]).squaredNorm()});
  });
  return std::sqrt(max2);
}

}  // namespace felt
