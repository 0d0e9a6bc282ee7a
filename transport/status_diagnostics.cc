#include "transport/status_diagnostics.h"

#include <string>
#include <utility>

#include "recordings/trace.h"

namespace felt::transport {
namespace {

std::string DiagnosticNumber(double v) {
  std::string s;
  AppendTraceNumber(v, -1, &s);
  return s;
}

}  // namespace

ros2::DiagnosticArray StatusDiagnostics(const ServerStatusView& s) {
  ros2::DiagnosticArray d;
  d.header.stamp = ros2::TimeFromNs(s.wall_time_ns);
  ros2::DiagnosticStatus st;
  st.name = "felt: server " + s.server_id;
  st.hardware_id = s.server_id;
  st.level = s.sim_stalled || s.nan_events > 0 ? ros2::DiagnosticStatus::kWarn
                                               : ros2::DiagnosticStatus::kOk;
  st.message = s.sim_stalled ? "sim stalled" : (s.nan_events > 0 ? "non-finite forces" : "ok");
  auto add = [&](const char* key, const std::string& value) { st.values.push_back({key, value}); };
  auto add_p = [&](const std::string& key, const PercentilesView& p) {
    add((key + ".p50").c_str(), DiagnosticNumber(p.p50));
    add((key + ".p99").c_str(), DiagnosticNumber(p.p99));
    add((key + ".p999").c_str(), DiagnosticNumber(p.p999));
    add((key + ".max").c_str(), DiagnosticNumber(p.max));
  };
  add("realtime", s.realtime ? "true" : "false");
  add("haptic_ticks", std::to_string(s.haptic_ticks));
  add("haptic_overruns", std::to_string(s.haptic_overruns));
  add_p("haptic_lateness_us", s.haptic_lateness_us);
  add_p("haptic_compute_us", s.haptic_compute_us);
  add("sim_frames", std::to_string(s.sim_frames));
  add_p("sim_frame_ms", s.sim_frame_ms);
  add_p("snapshot_age_ms", s.snapshot_age_ms);
  add("sim_stalled", s.sim_stalled ? "true" : "false");
  add("rejected_nonfinite", std::to_string(s.rejected_nonfinite));
  add("rejected_workspace", std::to_string(s.rejected_workspace));
  add("rejected_seq", std::to_string(s.rejected_seq));
  add("rejected_unknown_device", std::to_string(s.rejected_unknown_device));
  add("rejected_flood", std::to_string(s.rejected_flood));
  add("rejected_not_owner", std::to_string(s.rejected_not_owner));
  add("pointer_accepted", std::to_string(s.pointer_accepted));
  add("forces_published", std::to_string(s.forces_published));
  add("forces_queue_full", std::to_string(s.forces_queue_full));
  add("dds_errors", std::to_string(s.dds_errors));
  add("incompatible_qos", std::to_string(s.incompatible_qos));
  add("nan_events", std::to_string(s.nan_events));
  add("devices_connected", std::to_string(s.devices_connected));
  add("passivity_energy_J", DiagnosticNumber(s.passivity_energy_J));
  d.status.push_back(std::move(st));
  return d;
}

}  // namespace felt::transport
