#include "proxy/proxy_model.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "scene/scene_file.h"

namespace felt {
namespace {

// Throws std::invalid_argument "<field>: <rule>, got <value>" unless ok (the scene parser's
// wording, so a rule reads the same wherever it is checked).
// "must be in [lo, hi]" (appended piece by piece: GCC 12's -Warray-bounds misfires on
// "literal" + std::to_string(...) in a unity build).
std::string MustBeInRange(int64_t lo, int64_t hi) {
  std::string text = "must be in [";
  text += std::to_string(lo);
  text += ", ";
  text += std::to_string(hi);
  text += "]";
  return text;
}

void RequireModelField(bool ok, const char* field, const std::string& rule, double value) {
  if (!ok) {
    throw std::invalid_argument(std::string(field) + ": " + rule + ", got " +
                                FormatSceneNumber(value));
  }
}

bool PositiveFinite(double v) { return v > 0.0 && std::isfinite(v); }
bool NonNegativeFinite(double v) { return v >= 0.0 && std::isfinite(v); }

}  // namespace

ProxyModel CompileProxyModel(const DeviceSpec& device, const ProxySpec& proxy) {
  RequireModelField(PositiveFinite(device.stiffness_N_per_m), "device.stiffness_N_per_m",
                    "must be > 0", device.stiffness_N_per_m);
  RequireModelField(NonNegativeFinite(device.damping_N_s_per_m), "device.damping_N_s_per_m",
                    "must be >= 0", device.damping_N_s_per_m);
  RequireModelField(PositiveFinite(device.radius_m), "device.radius_m", "must be > 0",
                    device.radius_m);
  RequireModelField(PositiveFinite(device.max_force_N), "device.max_force_N", "must be > 0",
                    device.max_force_N);
  RequireModelField(PositiveFinite(device.scale), "device.scale", "must be > 0", device.scale);
  RequireModelField(device.rotation_WD.allFinite(), "device.rotation_WD", "must be finite", 0.0);
  RequireModelField(device.offset_W_m.allFinite(), "device.offset_m", "must be finite", 0.0);
  RequireModelField(NonNegativeFinite(proxy.friction_static), "proxy.friction_static",
                    "must be >= 0", proxy.friction_static);
  RequireModelField(NonNegativeFinite(proxy.friction_dynamic), "proxy.friction_dynamic",
                    "must be >= 0", proxy.friction_dynamic);
  RequireModelField(proxy.friction_dynamic <= proxy.friction_static, "proxy.friction_dynamic",
                    "must be <= friction_static (" + FormatSceneNumber(proxy.friction_static) + ")",
                    proxy.friction_dynamic);
  RequireModelField(proxy.max_iterations >= 1 && proxy.max_iterations <= kMaxProxyIterations,
                    "proxy.max_iterations",
                    MustBeInRange(1, kMaxProxyIterations),
                    proxy.max_iterations);
  RequireModelField(proxy.candidate_capacity >= kMinCandidateCapacity &&
                        proxy.candidate_capacity <= kMaxCandidateCapacity,
                    "proxy.candidate_capacity",
                    MustBeInRange(kMinCandidateCapacity, kMaxCandidateCapacity),
                    proxy.candidate_capacity);

  ProxyModel m;
  m.rotation_WD = device.rotation_WD;
  m.offset_W_m = device.offset_W_m;
  m.scale = device.scale;
  m.stiffness_N_per_m = device.stiffness_N_per_m;
  m.damping_N_s_per_m = device.damping_N_s_per_m;
  m.max_force_N = device.max_force_N;
  // The same expressions the tick evaluated before issue 19 (same bits).
  m.stiffness_W_N_per_m = device.stiffness_N_per_m / (device.scale * device.scale);
  m.max_force_W_N = device.max_force_N / device.scale;
  m.radius_m = device.radius_m;
  m.max_iterations = proxy.max_iterations;
  m.force_shading = proxy.force_shading;
  m.friction_static = proxy.friction_static;
  m.friction_dynamic = proxy.friction_dynamic;
  m.obstacles = proxy.obstacles;
  m.snapshot_mode = proxy.snapshot_mode;
  m.candidate_capacity = proxy.candidate_capacity;
  m.predict_hand = proxy.predict_hand && proxy.snapshot_mode == SnapshotMode::kPatch;
  return m;
}

}  // namespace felt
