// Contact springs of the haptic coupling, evaluated inside the cloth step (sim_loop/
// cloth_coupling.h; Colgate, Stanley & Brown 1995; Ruspini, Kolarov & Khatib 1997).

#include "sim_loop/cloth_coupling.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "sim_loop/cloth_internal.h"
#include "sim_loop/geometry.h"

namespace felt {
namespace {

// Fraction of the integrator's stable omega h the coupling spring may use.
constexpr double kCouplingSafety = 0.8;
// Critical omega h of symplectic Euler (x += h v_new), the explicit spring in implicit Euler.
constexpr double kSymplecticEulerLimit = 2.0;

// The integrator's critical omega h, from its stability limit for the stiffest pair. Implicit
// Euler (stable_dt_s infinite) integrates the cloth's springs implicitly: only the explicit
// contact spring is bounded, by symplectic Euler's limit.
double CriticalOmegaH(const ClothModel& model) {
  if (std::isfinite(model.stable_dt_s) && model.stable_dt_s > 0.0 &&
      model.omega_max_rad_per_s > 0.0) {
    return model.omega_max_rad_per_s * model.stable_dt_s;
  }
  return kSymplecticEulerLimit;
}

// Calls visit(triangle) for each triangle a spring on `triangle` searches: those of the 3 x 3 grid
// cells around its cell (two per cell, MakeGridTriangles' order), every triangle sharing a vertex
// with it. At most kMaxCouplingCandidates.
template <typename Visit>
void ForEachCandidate(const ClothModel& model, int32_t triangle, Visit&& visit) {
  const int32_t cells_per_row = model.width - 1;
  const int32_t cell = triangle / 2;
  const int32_t row = cell / cells_per_row, col = cell % cells_per_row;
  for (int32_t r = std::max(0, row - 1); r <= std::min(model.height - 2, row + 1); ++r) {
    for (int32_t c = std::max(0, col - 1); c <= std::min(cells_per_row - 1, col + 1); ++c) {
      visit(model.triangles[2 * (r * cells_per_row + c)]);
      visit(model.triangles[2 * (r * cells_per_row + c) + 1]);
    }
  }
}

// The largest weight a contact spring may put on one free particle: the nearest point it presses
// on can be a vertex, so 1 unless every particle of its candidates is pinned (then 0).
double MaxFreeWeight(const ClothModel& model, const ExternalForce& e) {
  bool any_free = false;
  ForEachCandidate(model, e.triangle, [&](const Triangle& t) {
    for (int32_t p : t) any_free = any_free || model.inv_mass_per_kg[p] > 0.0;
  });
  return any_free ? 1.0 : 0.0;
}

// True if `e` is a contact spring AddCouplingSpring accepts.
bool ValidSpring(const ClothModel& model, const ExternalForce& e) {
  const double n_len = e.normal.norm();
  return e.stiffness_N_per_m > 0.0 && e.triangle >= 0 &&
         e.triangle < static_cast<int32_t>(model.triangles.size()) && e.barycentric.allFinite() &&
         std::isfinite(e.stiffness_N_per_m) && e.anchor_m.allFinite() && e.normal.allFinite() &&
         n_len > 0.0 && e.max_force_N >= 0.0 && !std::isnan(e.max_force_N) && e.radius_m >= 0.0 &&
         std::isfinite(e.radius_m);
}

// Where a spring's sphere meets the cloth at positions x: the nearest point of its candidates to
// the goal, the unit direction n from that point toward the proxy's side, and the penetration
// radius - signed distance (Ericson 2005 §5.1.5 for the nearest point of each triangle).
struct SpringContact {
  int32_t candidate = 0;
  Vec3 barycentric = Vec3::Zero();
  Vec3 n = Vec3::UnitZ();
  double pen_m = 0.0;
};

SpringContact Contact(const CouplingSpring& s, std::span<const Vec3> x) {
  SpringContact out;
  TrianglePoint best;
  best.distance_sq = std::numeric_limits<double>::infinity();
  for (int32_t i = 0; i < s.num_candidates; ++i) {
    const Triangle& t = s.candidates[i];
    const TrianglePoint tp = ClosestPointOnTriangle(s.goal_m, x[t[0]], x[t[1]], x[t[2]]);
    if (tp.distance_sq < best.distance_sq) {
      best = tp;
      out.candidate = i;
    }
  }
  out.barycentric = best.barycentric;
  const Vec3 d = s.goal_m - best.point;
  const double dist = std::sqrt(best.distance_sq);
  // The signed distance of the goal: positive on the proxy's side of the cloth, negative past it.
  // Known flaw: where the nearest point is level with the centre (past a sheet's open edge, over
  // a fold) the sign flips with |g - c| > 0, a jump of 2 k R |g - c| in the energy. The plain
  // (unsigned) distance was tried and reverted: a cloth that crosses the centre within a frame is
  // then pushed on through the proxy (felt compare on poke_hold: the interpolate reference hit the
  // 3.3 N clamp on 50 ticks, blend_forces and extrapolate lost about 40 % of their contact ticks).
  const double along = d.dot(s.normal);
  double sd = along;
  out.n = s.normal;
  if (dist > 1e-12) {
    const bool past = along < 0.0;
    out.n = past ? Vec3(-d / dist) : Vec3(d / dist);
    sd = past ? -dist : dist;
  }
  out.pen_m = s.radius_m - sd;
  return out;
}

}  // namespace

double MaxCouplingStiffness(const ClothModel& model, double max_weight, double h_s) {
  if (!(max_weight > 0.0)) return std::numeric_limits<double>::infinity();
  // omega_c^2 = k w^2 / m <= (0.8 omega_stable)^2. The cloth's own springs are not subtracted
  // (their Gershgorin bound is loose; subtracting it left the default curtain a third of k).
  const double omega = kCouplingSafety * CriticalOmegaH(model) / h_s;
  return omega * omega * model.particle_mass_kg / (max_weight * max_weight);
}

double MaxCouplingStiffness(const ClothModel& model, double max_weight) {
  const IntegrationSpec& is = model.spec.integration;
  return MaxCouplingStiffness(model, max_weight, 1.0 / (is.frame_rate_hz * model.substeps));
}

int32_t CouplingSubsteps(const ClothModel& model, std::span<const ExternalForce> external,
                         double dt_s, int32_t substeps) {
  const int32_t cap = kMaxCouplingSubstepFactor * substeps;
  int32_t out = substeps;
  for (const ExternalForce& e : external) {
    if (!ValidSpring(model, e)) continue;
    const double w = MaxFreeWeight(model, e);
    if (!(w > 0.0)) continue;
    // k w^2 / m <= (0.8 critical / h)^2  <=>  h <= 0.8 critical sqrt(m / (k w^2)).
    const double h_max = kCouplingSafety * CriticalOmegaH(model) *
                         std::sqrt(model.particle_mass_kg / (e.stiffness_N_per_m * w * w));
    const double needed = std::ceil(dt_s / h_max - 1e-9);
    if (!(needed > out)) continue;
    out = needed >= cap ? cap : static_cast<int32_t>(needed);
  }
  return out;
}

void BeginCouplingFrame(CouplingSprings* springs) {
  springs->count = 0;
  springs->reduced_this_frame = false;
}

void AddCouplingSpring(const ClothModel& model, const ExternalForce& e, double h_s,
                       ClothState* state) {
  CouplingSprings& cs = state->scratch->coupling;
  if (!ValidSpring(model, e)) {
    ++state->counters.invalid_external_forces;
    return;
  }
  if (cs.count >= kMaxCouplingSprings) {
    ++state->counters.coupling_overflows;
    return;
  }
  // The candidates (ForEachCandidate); pinned particles take no share.
  CouplingSpring& s = cs.springs[cs.count++];
  s.num_candidates = 0;
  bool any_free = false;
  ForEachCandidate(model, e.triangle, [&](const Triangle& t) {
    s.candidates[s.num_candidates] = t;
    for (int k = 0; k < 3; ++k) {
      const bool free = model.inv_mass_per_kg[t[k]] > 0.0;
      s.free[s.num_candidates][k] = free ? 1.0 : 0.0;
      any_free = any_free || free;
    }
    ++s.num_candidates;
  });
  const double w_max = any_free ? 1.0 : 0.0;  // MaxFreeWeight, from the flags just made
  s.normal = e.normal / e.normal.norm();
  s.radius_m = e.radius_m;
  s.goal_m = e.anchor_m + e.radius_m * s.normal;
  s.max_force_N = e.max_force_N;
  // Bound k by what the integrator stays stable with at the substep (Colgate et al. 1995).
  const double k_max = MaxCouplingStiffness(model, w_max, h_s);
  s.stiffness_N_per_m = std::min(e.stiffness_N_per_m, k_max);
  if (e.stiffness_N_per_m > k_max && !cs.reduced_this_frame) {
    cs.reduced_this_frame = true;
    ++state->counters.coupling_reduced_frames;
  }
}

void AddCouplingForces(const CouplingSprings& springs, std::span<const Vec3> x, double scale,
                       double* f) {
  for (int32_t k = 0; k < springs.count; ++k) {
    const CouplingSpring& s = springs.springs[k];
    if (s.num_candidates <= 0) continue;
    const SpringContact c = Contact(s, x);
    if (!(c.pen_m > 0.0)) continue;
    // Unilateral: pushes the cloth away from the proxy, never pulls.
    const double magnitude = std::min(s.max_force_N, s.stiffness_N_per_m * c.pen_m);
    const Vec3 force = (-scale * magnitude) * c.n;
    const Triangle& t = s.candidates[c.candidate];
    for (int i = 0; i < 3; ++i) {
      const double w = s.free[c.candidate][i] * c.barycentric[i];
      if (w == 0.0) continue;
      double* fc = f + 3 * static_cast<size_t>(t[i]);
      fc[0] += w * force.x();
      fc[1] += w * force.y();
      fc[2] += w * force.z();
    }
  }
}

double CouplingEnergy(const CouplingSprings& springs, std::span<const Vec3> x) {
  double energy = 0.0;
  for (int32_t k = 0; k < springs.count; ++k) {
    const CouplingSpring& s = springs.springs[k];
    if (s.num_candidates <= 0 || !(s.stiffness_N_per_m > 0.0)) continue;
    const double pen = Contact(s, x).pen_m;
    if (!(pen > 0.0)) continue;
    const double pen_clamp = s.max_force_N / s.stiffness_N_per_m;  // where k pen reaches the clamp
    energy += pen <= pen_clamp ? 0.5 * s.stiffness_N_per_m * pen * pen
                               : s.max_force_N * (pen - 0.5 * pen_clamp);
  }
  return energy;
}

}  // namespace felt
