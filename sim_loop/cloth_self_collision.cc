// The cloth step's self-collision hook (issue 22): the response of collision/self_response.h on
// the motion of a frame (or of every few substeps), and the opt-in exact intersection count at
// the end of a frame.

#include <algorithm>
#include <chrono>
#include <cmath>

#include "collision/self_intersection.h"
#include "sim_loop/cloth.h"
#include "sim_loop/cloth_internal.h"

namespace felt {

void ApplySelfCollision(double h_s, SelfCollisionResponse* self, ClothState* state,
                        FrameResult* result) {
  const auto start = std::chrono::steady_clock::now();
  const SelfCollisionStats st = self->Resolve(h_s, state->x, state->v);
  result->self_collision_s +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ClothCounters& c = state->counters;
  const int64_t impulses = st.proximity_impulses + st.ccd_impulses;
  c.self_proximity_pairs += static_cast<uint64_t>(st.proximity_pairs);
  c.self_impulses += static_cast<uint64_t>(impulses);
  c.self_ccd_hits += static_cast<uint64_t>(st.ccd_hits);
  c.self_impact_zones += static_cast<uint64_t>(st.impact_zones);
  c.self_frozen_substeps += st.frozen ? 1 : 0;
  c.self_unresolved_substeps += st.unresolved > 0 ? 1 : 0;
  c.self_overflows += static_cast<uint64_t>(st.overflows);
  result->self_proximity_pairs += st.proximity_pairs;
  result->self_impulses += impulses;
  result->self_ccd_hits += st.ccd_hits;
  result->self_impact_zones += st.impact_zones;
  result->self_unresolved += st.unresolved;
}

namespace {
// The longest pass a quiet frame may take: ceil(substeps / min_passes_per_frame), at least 1.
int32_t SelfQuietPassLength(const SelfCollisionSettings& settings, int32_t substeps) {
  const int32_t fewest = std::max(1, settings.min_passes_per_frame);
  return std::max(1, (substeps + fewest - 1) / fewest);
}
}  // namespace

int32_t SelfPassSubsteps(const ClothModel& model, const SelfCollisionResponse& self,
                         int32_t substeps, std::span<const Vec3> v, double h_s, bool quiet) {
  if (model.integrator == IntegratorKind::kBasicVerlet) return 1;
  const SelfCollisionSettings& settings = self.settings();
  const int32_t passes = std::max(1, settings.passes_per_frame);
  int32_t every = std::max(1, (substeps + passes - 1) / passes);
  if (v.empty() || !(h_s > 0.0)) return every;  // no speeds: the count alone
  const bool lengthen =
      quiet && settings.slow_pass_motion > 0.0 && settings.min_passes_per_frame < passes;
  if (!lengthen && !(settings.max_pass_motion > 0.0)) return every;
  double v2 = 0.0;
  for (const Vec3& vi : v) v2 = std::max(v2, vi.squaredNorm());
  const double speed = std::sqrt(v2);
  if (lengthen) {
    // Slow frame: the fastest particle, with gravity's gain over the whole frame, moves at most
    // slow_pass_motion thicknesses in a pass of up to ceil(substeps / min_passes_per_frame).
    const double gain = model.gravity_m_per_s2.norm() * h_s * substeps;
    const double step_m = (speed + gain) * h_s;
    const int32_t longest = SelfQuietPassLength(settings, substeps);
    const double fit = step_m > 0.0 ? settings.slow_pass_motion * settings.thickness_m / step_m
                                    : static_cast<double>(longest);
    every = std::max(every, static_cast<int32_t>(std::min<double>(longest, fit)));
  }
  if (settings.max_pass_motion > 0.0) {
    // The pass's motion in thicknesses at the fastest particle's speed.
    const double step_m = speed * h_s;
    if (step_m > 0.0) {
      const double cap = settings.max_pass_motion * settings.thickness_m / step_m;
      if (cap < every) every = std::max(1, static_cast<int32_t>(cap));
    }
  }
  return every;
}

int32_t SelfPassLongest(const ClothModel& model, const SelfCollisionResponse& self,
                        int32_t substeps, int32_t planned) {
  const SelfCollisionSettings& settings = self.settings();
  if (model.integrator == IntegratorKind::kBasicVerlet || !(settings.hand_pass_motion > 0.0) ||
      settings.min_passes_per_frame >= settings.passes_per_frame) {
    return planned;
  }
  return std::max(planned, SelfQuietPassLength(settings, substeps));
}

bool SelfPassMayGoOn(const SelfCollisionResponse& self, std::span<const Vec3> x,
                     std::span<const Vec3> v, double h_s) {
  const SelfCollisionSettings& settings = self.settings();
  const std::span<const Vec3> x0 = self.x_before();
  // The pass's budget in thicknesses: hand_pass_motion, max_pass_motion's when that cap is set.
  double budget = settings.hand_pass_motion;
  if (settings.max_pass_motion > 0.0) budget = std::min(budget, settings.max_pass_motion);
  if (!(budget > 0.0) || x0.size() != x.size() || v.size() != x.size()) return false;
  double d2 = 0.0;     // the farthest any particle has moved since the pass began [m^2]
  double v2 = 0.0;     // the fastest particle now [m^2/s^2]
  double probe = 0.0;  // 0 unless a value is NaN or infinite (std::max drops a NaN)
  for (size_t i = 0; i < x.size(); ++i) {
    const double di = (x[i] - x0[i]).squaredNorm();
    const double vi = v[i].squaredNorm();
    d2 = std::max(d2, di);
    v2 = std::max(v2, vi);
    probe += (di + vi) * 0.0;
  }
  if (probe != 0.0) return false;
  // One more substep at the fastest particle's present speed must stay within the budget.
  const double moved_m = std::sqrt(d2) + std::sqrt(v2) * h_s;
  return moved_m <= budget * settings.thickness_m;  // NaN: false
}

void CountFrameIntersections(const ClothModel& model, ClothState* state, FrameResult* result) {
  const int64_t count = CountSelfIntersections(state->x, model.triangles);
  result->self_intersections = count;
  state->counters.self_intersections_max = std::max(state->counters.self_intersections_max, count);
}

}  // namespace felt
