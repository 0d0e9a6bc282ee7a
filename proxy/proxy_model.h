#pragma once
// The proxy's model (issue 19, "model and data apart at the tick"): everything ProxyTick reads and
// never writes, compiled once per device from its DeviceSpec and the scene's ProxySpec
// (proxy/proxy_spec.h holds the one default of every parameter; the model has none of its own).
// The tick's data live in ProxyState (proxy/proxy.h); kernels take (const ProxyModel&, inputs...,
// ProxyState*).
//
// Frames as in proxy_spec.h: device (_D), world (_W); p_W = scale * R_WD p_D + offset_W. The
// coupling spring acts in the device frame, F_D = k (proxy_D - device_D); in the world it is
// F_W = (k / scale^2) (proxy_W - goal_W), clamped to max_force_N / scale (power-consistent).

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "proxy/proxy_spec.h"
#include "sim_loop/cloth_spec.h"

namespace felt {

/// One device's proxy, compiled by CompileProxyModel; read-only during the ticks. No defaults of
/// its own: every field comes from (or is derived from) the specs.
struct ProxyModel {
  // The workspace map (DeviceSpec).
  Eigen::Matrix3d rotation_WD = Eigen::Matrix3d::Identity();  ///< device axes in the world
  Vec3 offset_W_m = Vec3::Zero();  ///< world position of the device origin, m
  double scale = 0.0;              ///< world metres per device metre

  // The coupling, device frame (DeviceSpec).
  double stiffness_N_per_m = 0.0;  ///< coupling spring k, device frame, N/m
  double damping_N_s_per_m = 0.0;  ///< coupling damper b on (v_proxy - v_device)_D, N s/m
  double max_force_N = 0.0;        ///< force clamp on the device, device frame, N

  // The coupling, world frame (derived once: the sim's contact spring).
  double stiffness_W_N_per_m = 0.0;  ///< k / scale^2, world, N/m
  double max_force_W_N = 0.0;        ///< max_force_N / scale, world, N

  // The god-object update (DeviceSpec::radius_m and ProxySpec).
  double radius_m = 0.0;          ///< proxy sphere radius, world, m
  int32_t max_iterations = 0;     ///< sweep/solve rounds per pass, >= 1
  bool force_shading = false;     ///< Morgenbesser & Srinivasan 1996: Ruspini 1997's two passes
  double friction_static = 0.0;   ///< mu_s >= 0 (0: frictionless; Ruspini 1997 §4)
  double friction_dynamic = 0.0;  ///< mu_d, <= mu_s
  /// The scene's static obstacles (world, m), constraint sources beside the cloth's triangles
  /// (proxy/obstacle_sweep.h). Empty: nothing is tested.
  std::vector<ObstacleSpec> obstacles;

  // The tick's cloth and its scratch.
  SnapshotMode snapshot_mode = SnapshotMode::kNewest;  ///< which cloth each tick runs against
  int32_t candidate_capacity = 0;  ///< triangles gathered per tick (ProxyState's size), >= 1
  /// The sim's contact spring moves with the device's velocity over its frame
  /// (ExternalForce::anchor_velocity_m_per_s): ProxySpec::predict_hand, in mode patch only (where
  /// the 60 Hz cloth drives the patch's rings); off by default (docs/proxy.md, "The hand over the
  /// frame").
  bool predict_hand = false;

  /// Device position [m, device frame] to world [m] (MapDeviceToWorld, as DeviceToWorld).
  Vec3 ToWorld(const Vec3& p_D) const {
    return MapDeviceToWorld(scale, rotation_WD, offset_W_m, p_D);
  }
  /// World position [m] to device frame [m] (MapWorldToDevice, as WorldToDevice).
  Vec3 ToDevice(const Vec3& p_W) const {
    return MapWorldToDevice(scale, rotation_WD, offset_W_m, p_W);
  }
};

/// Compiles the model of one device (`device`) under the scene's proxy settings (`proxy`).
/// Validates what the tick relies on and throws std::invalid_argument naming the field
/// ("device.radius_m: must be > 0, got 0"). Allocates (set-up time, not the tick).
ProxyModel CompileProxyModel(const DeviceSpec& device, const ProxySpec& proxy);

}  // namespace felt
