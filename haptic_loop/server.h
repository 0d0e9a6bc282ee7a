#pragma once
// The dual-loop real-time server (issue 5; docs/server.md): a 60 Hz sim thread, a 1 kHz haptic
// thread and a monitor thread around one cloth and any number of devices.
//
// Sim thread, each frame: pop the reaction batches the haptic thread queued (SPSC queue) and turn
// them into the frame's ExternalForce list, StepFrame, fill the triple buffer's write slot with the
// cloth and the frame's motion as its velocities (FillSnapshotWithFrameMotion, proxy/
// frame_motion.h; repairing the collision structure), stamp the publication time, Publish.
//
// Haptic thread, each tick (HapticTick, real-time safe): Acquire the newest snapshot (no wait);
// when a new one arrived, copy the one before it into a preallocated "previous" snapshot (for the
// snapshot modes that blend two cloths; copy-assignment of equally sized snapshots does not
// allocate) and hand the reactions of the frame that ended to the sim; then per device: read the
// newest pointer sample (PointerSource), run ProxyTick while the input is fresh, apply the safety
// layer (haptic_loop/safety.h), push the force (ForceSink) and record statistics.
//
// Reaction handoff, nothing lost: every device's ProxyState::reaction accumulates the impulses on
// the cloth over a frame. When a new snapshot arrives the haptic thread drains all of them into
// one ReactionBatch staged in the server (forces are time averages over the batch's duration) and
// TryPushes it on the SPSC queue; if the queue is full the batch stays staged and is pushed again
// next tick, and the accumulators keep accumulating meanwhile (they are drained only once the
// staged batch is gone), so no impulse is dropped. The sim applies the batches it pops in one
// frame weighted by their durations (impulse-preserving).
//
// Monitor thread: once per monitor period, logs FormatMonitorLine plus the server's counters with
// spdlog and calls the status callback (the DDS transport's PublishStatus in `felt serve`).
#include <array>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "haptic_loop/loop_stats.h"
#include "haptic_loop/pointer_source.h"
#include "haptic_loop/realtime.h"
#include "haptic_loop/safety.h"
#include "haptic_loop/server_spec.h"
#include "haptic_loop/spsc_queue.h"
#include "haptic_loop/triple_buffer.h"
#include "proxy/proxy.h"
#include "sim_loop/cloth.h"
#include "sim_loop/snapshot.h"

namespace felt {

/// The most reaction forces one batch holds (all devices together); beyond it, forces merge into
/// the last entry (total kept, counted by ReactionAccumulator::overflows()).
inline constexpr int32_t kMaxReactionForces = 1024;

/// The reactions of all devices over one sim frame, haptic -> sim. Plain fixed-size data.
struct ReactionBatch {
  int32_t count = 0;      ///< entries used in `forces`
  double duration_s = 0;  ///< haptic time the forces are averaged over, s
  std::array<ExternalForce, kMaxReactionForces> forces;  ///< world frame, N (time averages)
};

/// A published snapshot plus when it was published.
struct PublishedSnapshot {
  ClothSnapshot snapshot;  ///< the cloth of one frame
  int64_t publish_ns = 0;  ///< CLOCK_MONOTONIC at Publish, ns (0: the initial rest state)
};

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

/// A plain copy of one device's counters.
struct DeviceReport {
  std::string id;                 ///< the device id
  uint64_t ticks_with_input = 0;  ///< see DeviceCounters
  uint64_t contact_ticks = 0;
  uint64_t stale_ticks = 0;
  uint64_t ramping_ticks = 0;
  uint64_t clamped_ticks = 0;
  uint64_t stalled_ticks = 0;
  uint64_t nan_events = 0;
  uint64_t connects = 0;
  uint64_t forces_sent = 0;
  double peak_force_N = 0;
  double max_force_N = 0;  ///< the device's clamp
  double energy_J = 0;
  double dissipated_J = 0;
  double reaction_impulse_N_s = 0;
  bool connected = false;
};

/// Everything the server reports: loop statistics plus counters. Large (two LoopStatsSnapshots):
/// keep it on the heap.
struct ServerReport {
  LoopStatsSnapshot haptic;               ///< the 1 kHz loop
  LoopStatsSnapshot sim;                  ///< the 60 Hz loop
  bool realtime = false;                  ///< SCHED_FIFO granted to the haptic thread
  bool sim_realtime = false;              ///< SCHED_FIFO granted to the sim thread
  bool cpu_dma_latency_zero = false;      ///< /dev/cpu_dma_latency held at 0 while running
  std::string haptic_realtime_summary;    ///< RealtimeReport::Summary of the haptic thread
  std::string sim_realtime_summary;       ///< ... of the sim thread
  uint64_t body_ticks = 0;                ///< HapticTick calls (the body's own count)
  uint64_t sim_stalled_ticks = 0;         ///< ticks at which the snapshot was older than the limit
  bool sim_stalled = false;               ///< the last tick saw a stalled sim
  uint64_t reaction_batches = 0;          ///< batches pushed haptic -> sim
  uint64_t reaction_batches_applied = 0;  ///< batches the sim applied
  uint64_t reaction_queue_full = 0;       ///< ticks a staged batch waited for room (not lost)
  uint64_t reaction_overflows = 0;        ///< accumulator entries merged for lack of room
  uint64_t cloth_nan_events = 0;          ///< sim frames that recovered from non-finite values
  uint64_t contacts = 0;                  ///< device ticks in contact, all devices
  double peak_force_N = 0;                ///< largest |force| sent, all devices, N
  uint64_t nan_events = 0;                ///< safety NaN events, all devices
  double energy_J = 0;                    ///< passivity observer summed over devices, J
  uint32_t devices_connected = 0;         ///< devices with fresh input at the last tick
  std::vector<DeviceReport> devices;      ///< per device, in scene order
};

/// How a Server runs (beyond the scene).
struct ServerOptions {
  bool apply_realtime = true;  ///< apply the [haptic] real-time settings; false: normal threads
  bool monitor_log = true;     ///< log the monitor line once per period
  /// Called by the monitor thread once per period with a fresh report (e.g. PublishStatus).
  std::function<void(const ServerReport&)> on_report;
};

/// The server: owns the cloth, the proxies and the three threads. Construction is set-up
/// (allocates, validates); Start() launches the threads; Stop() (or destruction) joins them.
class Server {
 public:
  /// Builds the cloth, the snapshots and one proxy + safety state per device. `source` and
  /// `sink` must outlive the server and have room for spec.devices.size() devices. Throws
  /// std::invalid_argument naming the field for a bad spec (no devices, a bad safety value, a
  /// cloth BuildClothModel refuses).
  Server(ServerSpec spec, PointerSource* source, ForceSink* sink, ServerOptions options = {});
  /// Stops and joins the threads.
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  /// Starts the sim, haptic and monitor threads. Call once.
  void Start();
  /// Asks the threads to stop and joins them (idempotent). Not from a signal handler: set a flag
  /// there and call Stop() from a normal thread.
  void Stop();
  /// True between Start() and Stop().
  bool running() const { return running_; }

  /// One haptic tick at CLOCK_MONOTONIC `now_ns` for a tick of `dt_s` [s]: what the haptic thread
  /// runs each period (public so tests and the benchmark can drive it). Haptic thread only (one
  /// thread at a time). Real-time safe: no allocation, lock, log, exception or I/O.
  void HapticTick(int64_t now_ns, double dt_s);
  /// One sim frame of `frame_dt_s` [s], its snapshot stamped as published at CLOCK_MONOTONIC
  /// `publish_ns` (0: now, which the sim thread uses): what the sim thread runs each
  /// period (public so tests can drive it on a clock of their own). Sim thread only (one thread
  /// at a time). Real-time safe (StepFrame's one-time NaN log and the stall hook aside).
  void SimFrame(double frame_dt_s, int64_t publish_ns);

  /// Publishes the rest state (frame 0) stamped as published at `publish_ns` [ns, the caller's
  /// clock]: what Start() does with CLOCK_MONOTONIC before launching the threads, public so a
  /// caller driving HapticTick and SimFrame on a clock of its own (haptic_loop/lockstep.h) starts
  /// the same way. Only while the threads are not running.
  void PublishInitialSnapshot(int64_t publish_ns);

  /// Test hook: the sim thread's next frame first blocks for `duration_ns` (a stalled sim).
  void InjectSimStall(int64_t duration_ns) { stall_request_ns_.store(duration_ns); }

  /// A fresh report (statistics and counters). Any thread; allocates.
  std::unique_ptr<ServerReport> Report() const;
  /// The stats document (docs/server.md, "Stats"): haptic, sim, realtime, safety, devices.
  static std::string ReportJson(const ServerReport& report);
  /// One line of counters for the monitor log ("contacts 12 peak 1.2 N stale 0 nan 0 ...").
  static std::string FormatCounters(const ServerReport& report);

  /// The spec the server runs (validated).
  const ServerSpec& spec() const { return spec_; }
  /// The cloth model.
  const ClothModel& model() const { return model_; }
  /// The cloth state. Only while the sim thread is not running (before Start, after Stop, or
  /// from the thread that drives SimFrame).
  const ClothState& cloth() const { return cloth_; }
  /// The cloth's sim frames stepped so far (sim thread's count; any thread).
  uint64_t sim_frames() const { return sim_frames_.load(std::memory_order_acquire); }
  /// Sim time of the newest frame [s]: frames x 1 / frame_rate_hz (skipped periods are dropped).
  double sim_time_s() const { return sim_time_s_.load(std::memory_order_acquire); }
  /// Total reaction impulse the sim has applied to the cloth, N s (any thread).
  double applied_impulse_N_s() const { return applied_impulse_N_s_.load(); }

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
    const ProxyModel model;  ///< compiled once from spec and the scene's [proxy]
    ProxyState proxy;
    SafetyState safety;
    PointerInput input;
    bool have_input = false;
    bool fresh = false;
    uint64_t last_seq = 0;
    ProxyTickResult last_result;
    std::unique_ptr<DeviceCounters> counters = std::make_unique<DeviceCounters>();
  };

  void HapticThread();
  void SimThread();
  void MonitorThread();
  void StageReactions();

  ServerSpec spec_;
  ClothModel model_;
  ClothState cloth_;
  PointerSource* source_;
  ForceSink* sink_;
  ServerOptions options_;
  double haptic_dt_s_;
  double sim_dt_s_;

  // Sim -> haptic: newest snapshot. Haptic-owned, in modes that need the previous snapshot: the
  // newest and the previous, each swapped out of the read slot when it arrived (no deep copy).
  std::unique_ptr<TripleBuffer<PublishedSnapshot>> snapshots_;
  std::vector<ClothSnapshot> copies_;  // [2] the newest and the previous, alternating
  int newest_copy_ = -1;               // index into copies_ of the newest (-1: none yet)
  int previous_copy_ = -1;             // index into copies_ of the previous (-1: none yet)
  uint64_t newest_frame_ = 0;
  uint64_t sim_frame_counter_ = 0;
  // Sim-owned: the published positions of the last frame and the frame-motion velocities
  // (proxy/frame_motion.h), [particles] each, sized once.
  std::vector<Vec3> frame_start_x_;
  std::vector<Vec3> frame_motion_v_;

  // Haptic -> sim: reaction batches; the staged one waits for room.
  std::unique_ptr<SpscQueue<ReactionBatch>> reactions_;
  std::unique_ptr<ReactionBatch> staged_;
  bool staged_pending_ = false;
  std::unique_ptr<ReactionBatch> popped_;  // sim-owned scratch
  std::vector<ExternalForce> external_;    // sim-owned, sized once

  std::vector<Device> devices_;

  // Statistics.
  std::unique_ptr<LoopStats> haptic_stats_;
  std::unique_ptr<LoopStats> sim_stats_;
  std::atomic<uint64_t> body_ticks_{0};
  std::atomic<uint64_t> sim_stalled_ticks_{0};
  std::atomic<bool> sim_stalled_{false};
  std::atomic<uint64_t> reaction_batches_{0};
  std::atomic<uint64_t> reaction_batches_applied_{0};
  std::atomic<uint64_t> reaction_queue_full_{0};
  std::atomic<uint64_t> sim_frames_{0};
  std::atomic<double> sim_time_s_{0.0};
  std::atomic<uint64_t> cloth_nan_events_{0};
  std::atomic<double> applied_impulse_N_s_{0.0};
  std::atomic<int64_t> stall_request_ns_{0};

  // Threads and their real-time outcome (written before `*_ready_`, read after).
  std::atomic<bool> stop_{false};
  bool running_ = false;
  RealtimeReport haptic_report_;
  std::unique_ptr<CpuDmaLatencyHold> dma_hold_;  // between Start and Stop, when requested
  std::atomic<bool> dma_held_{false};            // the hold was granted (kept after Stop)
  RealtimeReport sim_report_;
  std::atomic<bool> haptic_ready_{false};
  std::atomic<bool> sim_ready_{false};
  std::thread sim_thread_;
  std::thread haptic_thread_;
  std::thread monitor_thread_;
  std::mutex monitor_mutex_;  // monitor thread's sleep only (never on a loop thread)
  std::condition_variable monitor_wake_;
};

}  // namespace felt
