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

/// One contact spring of the frame, resolved against the model.
struct CouplingSpring {
  std::array<int32_t, 3> particle = {0, 0, 0};  ///< the triangle's particles
  Vec3 barycentric = Vec3::Zero();              ///< of the contact point in the triangle
  Vec3 weight = Vec3::Zero();                   ///< force shares: barycentric, 0 where pinned
  Vec3 anchor_m = Vec3::Zero();                 ///< world, m
  Vec3 normal = Vec3::UnitZ();                  ///< unit, from the cloth toward the proxy
  double stiffness_N_per_m = 0.0;               ///< k_eff (after the stability bound)
  double max_force_N = 0.0;                     ///< force clamp, N
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
/// [s]: weights of pinned particles are zeroed, k is bounded by MaxCouplingStiffness
/// (state->counters. coupling_reduced_frames counts each frame once), entries with non-finite or
/// invalid fields are counted in invalid_external_forces, and entries past kMaxCouplingSprings in
/// coupling_overflows. Real-time safe.
void AddCouplingSpring(const ClothModel& model, const ExternalForce& e, double h_s,
                       ClothState* state);

/// Adds scale * the contact springs' forces at positions `x` [m, world, n entries] into `f`
/// (3 n packed doubles, xyz per particle): p = sum b_c x_c (barycentric b), depth = max(0, (p -
/// anchor) . normal), F = -normal min(max_force_N, k depth), particle c gets w_c F. Real-time safe.
void AddCouplingForces(const CouplingSprings& springs, std::span<const Vec3> x, double scale,
                       double* f);

}  // namespace felt
