#pragma once
// Pointer traces from MCAP files (issue 24): any geometry_msgs/PoseStamped topic (with its CRTK
// measured_cv TwistStamped sibling for velocity when there is one) or the Geomagic Touch
// driver's omni_msgs/OmniState (pose in millimetres, converted to metres) becomes a felt-trace
// (recordings/trace.h), so `felt replay`, `felt compare` and `felt trace import` read a
// `ros2 bag` of a device or a `felt record --out FILE.mcap`.

#include <cstdint>
#include <string>

#include "recordings/trace.h"

namespace felt {

/// Which time a trace sample gets from an MCAP message.
enum class McapTraceTime {
  kHeaderStamp,  ///< the message's header.stamp (the device's clock; the default)
  kLogTime,      ///< the MCAP record's log_time (when the recorder received it)
};

/// How ReadMcapTrace picks and converts messages.
struct McapTraceOptions {
  /// The topic read; "" = the first PoseStamped channel (lowest id), else the first OmniState.
  std::string topic;
  McapTraceTime time = McapTraceTime::kHeaderStamp;
  /// OmniState pose unit [m per unit]: 0.001 for the driver's default `units: mm`.
  double omni_position_scale_m = 0.001;
};

/// What ReadMcapTrace found.
struct McapTraceInfo {
  std::string topic;           ///< the pose topic read
  std::string type;            ///< its ROS 2 type
  std::string velocity_topic;  ///< the TwistStamped topic velocities came from ("" = none)
  std::string frame_id;        ///< header.frame_id of the first message
  uint64_t messages = 0;       ///< pose messages read
  uint64_t skipped_time_not_increasing = 0;  ///< messages whose time was not after the last one
  uint64_t velocity_from_differences = 0;    ///< samples whose velocity was differenced
};

/// True when `path` ends in ".mcap" (any case): the commands choose the format by extension.
bool IsMcapPath(const std::string& path);

/// Reads one pose topic of an MCAP file into a trace (device frame = the message frame; t_s from
/// the first message's time; velocity from the paired TwistStamped topic (`.../measured_cp` ->
/// `.../measured_cv`, matched by header stamp) or OmniState's velocity, else central
/// differences of the positions; buttons: OmniState close_gripper = bit 0, locked = bit 1, else
/// 0). Messages whose time is not after the previous one are skipped and counted. Throws
/// McapError (recordings/mcap.h) for a bad file, ros2::CdrError for a bad payload (its what()
/// prefixed with the file and the message's byte offset), TraceError for no pose topic, an
/// unknown --topic (the error lists the file's topics) or no sample.
Trace ReadMcapTrace(const std::string& path, const McapTraceOptions& options = {},
                    McapTraceInfo* info = nullptr);

/// ReadMcapTrace for a ".mcap" path (default options, `topic` when given), ReadTrace otherwise.
Trace ReadAnyTrace(const std::string& path, const std::string& topic = "");

}  // namespace felt
