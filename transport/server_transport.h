#pragma once
// The server side of Felt's DDS transport (docs/transport.md). The haptic thread never makes a DDS
// call: a receive path (a Cyclone listener or a waitset thread) validates each PointerSample and
// publishes it into a per-device triple buffer that LatestPointer reads; PushForce puts forces into
// an SPSC queue that a writer thread drains into dds_write. Cyclone types stay out of this header.

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "base/non_copyable.h"
#include "ros2/messages.h"
#include "rt/arrival_signal.h"
#include "rt/clock.h"
#include "transport/ros2_profile.h"
#include "transport/settings.h"
#include "transport/views.h"

namespace felt::transport {

/// How pointer samples are taken from DDS. Both run the same validation and slot code.
enum class ReceiveMode {
  kListener,  ///< in Cyclone's data-available callback, on its receive thread (lowest latency)
  kWaitset,   ///< on a transport thread blocked in dds_waitset_wait
};

/// What the server accepts from one device (from the scene). Frame: the device frame (_D).
struct DeviceLimits {
  std::string device_id;                                      ///< 1..64 characters, unique
  std::array<double, 3> workspace_min_m_D{-1.0, -1.0, -1.0};  ///< workspace box corner, m
  std::array<double, 3> workspace_max_m_D{1.0, 1.0, 1.0};     ///< opposite corner, m
  double max_rate_hz = 2000.0;  ///< token-bucket rate: sustained samples per second accepted
  double burst_samples = 50.0;  ///< token-bucket depth: samples accepted back to back
  /// The topics that carry this device (transport/ros2_profile.h): Felt's own, or ROS 2's.
  TransportProfile profile = TransportProfile::kFelt;
  /// The ROS 2 topics when profile is kRos2 (ParseTransportConfig starts from
  /// DefaultRos2Topics(device_id)); an empty pose or wrench name takes the default, an empty
  /// twist name means none (velocity by finite difference of the poses).
  Ros2DeviceTopics ros2;
};

/// The cloth and proxies as ROS 2 markers (ros2/markers.h, server/ros2_marker_feed.h): scene keys
/// [transport] ros2_markers*, docs/transport.md.
struct Ros2MarkerSettings {
  /// On, off, or unset: on exactly when a device is on the ROS 2 profile (Ros2MarkersOn).
  std::optional<bool> enabled;
  std::string topic = "/felt/markers";  ///< visualization_msgs/MarkerArray (DDS "rt" + this)
  std::string frame_id = "world";       ///< header.frame_id of the markers
  double rate_hz = 30.0;                ///< publications per second, (0, max_rate_hz]
  double max_rate_hz = 30.0;            ///< the bound on rate_hz a scene may raise
  /// "" draws in Felt's world frame; a device id draws in that device's frame (its inverse
  /// workspace map), where its driver's pose is, so the cloth overlays the device in RViz.
  std::string device;
};

/// Everything the server transport needs; validated by the ServerTransport constructor.
struct ServerTransportConfig {
  DdsSettings dds;                    ///< domain and Cyclone configuration
  TopicNames topics;                  ///< felt/pointer, felt/force, felt/status (+ affixes)
  std::vector<DeviceLimits> devices;  ///< allowed devices; device_index = position here
  size_t force_queue_capacity = 256;  ///< forces held between PushForce and the writer thread
  ReceiveMode receive_mode = ReceiveMode::kListener;  ///< see ReceiveMode
  /// One writer owns a device at a time: the first whose sample is accepted. Another writer's
  /// samples for it are rejected (rejected_not_owner) until the owner has sent nothing for this
  /// long [ns] (`felt serve`: the scene's haptic.stale_input_ms) or has disposed or unregistered
  /// the device's instance (a driver that exits, or restarts with a new writer after the
  /// silence); then the next writer's sample takes it over. > 0.
  int64_t ownership_timeout_ns = 50'000'000;
  /// Also publish each status as diagnostic_msgs/DiagnosticArray (transport/status_diagnostics.h)
  /// on ros2_diagnostics_topic: on when this is set or any device is on the ROS 2 profile.
  bool ros2_diagnostics = false;
  /// The ROS 2 topic of those diagnostics (DDS topic "rt" + this), as ROS 2 tools expect.
  std::string ros2_diagnostics_topic = "/diagnostics";
  /// The cloth and proxies as a visualization_msgs/MarkerArray (PublishMarkers).
  Ros2MarkerSettings ros2_markers;
};

/// Whether `config` publishes markers: ros2_markers.enabled when set, else whether any device is
/// on the ROS 2 profile.
bool Ros2MarkersOn(const ServerTransportConfig& config);

/// Percentiles of a hop's cost, microseconds, as bin upper edges of a rt/loop_stats.h
/// Histogram at 0.1 us resolution (never below the true value; max exact).
struct HopSummary {
  uint64_t count = 0;  ///< durations recorded
  double mean_us = 0;  ///< mean, us
  double p50_us = 0;   ///< median, us
  double p99_us = 0;   ///< 99th percentile, us
  double p999_us = 0;  ///< 99.9th percentile, us
  double max_us = 0;   ///< largest, us (exact)
};

/// Counters of the server transport since construction. Any thread may take a copy (Stats()).
struct TransportStats {
  uint64_t pointer_accepted = 0;         ///< samples that reached a device slot
  uint64_t rejected_nonfinite = 0;       ///< NaN or infinite position or velocity
  uint64_t rejected_workspace = 0;       ///< position outside the device's workspace box
  uint64_t rejected_seq = 0;             ///< seq not above the last accepted one of that writer
  uint64_t rejected_unknown_device = 0;  ///< device id not in ServerTransportConfig::devices
  uint64_t rejected_not_owner = 0;       ///< from a writer other than the device's owner
  uint64_t ownership_changes = 0;        ///< a device's ownership taken by another writer
  uint64_t rejected_flood = 0;           ///< above the device's token-bucket rate
  uint64_t forces_pushed = 0;            ///< PushForce calls that queued a force
  uint64_t forces_queue_full = 0;        ///< PushForce calls refused: queue full (never silent)
  uint64_t forces_bad_device = 0;        ///< PushForce calls with device_index out of range
  uint64_t forces_published = 0;         ///< forces written to DDS
  uint64_t statuses_published = 0;       ///< statuses written to DDS
  uint64_t markers_published = 0;        ///< MarkerArrays written to DDS (PublishMarkers)
  uint64_t dds_errors = 0;               ///< failed dds_take or dds_write calls
  uint64_t incompatible_qos = 0;  ///< DDS peers whose QoS does not match a Felt reader or writer
                                  ///< (requested/offered incompatible QoS totals, DDS's counts)
  HopSummary receive_hop;  ///< DDS callback/wake-up -> samples validated and in their slots
  HopSummary write_hop;    ///< force popped from the queue -> dds_write returned
};

/// Server side of the transport. Construction (set-up) allocates and creates the DDS entities;
/// afterwards LatestPointer and PushForce neither allocate, lock, wait nor call DDS.
/// Threads: LatestPointer and PushForce from ONE haptic thread; PublishStatus, Stats and the
/// Matched* queries from any other thread.
class ServerTransport : NonCopyable {
 public:
  /// Joins the domain and starts the receive path and the writer thread.
  /// Throws std::invalid_argument naming the field when the config is invalid (no device, an id
  /// empty, longer than 64 or repeated, an empty or inverted workspace box, a rate or burst not
  /// positive, a zero queue capacity) and std::runtime_error when Cyclone refuses a step.
  explicit ServerTransport(ServerTransportConfig config);
  /// Stops the receive path, publishes every force still queued, then leaves the domain.
  ~ServerTransport();

  /// Number of devices (device_index is 0..device_count()-1).
  size_t device_count() const;
  /// The index of `device_id`, or -1 when it is not allowed.
  int DeviceIndex(const std::string& device_id) const;

  /// The newest accepted sample of device `device_index` into `*out`; false (and `*out`
  /// untouched) when none has been accepted yet or the index is out of range. `out->seq` and
  /// `out->receive_time_ns` tell whether it is new and how old it is. Haptic thread only.
  /// Real-time safe: one atomic exchange and a copy.
  bool LatestPointer(uint32_t device_index, PointerSampleView* out);

  /// Counts the samples of device `device_index` accepted into its slot, each notified right
  /// after LatestPointer can read it (on the receive path's thread), so the haptic thread can
  /// tick on arrival (docs/server.md); nullptr for an index out of range. Lives as long as the
  /// transport. Any thread.
  const ArrivalSignal* Arrivals(uint32_t device_index) const;

  /// Queues `force` for publication; its `seq` is replaced by the device's next sequence number
  /// (assigned even when refused, so a refused force shows as a gap to the device). False when
  /// the queue is full or device_index is out of range, each counted. Haptic thread only.
  /// Real-time safe: no allocation or lock; wakes the writer thread (a futex wake when it sleeps).
  bool PushForce(const ForceCommandView& force);

  /// Publishes `status` on felt/status with the transport fields (rejected_*, pointer_accepted,
  /// forces_*, dds_errors) replaced by this transport's counters; wall_time_ns 0 means now. With
  /// ROS 2 diagnostics on (ServerTransportConfig::ros2_diagnostics), also as a DiagnosticArray.
  /// False (counted in dds_errors) when a dds_write fails. Monitor thread; not real-time.
  /// Throws std::invalid_argument when server_id is empty or longer than 64 characters.
  bool PublishStatus(const ServerStatusView& status);

  /// Whether the marker writer exists (Ros2MarkersOn of the configuration).
  bool markers_enabled() const;
  /// Publishes `markers` on the markers topic (ServerTransportConfig::ros2_markers): reliable,
  /// keep-last 1, volatile (Ros2MarkerWriterQos). False when markers are off or dds_write fails
  /// (counted in dds_errors). Not real-time (copies into the IDL type's buffers, reused between
  /// calls); one thread at a time (the marker feed's).
  bool PublishMarkers(const ros2::MarkerArray& markers);
  /// Marker subscribers currently matched. Any thread.
  uint32_t MatchedMarkerReaders() const;

  /// A copy of the counters and hop costs. Any thread.
  TransportStats Stats() const;

  /// Pointer writers currently matched (device drivers seen by discovery). Any thread.
  uint32_t MatchedPointerWriters() const;
  /// Force readers currently matched. Any thread.
  uint32_t MatchedForceReaders() const;

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace felt::transport
