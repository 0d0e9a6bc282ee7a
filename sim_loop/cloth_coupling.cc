// Contact springs of the haptic coupling, evaluated inside the cloth step (sim_loop/
// cloth_coupling.h; Colgate, Stanley & Brown 1995; Ruspini, Kolarov & Khatib 1997).

#include "sim_loop/cloth_coupling.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "base/check.h"
#include "collision/geometry.h"
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
         std::isfinite(e.radius_m) && e.anchor_velocity_m_per_s.allFinite();
}

// Where a spring's sphere meets one candidate triangle at positions x: its nearest point to the
// goal (Ericson 2005 §5.1.5), the unit direction n from it toward the proxy's side, the distance
// and the signed distance (+ on the proxy's side).
struct FacePoint {
  Vec3 barycentric = Vec3::Zero();
  Vec3 n = Vec3::UnitZ();
  double distance_m = 0.0;
  double signed_m = 0.0;
  double sign = 1.0;  // d signed_m / d distance_m
};

FacePoint NearestOnFace(const CouplingSpring& s, const Triangle& t, std::span<const Vec3> x) {
  FacePoint out;
  const TrianglePoint tp = ClosestPointOnTriangle(s.goal_m, x[t[0]], x[t[1]], x[t[2]]);
  out.barycentric = tp.barycentric;
  const Vec3 d = s.goal_m - tp.point;
  out.distance_m = std::sqrt(tp.distance_sq);
  // The signed distance of the goal: positive on the proxy's side of the cloth, negative past it.
  // Known flaw: where the nearest point is level with the centre (past a sheet's open edge, over
  // a fold) the sign flips with |g - c| > 0, a jump of 2 k R |g - c| in the energy. The plain
  // (unsigned) distance was tried and reverted: a cloth that crosses the centre within a frame is
  // then pushed on through the proxy (felt compare on poke_hold: the interpolate reference hit the
  // 3.3 N clamp on 50 ticks, blend_forces and extrapolate lost about 40 % of their contact ticks).
  const double along = d.dot(s.normal);
  out.signed_m = along;
  out.n = s.normal;
  if (out.distance_m > 1e-12) {
    const bool past = along < 0.0;
    out.n = past ? Vec3(-d / out.distance_m) : Vec3(d / out.distance_m);
    out.signed_m = past ? -out.distance_m : out.distance_m;
    out.sign = past ? -1.0 : 1.0;
  }
  return out;
}

// Where a spring's sphere meets the cloth at positions x: per candidate its nearest point, the
// direction n toward the proxy's side and its share of the force (AddCouplingForces), and the
// penetration radius - smooth signed distance.
struct SpringContact {
  std::array<Vec3, kMaxCouplingCandidates> barycentric;
  std::array<Vec3, kMaxCouplingCandidates> n;
  std::array<double, kMaxCouplingCandidates> share;
  double pen_m = 0.0;
};

// True if candidate i's nearest point (barycentrics[i]) lies on an edge or corner of it that
// candidate j != i also contains, with j nearer, or as near and listed before i.
bool Dominated(const CouplingSpring& s,
               const std::array<Vec3, kMaxCouplingCandidates>& barycentrics,
               const std::array<double, kMaxCouplingCandidates>& distance, int32_t i) {
  // The particles of the feature the nearest point lies on (all three: the face's interior).
  std::array<int32_t, 3> feature{};
  int32_t size = 0;
  for (int k = 0; k < 3; ++k) {
    if (barycentrics[i][k] > 0.0) feature[size++] = s.candidates[i][k];
  }
  if (size == 3) return false;
  for (int32_t j = 0; j < s.num_candidates; ++j) {
    if (j == i || distance[j] > distance[i] || (distance[j] == distance[i] && j > i)) continue;
    const Triangle& t = s.candidates[j];
    bool contains = true;
    for (int32_t f = 0; f < size; ++f) {
      contains = contains && (t[0] == feature[f] || t[1] == feature[f] || t[2] == feature[f]);
    }
    if (contains) return true;
  }
  return false;
}

SpringContact Contact(const CouplingSpring& s, std::span<const Vec3> x) {
  SpringContact out;
  std::array<double, kMaxCouplingCandidates> distance, signed_m, sign;
  // The nearest point of every candidate; the nearest of all (the first of equal ones).
  int32_t nearest = 0;
  for (int32_t i = 0; i < s.num_candidates; ++i) {
    const FacePoint fp = NearestOnFace(s, s.candidates[i], x);
    out.barycentric[i] = fp.barycentric;
    out.n[i] = fp.n;
    distance[i] = fp.distance_m;
    signed_m[i] = fp.signed_m;
    sign[i] = fp.sign;
    if (fp.distance_m < distance[nearest]) nearest = i;
  }
  if (!(s.smoothing_m > 0.0)) {
    // The exact nearest point: all of the force on the nearest triangle.
    for (int32_t i = 0; i < s.num_candidates; ++i) out.share[i] = i == nearest ? 1.0 : 0.0;
    out.pen_m = s.radius_m - signed_m[nearest];
    return out;
  }
  // The smooth minimum sd = sum w_i sd_i, w_i ~ exp(-(d_i - d_min) / eps) (Boltzmann operator,
  // Asadi & Littman 2017) over the local minima of the distance on the cloth: it equals the
  // nearest triangle's sd unless another local minimum is within a few eps as near, and is
  // continuously differentiable where the nearest point moves across a crease from one face to
  // another, so the force (its gradient) does not jump there. Left out:
  //  - a triangle whose nearest point lies on an edge or corner it shares with a candidate that
  //    is nearer (that point is not a local minimum; the other triangle's point is) or as near
  //    and listed first (the same point twice). Blended, a flat sheet's neighbouring face pulled
  //    its shared edge toward the sphere (its share is negative where it is a few eps farther
  //    than the mean), and the force tilted near every edge (measured in TableSlideTest: the
  //    proxy then entered the cloth by up to 66 um). Leaving such a point out is a step of its
  //    own where a face's foot leaves that face while it is still within a few eps of the
  //    nearest: of the order of e^-(d - d_min) / eps, e^-9 in ClothCouplingTest's 20 deg valley
  //    and e^-11 around the curtain's pressed vertex, larger only for creases nearly flat;
  //  - triangles the goal is past while the nearest is not, or the reverse (a sheet's open edge,
  //    a fold): blended, sd would run from -d to +d within eps.
  const double inv_eps = 1.0 / s.smoothing_m;
  const double d_min = distance[nearest];
  const double side = sign[nearest];
  std::array<double, kMaxCouplingCandidates> w;
  double w_sum = 0.0;
  double sd_sum = 0.0;
  for (int32_t i = 0; i < s.num_candidates; ++i) {
    w[i] = 0.0;
    if (sign[i] != side || Dominated(s, out.barycentric, distance, i)) continue;
    w[i] = std::exp(-(distance[i] - d_min) * inv_eps);
    w_sum += w[i];
    sd_sum += w[i] * signed_m[i];
  }
  const double sd = sd_sum / w_sum;
  // d sd / d sd_i = w_i (1 - sign_i (sd_i - sd) / eps) / sum w: the triangles' shares (sum 1).
  for (int32_t i = 0; i < s.num_candidates; ++i) {
    out.share[i] = w[i] / w_sum * (1.0 - sign[i] * (signed_m[i] - sd) * inv_eps);
  }
  out.pen_m = s.radius_m - sd;
  return out;
}

// The spring's penetration at x without smoothing [m].
double ExactPenetration(const CouplingSpring& s, std::span<const Vec3> x) {
  CouplingSpring exact = s;
  exact.smoothing_m = 0.0;
  return Contact(exact, x).pen_m;
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
  return MaxCouplingStiffness(model, max_weight, 1.0 / (model.frame_rate_hz * model.substeps));
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
  AddCouplingSpring(model, e, h_s, state->x, &state->scratch->coupling, &state->counters);
}

void AddCouplingSpring(const ClothModel& model, const ExternalForce& e, double h_s,
                       std::span<const Vec3> x, CouplingSprings* springs,
                       ClothCounters* counters) {
  CouplingSprings& cs = *springs;
  if (!ValidSpring(model, e)) {
    ++counters->invalid_external_forces;
    return;
  }
  if (cs.count >= kMaxCouplingSprings) {
    ++counters->coupling_overflows;
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
  s.goal_start_m = s.goal_m;
  s.goal_velocity_m_per_s = e.anchor_velocity_m_per_s;
  s.max_force_N = e.max_force_N;
  // The crease smoothing, in proportion to the press at the frame's start (so that a light press's
  // force turns across a crease over a fixed fraction of its penetration) up to 20 um, fixed for
  // the frame so the force stays a potential's gradient within it. The cap: with 50 or 100 um
  // (0.1 of a 0.5-1 mm press) `felt bench haptic` gave fast_swipe 1 pop-through in mode
  // extrapolate (20 um: none, as before the smoothing). Not traced further: a fast swipe's cloth
  // changes with any change of the coupling, and a larger eps blends more distant local minima
  // (e.g. the two layers of a fold).
  s.smoothing_m = 0.0;
  if (s.num_candidates > 0) {
    s.smoothing_m = std::clamp(kCouplingSmoothingFraction * ExactPenetration(s, x),
                               kMinCouplingSmoothing_m, kMaxCouplingSmoothing_m);
  }
  // Bound k by what the integrator stays stable with at the substep (Colgate et al. 1995).
  const double k_max = MaxCouplingStiffness(model, w_max, h_s);
  s.stiffness_N_per_m = std::min(e.stiffness_N_per_m, k_max);
  if (e.stiffness_N_per_m > k_max && !cs.reduced_this_frame) {
    cs.reduced_this_frame = true;
    ++counters->coupling_reduced_frames;
  }
}

CouplingSphere CouplingSphereAt(const ClothModel& model, const CouplingSpring& s,
                                std::span<const Vec3> x) {
  CouplingSphere out;
  if (!(s.radius_m > 0.0)) return out;
  if (s.num_candidates <= 0) return out;
  // The exact nearest candidate (the first of equal ones, as Contact's): goal = c + signed n, so
  // the sphere resting on the cloth is at c + max(signed, r) n.
  FacePoint fp;
  int32_t nearest = -1;
  for (int32_t i = 0; i < s.num_candidates; ++i) {
    const FacePoint face = NearestOnFace(s, s.candidates[i], x);
    if (nearest < 0 || face.distance_m < fp.distance_m) {
      fp = face;
      nearest = i;
    }
  }
  const Triangle& t = s.candidates[nearest];
  out.centre_m = s.goal_m + std::max(0.0, s.radius_m - fp.signed_m) * fp.n;
  out.radius_m = s.radius_m;
  out.up = fp.n;
  int32_t corner = 0;
  fp.barycentric.maxCoeff(&corner);
  out.contact_col = t[corner] % model.width;
  out.contact_row = t[corner] / model.width;
  out.excluded_cells = GuardExcludedCells(model, s.radius_m);
  out.valid = out.centre_m.allFinite();
  return out;
}

int32_t GuardExcludedCells(const ClothModel& model, double radius_m) {
  const double cells = std::ceil(std::numbers::pi * radius_m / model.spacing_m);
  return 1 + static_cast<int32_t>(std::min(cells, 1e6));
}

SphereGuardResult ApplySphereGuards(const ClothModel& model, double h_s, ClothState* state) {
  SphereGuardResult out;
  const CouplingSprings& springs = state->scratch->coupling;
  std::array<int32_t, kMaxGuardCells> cells;
  const GuardRect all[1] = {{0, 0, model.width - 1, model.height - 1}};
  for (int32_t k = 0; k < springs.count; ++k) {
    const CouplingSphere sphere = CouplingSphereAt(model, springs.springs[k], state->x);
    if (!sphere.valid) continue;
    const int32_t count = GuardCellsNear(
        model, sphere, std::span<const GuardRect>(all),
        [&](int32_t p) -> const Vec3& { return state->x[p]; }, &cells, &out.dropped_cells);
    for (int32_t i = 0; i < count; ++i) {
      out.triangles += GuardSphereCell(
          model, sphere, cells[i], state->scratch->x_start, state->x, state->v,
          [&](int32_t p) { return model.inv_mass_per_kg[p] > 0.0; },
          [&](int32_t p) { SyncVerletHistory(model, p, h_s, state); });
    }
  }
  return out;
}

void AdvanceCouplingSprings(double t_s, CouplingSprings* springs) {
  for (int32_t k = 0; k < springs->count; ++k) {
    CouplingSpring& s = springs->springs[k];
    s.goal_m = s.goal_start_m + t_s * s.goal_velocity_m_per_s;
  }
}

namespace {

// Calls emit(particle, addend) for every addend of scale * the springs' forces at `x`, in the
// order AddCouplingForces adds them (AddCouplingForces' formula).
template <typename Emit>
void ForEachCouplingTerm(const CouplingSprings& springs, std::span<const Vec3> x, double scale,
                         Emit&& emit) {
  for (int32_t k = 0; k < springs.count; ++k) {
    const CouplingSpring& s = springs.springs[k];
    if (s.num_candidates <= 0) continue;
    const SpringContact c = Contact(s, x);
    if (!(c.pen_m > 0.0)) continue;
    // Unilateral: pushes the cloth away from the proxy, never pulls.
    const double magnitude = std::min(s.max_force_N, s.stiffness_N_per_m * c.pen_m);
    // Each candidate's share along its own direction, to its corners by barycentric weight.
    for (int32_t i = 0; i < s.num_candidates; ++i) {
      if (c.share[i] == 0.0) continue;
      const Vec3 force = (-scale * magnitude * c.share[i]) * c.n[i];
      const Triangle& t = s.candidates[i];
      for (int j = 0; j < 3; ++j) {
        const double w = s.free[i][j] * c.barycentric[i][j];
        if (w == 0.0) continue;
        emit(t[j], Vec3(w * force.x(), w * force.y(), w * force.z()));
      }
    }
  }
}

}  // namespace

void AddCouplingForces(const CouplingSprings& springs, std::span<const Vec3> x, double scale,
                       double* f) {
  ForEachCouplingTerm(springs, x, scale, [f](int32_t particle, const Vec3& addend) {
    double* fc = f + 3 * static_cast<size_t>(particle);
    fc[0] += addend.x();
    fc[1] += addend.y();
    fc[2] += addend.z();
  });
}

int32_t CouplingTermsByRow(const CouplingSprings& springs, std::span<const Vec3> x, double scale,
                           int32_t width, CouplingTermRows* out) {
  FELT_CHECK(width > 0);
  const int32_t rows = static_cast<int32_t>(out->row_start.size()) - 1;
  FELT_CHECK(rows >= 0);
  // Counting sort by row, stable: a particle's addends keep AddCouplingForces' order.
  int32_t count = 0;
  ForEachCouplingTerm(springs, x, scale, [&](int32_t particle, const Vec3& addend) {
    out->unsorted[static_cast<size_t>(count++)] = {particle, addend};
  });
  std::fill(out->row_start.begin(), out->row_start.end(), 0);
  for (int32_t k = 0; k < count; ++k) ++out->row_start[out->unsorted[k].particle / width + 1];
  for (int32_t r = 0; r < rows; ++r) out->row_start[r + 1] += out->row_start[r];
  std::copy(out->row_start.begin(), out->row_start.end() - 1, out->cursor.begin());
  for (int32_t k = 0; k < count; ++k) {
    const CouplingTerm& t = out->unsorted[static_cast<size_t>(k)];
    out->sorted[static_cast<size_t>(out->cursor[t.particle / width]++)] = t;
  }
  return count;
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
