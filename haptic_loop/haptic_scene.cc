#include <optional>
#include <span>

#include "haptic_loop/haptic_spec.h"

namespace felt {

HapticSpec ParseHapticSpec(const SceneDocument& doc) {
  HapticSpec spec;
  const std::optional<SceneTable> table = SceneTable::Section(doc, "haptic");
  if (!table) return spec;
  table->ExpectKeys({"haptic_priority", "haptic_spin_us", "haptic_cpu", "sim_priority", "sim_cpu",
                     "lock_memory", "timer_slack_ns", "haptic_rate_hz", "stale_input_ms",
                     "sim_stall_ms", "ramp_in_s", "ramp_out_s", "max_force_rate_N_per_s",
                     "passivity_controller", "max_passivity_damping_N_s_per_m", "monitor_period_s",
                     "cpu_dma_latency_zero", "tick", "tick_device"});
  RealtimeSettings& h = spec.haptic_realtime;
  RealtimeSettings& s = spec.sim_realtime;
  h.fifo_priority = table->Integer("haptic_priority", h.fifo_priority, InRange(0, 99));
  h.spin_us = table->Integer("haptic_spin_us", h.spin_us, InRange(0, 500));
  h.cpu = table->Integer("haptic_cpu", h.cpu, AtLeast(-1));
  s.fifo_priority = table->Integer("sim_priority", s.fifo_priority, InRange(0, 99));
  s.cpu = table->Integer("sim_cpu", s.cpu, AtLeast(-1));
  h.lock_memory = s.lock_memory = table->Bool("lock_memory", h.lock_memory);
  h.timer_slack_ns = s.timer_slack_ns =
      table->Integer("timer_slack_ns", static_cast<int32_t>(h.timer_slack_ns), InRange(0, 1e9));
  spec.haptic_rate_hz = table->Number("haptic_rate_hz", spec.haptic_rate_hz, InRange(100, 10000));
  if (h.spin_us * 1e-6 >= 1.0 / spec.haptic_rate_hz) {
    table->Fail("haptic_spin_us", "must be shorter than the haptic period");
  }
  spec.stale_input_s = table->Number("stale_input_ms", spec.stale_input_s * 1e3, Positive()) / 1e3;
  spec.sim_stall_s = table->Number("sim_stall_ms", spec.sim_stall_s * 1e3, Positive()) / 1e3;
  spec.monitor_period_s =
      table->Number("monitor_period_s", spec.monitor_period_s, InRangeOpenMin(0.0, 3600.0));
  spec.cpu_dma_latency_zero = table->Bool("cpu_dma_latency_zero", spec.cpu_dma_latency_zero);
  static constexpr NamedValue<HapticTickTrigger> kTicks[] = {
      {"arrival", HapticTickTrigger::kArrival}, {"periodic", HapticTickTrigger::kPeriodic}};
  spec.tick_trigger = table->Choice<HapticTickTrigger>(
      "tick", spec.tick_trigger, std::span<const NamedValue<HapticTickTrigger>>(kTicks));
  spec.tick_device = table->String("tick_device", spec.tick_device);  // checked by the server
  SafetySpec& safety = spec.safety;
  safety.ramp_in_s = table->Number("ramp_in_s", safety.ramp_in_s, Positive());
  safety.ramp_out_s = table->Number("ramp_out_s", safety.ramp_out_s, Positive());
  safety.max_force_rate_N_per_s =
      table->Number("max_force_rate_N_per_s", safety.max_force_rate_N_per_s, Positive());
  safety.passivity_controller = table->Bool("passivity_controller", safety.passivity_controller);
  safety.max_passivity_damping_N_s_per_m = table->Number(
      "max_passivity_damping_N_s_per_m", safety.max_passivity_damping_N_s_per_m, NonNegative());
  return spec;
}

SafetySpec DeviceSafetySpec(const HapticSpec& haptic, const DeviceSpec& device) {
  SafetySpec safety = haptic.safety;
  safety.max_force_N = device.max_force_N;
  return safety;
}

}  // namespace felt
