#pragma once
// The dual-loop real-time server (docs/server.md): the 60 Hz sim loop (sim_loop/sim_frame.h), the
// 1 kHz haptic loop (haptic_loop/haptic_tick.h) and a monitor, each on a thread of its own, around
// one cloth and any number of devices. The loops' threads run rt/loop_runner.h's RunLoop (absolute
// deadlines, skipped periods counted, real-time settings applied when permitted).
//
// Monitor thread: once per monitor period, logs FormatMonitorLine plus the server's counters with
// spdlog and calls the status callback (the DDS transport's PublishStatus in `felt serve`).
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

#include "base/non_copyable.h"
#include "haptic_loop/haptic_tick.h"
#include "haptic_loop/pointer_source.h"
#include "rt/loop_runner.h"
#include "rt/loop_stats.h"
#include "rt/realtime.h"
#include "server/server_spec.h"
#include "server/view_tap.h"
#include "sim_loop/sim_frame.h"

namespace felt {

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

/// A plain copy of device counters `c` of the device `spec` (any thread; allocates).
DeviceReport ReportDevice(const DeviceSpec& spec, const DeviceCounters& c);

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
  uint64_t held_spring_frames = 0;        ///< sim frames that reused the last batch's springs
  uint64_t patch_ticks = 0;               ///< mode patch: ticks that stepped a window
  uint64_t patch_nan_events = 0;          ///< mode patch: steps restarted from the 60 Hz cloth
  uint64_t guard_pushes = 0;        ///< triangles the sim's proxy sphere guard pushed (substeps)
  uint64_t patch_guard_pushes = 0;  ///< mode patch: triangles the patch's sphere guard pushed
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
class Server : NonCopyable {
 public:
  /// Builds the cloth, the snapshots and one proxy + safety state per device. `source` and
  /// `sink` must outlive the server and have room for spec.devices.size() devices. Throws
  /// std::invalid_argument naming the field for a bad spec (no devices, a bad safety value, a
  /// cloth BuildClothModel refuses, a haptic.tick_device that is not a device).
  Server(ServerSpec spec, PointerSource* source, ForceSink* sink, ServerOptions options = {});
  /// Stops and joins the threads.
  ~Server();

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
  /// caller driving HapticTick and SimFrame on a clock of its own (compare/lockstep.h) starts
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
  const ClothModel& model() const { return sim_.model(); }
  /// The cloth state. Only while the sim thread is not running (before Start, after Stop, or
  /// from the thread that drives SimFrame).
  const ClothState& cloth() const { return sim_.cloth(); }
  /// The cloth's sim frames stepped so far (sim thread's count; any thread).
  uint64_t sim_frames() const { return sim_.counters().frames.load(std::memory_order_acquire); }
  /// Sim time of the newest frame [s]: frames x 1 / frame_rate_hz (skipped periods are dropped).
  double sim_time_s() const { return sim_.counters().time_s.load(std::memory_order_acquire); }
  /// The haptic loop (its proxies' state: only from the thread driving HapticTick, or while the
  /// haptic thread is not running).
  const HapticLoop& haptic() const { return haptic_; }
  /// Total reaction impulse the sim has applied to the cloth, N s (any thread).
  double applied_impulse_N_s() const { return sim_.counters().applied_impulse_N_s.load(); }

  /// Makes the loops publish the cloth (each frame) and the devices (each tick) into a tap for
  /// one observer thread (server/view_tap.h, the live view) and returns it; idempotent. Call
  /// before Start (throws std::logic_error after it) or while driving the loops yourself (set-up:
  /// allocates). Lives with the server.
  ViewTap* EnableViewTap();
  /// The tap (null unless EnableViewTap was called). Its read sides belong to one observer thread.
  ViewTap* view_tap() const { return view_tap_.get(); }
  /// A tap of its own for another observer thread (the ROS 2 marker feed,
  /// server/ros2_marker_feed.h), filled like the view's: each call adds one (at most
  /// kMaxObserverTaps in all, the view's included; throws std::length_error beyond). Same rules as
  /// EnableViewTap: before Start (throws std::logic_error after it); set-up, allocates.
  ViewTap* AddObserverTap();
  /// The most taps the loops fill (each costs a copy of the cloth per frame, of the devices per
  /// tick).
  static constexpr size_t kMaxObserverTaps = 4;

 private:
  // Copies the cloth's positions into each tap's cloth slot and publishes it (taps only).
  void PublishViewCloth();
  // Copies the cloth's positions into one tap's cloth slot and publishes it.
  void PublishViewCloth(ViewTap* tap);
  // Copies the devices of the last tick into each tap's devices slot and publishes it.
  void PublishViewDevices();
  // A new tap, filled with the current cloth, its pointer appended to taps_ (set-up).
  std::unique_ptr<ViewTap> NewTap();
  void HapticThread();
  void SimThread();
  void MonitorThread();
  // RunLoop's options for a loop thread at `rate_hz` with `realtime` (when applied), recording
  // what was granted into `*granted` and then setting `*ready`.
  LoopRunOptions ThreadLoop(double rate_hz, const RealtimeSettings& realtime,
                            RealtimeReport* granted, std::atomic<bool>* ready) const;

  ServerSpec spec_;
  ServerOptions options_;
  double haptic_dt_s_;
  double sim_dt_s_;
  std::unique_ptr<LoopStats> haptic_stats_;
  std::unique_ptr<LoopStats> sim_stats_;
  SimLoop sim_;
  HapticLoop haptic_;
  std::atomic<int64_t> stall_request_ns_{0};
  PointerSource* source_;  // the haptic loop's source (for its arrival signal)
  int tick_device_;        // TickDeviceIndex: the device whose arrivals trigger the tick
  std::unique_ptr<ViewTap> view_tap_;  // null unless EnableViewTap (written before the threads)
  std::vector<std::unique_ptr<ViewTap>> observer_taps_;  // AddObserverTap's (before the threads)
  // Every tap the loops fill (view_tap_ and observer_taps_; reserved kMaxObserverTaps: the loops
  // iterate it without allocating; written before the threads).
  std::vector<ViewTap*> taps_;

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
