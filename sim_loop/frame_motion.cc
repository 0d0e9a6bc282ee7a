// Frame-motion velocities for the haptic snapshots (sim_loop/frame_motion.h).

#include "sim_loop/frame_motion.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>

namespace felt {

RepairStats FillSnapshotWithFrameMotion(const ClothState& state, std::span<const Vec3> x_start_m,
                                        double frame_dt_s, uint64_t frame,
                                        std::span<Vec3> v_scratch, ClothSnapshot* snapshot) {
  const size_t n = state.x.size();
  if (x_start_m.size() != n || v_scratch.size() != n) {
    std::fprintf(stderr, "FillSnapshotWithFrameMotion: span sizes differ from the cloth's\n");
    std::abort();
  }
  // Mean velocity over the frame: the published cloth's own motion.
  // The largest displacement too (MaxDisplacement's arithmetic), so the haptic thread need not
  // pass over the whole cloth when the snapshot arrives.
  const double inv_dt = frame_dt_s > 0.0 ? 1.0 / frame_dt_s : 0.0;
  double m2 = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const Vec3 d = state.x[i] - x_start_m[i];
    m2 = std::max(m2, d.squaredNorm());
    v_scratch[i] = d * inv_dt;
  }
  const RepairStats stats =
      FillSnapshot(state.x, v_scratch, state.normals, frame, state.time_s, frame_dt_s, snapshot);
  snapshot->displacement_from_previous_m = std::sqrt(m2);
  return stats;
}

}  // namespace felt
