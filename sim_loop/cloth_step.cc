// StepFrame: one 60 Hz frame of the cloth, cut into substeps.

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include "sim_loop/cloth.h"
#include "sim_loop/cloth_internal.h"

namespace felt {
namespace {

// Spreads the frame's point forces over their triangles' particles by barycentric weight.
void GatherExternalForces(const ClothModel& model, std::span<const ExternalForce> external,
                          double h_s, ClothState* state) {
  std::vector<Vec3>& out = state->scratch->external_N;
  std::fill(out.begin(), out.end(), Vec3::Zero());
  BeginCouplingFrame(&state->scratch->coupling);
  const int32_t num_triangles = static_cast<int32_t>(model.triangles.size());
  for (const ExternalForce& e : external) {
    if (e.triangle < 0 || e.triangle >= num_triangles || !e.force_N.allFinite() ||
        !e.barycentric.allFinite()) {
      ++state->counters.invalid_external_forces;
      continue;
    }
    // Contact springs are evaluated at every force evaluation (sim_loop/cloth_coupling.h).
    if (e.stiffness_N_per_m > 0.0) {
      AddCouplingSpring(model, e, h_s, state);
      continue;
    }
    const Triangle& t = model.triangles[e.triangle];
    for (int c = 0; c < 3; ++c) out[t[c]] += e.barycentric[c] * e.force_N;
  }
}

// True if every position and velocity is finite (x * 0 is 0 unless x is inf or NaN).
bool AllFinite(const ClothState& state) {
  double probe = 0.0;
  for (size_t p = 0; p < state.x.size(); ++p) {
    probe += (state.x[p] * 0.0).sum() + (state.v[p] * 0.0).sum();
  }
  return probe == 0.0;
}

}  // namespace

FrameResult StepFrame(const ClothModel& model, std::span<const ExternalForce> external,
                      double frame_dt_s, ClothState* state) {
  FrameResult result;
  if (!(frame_dt_s > 0.0)) return result;
  ClothState::Scratch& s = *state->scratch;

  // Clamp a late frame, then cut it into substeps no longer than the nominal one.
  double dt = frame_dt_s;
  if (dt > model.max_frame_dt_s) {
    dt = model.max_frame_dt_s;
    result.clamped = true;
    ++state->counters.clamped_frames;
  }
  const double h_nominal = 1.0 / (model.frame_rate_hz * model.substeps);
  const int32_t plain = std::max(1, static_cast<int32_t>(std::ceil(dt / h_nominal - 1e-9)));
  // A held contact spring too stiff for this substep gets shorter substeps (up to a bound).
  const int32_t substeps = CouplingSubsteps(model, external, dt, plain);
  if (substeps > plain) ++state->counters.coupling_substepped_frames;
  const double h = dt / substeps;
  result.substeps = substeps;
  result.dt_s = dt;

  GatherExternalForces(model, external, h, state);
  const bool obstacles = !model.obstacles.empty();
  const bool provot = model.provot_enabled && !model.provot_families.empty();
  const double t0 = state->time_s;
  SelfCollisionResponse* self = s.self_collision ? &*s.self_collision : nullptr;
  // The proxy's sphere guard runs while a hand's contact spring acts (sim_loop/cloth_coupling.h).
  const bool guard = self != nullptr && model.self_collision_guard_proxy && s.coupling.count > 0;
  // Self-collision passes cover several substeps (a few per frame; Bridson et al. 2002's
  // collision step): self_h is the time since the pass's BeginStep. After a frame without
  // contact, fewer, longer passes: planned from the frame-start speeds when no hand acts; with a
  // hand (its pull is not in the speeds) a pass goes on past the count's length, substep by
  // substep, while its measured motion allows (SelfPassMayGoOn), up to self_longest.
  const bool hand = !external.empty();
  const int32_t self_every =
      self ? SelfPassSubsteps(model, *self, substeps, state->v, h, s.self_quiet && !hand) : 1;
  const int32_t self_longest = self && s.self_quiet && hand
                                   ? SelfPassLongest(model, *self, substeps, self_every)
                                   : self_every;
  double self_h = 0.0;
  int32_t self_in_pass = 0;  // substeps since the pass's BeginStep
  for (int32_t k = 0; k < substeps; ++k) {
    if (self && self_h == 0.0) self->BeginStep(state->x);  // the pass's start positions
    // Integrate, then constrain: Provot (000 slide 9), obstacles, pins at the substep's end time.
    // The substep's start positions: the obstacles' sweeps and the sphere guard's sides.
    if (obstacles || guard) std::copy(state->x.begin(), state->x.end(), s.x_start.begin());
    if (k > 0) AdvanceCouplingSprings(k * h, &s.coupling);  // predicted hands (zero: held)
    if (!IntegrateSubstep(model, h, state)) ++state->counters.cg_not_converged;
    if (provot) ApplyProvot(model, h, state);
    if (obstacles) ApplyObstacles(model, h, state);
    // The proxy's sphere keeps the cloth's other layers out (issue 22; sim_loop/cloth_coupling.h).
    if (guard) {
      const SphereGuardResult g = ApplySphereGuards(model, h, state);
      state->counters.guard_pushes += static_cast<uint64_t>(g.triangles);
      state->counters.guard_dropped_cells += static_cast<uint64_t>(g.dropped_cells);
    }
    ApplyPins(model, t0 + (k + 1) * h, state);
    // Self-collision (issue 22) on the pass's whole motion x_before -> x, after every other
    // constraint (collision/self_response.h; sim_loop/cloth_self_collision.cc).
    if (self) {
      self_h += h;
      ++self_in_pass;
      bool end = k + 1 == substeps;
      if (!end && self_in_pass >= self_every) {
        end = self_in_pass >= self_longest || !SelfPassMayGoOn(*self, state->x, state->v, h);
      }
      if (end) {
        ApplySelfCollision(self_h, self, state, &result);
        self_h = 0.0;
        self_in_pass = 0;
      }
    }
  }
  state->time_s = t0 + dt;
  if (self) s.self_quiet = result.self_proximity_pairs == 0 && result.self_ccd_hits == 0;

  // Non-finite values never stay: restore the last good frame (MuJoCo-style count and warn once).
  if (AllFinite(*state)) {
    std::copy(state->x.begin(), state->x.end(), s.good_x.begin());
    std::copy(state->v.begin(), state->v.end(), s.good_v.begin());
    s.good_time_s = state->time_s;
  } else {
    ++state->counters.nan_events;
    if (!s.nan_logged) {
      s.nan_logged = true;
      spdlog::warn(
          "cloth: non-finite positions or velocities at t = {:.4f} s; restored the last "
          "good state (t = {:.4f} s); further events are only counted",
          state->time_s, s.good_time_s);
    }
    std::copy(s.good_x.begin(), s.good_x.end(), state->x.begin());
    std::copy(s.good_v.begin(), s.good_v.end(), state->v.begin());
    state->time_s = s.good_time_s;
    s.history_valid = false;
    s.self_quiet = false;
    result.recovered = true;
  }
  if (self && model.self_collision_count_intersections) {
    CountFrameIntersections(model, state, &result);
  }
  ComputeVertexNormals(state->x, model.triangles, state->normals);
  ++state->counters.frames;
  return result;
}

}  // namespace felt
