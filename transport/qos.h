#pragma once
// The QoS of Felt's three topics, chosen once here (docs/transport.md, "QoS").
//
// felt/pointer and felt/force are 1 kHz streams where only the newest sample matters:
//   BEST_EFFORT  a lost sample is replaced 1 ms later; retransmitting an old position or force
//                would only add latency (and reliable costs the same on loopback, but not on a
//                lossy network, where it would queue behind retransmissions).
//   KEEP_LAST 1  per instance (device id): a slow reader gets the newest sample, never a backlog.
//   DEADLINE     kStreamDeadline (10 ms) offered by writers and requested by readers: ten missed
//                periods; Cyclone counts each miss (requested/offered_deadline_missed), which the
//                transport reports. The safety reaction (zero force) does not rely on it: the
//                server's stale-input rule and the driver's silence timeout do that.
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

/// QoS of felt/status, for readers and writers alike: reliable, transient-local, keep-last 1.
Qos StatusQos();

}  // namespace felt::transport
