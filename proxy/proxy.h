#pragma once
// The god-object proxy against the moving cloth (issue 4): what the user feels.
//
// Per device and per 1 kHz tick the server calls ProxyTick once, under the device's ProxyModel
// (proxy/proxy_model.h, compiled once at start-up), with the newest cloth snapshot,
// the previous one, the time since the newest arrived and the device sample. The tick
//  1. maps the device position into the world (the goal),
//  2. chooses the cloth of this tick by the snapshot mode (newest; both, forces blended; positions
//     interpolated; positions extrapolated: ProxySpec::snapshot_mode, 001_0f9f1b7fedff7723.txt §7),
//  3. carries a proxy in contact with its contact triangle to the new cloth (barycentric point,
//     side and offset in the triangle's frame), and catches a proxy that the moving cloth sweeps
//     over (MovingTriangleSphereContact), so the thin cloth never passes through it,
//  4. moves the proxy toward the goal by the god-object update of Ruspini, Kolarov & Khatib 1997
//     (after Zilles & Salisbury 1995): sweep to the first contact, add its plane, solve for the
//     closest point to the goal on the free side of every active plane (up to three), sweep
//     toward that, until converged, all within the tick. With force shading (Morgenbesser &
//     Srinivasan 1996) it does so twice: first toward the goal, then toward the goal projected on
//     the planes through the proxy with the interpolated vertex normals (Ruspini 1997 §5),
//  5. applies friction (Ruspini 1997 §4; the friction cone of Salisbury et al. 1995): a stuck
//     proxy keeps its place on the cloth while the goal stays inside the static cone; once it
//     slips it trails the frictionless point at the edge of the dynamic cone until the goal comes
//     back inside that cone (kinetic friction lasts while sliding),
//  6. computes the force F_D = k (proxy_D - device_D) + b (v_proxy - v_device)_D clamped to
//     max_force_N (direction kept), and puts -F_W on the cloth (ReactionAccumulator).
// Everything is deterministic: the same inputs give the same bits.

#include <array>
#include <cstdint>

#include "proxy/local_cloth.h"
#include "proxy/plane_constraints.h"
#include "proxy/proxy_model.h"
#include "proxy/proxy_spec.h"
#include "proxy/reaction.h"
#include "sim_loop/snapshot.h"

namespace felt {

/// One device sample, device frame.
struct DeviceSample {
  Vec3 p_D_m = Vec3::Zero();        ///< stylus tip position, device frame, m
  Vec3 v_D_m_per_s = Vec3::Zero();  ///< its velocity, device frame, m/s (for damping)
};

/// One constraint of the proxy: a point of the cloth (or of an obstacle) the proxy sphere touches.
struct ProxyContact {
  /// Index into the snapshot's triangles (>= 0), or for a static obstacle of the scene the
  /// negative id ObstacleContactId(k) = -1 - k of ProxySpec::obstacles[k] (proxy/obstacle_sweep.h;
  /// barycentric and local_m are then unused, and the contact puts no force on the cloth).
  int32_t triangle = -1;
  Vec3 barycentric = Vec3::Zero();  ///< of the touched point in the triangle
  Vec3 point_W_m = Vec3::Zero();    ///< the touched point, world, m
  Vec3 normal_W = Vec3::Zero();     ///< unit, from the cloth toward the proxy centre, world
  Vec3 local_m = Vec3::Zero();      ///< proxy centre - point in the triangle's frame, m
};

/// A proxy against one cloth: its centre and its contacts (at most kMaxConstraintPlanes).
struct GodObject {
  Vec3 p_W_m = Vec3::Zero();                                ///< proxy sphere centre, world, m
  int32_t num_contacts = 0;                                 ///< active contacts, 0..3
  std::array<ProxyContact, kMaxConstraintPlanes> contacts;  ///< the first num_contacts are active
  bool placed = false;    ///< false until the first tick puts it at the goal
  bool slipping = false;  ///< friction: sliding (dynamic cone) rather than stuck (static)
};

/// Counters of a proxy state since it was made (for stats and the benchmark).
struct ProxyCounters {
  uint64_t ticks = 0;              ///< ProxyTick calls
  uint64_t new_snapshots = 0;      ///< ticks at which a newer snapshot arrived
  uint64_t catches = 0;            ///< free proxies caught by the moving cloth
  uint64_t overflow_ticks = 0;     ///< ticks whose gather overflowed candidate_capacity
  uint64_t unconverged_ticks = 0;  ///< ticks that used every iteration (max_iterations)
  uint64_t infeasible_ticks = 0;   ///< ticks whose active planes had no common free point
  uint64_t clamped_ticks = 0;      ///< ticks whose force was clamped to max_force_N
};

/// Everything one device's proxy keeps between ticks, sized once by MakeProxyState.
struct ProxyState {
  GodObject body;               ///< against the tick's cloth (mode b: against the newest snapshot)
  GodObject body_prev;          ///< mode b only: against the previous snapshot
  uint64_t newest_frame = 0;    ///< frame of the newest snapshot seen
  bool have_frame = false;      ///< false before the first tick
  double last_alpha = 0.0;      ///< the previous tick's interpolation weight (modes b, c)
  double last_tau_s = 0.0;      ///< the previous tick's extrapolation time (mode d)
  bool last_on_newest = false;  ///< modes c, d: the previous tick ran on its newest snapshot
                                ///< itself (after a gather overflow)
  double pair_displacement_m = 0.0;    ///< max vertex displacement previous -> newest, m
  Vec3 last_proxy_W_m = Vec3::Zero();  ///< the proxy reported last tick (damping velocity), m
  ProxyContact hand_seed;  ///< the last cloth contact, where the sim's hand sphere stays seeded
                           ///< while the free proxy is near it (triangle < 0: none)
  LocalCloth local;        ///< the gathered triangles of the tick (scratch)
  ReactionAccumulator reaction;  ///< two-way coupling: forces on the cloth, drained per frame
  ProxyCounters counters;        ///< since MakeProxyState

  explicit ProxyState(int32_t candidate_capacity, int32_t reaction_capacity = 256)
      : local(candidate_capacity), reaction(reaction_capacity) {}
};

/// A state for one device with the capacities of `model` (the proxy is placed at the goal on the
/// first tick). Allocates (set-up time).
ProxyState MakeProxyState(const ProxyModel& model);

/// What one tick produced.
struct ProxyTickResult {
  Vec3 force_D_N = Vec3::Zero();  ///< force to command on the device, device frame, N (clamped)
  Vec3 force_W_N = Vec3::Zero();  ///< the same force in the world, R_WD F_D / scale, N; the
                                  ///< cloth receives -force_W_N (added to the state's reaction)
  Vec3 proxy_W_m = Vec3::Zero();  ///< proxy centre, world, m (mode b: blended)
  Vec3 goal_W_m = Vec3::Zero();   ///< device position mapped into the world, m
  int32_t num_contacts = 0;       ///< active contacts at the end of the tick
  int32_t iterations = 0;         ///< sweep rounds used (both passes; mode b: both proxies)
  bool clamped = false;           ///< the force was clamped to max_force_N
  bool overflow = false;          ///< the gather overflowed: this tick may have missed triangles
  bool caught = false;            ///< the moving cloth caught a free proxy this tick
  bool on_newest = false;  ///< modes c, d: the gather overflowed, so this tick ran on `newest`
                           ///< itself (the cloth the structure's fallback queries answer for)
};

/// The local patch a tick in mode patch renders (sim_loop/cloth_patch.h; the haptic loop steps it
/// before the proxies). Its particles replace the extrapolated cloth's in the tick's cloth.
struct PatchOverlay {
  const ClothPatch* patch = nullptr;  ///< the patch: roles, positions now and before, normals
  double offset_m = 0.0;  ///< bound on |patch x - newest x| over its particles, now and before, m
};

/// The cloth of one tick (step 2 of the file comment), as ChooseTickCloth chose it.
struct TickCloth {
  const ClothSnapshot* prev = nullptr;        ///< `previous` if of the same cloth, else nullptr
  SnapshotMode mode = SnapshotMode::kNewest;  ///< the model's, or kNewest without `prev`
  bool arrived = false;       ///< a newer snapshot than the state had seen (or the first tick)
  bool first = false;         ///< the state's first tick
  double alpha = 1.0;         ///< interpolation weight since_newest_s / frame_dt_s in [0, 1]
  double tau_s = 0.0;         ///< extrapolation time max(0, since_newest_s), s
  ClothView now;              ///< the cloth of this tick
  ClothView before;           ///< the cloth of the previous tick (meaningful when `moved`)
  bool moved = false;         ///< the proxy is to be carried from `before` to `now`
  double inflation_m = 0.0;   ///< bound on how far `now` and `before` lie from `newest`, m
                              ///< (mode patch: outside the patch's windows)
  double patch_offset_m = 0.0;  ///< mode patch: bound on how far the windows lie from `newest`, m
  bool interpolated = false;  ///< modes c, d (their gather overflow falls back to `newest`)
};

/// Step 2 of ProxyTick: which snapshots this tick has (a `previous` of another cloth is ignored),
/// the mode they allow, and the tick's cloth and the previous tick's by that mode (`newest`,
/// `previous` and `since_newest_s` [s] as for ProxyTick). Records a newer snapshot's arrival in
/// `state` (frame, pair displacement, counters.new_snapshots). Real-time safe.
/// Mode patch: `patch` (null, or before the patch holds a window: mode extrapolate's cloth).
TickCloth ChooseTickCloth(const ProxyModel& model, const ClothSnapshot& newest,
                          const ClothSnapshot* previous, double since_newest_s, ProxyState* state,
                          const PatchOverlay* patch = nullptr);

/// A device force after the clamp.
struct ClampedForce {
  Vec3 force_D_N = Vec3::Zero();  ///< the force, device frame, N, |force| <= max_force_N
  double factor = 1.0;            ///< max_force_N / |unclamped| when clamped, else 1
  bool clamped = false;           ///< |unclamped| exceeded max_force_N
};

/// Clamps `force_D_N` [N, device frame] to model.max_force_N, direction kept. Real-time safe.
ClampedForce ClampDeviceForce(const ProxyModel& model, const Vec3& force_D_N);

/// One haptic tick for one device (see the file comment) under `model` (compiled once by
/// CompileProxyModel). `newest` is the newest snapshot, `previous` the one before it (nullptr if
/// none yet: modes b-d then act as mode a); `since_newest_s` the time since `newest` arrived [s];
/// `sample` the device sample (device frame); `tick_dt_s` the tick period [s] (reaction time
/// weight and damping velocity). A newer newest.frame than the state has seen means a new
/// snapshot arrived. Snapshots of the same cloth only. Mode patch renders `patch` (the haptic
/// loop's local patch, already stepped to this tick; null: as mode extrapolate). Real-time safe:
/// no allocation, lock, exception, log or I/O.
ProxyTickResult ProxyTick(const ProxyModel& model, const ClothSnapshot& newest,
                          const ClothSnapshot* previous, double since_newest_s,
                          const DeviceSample& sample, double tick_dt_s, ProxyState* state,
                          const PatchOverlay* patch = nullptr);

/// What one god-object update did.
struct GodObjectStep {
  int32_t iterations = 0;  ///< sweep rounds, all passes
  bool converged = true;   ///< false when a pass used max_iterations rounds
  bool feasible = true;    ///< false when the active planes admitted no point (proxy kept)
};

/// The god-object update of one proxy toward `goal_W` [m, world] against `cloth` (gathered for
/// this tick; `view` gives the vertex normals for shading) and model.obstacles, from
/// body->p_W_m, with Ruspini 1997's constraint iteration, optional force shading (Morgenbesser &
/// Srinivasan 1996) and friction, by the model's radius, iterations, shading and friction. Cloth
/// and obstacle contacts share the up-to-three planes of one solve. body->contacts are rewritten.
/// Real-time safe.
GodObjectStep UpdateGodObject(const ProxyModel& model, const LocalCloth& cloth,
                              const ClothView& view, const Vec3& goal_W, GodObject* body);

/// Moves `body` with its first cloth contact's triangle from cloth `before` to cloth `now`
/// (barycentric point plus the offset in the triangle's frame: side and radius kept). No-op for a
/// body with no cloth contact (obstacles are static). Real-time safe.
void CarryGodObject(const ClothView& before, const ClothView& now, GodObject* body);

/// Which side of the cloth a point is on near a triangle: the sign (+1, -1) of
/// face_normal . (p - closest point of the triangle), 0 if degenerate or on it. Real-time safe.
int32_t SideOfTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

}  // namespace felt
