#pragma once
// The velocities a snapshot carries for the haptic side (snapshot mode d extrapolates with them;
// their maximum bounds the extrapolated cloth's reach): the motion of the published cloth over the
// frame, v_i = (x_i(end) - x_i(start)) / dt, not the integrator's own velocities.
//
// Why: where Provot's constraints (000_25210a744b053ca5.txt slide 9) or pins hold particles, the
// integrator's state velocity is not how they move. Leapfrog keeps the synchronised velocity
// v_n = v_{n-1/2} + h/2 a (001_0f9f1b7fedff7723.txt §3.5); when the constraints cancel the step's
// motion each substep it stays h/2 a (0.1 m/s at a held press on the default curtain, whose
// particles do not move), and extrapolating it over a 60 Hz frame moved a resting cloth ~2 mm.
// The frame's mean velocity is what a linear predictor of the published positions needs: zero for
// a cloth at rest, the true velocity to O(dt) for smooth motion. And since each snapshot carries
// the motion that led to it, the previous snapshot extrapolated with its own velocities is exactly
// the cloth the proxy saw before a new one arrived (the moving test of proxy/proxy.h).

#include <cstdint>
#include <span>

#include "sim_loop/cloth.h"
#include "sim_loop/snapshot.h"

namespace felt {

/// Refills `snapshot` from `state` (positions, normals, time_s) with the frame's mean velocities
/// v_i = (state.x_i - x_start_m_i) / frame_dt_s [m/s, world] (zero when frame_dt_s <= 0), written
/// into `v_scratch` first. `x_start_m` [m, world]: the positions of the previous published
/// snapshot (frame - 1: displacement_from_previous_m is set from them); `frame_dt_s` [s]: the sim
/// time between the two. Every span has
/// state.x.size() entries (aborts otherwise, like FillSnapshot). Returns the structure repair's
/// counters. Real-time safe (no allocation, no exception).
RepairStats FillSnapshotWithFrameMotion(const ClothState& state, std::span<const Vec3> x_start_m,
                                        double frame_dt_s, uint64_t frame,
                                        std::span<Vec3> v_scratch, ClothSnapshot* snapshot);

}  // namespace felt
