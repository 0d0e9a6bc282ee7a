#pragma once
// What a scene's [haptic] section declares about the server's loops and safety (docs/server.md):
//
//   [haptic]
//   haptic_priority = 80        # SCHED_FIFO priority of the 1 kHz thread, 0 = normal scheduling
//   haptic_spin_us = 50         # sleep to this many us before each deadline, then spin; 0 = none
//   haptic_cpu = -1             # pin the haptic thread to this CPU, -1 = no pinning
//   sim_priority = 70           # SCHED_FIFO priority of the 60 Hz sim thread, 0 = normal
//   sim_cpu = -1                # pin the sim thread, -1 = no pinning
//   lock_memory = true          # mlockall(MCL_CURRENT | MCL_FUTURE)
//   timer_slack_ns = 1          # PR_SET_TIMERSLACK of both loop threads, 0 = leave as is
//   stale_input_ms = 50         # no new pointer sample for longer: the force ramps to zero
//   sim_stall_ms = 100          # no new snapshot for longer: forces flagged "sim stalled"
//   ramp_in_s = 0.5             # force gain 0 -> 1 at start and after a reconnect
//   ramp_out_s = 0.05           # force gain 1 -> 0 once the input is stale
//   max_force_rate_N_per_s = 500  # jerk limit
//   passivity_controller = false  # Hannaford & Ryu 2002 damping when the observed energy < 0
//   max_passivity_damping_N_s_per_m = 50
//   monitor_period_s = 1.0      # the monitor's log line and status period
//   cpu_dma_latency_zero = true # hold /dev/cpu_dma_latency at 0 while running (no deep C-states)
//   tick = "arrival"            # "arrival": tick when tick_device's sample arrives, the periodic
//                               # deadline as fallback; "periodic": every period only
//   tick_device = ""            # the device whose samples trigger the tick ("": the first)
#include <string>

#include "haptic_loop/safety.h"
#include "proxy/proxy_spec.h"
#include "rt/realtime.h"
#include "scene/scene_file.h"

namespace felt {

/// When the haptic tick runs (docs/server.md, "The tick: periodic or on arrival").
enum class HapticTickTrigger {
  kPeriodic,  ///< at every period boundary start + k * period
  kArrival,   ///< as soon as the trigger device's sample arrives, at most at the boundary
};

/// The [haptic] section: loop timing and safety shared by every device.
struct HapticSpec {
  RealtimeSettings haptic_realtime{.fifo_priority = 80,
                                   .cpu = -1,
                                   .lock_memory = true,
                                   .spin_us = 50,
                                   .timer_slack_ns = 1};  ///< the 1 kHz thread
  RealtimeSettings sim_realtime{.fifo_priority = 70,
                                .cpu = -1,
                                .lock_memory = true,
                                .spin_us = 0,
                                .timer_slack_ns = 1};  ///< the 60 Hz sim thread
  double haptic_rate_hz = 1000.0;                      ///< the haptic tick rate, Hz (100..10000)
  double stale_input_s = 0.050;                        ///< input older than this is stale, s (> 0)
  double sim_stall_s = 0.100;     ///< a snapshot older than this means a stalled sim, s (> 0)
  double monitor_period_s = 1.0;  ///< monitor log / status period, s (> 0)
  /// Hold /dev/cpu_dma_latency at 0 while the server runs (with the real-time settings): idle
  /// CPUs then never enter deep sleep states, whose wake-up costs the 1 kHz loop milliseconds on
  /// these VMs (shared/notes/cyclonedds-and-realtime.md; a 10-minute soak measured p99 lateness
  /// 1568 us without it and 17 us with it).
  bool cpu_dma_latency_zero = true;
  /// When the tick runs: on arrival of tick_device's samples (a sample is answered ~0.1 ms after
  /// it arrives instead of 0..1 ms later; bench/results/transport.md), with the periodic
  /// deadline as fallback and bound, or periodically only.
  HapticTickTrigger tick_trigger = HapticTickTrigger::kArrival;
  /// The id of the device whose arrivals trigger the tick; "" = the scene's first device.
  std::string tick_device;
  /// Safety rules shared by every device; max_force_N is replaced per device by its own.
  SafetySpec safety;
};

/// Reads [haptic] (absent: the defaults above). Throws SceneError naming the field.
HapticSpec ParseHapticSpec(const SceneDocument& doc);

/// The safety rules of `device`: the scene's [haptic] rules with the device's max_force_N.
SafetySpec DeviceSafetySpec(const HapticSpec& haptic, const DeviceSpec& device);

}  // namespace felt
