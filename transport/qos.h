#pragma once
// The QoS of Felt's three topics, chosen once here (docs/transport.md, "QoS").
//
// felt/pointer and felt/force are 1 kHz streams where only the newest sample matters:
//   BEST_EFFORT  a lost sample is replaced 1 ms later; retransmitting an old position or force
//                would only add latency (and reliable costs the same on loopback, but not on a
//                lossy network, where it would queue behind retransmissions).
//   KEEP_LAST 1  per instance (device id): a slow reader gets the newest sample, never a backlog.
//   DEADLINE     kStreamDeadline (10 ms) offered by Felt's writers, requested by none of its
//                readers: a reader requesting a deadline does not match a writer offering none (a
//                ROS 2 publisher's default), and such a driver would get nothing, silently. The
//                safety reaction (zero force) never relied on it: the server's stale-input rule
//                and the driver's silence timeout do that.
//   VOLATILE     a late joiner must never act on an old position or force.
// felt/status is a 1 Hz summary for monitors that may start at any time:
//   RELIABLE + TRANSIENT_LOCAL + KEEP_LAST 1: a late subscriber receives the latest status at once.

#include <dds/dds.h>

#include <chrono>
#include <memory>

namespace felt::transport {

/// The deadline of the pointer and force streams: 10 ms (ten 1 kHz periods).
inline constexpr std::chrono::milliseconds kStreamDeadline{10};

/// Deletes a dds_qos_t.
struct QosDeleter {
  void operator()(dds_qos_t* qos) const { dds_delete_qos(qos); }
};

/// An owned dds_qos_t.
using Qos = std::unique_ptr<dds_qos_t, QosDeleter>;

/// QoS of felt/pointer and felt/force, for readers and writers alike: best-effort, keep-last 1,
/// volatile, deadline `deadline` (kStreamDeadline by default). Throws std::bad_alloc only.
Qos StreamQos(std::chrono::nanoseconds deadline = kStreamDeadline);

/// QoS of Felt's readers of felt/pointer and felt/force: StreamQos without a requested deadline,
/// so that a writer offering none (a ROS 2 publisher's default) matches; Felt's writers still offer
/// kStreamDeadline to readers that request one. Throws std::bad_alloc only.
Qos StreamReaderQos();

/// QoS of the ROS 2 profile's force writer (WrenchStamped): reliable (1 ms blocking at most),
/// keep-last 1, volatile, no deadline. Reliable so that a subscriber with ROS 2's default profile
/// (reliable, keep-last 10) matches, and a SensorDataQoS (best-effort) one too; keep-last 1 so a
/// slow subscriber gets the newest force, never a backlog. Felt's ROS 2 readers use
/// StreamReaderQos (best-effort: matches reliable and best-effort publishers). Throws
/// std::bad_alloc only.
Qos Ros2WrenchWriterQos();

/// ROS 2 diagnostics (/diagnostics) writer: rclcpp's default QoS, reliable, keep-last 10,
/// volatile, as diagnostic_updater publishes; it matches ROS 2 tools' default subscriptions.
Qos Ros2DiagnosticsWriterQos();

/// The ROS 2 markers' writer (visualization_msgs/MarkerArray): reliable (100 ms blocking at most,
/// on the marker feed's thread, never a loop's), keep-last 1 (markers are state: a slow subscriber
/// gets the newest cloth, never a backlog), transient-local. It matches RViz's default marker
/// subscription (reliable, volatile, keep-last 5), one set to transient-local durability, and a
/// best-effort one (Foxglove's bridge, SensorDataQoS). Throws std::bad_alloc only.
Qos Ros2MarkerWriterQos();

/// The name of a DDS QoS policy id (dds_qos_policy_id_t: "DEADLINE", "RELIABILITY", ...), as
/// the incompatible-QoS statuses report it; "UNKNOWN" for an id this Cyclone does not define.
const char* QosPolicyName(uint32_t policy_id);

/// QoS of felt/status, for readers and writers alike: reliable, transient-local, keep-last 1.
Qos StatusQos();

}  // namespace felt::transport
