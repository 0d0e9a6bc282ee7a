#pragma once
// Internal to transport/*.cc: the idlc message <-> view conversions, written once. Real-time safe
// (plain copies, no allocation).

#include <cstdint>
#include <cstring>

#include "felt_types.h"
#include "transport/views.h"

namespace felt::transport {

/// The view of a received PointerSample, taken at CLOCK_MONOTONIC `receive_time_ns` for device
/// `device_index` (the receiver's index of m.device_id).
inline PointerSampleView PointerViewOf(const felt_msgs_PointerSample& m, uint32_t device_index,
                                       int64_t receive_time_ns) {
  PointerSampleView v;
  v.device_index = device_index;
  v.seq = m.seq;
  v.device_time_ns = m.device_time_ns;
  for (int k = 0; k < 3; ++k) {
    v.position_m_D[k] = m.position_m[k];
    v.velocity_m_per_s_D[k] = m.velocity_m_per_s[k];
  }
  v.buttons = m.buttons;
  v.receive_time_ns = receive_time_ns;
  return v;
}

/// The view of a received ForceCommand, taken at CLOCK_MONOTONIC `receive_time_ns` for device
/// `device_index` (the receiver's index of m.device_id).
inline ForceCommandView ForceViewOf(const felt_msgs_ForceCommand& m, uint32_t device_index,
                                    int64_t receive_time_ns) {
  ForceCommandView v;
  v.device_index = device_index;
  v.seq = m.seq;
  v.answers_seq = m.answers_seq;
  v.answers_device_time_ns = m.answers_device_time_ns;
  for (int k = 0; k < 3; ++k) {
    v.force_N_D[k] = m.force_N[k];
    v.proxy_position_m_D[k] = m.proxy_position_m[k];
    v.contact_point_m_D[k] = m.contact_point_m[k];
    v.contact_normal_D[k] = m.contact_normal[k];
  }
  v.in_contact = m.in_contact;
  v.flags = m.flags;
  v.contact_stiffness_N_per_m = m.contact_stiffness_N_per_m;
  v.receive_time_ns = receive_time_ns;
  return v;
}

/// Fills `m` (reused between writes) from `v` for the device with id `device_id` (the
/// felt_msgs_PointerSample.device_id bytes).
inline void FillPointerMessage(const PointerSampleView& v, const char* device_id,
                               felt_msgs_PointerSample* m) {
  std::memcpy(m->device_id, device_id, sizeof(m->device_id));
  m->seq = v.seq;
  m->device_time_ns = v.device_time_ns;
  for (int k = 0; k < 3; ++k) {
    m->position_m[k] = v.position_m_D[k];
    m->velocity_m_per_s[k] = v.velocity_m_per_s_D[k];
  }
  m->buttons = v.buttons;
}

/// Fills `m` (reused between writes) from `v` for the device with id `device_id` (the
/// felt_msgs_ForceCommand.device_id bytes).
inline void FillForceMessage(const ForceCommandView& v, const char* device_id,
                             felt_msgs_ForceCommand* m) {
  std::memcpy(m->device_id, device_id, sizeof(m->device_id));
  m->seq = v.seq;
  m->answers_seq = v.answers_seq;
  m->answers_device_time_ns = v.answers_device_time_ns;
  for (int k = 0; k < 3; ++k) {
    m->force_N[k] = v.force_N_D[k];
    m->proxy_position_m[k] = v.proxy_position_m_D[k];
    m->contact_point_m[k] = v.contact_point_m_D[k];
    m->contact_normal[k] = v.contact_normal_D[k];
  }
  m->in_contact = v.in_contact;
  m->flags = v.flags;
  m->contact_stiffness_N_per_m = v.contact_stiffness_N_per_m;
}

/// The view of a received ServerStatus (every field; the server id up to its terminating NUL).
/// Allocates (the id is a std::string): not for the haptic thread.
inline ServerStatusView StatusViewOf(const felt_msgs_ServerStatus& m) {
  const auto copy = [](const felt_msgs_Percentiles& in) {
    return PercentilesView{in.p50, in.p99, in.p999, in.max};
  };
  ServerStatusView v;
  v.server_id.assign(m.server_id, strnlen(m.server_id, sizeof(m.server_id)));
  v.wall_time_ns = m.wall_time_ns;
  v.realtime = m.realtime;
  v.haptic_ticks = m.haptic_ticks;
  v.haptic_overruns = m.haptic_overruns;
  v.haptic_lateness_us = copy(m.haptic_lateness_us);
  v.haptic_compute_us = copy(m.haptic_compute_us);
  v.sim_frames = m.sim_frames;
  v.sim_frame_ms = copy(m.sim_frame_ms);
  v.snapshot_age_ms = copy(m.snapshot_age_ms);
  v.sim_stalled = m.sim_stalled;
  v.rejected_nonfinite = m.rejected_nonfinite;
  v.rejected_workspace = m.rejected_workspace;
  v.rejected_seq = m.rejected_seq;
  v.rejected_unknown_device = m.rejected_unknown_device;
  v.rejected_flood = m.rejected_flood;
  v.rejected_not_owner = m.rejected_not_owner;
  v.pointer_accepted = m.pointer_accepted;
  v.forces_published = m.forces_published;
  v.forces_queue_full = m.forces_queue_full;
  v.dds_errors = m.dds_errors;
  v.incompatible_qos = m.incompatible_qos;
  v.nan_events = m.nan_events;
  v.devices_connected = m.devices_connected;
  v.passivity_energy_J = m.passivity_energy_J;
  return v;
}

}  // namespace felt::transport
