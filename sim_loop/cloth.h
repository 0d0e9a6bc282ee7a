#pragma once
// The mass-spring cloth of the 60 Hz thread: an immutable model built once from a SimSpec, a state
// sized once, and StepFrame, which never allocates.
// Model/state split after MuJoCo's mjModel/mjData (shared/STYLE.md).

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "collision/mesh.h"
#include "sim_loop/cloth_spec.h"

namespace felt {

/// The kind of a spring (001_0f9f1b7fedff7723.txt §2, Figure 1).
enum class SpringType : uint8_t { kStructural, kShear, kBend };

/// One spring between particles i and j.
struct Spring {
  int32_t i = 0;
  int32_t j = 0;
  double rest_length_m = 0.0;
  double stiffness_N_per_m = 0.0;
  double damping_N_s_per_m = 0.0;
  SpringType type = SpringType::kStructural;
};

/// All springs of one type and one grid direction: end i at (col, row), end j at (col + dc, row +
/// dr), for every (col, row) where both are on the grid. A rectangular grid with uniform spacing
/// gives every spring of a family the same rest length and constants, so the force kernel runs over
/// whole rows of particles (a stencil) with no per-spring index or constant loads.
struct SpringFamily {
  int32_t dc = 0;  ///< column offset of end j from end i, in particles
  int32_t dr = 0;  ///< row offset of end j from end i, >= 0
  double rest_length_m = 0.0;
  double stiffness_N_per_m = 0.0;
  double damping_N_s_per_m = 0.0;
  SpringType type = SpringType::kStructural;
};

/// One family of Provot deformation constraints (000_25210a744b053ca5.txt slide 9) as a grid
/// stencil: particle (col, row) and particle (col + dc, row + dr) may be at most max_length_m
/// apart, for every (col, row) where both are on the grid. A violation is removed by moving the two
/// ends by equal shares (the free end alone if the other is pinned). `level` 1 is a spring family
/// (structural or shear); level s > 1 joins particles s apart along a row, column or diagonal (see
/// ProvotSpec::multiresolution).
struct ProvotFamily {
  /// Particles [lo, hi) of one row, whose pairs a sweep projects together (see runs).
  struct Run {
    int32_t lo = 0;
    int32_t hi = 0;
    int32_t pinned = 0;  ///< 1 if a pair of the run has a pinned end (else both ends move)
  };
  int32_t dc = 0;             ///< column offset of end j from end i, in particles
  int32_t dr = 0;             ///< row offset of end j from end i, >= 0
  double max_length_m = 0.0;  ///< (1 + max_elongation) * rest distance of the two ends
  int32_t level = 1;          ///< 1: a spring family; s > 1: a multiresolution family of stride s
  /// The pairs in sweep order, as runs of end-i particles: along a row with dc 1, 2, 4 or 8
  /// (strided()) a run holds the first dc of every 2 dc particles from lo, below hi (dc = 1: every
  /// second one), else every particle in [lo, hi). The runs of the first colour come first; no two
  /// pairs of one colour share a particle.
  std::vector<Run> runs;
  /// The length the sweeps project onto, m: (1 - ProvotSpec::sweep_headroom) * max_length_m (the
  /// finishing worklist holds max_length_m itself).
  double sweep_length_m = 0.0;
  /// The length the haptic local patch's sweeps project onto, m: (1 -
  /// ProvotSpec::patch_sweep_headroom) * max_length_m (sim_loop/cloth_patch.h).
  double patch_sweep_length_m = 0.0;

  /// True if the runs are strided (along a row, dc 1, 2, 4 or 8: a colour's pairs interleave
  /// within a row, every sixteen particles holding eight pairs).
  bool strided() const { return dr == 0 && (dc == 1 || dc == 2 || dc == 4 || dc == 8); }
};

/// One family of spring limits that the stretch limiter's finishing worklist holds
/// (ProvotSpec::finish): particle (col, row) and particle (col + dc, row + dr) may be at most max_m
/// apart, for every (col, row) where both are on the grid: the structural (and, with
/// ProvotSpec::shear, shear) springs.
struct LimitFamily {
  int32_t dc = 0;        ///< column offset of end j from end i, in particles
  int32_t dr = 0;        ///< row offset of end j from end i, >= 0
  int32_t off = 0;       ///< index offset of end j from end i: dr * width + dc
  double max_m = 0.0;    ///< (1 + max_elongation) * rest length, m
  double max2_m2 = 0.0;  ///< max_m squared, m^2
};

/// A long range attachment (ProvotSpec::long_range_attachments): free particle `particle` may be
/// at most max_length_m from pinned particle `pin`.
struct PinAttachment {
  int32_t particle = 0;
  int32_t pin = 0;
  double max_length_m = 0.0;  ///< (1 + max_elongation) * rest distance
};

/// A point force the haptic side puts on the cloth for the next frame (two-way coupling): applied
/// at the point with barycentric weights `barycentric` in triangle `triangle`, split over its three
/// particles by those weights. World frame, newtons.
///
/// With stiffness_N_per_m > 0 it is instead a unilateral contact spring to the user's hand,
/// evaluated at every force evaluation of the step (every substep and integrator stage) at the
/// positions being evaluated (virtual coupling, Colgate, Stanley & Brown 1995, on the god-object
/// contact of Ruspini, Kolarov & Khatib 1997): the proxy sphere of radius_m centred at g = anchor_m
/// + radius_m normal penetrates the cloth by pen = radius_m - sd, where sd is g's distance to the
/// cloth around `triangle` (the triangles of the 3 x 3 grid cells around its cell), negative when
/// g is past the cloth (normal says which side is the proxy's): the distance to the nearest point
/// where one face is clearly nearest, a smooth minimum over the faces of a crease where several
/// are (sim_loop/cloth_coupling.h, AddCouplingForces). The cloth gets the force
/// -dE/dx of E = 1/2 k_eff pen^2 (|F| <= max_force_N), each face its share of the gradient split
/// over its particles by the barycentric weights of its nearest point (pinned particles get
/// nothing), so the coupling is conservative however the cloth moves under it; `barycentric`
/// only names where the haptic side found the contact, and force_N is not applied. A frame holding
/// a spring too stiff for its substep is cut into up to 4 times its substeps
/// (ClothCounters::coupling_substepped_frames); beyond that k_eff = min(k, the largest stiffness
/// the integrator is stable with at the substep; see ClothCounters::coupling_reduced_frames). At
/// most 16 springs per frame (more are counted and dropped).
struct ExternalForce {
  int32_t triangle = 0;
  Vec3 barycentric = Vec3(1.0 / 3, 1.0 / 3, 1.0 / 3);  ///< non-negative, sums to 1
  Vec3 force_N = Vec3::Zero();     ///< applied force; for a spring: the haptic side's average, info
  double stiffness_N_per_m = 0.0;  ///< contact spring k, world; 0: a plain force
  Vec3 anchor_m = Vec3::Zero();    ///< spring: the user's hand (device goal), world, m
  Vec3 normal = Vec3::UnitZ();     ///< spring: unit, from the cloth toward the proxy's side
  double max_force_N = 0.0;        ///< spring: force clamp (the device's, mapped to world), N
  double radius_m = 0.0;           ///< spring: the proxy sphere's radius, world, m (>= 0)
  /// spring: the hand's velocity, world, m/s: the sphere moves at it from the frame's start
  /// (a first-order prediction of the hand over the frame; zero: held where it is)
  Vec3 anchor_velocity_m_per_s = Vec3::Zero();
};

/// The validated, immutable cloth: shared read-only by every thread. Compiled from a SimSpec by
/// BuildClothModel; it keeps what the kernels read, not the spec.
struct ClothModel {
  int32_t width = 0;                      ///< particles along u
  int32_t height = 0;                     ///< particles along v
  double spacing_m = 0.0;                 ///< rest distance between grid neighbours, m
  std::vector<Vec3> rest_position_m;      ///< [width*height] rest places, index = row*width + col
  std::vector<double> inv_mass_per_kg;    ///< [width*height] 1/m, 0 for pinned particles
  std::vector<int32_t> pinned;            ///< indices of pinned particles
  std::vector<int32_t> pin_spec;          ///< [pinned.size()] index of its [[cloth.pins]] entry
  std::vector<PinMotionSpec> pin_motion;  ///< [pinned.size()] that entry's scripted motion
  std::vector<Spring> springs;            ///< only the spring types the spec declares
  std::vector<Triangle> triangles;        ///< 2 (W-1)(H-1), see MakeGridTriangles
  std::vector<ObstacleSpec> obstacles;   ///< the scene's obstacles, world frame (only these tested)
  Vec3 gravity_m_per_s2 = Vec3::Zero();  ///< world frame, m/s^2
  double drag_N_s_per_m = 0.0;           ///< viscous drag per particle, F = -c v

  // Integration (IntegrationSpec, validated).
  IntegratorKind integrator = IntegratorKind::kLeapfrogVerlet;  ///< the step's integrator
  bool auto_substeps = true;      ///< substeps chosen from the stability limit ("auto")
  int32_t substeps = 1;           ///< per nominal frame, resolved ("auto" -> number)
  double frame_rate_hz = 60.0;    ///< nominal frame rate, Hz
  double max_frame_dt_s = 0.0;    ///< a late frame integrates at most this much time, s
  int32_t cg_max_iterations = 0;  ///< implicit Euler: conjugate-gradient iteration cap
  double cg_tolerance = 0.0;      ///< implicit Euler: relative residual to stop at
  double stable_dt_s = 0.0;       ///< the integrator's stability limit, s (StableStep)

  // Provot (ProvotSpec, validated).
  bool provot_enabled = false;    ///< Provot's constraints are applied after each substep
  int32_t provot_iterations = 0;  ///< Gauss-Seidel sweeps per substep
  int32_t provot_coarse_sweeps = 0;  ///< the first sweeps that visit the multiresolution families
  int32_t patch_provot_iterations = 0;  ///< the haptic local patch's sweeps per 1 kHz step

  // Self-collision (SelfCollisionSpec, validated; issue 22). Nothing is built without it.
  bool self_collision_enabled = false;              ///< the scene declared [self_collision]
  SelfCollisionSettings self_collision;             ///< its settings (k resolved)
  bool self_collision_count_intersections = false;  ///< exact end-of-frame count (O(T^2))
  /// With [self_collision]: the proxy's sphere keeps the cloth's other layers out
  /// (SelfCollisionSpec::guard_proxy; ApplySphereGuards).
  bool self_collision_guard_proxy = false;

  // Derived constants (filled by BuildClothModel; read by the kernels and the benchmarks).
  double particle_mass_kg = 0.0;      ///< mass of every particle (pinned ones included)
  std::vector<uint8_t> pin_scripted;  ///< [pinned.size()] 1 if that pin's motion is not all zero
  /// Provot's constraint families in sweep order: multiresolution ones coarsest first, then the
  /// structural (+ shear) spring families. Empty when Provot is off.
  std::vector<ProvotFamily> provot_families;
  std::vector<float> provot_movable;  ///< [width*height] 1 for a free particle, 0 for a pin
  /// Each free particle to the nearest pin of each group of touching pins (of the four groups
  /// nearest it at most), particle by particle, the nearest first.
  std::vector<PinAttachment> attachments;
  /// The same attachments as dense ranks for the vector kernels: rank k < attachment_ranks of
  /// particle p at [k * width * height + p] is its k-th attachment, pin index and limit length (m,
  /// single precision); a pinned particle is attached to itself with limit 0, so it never moves.
  int32_t attachment_ranks = 0;
  std::vector<int32_t> attachment_pin;
  std::vector<float> attachment_max_m;        ///< see attachment_pin
  std::vector<SpringFamily> spring_families;  ///< `springs` grouped by type and direction
  /// The spring limits the finishing worklist holds (ProvotSpec::finish; empty: no worklist),
  /// the level-1 provot_families at their max_length_m.
  std::vector<LimitFamily> limit_families;
  /// Bound on the highest natural frequency of the linearised spring system, rad/s, for every
  /// configuration: omega_max^2 = max over wave vectors of the grid Laplacian's symbol / m (see
  /// ComputeFrequencyBounds in cloth_build.cc; 000_25210a744b053ca5.txt slide 8: the critical
  /// stiffness depends on the natural period).
  double omega_max_rad_per_s = 0.0;
  /// Bound on the frequency, rad/s, of the modes that only drag damps (motion across a stretched
  /// spring: its dashpot acts along it only): omega_max sqrt(1 - 1 / r) for springs at most r times
  /// their rest length (r from Provot's limit; omega_max without Provot).
  double omega_transverse_rad_per_s = 0.0;
  double drag_rate_per_s = 0.0;     ///< drag / particle mass: damping rate of every mode, 1/s
  double damping_time_min_s = 0.0;  ///< smallest c/k over the declared spring types, s
  double damping_time_max_s = 0.0;  ///< largest c/k over the declared spring types, s
  double gamma_max_per_s = 0.0;     ///< bound on the highest modal damping rate (same symbol), 1/s

  int32_t num_particles() const { return width * height; }
};

/// Counters of what happened to a state, for logs and stats.
struct ClothCounters {
  uint64_t frames = 0;            ///< frames stepped
  uint64_t nan_events = 0;        ///< frames that produced non-finite values (state restored)
  uint64_t clamped_frames = 0;    ///< frames whose dt was clamped to max_frame_dt_s
  uint64_t cg_not_converged = 0;  ///< implicit Euler solves that hit the iteration cap
  uint64_t invalid_external_forces = 0;  ///< ExternalForce entries ignored (bad triangle/values)
  uint64_t coupling_reduced_frames = 0;  ///< frames where a contact spring's k was lowered to the
                                         ///< integrator's stable bound (k_eff < k)
  uint64_t coupling_overflows = 0;       ///< contact springs dropped: more than 16 in a frame
  uint64_t coupling_substepped_frames = 0;  ///< frames cut into more substeps for a contact
                                            ///< spring (CouplingSubsteps)
  // Self-collision (only with [self_collision]; sums over all substeps, see SelfCollisionStats).
  uint64_t self_proximity_pairs = 0;      ///< pairs closer than the thickness at a substep start
  uint64_t self_impulses = 0;             ///< repulsion and CCD impulses applied
  uint64_t self_ccd_hits = 0;             ///< colliding pairs of the first CCD pass
  uint64_t self_impact_zones = 0;         ///< impact zones formed by the fail-safe
  uint64_t self_frozen_substeps = 0;      ///< substeps whose zones were frozen at x_before
  uint64_t self_unresolved_substeps = 0;  ///< substeps that ended with a collision left
  uint64_t self_overflows = 0;            ///< detections whose buffers overflowed
  uint64_t guard_pushes =
      0;  ///< triangles the proxy's sphere guard pushed out (summed over substeps)
  uint64_t guard_dropped_cells = 0;  ///< grid cells past the guard's capacity, not tested
  // The stretch limiter's finishing worklist (ProvotSpec::finish), summed over substeps.
  uint64_t limiter_initial = 0;      ///< pairs over their limit when the worklist started
  uint64_t limiter_projections = 0;  ///< projections the worklist made
  uint64_t limiter_unconverged = 0;  ///< substeps whose worklist ran out of budget
  /// Most intersecting non-adjacent triangle pairs at the end of a frame, by the exact test
  /// (only with SelfCollisionSpec::count_intersections; -1 when not counted).
  int64_t self_intersections_max = -1;
};

/// Everything that changes while stepping, sized once by MakeClothState.
struct ClothState {
  std::vector<Vec3> x;        ///< [n] positions, world, m
  std::vector<Vec3> v;        ///< [n] velocities, world, m/s
  std::vector<Vec3> normals;  ///< [n] area-weighted unit vertex normals, world
  double time_s = 0.0;        ///< simulated time
  ClothCounters counters;
  // Scratch (integrator stages, previous positions, last good state, CG buffers) lives in an
  // opaque block owned here so StepFrame never allocates. A copy of the state copies it too (the
  // integrator's history is part of the state), so two states never share it.
  struct Scratch;
  std::unique_ptr<Scratch> scratch;

  ClothState();
  ~ClothState();
  ClothState(const ClothState& other);             ///< deep copy (allocates)
  ClothState& operator=(const ClothState& other);  ///< deep copy (allocates)
  ClothState(ClothState&& other) noexcept;
  ClothState& operator=(ClothState&& other) noexcept;
};

/// Number of particle pairs Provot's sweeps visit (every family's pairs on the grid), per sweep.
int64_t ProvotPairCount(const ClothModel& model);

/// Validates `spec` and builds the model. Throws std::invalid_argument whose message names the
/// field (e.g. "cloth.width: must be >= 2, got 1").
ClothModel BuildClothModel(const SimSpec& spec);

/// A state at rest: particles at their rest places, zero velocity, normals computed, scratch sized.
ClothState MakeClothState(const ClothModel& model);

/// What one frame did.
struct FrameResult {
  int32_t substeps = 0;    ///< substeps integrated
  double dt_s = 0.0;       ///< time integrated (after clamping)
  bool clamped = false;    ///< frame_dt_s was larger than max_frame_dt_s
  bool recovered = false;  ///< non-finite values appeared and the last good state was restored
  // Self-collision, summed over the frame's substeps (zero without [self_collision]).
  int64_t self_proximity_pairs = 0;  ///< pairs within the thickness at substep starts
  int64_t self_impulses = 0;         ///< repulsion and CCD impulses
  int64_t self_ccd_hits = 0;         ///< colliding pairs of the first CCD pass
  int64_t self_impact_zones = 0;     ///< impact zones of the fail-safe
  int64_t self_unresolved = 0;       ///< collisions left at substep ends (0 with the fail-safe)
  double self_collision_s = 0.0;     ///< wall time spent in the response over the frame, s
  /// Intersecting non-adjacent triangle pairs at the frame's end (exact test), -1 if not counted.
  int64_t self_intersections = -1;
};

/// Advances the cloth by `frame_dt_s` (clamped to spec.integration.max_frame_dt_s), applying
/// `external` forces (held constant over the frame), pins, obstacles and Provot constraints, then
/// recomputes normals. The frame is cut into ceil(dt / h_nominal) substeps, h_nominal = (1 /
/// frame_rate_hz) / model.substeps, so a substep never exceeds the nominal one. Each substep:
/// integrate, Provot, obstacles, pins, then (with [self_collision]) the self-collision response on
/// the substep's motion (collision/self_response.h). Non-finite results restore the last good state
/// (x, v, time_s of the end of the last good frame; counted in counters.nan_events, logged once per
/// state). A frame_dt_s that is not > 0 (or NaN) does nothing. External forces with a triangle
/// out of range or non-finite values are skipped and counted. Does not allocate (the one-time
/// NaN log line aside); does not throw.
FrameResult StepFrame(const ClothModel& model, std::span<const ExternalForce> external,
                      double frame_dt_s, ClothState* state);

/// Largest length / rest length over the structural springs (1.0 = unstretched).
double MaxStretch(const ClothModel& model, const ClothState& state);

/// Largest length / rest length over the springs of `type` (1.0 if the cloth has none).
double MaxStretchOf(const ClothModel& model, const ClothState& state, SpringType type);

/// Kinetic + gravitational + spring potential energy, joules (pins excluded from kinetic).
double TotalEnergy(const ClothModel& model, const ClothState& state);

/// Adds the spring forces (Hooke term plus the dashpot along the spring, 001 §2) at positions `x`
/// [m] and velocities `v` [m/s] into `f` [N]; all three have model.num_particles() entries. A
/// spring shorter than 1e-12 m has no direction and adds nothing. Real-time safe.
void AddSpringForces(const ClothModel& model, std::span<const Vec3> x, std::span<const Vec3> v,
                     std::span<Vec3> f);

/// The largest stable step [s] of `kind` for the model's frequency bounds (omega_max with the
/// range of spring damping, and the drag-only modes up to omega_transverse), without safety
/// factor: the largest h at which no mode of the scalar test oscillator grows faster than 0.1 %
/// per second. +infinity for implicit Euler; tiny
/// for explicit Euler or midpoint with neither damping nor drag (they have no stable step).
double StableStep(const ClothModel& model, IntegratorKind kind);

/// Signed distance [m] from `p_m` (world) to the obstacle's surface, margin not included:
/// negative inside. `normal` gets the unit outward direction to push along (the gradient).
/// Exact for every shape outside it. Real-time safe.
double ObstacleDistance(const ObstacleSpec& obstacle, const Vec3& p_m, Vec3* normal);

/// Offset [m] of a pin from its rest place at sim time `t_s` (the formula of PinMotionSpec).
Vec3 PinOffset(const PinMotionSpec& motion, double t_s);

/// Time derivative [m/s] of PinOffset at `t_s`.
Vec3 PinVelocity(const PinMotionSpec& motion, double t_s);

/// Forgets the integrator's history (leapfrog's last acceleration, basic Verlet's previous
/// positions); the next StepFrame restarts it from state->x and state->v. Call it after editing
/// x or v by hand between frames. Real-time safe.
void ResetIntegratorHistory(ClothState* state);

}  // namespace felt
