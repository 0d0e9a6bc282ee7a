#pragma once
// Internals of the cloth step shared by sim_loop/cloth_*.cc: the scratch block every StepFrame
// works in, and the kernels that operate on it. Not for use outside sim_loop/cloth_*.cc.

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "collision/self_response.h"
#include "sim_loop/cloth.h"
#include "sim_loop/cloth_coupling.h"

namespace felt {

/// Springs shorter than this (m) have no usable direction: they exert no force and add no
/// stiffness to implicit Euler's Jacobian.
inline constexpr double kMinSpringLength_m = 1e-12;

/// Preallocated work arrays of one ClothState, sized once by MakeClothState (n = particles).
struct ClothState::Scratch {
  // Forces and integrator stages, [n] each.
  std::vector<Vec3> force_N;     ///< force accumulator
  std::vector<Vec3> external_N;  ///< external point forces of this frame, per particle
  std::vector<Vec3> accel;       ///< acceleration of the current stage, m/s^2
  std::vector<Vec3> x_stage;     ///< stage positions (midpoint, RK4, velocity Verlet)
  std::vector<Vec3> v_stage;     ///< stage velocities
  std::vector<Vec3> kx_sum;      ///< RK4: weighted sum of position slopes
  std::vector<Vec3> kv_sum;      ///< RK4: weighted sum of velocity slopes
  std::vector<Vec3> x_start;     ///< positions at the start of the substep (obstacle sweeps)
  CouplingSprings coupling;      ///< contact springs of this frame (fixed capacity)
  /// The contact springs' accelerations by row, for StreamAccelerations (fixed capacity).
  CouplingTermRows coupling_rows;
  /// [StreamScratchSize] StreamAccelerations' ring of rows (positions, velocities, forces and
  /// springs of max(dr) + 2 rows) and two rows of accelerations.
  std::vector<double> stream_rows;
  /// Self-collision response (collision/self_response.h), built only with [self_collision].
  std::optional<SelfCollisionResponse> self_collision;
  /// The last frame's self-collision found no contact (no pair within the thickness, no
  /// collision): this frame may take fewer, longer passes (SelfPassSubsteps).
  bool self_quiet = false;
  /// [12 SoaStride(n)] structure-of-arrays work space of the force kernel: x, y, z, vx, vy, vz,
  /// then the force fx, fy, fz, then one spring family's forces (cloth_forces.cc).
  std::vector<double> soa;
  /// [3 ProvotSoaStride(n)] ApplyProvot's positions x, y, z as it moves them: single precision,
  /// metres from the first particle.
  std::vector<float> provot_soa;
  /// Stretch limiter's worklist: [limit_families * n] 1 while a pair is queued, and the queue (a
  /// ring of pair ids f * n + p, each queued at most once).
  std::vector<uint8_t> limit_queued;
  std::vector<int32_t> limit_ring;
  /// [n] 1 while a particle's pre-worklist state is in the undo log; the log: [n] particle
  /// indices and [6 n] their x, v (so an unconverged worklist leaves the sweeps' result).
  std::vector<uint8_t> limit_logged;
  std::vector<int32_t> limit_log_index;
  std::vector<double> limit_log_xv;

  // Integrator history (leapfrog, basic Verlet), [n] each.
  bool history_valid = false;  ///< false: restart from x, v at the next substep
  double history_h_s = 0.0;    ///< substep length the history was made with
  std::vector<Vec3> a_last;    ///< acceleration of the previous substep
  std::vector<Vec3> x_prev;    ///< basic Verlet: positions one substep back
  /// leapfrog, [n]: 1 where a constraint replaced the particle's velocity (SyncVerletHistory), so
  /// the next substep restarts it from that velocity
  std::vector<uint8_t> restart;

  // Last good state, restored when a frame produces non-finite values.
  std::vector<Vec3> good_x;
  std::vector<Vec3> good_v;
  double good_time_s = 0.0;
  bool nan_logged = false;

  // Implicit Euler (Baraff & Witkin 1998): A dv = b on 3n unknowns; pattern built once.
  Eigen::SparseMatrix<double, Eigen::RowMajor> A;
  std::vector<std::array<int32_t, 3>> diag_offset;  ///< [n] value index of row 3i+r, col 3i
  std::vector<std::array<int32_t, 3>> ij_offset;    ///< [springs] value index of (3i+r, 3j)
  std::vector<std::array<int32_t, 3>> ji_offset;    ///< [springs] value index of (3j+r, 3i)
  Eigen::VectorXd b, dv, r, z, p, Ap, inv_diag;     ///< [3n] CG vectors
};

/// Distance, in doubles, between consecutive arrays of a structure-of-arrays block for n particles:
/// n rounded up to a cache line plus one more line, so the arrays never start a multiple of 4 KiB
/// apart (with n = 4096 the twelve arrays would share the same L1 sets and alias on 4 KiB pages).
constexpr size_t SoaStride(size_t n) { return (n + 7) / 8 * 8 + 8; }

/// Distance, in floats, between ApplyProvot's single-precision arrays x, y, z for n particles: n
/// rounded up to 1024 floats (4 KiB) plus 344 (1376 bytes), so the three arrays start about a
/// third of a 4 KiB page apart. Arrays a multiple of 4 KiB apart (or a few lines from it) make a
/// load of one alias a store to another in the low 12 address bits, which the CPU treats as a
/// possible store-to-load dependency ("4K aliasing", Intel optimization manual §3.6.8; AMD's
/// Zen cores match on the same bits).
constexpr size_t ProvotSoaStride(size_t n) { return (n + 1023) / 1024 * 1024 + 344; }

/// The first element of `data` that starts a 64-byte cache line (at most 64 bytes on: a buffer
/// meant for it has that much slack).
template <class T>
T* OnCacheLine(T* data) {
  return data + (64 - reinterpret_cast<uintptr_t>(data) % 64) % 64 / sizeof(T);
}

/// ApplyProvot's single-precision positions x, y, z [m from the first particle] in
/// scratch.provot_soa, for n particles.
struct ProvotSoaArrays {
  float* x;
  float* y;
  float* z;
};

/// Where ApplyProvot keeps its arrays in `soa` (sized 3 ProvotSoaStride(n)), and where
/// ApplyLimitWorklist reads them: x on the buffer's first cache line, y and z each
/// ProvotSoaStride(n) rounded down to 16 floats after the one before, so that with n a multiple of
/// 16 a row of 16 floats is one line, not two. Every array keeps at least 336 - 15 floats of
/// padding, and they stay about a third of a 4 KiB page apart (AVX-512 sweeps of curtain_128
/// without the worklist: 0.147 -> 0.140 ms a substep).
inline ProvotSoaArrays ProvotSoaIn(std::vector<float>* soa, size_t n) {
  float* const x = OnCacheLine(soa->data());
  const size_t stride = ProvotSoaStride(n) / 16 * 16;
  return {x, x + stride, x + 2 * stride};
}

/// A long range attachment (Kim, Chentanez & Mueller 2012) in single-precision arrays x, y, z [m]:
/// particle p, if outside the ball of radius max_len [m] around particle q, goes back onto it; q
/// (a pin) does not move. ApplyProvot's scalar path and the haptic patch's windows.
inline void ProjectIntoBall(float* x, float* y, float* z, size_t p, size_t q, float max_len) {
  const float dx = x[p] - x[q], dy = y[p] - y[q], dz = z[p] - z[q];
  const float len2 = dx * dx + dy * dy + dz * dz;
  if (len2 <= max_len * max_len) return;
  const float len = std::sqrt(len2);
  const float scale = (len - max_len) / len;
  x[p] -= scale * dx;
  y[p] -= scale * dy;
  z[p] -= scale * dz;
}

/// Accelerations [m/s^2] at positions x and velocities v: gravity, drag, springs, and the frame's
/// external forces (scratch.external_N); zero for pinned particles. Works in scratch.soa (spring
/// families as grid stencils, with the kernels of base/simd.h's level in use).
void ComputeAccelerations(const ClothModel& model, std::span<const Vec3> x, std::span<const Vec3> v,
                          ClothState::Scratch* scratch, std::span<Vec3> a);

/// Spring families a grid model has at most: structural, shear and bend, two directions each
/// (StreamAccelerations' fixed work space).
inline constexpr size_t kMaxSpringFamilies = 6;

/// Receives grid row `row`'s accelerations from StreamAccelerations: accel [m/s^2], xyz per
/// particle of the row (3 width doubles).
struct AcceleratedRows {
  void* context = nullptr;
  void (*rows)(void* context, int32_t row, const double* accel) = nullptr;
};

/// Doubles of ClothState::Scratch::stream_rows that StreamAccelerations needs for `model`.
size_t StreamScratchSize(const ClothModel& model);

/// ComputeAccelerations' accelerations, bit for bit, made a grid row at a time and handed to
/// `sink` as soon as a row's are final, in row order. No later row's forces read that row's x or
/// v again (they are copied ahead into a ring of rows, and the contact springs evaluated first),
/// so the sink may overwrite them: a fused integrator makes one pass over the particles per
/// substep instead of a pass per spring family and one each for the split, the accelerations and
/// the update, and its work space (max(dr) + 2 rows: 117 KiB at width 128) stays in the L2 cache.
void StreamAccelerations(const ClothModel& model, std::span<const Vec3> x, std::span<const Vec3> v,
                         ClothState::Scratch* scratch, AcceleratedRows sink);

/// Advances state->x, state->v by one substep of length h_s with the model's integrator
/// (001_0f9f1b7fedff7723.txt §3). Pins keep the velocity they were given. Returns false if the
/// implicit solve hit its iteration cap.
bool IntegrateSubstep(const ClothModel& model, double h_s, ClothState* state);

/// Provot 1995 (000_25210a744b053ca5.txt slides 9-10): the long range attachments, then sweeps over
/// model.provot_families, shortening every pair longer than its sweep length (sweep_length_m),
/// then the finishing worklist (ApplyLimitWorklist); velocities are corrected by the move / h_s.
/// Single precision, with the kernels of base/simd.h's level in use.
void ApplyProvot(const ClothModel& model, double h_s, ClothState* state);

/// The stretch limiter's finishing pass (ProvotSpec::finish; sim_loop/cloth_limiter.cc), called
/// by ApplyProvot after its sweeps (it reads their single-precision positions in
/// scratch.provot_soa): every pair of model.limit_families longer than its limit is queued, then
/// projected exactly (double precision) to just under its limit, re-queuing the pairs at its ends
/// it pushed over, until none is over or the budget is spent; velocities follow, v += dx / h_s. A
/// worklist that spends its budget is undone (the sweeps' result stays). Real-time safe.
void ApplyLimitWorklist(const ClothModel& model, double h_s, ClothState* state);

/// A Provot family's limit as ApplyProvot's single-precision sweeps use it: max2 = the squared
/// sweep length (ProvotFamily::sweep_length_m, m^2), loose2 = (1 + 1e-3)^2 max2, the squared length
/// above which a pair keeps the sweeps going.
struct ProvotLimits {
  float max2;
  float loose2;
};

/// The limits of family f (computed one way for the kernels and the tests' reference).
ProvotLimits ProvotLimitsOf(const ProvotFamily& f);

/// Keeps free particles outside every declared obstacle (surface + margin), sweeping the path
/// from scratch.x_start so a fast particle cannot tunnel through an obstacle, whether it started
/// clear of it or resting on it; removes the inward normal velocity and applies Coulomb friction
/// to the tangential velocity.
void ApplyObstacles(const ClothModel& model, double h_s, ClothState* state);

/// Sets every pinned particle to rest + PinOffset(t_s) and its velocity to PinVelocity(t_s).
void ApplyPins(const ClothModel& model, double t_s, ClothState* state);

/// After a substep moved a free particle's position and replaced its velocity by hand (obstacles):
/// basic Verlet's previous position is re-derived from the corrected velocity so the two stay
/// consistent; leapfrog restarts the particle from it at the next substep (scratch.restart).
void SyncVerletHistory(const ClothModel& model, int32_t particle, double h_s, ClothState* state);

/// Runs the self-collision response on the motion since its BeginStep (the last h_s seconds,
/// one or more substeps) and adds its counts to state->counters and *result
/// (sim_loop/cloth_self_collision.cc). Real-time safe.
void ApplySelfCollision(double h_s, SelfCollisionResponse* self, ClothState* state,
                        FrameResult* result);

/// Substeps covered by one self-collision pass of a frame cut into `substeps`:
/// ceil(substeps / SelfCollisionSettings::passes_per_frame), and with the particles' velocities
/// v [m/s] and the substep h_s [s] at most max_pass_motion * thickness / (max |v| h_s) (at least
/// 1); with `quiet` (the last frame found no contact and no hand acts) up to
/// ceil(substeps / min_passes_per_frame) while the fastest particle, at max |v| plus |g| times
/// the frame, moves at most slow_pass_motion thicknesses per pass; always 1 for basic Verlet, whose
/// velocity comes from the last substep's positions, so a correction spread over a longer step
/// would be amplified. Real-time safe.
int32_t SelfPassSubsteps(const ClothModel& model, const SelfCollisionResponse& self,
                         int32_t substeps, std::span<const Vec3> v = {}, double h_s = 0.0,
                         bool quiet = false);

/// The most substeps a self-collision pass may cover in a frame with a hand on the cloth after
/// one without contact, when its measured motion allows (SelfPassMayGoOn):
/// ceil(substeps / min_passes_per_frame), never fewer than `planned` (SelfPassSubsteps);
/// `planned` when hand_pass_motion is 0, min_passes_per_frame >= passes_per_frame, or for basic
/// Verlet. Real-time safe.
int32_t SelfPassLongest(const ClothModel& model, const SelfCollisionResponse& self,
                        int32_t substeps, int32_t planned);

/// True if a self-collision pass begun at self.x_before() may take one more substep of h_s [s]
/// (a hand acts: its pull is not in the frame-start speeds, so the motion is measured): the
/// farthest any particle has moved since, max |x - x_before| [m], plus max |v| h_s [m/s] stays
/// within hand_pass_motion thicknesses, and within max_pass_motion when set; false on a NaN.
/// Real-time safe.
bool SelfPassMayGoOn(const SelfCollisionResponse& self, std::span<const Vec3> x,
                     std::span<const Vec3> v, double h_s);

/// The exact count of intersecting non-adjacent triangle pairs at the frame's end into
/// result->self_intersections and counters.self_intersections_max (O(T^2); opt-in diagnostic).
void CountFrameIntersections(const ClothModel& model, ClothState* state, FrameResult* result);

/// Builds the implicit Euler matrix pattern and offsets in `scratch` (once, in MakeClothState).
void BuildImplicitPattern(const ClothModel& model, ClothState::Scratch* scratch);

}  // namespace felt
