#pragma once
// Runs a loop body periodically with real-time settings and records its statistics: the shared
// skeleton of the haptic thread, the sim thread, `felt run` and `felt bench loops`.

#include <atomic>
#include <cstdint>
#include <functional>
#include <thread>
#include <utility>

#include "rt/arrival_signal.h"
#include "rt/loop_stats.h"
#include "rt/periodic_loop.h"
#include "rt/realtime.h"

namespace felt {

/// How RunLoop() runs a body.
struct LoopRunOptions {
  int64_t period_ns = 1'000'000;  ///< the loop's period (1 kHz by default)
  int64_t duration_ns = 0;        ///< stop after this long from the first deadline; 0 = no limit
  RealtimeSettings realtime;      ///< applied to the loop's thread first (spin_us sets the spin)
  const std::atomic<bool>* stop = nullptr;  ///< stop when this becomes true (checked every tick)
  /// Tick on the arrivals this signal counts, the periodic deadline as fallback
  /// (PeriodicLoop::WakeOnArrival); nullptr: periodic only. Must outlive the run.
  const ArrivalSignal* arrival = nullptr;
  /// Called on the loop's thread once the real-time settings are applied, before the first tick,
  /// with what was granted (set-up: may allocate). Empty: nothing is called.
  std::function<void(const RealtimeReport&)> on_started;
};

/// Throws std::invalid_argument when `options` cannot run (no end, bad period or spin).
void ValidateLoopRunOptions(const LoopRunOptions& options);

/// Runs `body(const TickInfo&)` once per period on the calling thread until `duration_ns` has
/// passed or `*stop` is true, recording every tick (lateness, period, compute time, overruns,
/// skipped periods) into `*stats`, which a monitor thread may read meanwhile. Applies
/// `options.realtime` to the calling thread first (set-up: logs refusals) and returns what was
/// granted. Needs a duration or a stop flag (else throws std::invalid_argument). The per-tick
/// part is real-time safe when `body` is.
template <typename Body>
RealtimeReport RunLoop(const LoopRunOptions& options, LoopStats* stats, Body&& body);

/// RunLoop() on a new thread that is joined before returning, so the real-time settings apply to
/// that thread only (mlockall, if requested, stays in force for the process).
template <typename Body>
RealtimeReport RunLoopOnThread(const LoopRunOptions& options, LoopStats* stats, Body&& body) {
  ValidateLoopRunOptions(options);  // throw here, not on the thread
  RealtimeReport report;
  std::thread thread([&] { report = RunLoop(options, stats, std::forward<Body>(body)); });
  thread.join();
  return report;
}

template <typename Body>
RealtimeReport RunLoop(const LoopRunOptions& options, LoopStats* stats, Body&& body) {
  // Set-up: validate, apply the real-time settings, start one period from now.
  ValidateLoopRunOptions(options);
  const RealtimeReport report = ApplyRealtime(options.realtime);
  if (options.on_started) options.on_started(report);
  PeriodicLoop loop(options.period_ns, int64_t{options.realtime.spin_us} * 1000);
  loop.WakeOnArrival(options.arrival);
  const int64_t start_ns = MonotonicNowNs() + options.period_ns;
  const int64_t end_ns = options.duration_ns > 0 ? start_ns + options.duration_ns : INT64_MAX;
  loop.Start(start_ns);

  // The ticks: wait, run the body, record.
  while (options.stop == nullptr || !options.stop->load(std::memory_order_relaxed)) {
    const TickInfo tick = loop.WaitNext();
    if (tick.deadline_ns >= end_ns) {
      // A stall over the end: the boundaries it skipped that were due before the end are skipped
      // periods of this run (boundary k is due at start + k period; those below `due` count).
      const uint64_t first_skipped = tick.period_index - tick.periods_skipped;
      const uint64_t due =
          static_cast<uint64_t>((end_ns - start_ns + options.period_ns - 1) / options.period_ns);
      stats->RecordEndOfRun(tick, due > first_skipped ? due - first_skipped : 0);
      break;
    }
    body(tick);
    stats->RecordTick(tick, MonotonicNowNs() - tick.wake_ns);
  }
  return report;
}

}  // namespace felt
