// Contact springs of the haptic coupling, evaluated inside the cloth step (sim_loop/
// cloth_coupling.h; Colgate, Stanley & Brown 1995; Ruspini, Kolarov & Khatib 1997).

#include "sim_loop/cloth_coupling.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "sim_loop/cloth_internal.h"

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

// The largest weight of a contact spring on a free particle of its triangle; 0 if all pinned.
double MaxFreeWeight(const ClothModel& model, const ExternalForce& e) {
  const Triangle& t = model.triangles[e.triangle];
  double w_max = 0.0;
  for (int c = 0; c < 3; ++c) {
    if (model.inv_mass_per_kg[t[c]] > 0.0) w_max = std::max(w_max, e.barycentric[c]);
  }
  return w_max;
}

// True if `e` is a contact spring AddCouplingSpring accepts.
bool ValidSpring(const ClothModel& model, const ExternalForce& e) {
  const double n_len = e.normal.norm();
  return e.stiffness_N_per_m > 0.0 && e.triangle >= 0 &&
         e.triangle < static_cast<int32_t>(model.triangles.size()) && e.barycentric.allFinite() &&
         std::isfinite(e.stiffness_N_per_m) && e.anchor_m.allFinite() && e.normal.allFinite() &&
         n_len > 0.0 && e.max_force_N >= 0.0 && !std::isnan(e.max_force_N);
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
  // Resolve the triangle; pinned particles take no share.
  CouplingSpring& s = cs.springs[cs.count++];
  const Triangle& t = model.triangles[e.triangle];
  for (int c = 0; c < 3; ++c) {
    s.particle[c] = t[c];
    s.barycentric[c] = e.barycentric[c];
    s.weight[c] = model.inv_mass_per_kg[t[c]] > 0.0 ? e.barycentric[c] : 0.0;
  }
  const double w_max = MaxFreeWeight(model, e);
  s.anchor_m = e.anchor_m;
  s.normal = e.normal / e.normal.norm();
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
    // The contact point at these positions and how far it is still on the proxy's side.
    const Vec3 p = s.barycentric[0] * x[s.particle[0]] + s.barycentric[1] * x[s.particle[1]] +
                   s.barycentric[2] * x[s.particle[2]];
    const double depth = (p - s.anchor_m).dot(s.normal);
    if (!(depth > 0.0)) continue;
    // Unilateral: pushes the cloth away from the proxy, never pulls.
    const double magnitude = std::min(s.max_force_N, s.stiffness_N_per_m * depth);
    const Vec3 force = (-scale * magnitude) * s.normal;
    for (int c = 0; c < 3; ++c) {
      if (s.weight[c] == 0.0) continue;
      double* fc = f + 3 * static_cast<size_t>(s.particle[c]);
      fc[0] += s.weight[c] * force.x();
      fc[1] += s.weight[c] * force.y();
      fc[2] += s.weight[c] * force.z();
    }
  }
}

}  // namespace felt
