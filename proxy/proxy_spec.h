#pragma once
// What a scene declares about a haptic device and its god-object proxy: plain structs with
// defaults and units in the names (parsed by proxy/proxy_scene.h from [device], [[devices]] and
// [proxy]), and the device-to-world workspace map.
//
// Frames: device (_D) is the haptic device's own frame (metres at the stylus tip); world (_W) is
// the cloth's frame (sim_loop/cloth_spec.h: metres, y up). p_W = scale * R_WD p_D + offset_W.
//
// Forces: the proxy (a sphere of radius radius_m in the world) is tied to the device by a spring
// that acts in the DEVICE frame, F_D = k (proxy_D - device_D), so stiffness_N_per_m is what the
// hand feels per metre of device motion (a Touch-class device renders about 1 N/mm at most, so the
// default 400 N/m is safely inside it). The world-frame force on the proxy is the power-consistent
// F_W = R_WD F_D / scale (F_W . dp_W = F_D . dp_D), and the cloth gets -F_W (two-way coupling).

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "collision/collision_structure.h"
#include "collision/mesh.h"
#include "sim_loop/cloth_spec.h"

namespace felt {

/// One haptic device: its coupling to the proxy, its force limit and its workspace map.
struct DeviceSpec {
  std::string id = "default";        ///< device id ([[devices]] id; "default" for [device])
  double stiffness_N_per_m = 400.0;  ///< coupling spring k in the device frame, > 0
  double damping_N_s_per_m = 0.0;    ///< coupling damper b on (v_proxy - v_device)_D, >= 0
  double radius_m = 0.004;           ///< proxy sphere radius in the world, > 0
  double max_force_N = 3.3;          ///< force clamp on the device, > 0 (Touch: 3.3 N peak)
  double scale = 3.0;                ///< world metres per device metre, > 0
  Eigen::Matrix3d rotation_WD = Eigen::Matrix3d::Identity();  ///< device axes in the world
  Vec3 offset_W_m = Vec3::Zero();  ///< world position of the device origin, m
};

/// The workspace map's one expression: p_W = scale * R_WD p_D + offset_W [m].
inline Vec3 MapDeviceToWorld(double scale, const Eigen::Matrix3d& rotation_WD,
                             const Vec3& offset_W_m, const Vec3& p_D) {
  return scale * (rotation_WD * p_D) + offset_W_m;
}
/// Its inverse: p_D = R_WD^T (p_W - offset_W) / scale [m].
inline Vec3 MapWorldToDevice(double scale, const Eigen::Matrix3d& rotation_WD,
                             const Vec3& offset_W_m, const Vec3& p_W) {
  return rotation_WD.transpose() * (p_W - offset_W_m) / scale;
}

/// Device position [m, device frame] to world [m]: scale * R_WD p_D + offset_W.
inline Vec3 DeviceToWorld(const DeviceSpec& d, const Vec3& p_D) {
  return MapDeviceToWorld(d.scale, d.rotation_WD, d.offset_W_m, p_D);
}
/// World position [m] to device frame [m]: the inverse of DeviceToWorld.
inline Vec3 WorldToDevice(const DeviceSpec& d, const Vec3& p_W) {
  return MapWorldToDevice(d.scale, d.rotation_WD, d.offset_W_m, p_W);
}

/// Which cloth the proxy is run against each tick (issue 4; 001_0f9f1b7fedff7723.txt §7).
enum class SnapshotMode : uint8_t {
  kNewest,       ///< (a) the newest snapshot only: the cloth jumps once per sim frame
  kBlendForces,  ///< (b) 001 §7: a proxy on each of the two newest cloths, forces blended by
                 ///<     time since the newest arrived / its frame dt
  kInterpolate,  ///< (c) positions interpolated between the two newest snapshots (one frame late)
  kExtrapolate,  ///< (d) positions extrapolated from the newest with its velocities
  kPatch,        ///< (e) issue 20: the cloth near each contact stepped at the haptic rate in the
                 ///<     tick (sim_loop/cloth_patch.h), the rest extrapolated as (d)
};

/// Every snapshot mode, in the order tables list them.
inline constexpr SnapshotMode kSnapshotModes[] = {SnapshotMode::kNewest, SnapshotMode::kBlendForces,
                                                  SnapshotMode::kInterpolate,
                                                  SnapshotMode::kExtrapolate, SnapshotMode::kPatch};

/// The scene-file name of a mode: "newest", "blend_forces", "interpolate", "extrapolate", "patch".
const char* SnapshotModeName(SnapshotMode mode);

/// Limits that the scene parser (proxy/proxy_scene.h) and CompileProxyModel both enforce, so a
/// key's rule is the same wherever it is validated.
inline constexpr int32_t kMaxProxyIterations = 100;      ///< proxy.max_iterations
inline constexpr int32_t kMinCandidateCapacity = 16;     ///< proxy.candidate_capacity
inline constexpr int32_t kMaxCandidateCapacity = 65536;  ///< proxy.candidate_capacity

/// How the proxy renders: [proxy] in a scene.
struct ProxySpec {
  bool force_shading = true;      ///< Morgenbesser & Srinivasan 1996, Ruspini 1997's two passes
  double friction_static = 0.0;   ///< static friction coefficient mu_s >= 0 (0: frictionless)
  double friction_dynamic = 0.0;  ///< dynamic friction coefficient, 0 <= mu_d <= mu_s
  /// Which cloth the proxy renders between sim frames (docs/proxy.md, "Snapshot modes"); patch
  /// by measurement (bench/results/haptic.md, issue 20).
  SnapshotMode snapshot_mode = SnapshotMode::kPatch;
  /// Mode patch: the local patch's windows reach this many particles each way from a contact
  /// (sim_loop/cloth_patch.h), in [kMinPatchRadius, kMaxPatchRadius] (sim_loop/cloth_spec.h);
  /// unused by the other modes.
  int32_t patch_radius = 8;
  /// Mode patch: a window moves to its contact once the contact is this many particles
  /// (Chebyshev) from the window's centre, in [1, patch_radius] (kPatchDefaultFollow: 2, by
  /// measurement, docs/proxy.md "Where"); unused by the other modes.
  int32_t patch_follow = kPatchDefaultFollow;
  /// Mode patch: the sim's contact spring moves with the device's velocity over its frame (a
  /// first-order prediction of the hand: ProxyModel::predict_hand). Off by default: the
  /// instantaneous velocity of a vibrating or trembling hand, carried over a 16.7 ms frame, moves
  /// the 60 Hz cloth that drives the patch's rings by centimetres (docs/proxy.md, "The hand over
  /// the frame"); unused by the other modes.
  bool predict_hand = false;
  int32_t max_iterations = 10;  ///< sweep/solve rounds per pass within one tick, >= 1
  /// Triangles near the proxy gathered per tick (sized once in the proxy state), >= 16. A tick
  /// that finds more is counted (ProxyCounters::overflow_ticks) and uses the first ones found.
  int32_t candidate_capacity = 1024;
  /// What the sim builds into each snapshot (default bvh-aabb-4: DefaultCollisionStructure).
  CollisionStructureSpec structure = DefaultCollisionStructure();
  /// The scene's static obstacles ([[obstacles]], the same ones the cloth is kept out of; world,
  /// m): the proxy cannot enter them either (proxy/obstacle_sweep.h). Not a [proxy] key: the
  /// server copies SimSpec's (ParseServerSpec). Empty: nothing is tested, at no cost.
  std::vector<ObstacleSpec> obstacles;
};

}  // namespace felt
