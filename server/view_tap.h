#pragma once
// What the loops publish for an observer that must never slow them (the live view, view/): the
// sim thread's cloth positions after each frame and the haptic thread's per-device state after
// each tick, each through a TripleBuffer whose only reader is the observer's thread (docs/view.md).
// The writers fill a preallocated slot and publish with one atomic exchange: no allocation, lock
// or wait, whatever the reader does (or if it never reads).
#include <array>
#include <cstdint>
#include <vector>

#include "proxy/proxy.h"
#include "rt/triple_buffer.h"

namespace felt {

/// The cloth of one sim frame, for the view: positions as float32 (what the view sends).
struct ViewCloth {
  uint64_t frame = 0;        ///< the sim's frame number
  double time_s = 0.0;       ///< sim time of the positions, s
  std::vector<float> xyz_m;  ///< [3 n] particle positions x0 y0 z0 x1 ..., world, m
};

/// One device after one haptic tick, for the view. World frame, SI units.
struct ViewDevice {
  Vec3 goal_W_m = Vec3::Zero();   ///< the device's point mapped into the world, m
  Vec3 proxy_W_m = Vec3::Zero();  ///< proxy sphere centre, m
  Vec3 force_W_N = Vec3::Zero();  ///< the proxy's force in the world (ProxyTickResult), N
  int32_t num_contacts = 0;       ///< active contacts, 0..kMaxConstraintPlanes
  std::array<ProxyContact, kMaxConstraintPlanes> contacts;  ///< the first num_contacts are active
  bool fresh = false;                                       ///< the device's input is fresh
};

/// The devices of one haptic tick.
struct ViewDevices {
  uint64_t tick = 0;                ///< haptic ticks so far
  std::vector<ViewDevice> devices;  ///< [devices], scene order
};

/// The two handoffs loops -> view. Sized once at construction (allocates); the loops then write
/// into write_slot() without allocating.
struct ViewTap {
  /// A tap for `particles` particles and `devices` devices (set-up time: allocates).
  ViewTap(int32_t particles, uint32_t device_count)
      : cloth(ViewCloth{0, 0.0, std::vector<float>(3 * static_cast<size_t>(particles), 0.0f)}),
        devices(ViewDevices{0, std::vector<ViewDevice>(device_count)}) {}
  TripleBuffer<ViewCloth> cloth;      ///< sim thread writes, view thread reads
  TripleBuffer<ViewDevices> devices;  ///< haptic thread writes, view thread reads
};

}  // namespace felt
