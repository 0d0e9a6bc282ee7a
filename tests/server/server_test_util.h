#pragma once
// Shared set-up of the server tests: a small curtain with the geometry of scenes/curtain.toml
// (16 x 16 particles 32 mm apart, so the bundled traces still press its middle), devices pressing
// it from +z, and a driver that runs the server's tick and frame on a test-controlled clock.
#include <cstdint>
#include <string>
#include <vector>

#include "haptic_loop/pointer_source.h"
#include "scene/scene_file.h"
#include "server/server.h"
#include "server/server_spec.h"

namespace felt::testing_server {

inline constexpr int64_t kTickNs = 1'000'000;

/// The bundled curtain scene, made small, with `devices` (empty: the scene's own [device]).
inline ServerSpec SmallCurtain(std::vector<DeviceSpec> devices = {}) {
  const std::filesystem::path scene = FELT_SOURCE_DIR "/scenes/curtain.toml";
  ServerSpec spec = ParseServerSpec(LoadSceneDocument(scene));
  spec.sim.cloth.width = 16;
  spec.sim.cloth.height = 16;
  spec.sim.cloth.spacing_m = 0.496 / 15.0;
  if (!devices.empty()) spec.devices = std::move(devices);
  return spec;
}

/// A device whose origin sits at world `offset_W` (scale 3, no rotation).
inline DeviceSpec DeviceAt(const std::string& id, const Vec3& offset_W) {
  DeviceSpec d;
  d.id = id;
  d.offset_W_m = offset_W;
  return d;
}

/// The device tip over `ms` milliseconds of a press: from z_D = +20 mm down to -15 mm (45 mm in
/// the world: the soft curtain gives way) in 200 ms, then held there.
inline Vec3 PressPosition(double ms) {
  const double z = ms < 200.0 ? 0.020 - 0.035 * ms / 200.0 : -0.015;
  return Vec3(0.0, 0.0, z);
}

/// Velocity of PressPosition, m/s.
inline Vec3 PressVelocity(double ms) { return ms < 200.0 ? Vec3(0, 0, -0.175) : Vec3::Zero(); }

/// Drives a (not started) server on a virtual clock: one HapticTick per ms, one SimFrame every
/// 1/60 s of that clock.
class Driver {
 public:
  Driver(Server* server, LatestPointerSource* source, int64_t start_ns = 1'000'000'000'000)
      : server_(server), source_(source), now_ns_(start_ns), next_frame_ns_(start_ns) {}

  /// Advances one tick; `feed(device, ms)` decides whether each device gets a new sample
  /// (return true and fill the sample) at this tick.
  template <typename Feed>
  void Tick(uint32_t devices, Feed&& feed) {
    if (now_ns_ >= next_frame_ns_) {
      server_->SimFrame(1.0 / 60.0, now_ns_);
      next_frame_ns_ += 16'666'667;
    }
    for (uint32_t d = 0; d < devices; ++d) {
      PointerInput in;
      if (feed(d, ms(), &in)) {
        in.seq = ++seq_;
        in.receive_time_ns = now_ns_;
        in.device_time_ns = now_ns_;
        source_->Set(d, in);
      }
    }
    server_->HapticTick(now_ns_, 1e-3);
    now_ns_ += kTickNs;
  }

  /// Milliseconds of virtual time since the start.
  double ms() const { return static_cast<double>(now_ns_ - start_ns_) * 1e-6; }
  int64_t now_ns() const { return now_ns_; }

 private:
  Server* server_;
  LatestPointerSource* source_;
  int64_t now_ns_;
  int64_t start_ns_ = now_ns_;
  int64_t next_frame_ns_;
  uint64_t seq_ = 0;
};

/// A feed that presses every device (PressPosition) until `stop_ms` (never when < 0).
inline auto PressFeed(double stop_ms = -1.0) {
  return [stop_ms](uint32_t, double ms, PointerInput* in) {
    if (stop_ms >= 0.0 && ms >= stop_ms) return false;
    in->p_D_m = PressPosition(ms);
    in->v_D_m_per_s = PressVelocity(ms);
    return true;
  };
}

/// Presses every device until each one's newest force exceeds `min_N` or `max_ticks` pass;
/// returns whether all did.
inline bool PressUntilForce(Driver* driver, CapturingForceSink* sink, uint32_t devices,
                            double min_N, int max_ticks = 2000) {
  for (int i = 0; i < max_ticks; ++i) {
    driver->Tick(devices, PressFeed());
    bool all = true;
    for (uint32_t d = 0; d < devices; ++d) {
      ForceOutput f;
      all = all && sink->Newest(d, &f) && f.force_D_N.norm() > min_N;
    }
    if (all) return true;
  }
  return false;
}

}  // namespace felt::testing_server
