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

}  // namespace felt::transport
