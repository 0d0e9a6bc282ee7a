#pragma once
// The 1 kHz loop's tick (docs/server.md): what the haptic thread runs each period.
//
// Each tick (HapticLoop::Tick, real-time safe): take the newest snapshot (no wait); when a new one
// arrived, keep the one before it as "previous" (for the snapshot modes that blend two cloths) and
// hand the reactions of the frame that ended to the sim; then per device: read the newest pointer
// sample (PointerSource), run ProxyTick while the input is fresh, apply the safety layer
// (haptic_loop/safety.h), push the force (ForceSink) and count.
//
// Reaction handoff, nothing lost: every device's ProxyState::reaction accumulates the impulses on
// the cloth over a frame. When a new snapshot arrives the tick drains all of them into one
// ReactionBatch staged here (forces are time averages over the batch's duration) and TryPushes it
// on the SPSC queue (sim_loop/sim_frame.h); if the queue is full the batch stays staged and is
// pushed again next tick, and the accumulators keep accumulating meanwhile (they are drained only
// once the staged batch is gone), so no impulse is dropped.
//
// Mode patch (issue 20): after taking the snapshot and before the proxies, the tick places the
// local patch's windows around each device's last contact (or the cloth point its free proxy still
// presses: ProxyState::hand_seed) and steps the patch by the tick with the contact springs of the
// last tick (sim_loop/cloth_patch.h); the proxies then render the patch where it is and the newest
// snapshot extrapolated elsewhere. The sim receives the reactions as in every mode (the push once,
// with the hand's predicted velocity); the patch's own state stays local (sim_loop/cloth_patch.h,
// "Hand-back").
#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "haptic_loop/haptic_spec.h"
#include "haptic_loop/pointer_source.h"
#include "haptic_loop/safety.h"
#include "proxy/proxy.h"
#include "rt/loop_stats.h"
#include "sim_loop/sim_frame.h"

namespace felt {

/// Per-device counters, written by the haptic thread, read by any thread.
struct DeviceCounters {
  std::atomic<uint64_t> ticks_with_input{0};      ///< ticks at which the device had a sample
  std::atomic<uint64_t> contact_ticks{0};         ///< ticks with the proxy in contact
  std::atomic<uint64_t> stale_ticks{0};           ///< ticks flagged stale input
  std::atomic<uint64_t> ramping_ticks{0};         ///< ticks flagged ramping
  std::atomic<uint64_t> clamped_ticks{0};         ///< ticks flagged clamped (force or rate)
  std::atomic<uint64_t> stalled_ticks{0};         ///< ticks flagged sim stalled
  std::atomic<uint64_t> nan_events{0};            ///< ticks with a non-finite input or output
  std::atomic<uint64_t> connects{0};              ///< times the input became fresh (1 = first)
  std::atomic<uint64_t> forces_sent{0};           ///< forces pushed to the sink
  std::atomic<double> peak_force_N{0.0};          ///< largest |force| sent, N
  std::atomic<double> energy_J{0.0};              ///< passivity observer, J (safety.h)
  std::atomic<double> dissipated_J{0.0};          ///< passivity controller's removed energy, J
  std::atomic<double> reaction_impulse_N_s{0.0};  ///< sum of |reaction impulse| queued, N s
  std::atomic<bool> connected{false};             ///< input fresh at the last tick
};

/// What the haptic loop counts beyond its devices, written by the haptic thread, read by any.
struct HapticCounters {
  std::atomic<uint64_t> ticks{0};                ///< Tick calls
  std::atomic<uint64_t> sim_stalled_ticks{0};    ///< ticks whose snapshot was older than the limit
  std::atomic<bool> sim_stalled{false};          ///< the last tick saw a stalled sim
  std::atomic<uint64_t> reaction_batches{0};     ///< batches pushed haptic -> sim
  std::atomic<uint64_t> reaction_queue_full{0};  ///< ticks a staged batch waited for room
  std::atomic<uint64_t> patch_ticks{0};          ///< mode patch: ticks that stepped a window
  std::atomic<uint64_t> patch_nan_events{0};     ///< mode patch: steps restarted from the drive
  std::atomic<uint64_t> patch_guard_pushes{0};   ///< mode patch: triangles its sphere guard pushed
};

/// The haptic loop: every device's proxy, safety state and counters, the haptic side of both
/// handoffs, and the tick. Construction is set-up (allocates, validates).
class HapticLoop {
 public:
  /// One proxy and safety state per device of `devices` (at least one), rendering with `proxy`
  /// under `haptic`'s timing and safety rules. `initial` is a snapshot sized like every snapshot
  /// the sim publishes; `snapshots` and `reactions` are the sim loop's handoffs; `source`, `sink`
  /// have room for devices.size() devices; `stats` records the snapshot's age at each tick. All
  /// must outlive the loop. Throws std::invalid_argument naming the field (no device, a bad
  /// safety value).
  HapticLoop(const ProxySpec& proxy, const std::vector<DeviceSpec>& devices,
             const HapticSpec& haptic, const ClothModel& cloth, const ClothSnapshot& initial,
             SnapshotBuffer* snapshots, ReactionQueue* reactions, PointerSource* source,
             ForceSink* sink, LoopStats* stats);

  /// One tick at CLOCK_MONOTONIC `now_ns` for a tick of `dt_s` [s]. Haptic thread only (one
  /// thread at a time). Real-time safe: no allocation, lock, log, exception or I/O.
  void Tick(int64_t now_ns, double dt_s);

  /// Devices, in scene order.
  uint32_t device_count() const { return static_cast<uint32_t>(devices_.size()); }
  /// The spec of device `i`.
  const DeviceSpec& device_spec(uint32_t i) const { return devices_[i].spec; }
  /// The counters of device `i` (any thread).
  const DeviceCounters& device_counters(uint32_t i) const { return *devices_[i].counters; }
  /// The proxy model of device `i`.
  const ProxyModel& proxy_model(uint32_t i) const { return devices_[i].model; }
  /// The proxy state of device `i`: from the haptic thread, or while it is not ticking.
  const ProxyState& proxy_state(uint32_t i) const { return devices_[i].proxy; }
  /// The last tick's proxy result of device `i`: same thread rule as proxy_state.
  const ProxyTickResult& last_result(uint32_t i) const { return devices_[i].last_result; }
  /// Whether device `i`'s input was fresh at the last tick: same thread rule as proxy_state.
  bool input_fresh(uint32_t i) const { return devices_[i].fresh; }
  /// The local patch (mode patch; null otherwise): from the haptic thread, or while it is not
  /// ticking.
  const ClothPatch* patch() const { return patch_.get(); }
  /// The loop's own counters (any thread).
  const HapticCounters& counters() const { return counters_; }

 private:
  struct Device {
    Device(DeviceSpec device, SafetySpec safety_rules, ProxyModel proxy_model,
           ProxyState proxy_state)
        : spec(std::move(device)),
          safety_spec(safety_rules),
          model(std::move(proxy_model)),
          proxy(std::move(proxy_state)) {}
    DeviceSpec spec;
    SafetySpec safety_spec;
    ProxyModel model;  ///< compiled once from spec and the scene's [proxy]
    ProxyState proxy;
    SafetyState safety;
    PointerInput input;
    bool have_input = false;
    bool fresh = false;
    ProxyTickResult last_result;
    std::unique_ptr<DeviceCounters> counters = std::make_unique<DeviceCounters>();
  };

  /// The cloth of one tick: the newest snapshot, the one before it, and their age.
  struct TickCloth {
    const ClothSnapshot* newest = nullptr;
    const ClothSnapshot* previous = nullptr;  ///< nullptr before the second snapshot
    double since_newest_s = 0.0;              ///< time since the newest was published, s
    double horizon_s = 0.0;  ///< the newest is extrapolated at most this long past it, s
    bool stalled = false;    ///< older than the [haptic] sim_stall limit
  };

  TickCloth TakeNewestSnapshot(int64_t now_ns, bool* arrived);
  void StepPatch(const TickCloth& cloth, double dt_s);
  // Mode patch: copies this tick's contact springs for the next tick's StepPatch.
  void KeepPatchSprings();
  void StageReactions();
  void TickDevice(uint32_t index, int64_t now_ns, double dt_s, const TickCloth& cloth);
  bool ReadInput(uint32_t index, int64_t now_ns, Device* d);
  SafetyOutput ApplyDeviceSafety(const TickCloth& cloth, bool input_nan, double dt_s, Device* d);
  void SendForce(uint32_t index, int64_t now_ns, const SafetyOutput& out, Device* d);

  int64_t stale_ns_;
  int64_t stall_ns_;
  SnapshotBuffer* snapshots_;
  ReactionQueue* reactions_;
  PointerSource* source_;
  ForceSink* sink_;
  LoopStats* stats_;

  // The newest and the previous snapshot, each swapped out of the read slot when it arrived (no
  // deep copy), alternating between the two copies.
  std::vector<ClothSnapshot> copies_;  // [2]
  int newest_copy_ = -1;               // index into copies_ of the newest (-1: none yet)
  int previous_copy_ = -1;             // index into copies_ of the previous (-1: none yet)
  uint64_t newest_frame_ = 0;

  // The staged reaction batch waits for room in the queue.
  std::unique_ptr<ReactionBatch> staged_;
  bool staged_pending_ = false;

  std::vector<Device> devices_;
  HapticCounters counters_;

  // Mode patch: the local patch, the overlay the proxies read, and the tick's scratch.
  std::unique_ptr<ClothPatch> patch_;
  PatchOverlay overlay_;
  std::vector<int32_t> patch_centres_;        // [devices]
  std::vector<ExternalForce> patch_springs_;  // [devices] the last tick's contact springs
  int32_t patch_spring_count_ = 0;            // entries of patch_springs_ in use
};

}  // namespace felt
