#pragma once
// Virtual coupling of a haptic contact inside the cloth step (issue 4, two-way coupling): a
// unilateral spring from a point of the cloth to the user's hand, evaluated at every force
// evaluation of the integrator (every substep and stage) instead of a force sampled at 60 Hz and
// held for the frame. Colgate, Stanley & Brown 1995 (virtual coupling: the coupling spring is
// what the simulation must integrate stably) applied to the god-object contact of Ruspini,
// Kolarov & Khatib 1997. Not for use outside sim_loop/cloth_*.cc.

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "sim_loop/cloth.h"

namespace felt {

/// Contact springs one StepFrame can hold; further ones are counted (ClothCounters::
/// coupling_overflows) and dropped.
inline constexpr int32_t kMaxCouplingSprings = 16;

/// Triangles a contact spring searches for the cloth's nearest point: those of the 3 x 3 grid
/// cells around the contact triangle's cell (every triangle that shares a vertex with it).
inline constexpr int32_t kMaxCouplingCandidates = 18;

/// The crease smoothing of a contact spring (CouplingSpring::smoothing_m) is this fraction of the
/// spring's penetration at the start of its frame, within [kMinCouplingSmoothing_m,
/// kMaxCouplingSmoothing_m].
inline constexpr double kCouplingSmoothingFraction = 0.1;
/// The smallest crease smoothing, m.
inline constexpr double kMinCouplingSmoothing_m = 1e-6;
/// The largest crease smoothing, m.
inline constexpr double kMaxCouplingSmoothing_m = 20e-6;

/// One contact spring of the frame, resolved against the model: the proxy sphere (centre goal_m,
/// radius_m) pressing on the nearest point of its candidate triangles (ExternalForce), that
/// nearest point smoothed across the mesh's creases over smoothing_m (AddCouplingForces).
struct CouplingSpring {
  std::array<Triangle, kMaxCouplingCandidates> candidates{};  ///< particles of each candidate
  std::array<Vec3, kMaxCouplingCandidates> free{};  ///< per corner: 1 if free, 0 if pinned
  int32_t num_candidates = 0;
  Vec3 goal_m = Vec3::Zero();      ///< sphere centre (the user's hand), world, m
  double radius_m = 0.0;           ///< sphere radius, m
  Vec3 normal = Vec3::UnitZ();     ///< unit, from the cloth toward the proxy's side
  double stiffness_N_per_m = 0.0;  ///< k_eff (after the stability bound)
  double max_force_N = 0.0;        ///< force clamp, N
  double smoothing_m = 0.0;        ///< crease smoothing epsilon, m (0: the exact nearest point)
  Vec3 goal_start_m = Vec3::Zero();         ///< goal_m at the frame's start, m
  Vec3 goal_velocity_m_per_s = Vec3::Zero();  ///< the goal's predicted velocity, m/s
};

/// The frame's contact springs: storage of kMaxCouplingSprings, count in use.
struct CouplingSprings {
  std::array<CouplingSpring, kMaxCouplingSprings> springs;
  int32_t count = 0;
  bool reduced_this_frame = false;  ///< some spring's k was lowered to k_eff this frame
};

/// A frame with a contact spring stiffer than its substep allows is cut into up to this many times
/// the nominal substeps (CouplingSubsteps); beyond that, k is lowered to the bound.
inline constexpr int32_t kMaxCouplingSubstepFactor = 4;

/// The largest coupling stiffness [N/m] the model's integrator integrates stably at substep h_s
/// [s] for a spring
/// whose largest weight on a free particle is `max_weight`: omega_c^2 = k w^2 / m <= (0.8
/// omega_stable(h))^2, with omega_stable(h) = omega_max * stable_dt_s / h (the integrator's
/// critical omega h, damping included); for implicit Euler (stable_dt_s infinite: its springs are
/// implicit) k w^2 / m <= (0.8 * 2 / h)^2, symplectic Euler's limit for the explicit contact
/// spring. +infinity for max_weight <= 0. Real-time safe.
double MaxCouplingStiffness(const ClothModel& model, double max_weight, double h_s);

/// MaxCouplingStiffness at the nominal substep h = 1 / (frame_rate_hz * substeps).
double MaxCouplingStiffness(const ClothModel& model, double max_weight);

/// Substeps for a frame of dt_s [s] normally cut into `substeps`: raised, to at most
/// kMaxCouplingSubstepFactor times `substeps`, until every valid contact spring of `external` has
/// k <= MaxCouplingStiffness at h = dt_s / result, so the hand's stiffness reaches the cloth
/// unreduced (Colgate, Stanley & Brown 1995: the coupling must be stable at the simulation's
/// step). Real-time safe.
int32_t CouplingSubsteps(const ClothModel& model, std::span<const ExternalForce> external,
                         double dt_s, int32_t substeps);

/// Forgets the previous frame's springs. Real-time safe.
void BeginCouplingFrame(CouplingSprings* springs);

/// Adds `e` (stiffness_N_per_m > 0, triangle in range) as a contact spring for substeps of h_s
/// [s], with its crease smoothing set from its penetration at state->x (the frame's start):
/// kCouplingSmoothingFraction * penetration clamped to [kMinCouplingSmoothing_m,
/// kMaxCouplingSmoothing_m], constant over the frame. Weights of pinned particles are zeroed, k is
/// bounded by MaxCouplingStiffness (state->counters. coupling_reduced_frames counts each frame
/// once), entries with non-finite or invalid fields are counted in invalid_external_forces, and
/// entries past kMaxCouplingSprings in coupling_overflows. Real-time safe.
void AddCouplingSpring(const ClothModel& model, const ExternalForce& e, double h_s,
                       ClothState* state);

/// AddCouplingSpring on explicit parts: positions `x` [m, world, n entries; only the candidates'
/// corners are read], the springs to add to and the counters to count in (the local patch of the
/// haptic loop, sim_loop/cloth_patch.h, keeps its own). Real-time safe.
void AddCouplingSpring(const ClothModel& model, const ExternalForce& e, double h_s,
                       std::span<const Vec3> x, CouplingSprings* springs, ClothCounters* counters);

/// Moves every spring's goal to where its predicted hand is `t_s` [s] after the frame's start:
/// goal = goal_start + t_s goal_velocity (ExternalForce::anchor_velocity_m_per_s). Real-time safe.
void AdvanceCouplingSprings(double t_s, CouplingSprings* springs);

/// Adds scale * the contact springs' forces at positions `x` [m, world, n entries] into `f`
/// (3 n packed doubles, xyz per particle). Per spring and candidate triangle i: its nearest point
/// c_i to the goal g (barycentrics b_i), d_i = |g - c_i|, sd_i = d_i signed by the side of
/// `normal`, n_i the unit direction from c_i toward the proxy's side (`normal` where g lies on the
/// cloth). The signed distance is their smooth minimum sd = sum w_i sd_i, w_i proportional to
/// exp(-(d_i - min d) / smoothing_m) (the Boltzmann operator, Asadi & Littman 2017) over the
/// local minima of the distance: w_i = 0 for a triangle on the other side of the goal than the
/// nearest one, or whose nearest point lies on an edge or corner it shares with a nearer
/// candidate (or an as near one listed first). With smoothing_m = 0: the first nearest
/// triangle's sd_i. pen = radius - sd. If pen > 0, triangle i gets F_i = -min(max_force_N,
/// k pen) s_i n_i with s_i = w_i (1 - sign_i (sd_i - sd) / smoothing_m) (the chain rule of sd;
/// sum s_i = 1), its corner j free_j b_ij F_i. The smooth minimum keeps the force continuous
/// where the nearest point moves from one face to another across a crease (around a pressed
/// vertex), which the explicit integrators need to keep energy (Hairer, Lubich & Wanner 2006,
/// Geometric Numerical Integration, ch. IX, assumes smooth forces). The force is minus the
/// gradient of CouplingEnergy. Real-time safe.
void AddCouplingForces(const CouplingSprings& springs, std::span<const Vec3> x, double scale,
                       double* f);

/// One addend of the contact springs' force on a particle (AddCouplingForces adds them in order).
struct CouplingTerm {
  int32_t particle = 0;
  Vec3 value = Vec3::Zero();  ///< scale * force share, same units as AddCouplingForces' f
};

/// The most addends one frame's springs produce: 3 corners of every candidate of every spring.
inline constexpr int32_t kMaxCouplingTerms = kMaxCouplingSprings * kMaxCouplingCandidates * 3;

/// AddCouplingForces' addends grouped by grid row (preallocated; see CouplingTermsByRow).
struct CouplingTermRows {
  std::vector<CouplingTerm> unsorted;  ///< [kMaxCouplingTerms] in AddCouplingForces' order
  std::vector<CouplingTerm> sorted;    ///< [kMaxCouplingTerms] by row, that order within a row
  std::vector<int32_t> row_start;      ///< [rows + 1] row r's addends: sorted[row_start[r], [r+1])
  std::vector<int32_t> cursor;         ///< [rows] work space of the sort
};

/// The addends AddCouplingForces would add to f (scale * the springs' forces at `x`), sorted by
/// the grid row (particle / width) of their particle, stably, so that adding each row's in order
/// gives AddCouplingForces' bits. `out` must be sized for the grid's rows. Returns their count.
/// Real-time safe.
int32_t CouplingTermsByRow(const CouplingSprings& springs, std::span<const Vec3> x, double scale,
                           int32_t width, CouplingTermRows* out);

/// The springs' potential energy at `x` [J], pen as in AddCouplingForces: per spring 1/2 k pen^2
/// while k pen <= max_force_N, then max_force_N (pen - max_force_N / (2 k)) (the clamp's linear
/// continuation), 0 for pen <= 0.
/// Its gradient with respect to the free particles' positions is minus AddCouplingForces' forces
/// (with scale 1). For tests and energy bookkeeping. Real-time safe.
double CouplingEnergy(const CouplingSprings& springs, std::span<const Vec3> x);

}  // namespace felt
