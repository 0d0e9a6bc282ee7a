#pragma once
// Felt's status (felt/status, ServerStatusView) as a ROS 2 diagnostic_msgs/DiagnosticArray: what
// `felt record` writes to /diagnostics in MCAP and what the ROS 2 profile publishes on the DDS
// topic rt/diagnostics (issue 24), so rqt_robot_monitor and Foxglove show it.
//
// One DiagnosticStatus named "felt: server <server_id>", hardware_id the server id, level WARN
// when the sim stalled or a tick produced a non-finite force (message "sim stalled",
// "non-finite forces"), else OK ("ok"); stamp = wall_time_ns. One KeyValue per felt/status field,
// named as the field, values as text (numbers shortest round-trip, booleans "true"/"false"), each
// percentile as four keys <field>.p50, .p99, .p999, .max.

#include "ros2/messages.h"
#include "transport/views.h"

namespace felt::transport {

/// The DiagnosticArray of `status` (file comment). Allocates; not for the real-time loops.
ros2::DiagnosticArray StatusDiagnostics(const ServerStatusView& status);

}  // namespace felt::transport
