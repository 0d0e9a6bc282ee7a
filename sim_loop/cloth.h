#pragma once
// The mass-spring cloth of the 60 Hz thread: an immutable model built once from a SimSpec, a state
// sized once, and StepFrame, which never allocates.
// Model/state split after MuJoCo's mjModel/mjData (shared/STYLE.md).

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "sim_loop/cloth_spec.h"
#include "sim_loop/mesh.h"

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

/// A point force the haptic side puts on the cloth for the next frame (two-way coupling): applied
/// at the point with barycentric weights `barycentric` in triangle `triangle`, split over its three
/// particles by those weights. World frame, newtons.
struct ExternalForce {
  int32_t triangle = 0;
  Vec3 barycentric = Vec3(1.0 / 3, 1.0 / 3, 1.0 / 3);  ///< non-negative, sums to 1
  Vec3 force_N = Vec3::Zero();
};

/// The validated, immutable cloth: shared read-only by every thread.
struct ClothModel {
  SimSpec spec;                        ///< the spec it was built from, as validated
  int32_t width = 0;                   ///< particles along u
  int32_t height = 0;                  ///< particles along v
  std::vector<Vec3> rest_position_m;   ///< [width*height] rest places, index = row*width + col
  std::vector<double> inv_mass_per_kg; ///< [width*height] 1/m, 0 for pinned particles
  std::vector<int32_t> pinned;         ///< indices of pinned particles
  std::vector<int32_t> pin_spec;       ///< [pinned.size()] index into spec.cloth.pins
  std::vector<Spring> springs;         ///< only the spring types the spec declares
  std::vector<Triangle> triangles;     ///< 2 (W-1)(H-1), see MakeGridTriangles
  int32_t substeps = 1;                ///< per nominal frame, resolved from spec ("auto" -> number)
  double stable_dt_s = 0.0;            ///< the integrator's stability limit for the stiffest pair

  int32_t num_particles() const { return width * height; }
};

/// Counters of what happened to a state, for logs and stats.
struct ClothCounters {
  uint64_t frames = 0;            ///< frames stepped
  uint64_t nan_events = 0;        ///< frames that produced non-finite values (state restored)
  uint64_t clamped_frames = 0;    ///< frames whose dt was clamped to max_frame_dt_s
  uint64_t cg_not_converged = 0;  ///< implicit Euler solves that hit the iteration cap
};

/// Everything that changes while stepping, sized once by MakeClothState.
struct ClothState {
  std::vector<Vec3> x;        ///< [n] positions, world, m
  std::vector<Vec3> v;        ///< [n] velocities, world, m/s
  std::vector<Vec3> normals;  ///< [n] area-weighted unit vertex normals, world
  double time_s = 0.0;        ///< simulated time
  ClothCounters counters;
  // Scratch (integrator stages, previous positions, last good state, CG buffers) lives in an
  // opaque block owned here so StepFrame never allocates.
  struct Scratch;
  std::shared_ptr<Scratch> scratch;
};

/// Validates `spec` and builds the model. Throws std::invalid_argument whose message names the
/// field (e.g. "cloth.width: must be >= 2, got 1").
ClothModel BuildClothModel(const SimSpec& spec);

/// A state at rest: particles at their rest places, zero velocity, normals computed, scratch sized.
ClothState MakeClothState(const ClothModel& model);

/// What one frame did.
struct FrameResult {
  int32_t substeps = 0;       ///< substeps integrated
  double dt_s = 0.0;          ///< time integrated (after clamping)
  bool clamped = false;       ///< frame_dt_s was larger than max_frame_dt_s
  bool recovered = false;     ///< non-finite values appeared and the last good state was restored
};

/// Advances the cloth by `frame_dt_s` (clamped to spec.integration.max_frame_dt_s), applying
/// `external` forces (held constant over the frame), pins, obstacles and Provot constraints, then
/// recomputes normals. Non-finite results restore the last good state (counted, logged once).
/// Does not allocate.
FrameResult StepFrame(const ClothModel& model, std::span<const ExternalForce> external,
                      double frame_dt_s, ClothState* state);

/// Largest length / rest length over the structural springs (1.0 = unstretched).
double MaxStretch(const ClothModel& model, const ClothState& state);

/// Kinetic + gravitational + spring potential energy, joules (pins excluded from kinetic).
double TotalEnergy(const ClothModel& model, const ClothState& state);

}  // namespace felt
