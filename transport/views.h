#pragma once
// Plain C++ views of Felt's DDS messages (transport/felt_types.idl). The haptic and monitor threads
// use these; they hold no DDS type and no heap memory, so copying one is real-time safe.

#include <array>
#include <cstdint>
#include <string>

namespace felt::transport {

/// Longest device id or server id, characters (the IDL's string<64>).
inline constexpr std::size_t kMaxIdLength = 64;

/// ForceCommandView::flags bits (the IDL's kForce* constants).
inline constexpr uint32_t kForceClamped = 1;     ///< clamped to the device's maximum force or rate
inline constexpr uint32_t kForceStaleInput = 2;  ///< no fresh pointer sample: force ramps to zero
inline constexpr uint32_t kForceSimStalled = 4;  ///< the sim is late: last snapshot used
inline constexpr uint32_t kForceRamping = 8;     ///< ramp-in after start or reconnect

/// One accepted pointer sample, as the haptic thread sees it.
struct PointerSampleView {
  uint32_t device_index = 0;             ///< index into the device list given at construction
  uint64_t seq = 0;                      ///< the driver's sequence number
  int64_t device_time_ns = 0;            ///< the driver's clock at measurement, ns (any epoch)
  std::array<double, 3> position_m_D{};  ///< tip position, device frame, m
  std::array<double, 3> velocity_m_per_s_D{};  ///< tip velocity, device frame, m/s
  uint32_t buttons = 0;                        ///< bit mask, bit 0 = first button
  int64_t receive_time_ns = 0;  ///< CLOCK_MONOTONIC when the transport took it, ns (0 = none)
};

/// One force for a device, as the haptic thread produces it.
struct ForceCommandView {
  uint32_t device_index = 0;           ///< index into the device list given at construction
  uint64_t seq = 0;                    ///< per-device sequence number (the sender assigns it)
  uint64_t answers_seq = 0;            ///< seq of the PointerSample this force answers
  int64_t answers_device_time_ns = 0;  ///< device_time_ns of that sample, ns
  std::array<double, 3> force_N_D{};   ///< force to output, device frame, N
  std::array<double, 3> proxy_position_m_D{};  ///< god-object proxy, device frame, m
  bool in_contact = false;                     ///< proxy touches the cloth
  uint32_t flags = 0;                          ///< bit mask of kForce* above
  std::array<double, 3> contact_point_m_D{};   ///< a point of the contact plane, device frame, m
  std::array<double, 3> contact_normal_D{};    ///< unit plane normal to the free side, device frame
  double contact_stiffness_N_per_m = 0;  ///< local model spring k, device frame, N/m (0: none)
  int64_t receive_time_ns = 0;                 ///< receiver side only: CLOCK_MONOTONIC at take, ns
};

/// Percentiles of a distribution, in the unit of the field that holds it.
struct PercentilesView {
  double p50 = 0;   ///< median
  double p99 = 0;   ///< 99th percentile
  double p999 = 0;  ///< 99.9th percentile
  double max = 0;   ///< largest value
};

/// The server's statistics, published once a second on felt/status.
/// The fields marked "transport" are filled by ServerTransport::PublishStatus from its own
/// counters (whatever the caller puts there is replaced).
struct ServerStatusView {
  std::string server_id;                 ///< one status instance per server id (at most 64 chars)
  int64_t wall_time_ns = 0;              ///< CLOCK_REALTIME at publication, ns since 1970 (0 = now)
  bool realtime = false;                 ///< SCHED_FIFO granted
  uint64_t haptic_ticks = 0;             ///< haptic ticks since start
  uint64_t haptic_overruns = 0;          ///< haptic ticks that missed their deadline
  PercentilesView haptic_lateness_us;    ///< wake-up lateness of the 1 kHz tick, us
  PercentilesView haptic_compute_us;     ///< compute time per tick, us
  uint64_t sim_frames = 0;               ///< sim frames since start
  PercentilesView sim_frame_ms;          ///< compute time per sim frame, ms
  PercentilesView snapshot_age_ms;       ///< age of the snapshot used at each tick, ms
  bool sim_stalled = false;              ///< the sim is late: the haptic loop uses an old snapshot
  uint64_t rejected_nonfinite = 0;       ///< transport: NaN or infinite position/velocity
  uint64_t rejected_workspace = 0;       ///< transport: position outside the device's box
  uint64_t rejected_seq = 0;             ///< transport: seq not above the last accepted one
  uint64_t rejected_unknown_device = 0;  ///< transport: device id not in the scene
  uint64_t rejected_flood = 0;           ///< transport: above the device's rate limit
  uint64_t rejected_not_owner = 0;       ///< transport: from a writer not owning the device
  uint64_t pointer_accepted = 0;         ///< transport: samples that reached the haptic loop
  uint64_t forces_published = 0;         ///< transport: ForceCommands written
  uint64_t forces_queue_full = 0;        ///< transport: forces PushForce could not queue
  uint64_t dds_errors = 0;               ///< transport: failed dds_take/dds_write calls
  uint64_t incompatible_qos = 0;         ///< transport: DDS peers whose QoS does not match
  uint64_t nan_events = 0;               ///< haptic ticks that produced a non-finite force
  uint32_t devices_connected = 0;        ///< devices with fresh input
  double passivity_energy_J = 0;         ///< passivity observer, sum of F.v.dt, J
};

}  // namespace felt::transport
