#include "recordings/mcap_trace.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <vector>

#include "recordings/mcap.h"
#include "ros2/cdr.h"
#include "ros2/messages.h"

namespace felt {
namespace {

constexpr std::string_view kPoseType = "geometry_msgs/msg/PoseStamped";
constexpr std::string_view kTwistType = "geometry_msgs/msg/TwistStamped";
constexpr std::string_view kOmniType = "omni_msgs/msg/OmniState";

// The ROS 2 type of a channel ("" when it has no schema). ROS 1 style names ("pkg/Type") are
// accepted too.
std::string McapTypeOf(const McapReader& r, const McapChannel& c) {
  const auto it = r.schemas().find(c.schema_id);
  if (it == r.schemas().end()) return "";
  std::string name = it->second.name;
  const size_t slash = name.find('/');
  if (slash != std::string::npos && name.find("/msg/") == std::string::npos) {
    name.insert(slash, "/msg");
  }
  return name;
}

std::string McapTopicList(const McapReader& r) {
  std::string list;
  for (const auto& [id, c] : r.channels()) {
    if (!list.empty()) list += ", ";
    list += c.topic + " (" + McapTypeOf(r, c) + ")";
  }
  return list.empty() ? "none" : list;
}

}  // namespace

bool IsMcapPath(const std::string& path) {
  if (path.size() < 5) return false;
  std::string ext = path.substr(path.size() - 5);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char ch) { return std::tolower(ch); });
  return ext == ".mcap";
}

Trace ReadMcapTrace(const std::string& path, const McapTraceOptions& options, McapTraceInfo* info) {
  McapReader reader(path);
  McapTraceInfo found;
  // The pose channel: the one asked for, else the first PoseStamped, else the first OmniState.
  const McapChannel* pose = nullptr;
  for (const std::string_view want : {kPoseType, kOmniType}) {
    for (const auto& [id, c] : reader.channels()) {
      if (pose != nullptr) break;
      const std::string type = McapTypeOf(reader, c);
      if (!options.topic.empty()) {
        if (c.topic == options.topic) {
          if (type != kPoseType && type != kOmniType) {
            throw TraceError(path, 0,
                             "topic " + c.topic + " is a " + type + ", not a " +
                                 std::string(kPoseType) + " or " + std::string(kOmniType));
          }
          pose = &c;
        }
      } else if (type == want) {
        pose = &c;
      }
    }
  }
  if (pose == nullptr) {
    throw TraceError(path, 0,
                     (options.topic.empty() ? std::string("no PoseStamped or OmniState topic")
                                            : "no topic " + options.topic) +
                         " in this MCAP file; its topics: " + McapTopicList(reader));
  }
  if (pose->message_encoding != "cdr") {
    throw TraceError(
        path, 0,
        "topic " + pose->topic + " has message encoding '" + pose->message_encoding + "', not cdr");
  }
  found.topic = pose->topic;
  found.type = McapTypeOf(reader, *pose);
  const bool omni = found.type == kOmniType;

  // The velocity channel: CRTK's measured_cv beside a measured_cp.
  const McapChannel* twist = nullptr;
  const std::string cp = "measured_cp";
  if (!omni && pose->topic.size() >= cp.size() &&
      pose->topic.compare(pose->topic.size() - cp.size(), cp.size(), cp) == 0) {
    const std::string cv = pose->topic.substr(0, pose->topic.size() - cp.size()) + "measured_cv";
    for (const auto& [id, c] : reader.channels()) {
      if (c.topic == cv && McapTypeOf(reader, c) == kTwistType && c.message_encoding == "cdr") {
        twist = &c;
      }
    }
  }
  if (twist != nullptr) found.velocity_topic = twist->topic;

  // One pass over both channels: poses in order; twists by stamp.
  struct Raw {
    int64_t t_ns, stamp_ns;
    Vec3 p, v;
    bool have_v;
    uint32_t buttons;
  };
  std::vector<Raw> raw;
  std::unordered_map<int64_t, Vec3> twists;
  std::vector<uint16_t> ids = {pose->id};
  if (twist != nullptr) ids.push_back(twist->id);
  const uint16_t pose_id = pose->id;
  reader.ReadMessages(
      [&](const McapMessage& m) {
        try {
          if (m.channel_id != pose_id) {
            const ros2::TwistStamped tw = ros2::ParseTwistStamped(m.data);
            twists[ros2::NsFromTime(tw.header.stamp)] =
                Vec3(tw.twist.linear.x, tw.twist.linear.y, tw.twist.linear.z);
            return;
          }
          Raw r{};
          ros2::Header header;
          if (omni) {
            const ros2::OmniState s = ros2::ParseOmniState(m.data);
            header = s.header;
            const double k = options.omni_position_scale_m;
            r.p = Vec3(s.pose.position.x * k, s.pose.position.y * k, s.pose.position.z * k);
            r.v = Vec3(s.velocity.x, s.velocity.y, s.velocity.z);
            r.have_v = true;
            r.buttons = (s.close_gripper ? 1u : 0u) | (s.locked ? 2u : 0u);
          } else {
            const ros2::PoseStamped ps = ros2::ParsePoseStamped(m.data);
            header = ps.header;
            r.p = Vec3(ps.pose.position.x, ps.pose.position.y, ps.pose.position.z);
          }
          if (found.messages == 0) found.frame_id = header.frame_id;
          ++found.messages;
          r.stamp_ns = ros2::NsFromTime(header.stamp);
          if (options.time == McapTraceTime::kLogTime &&
              m.log_time_ns > static_cast<uint64_t>(INT64_MAX)) {
            throw McapError(
                path, m.file_offset, "Message",
                "log_time " + std::to_string(m.log_time_ns) + " ns is beyond the year 2262");
          }
          r.t_ns = options.time == McapTraceTime::kHeaderStamp
                       ? r.stamp_ns
                       : static_cast<int64_t>(m.log_time_ns);
          if (!raw.empty() && r.t_ns <= raw.back().t_ns) {
            ++found.skipped_time_not_increasing;
            return;
          }
          raw.push_back(r);
        } catch (const ros2::CdrError& e) {
          throw McapError(
              path, m.file_offset, "Message",
              "payload of topic " + reader.channels().at(m.channel_id).topic + ": " + e.what());
        }
      },
      ids);
  if (raw.empty()) throw TraceError(path, 0, "topic " + found.topic + " has no message");

  // Velocities: the twist of the same stamp, else central differences.
  for (size_t i = 0; i < raw.size(); ++i) {
    Raw& r = raw[i];
    if (r.have_v) continue;
    const auto it = twists.find(r.stamp_ns);
    if (it != twists.end()) {
      r.v = it->second;
      continue;
    }
    ++found.velocity_from_differences;
    const size_t a = i > 0 ? i - 1 : i, b = i + 1 < raw.size() ? i + 1 : i;
    r.v =
        a == b
            ? Vec3::Zero()
            : Vec3((raw[b].p - raw[a].p) / (static_cast<double>(raw[b].t_ns - raw[a].t_ns) / 1e9));
  }

  // The trace: rate from the median interval.
  std::vector<int64_t> dts;
  for (size_t i = 1; i < raw.size(); ++i) dts.push_back(raw[i].t_ns - raw[i - 1].t_ns);
  double rate_hz = 1000.0;
  if (!dts.empty()) {
    std::nth_element(dts.begin(), dts.begin() + dts.size() / 2, dts.end());
    rate_hz = 1e9 / static_cast<double>(dts[dts.size() / 2]);
  }
  std::string device = "mcap";
  if (pose->topic.size() > 1 && pose->topic[0] == '/' &&
      pose->topic.find('/', 1) != std::string::npos) {
    device = pose->topic.substr(1, pose->topic.find('/', 1) - 1);
  }
  Trace trace;
  trace.header =
      MakeTraceHeader(rate_hz, device,
                      "mcap " + found.topic + " (" + found.type + ")" +
                          (found.velocity_topic.empty() ? "" : " + " + found.velocity_topic));
  trace.header.Set("timebase",
                   options.time == McapTraceTime::kHeaderStamp ? "header.stamp" : "log_time");
  if (!found.frame_id.empty()) trace.header.Set("ros_frame_id", found.frame_id);
  trace.samples.reserve(raw.size());
  for (size_t i = 0; i < raw.size(); ++i) {
    const Raw& r = raw[i];
    if (!r.p.allFinite() || !r.v.allFinite()) {
      throw TraceError(path, 0,
                       "topic " + found.topic + ", pose message " + std::to_string(i + 1) +
                           ": position or velocity not finite");
    }
    TraceSample s;
    s.t_s = static_cast<double>(r.t_ns - raw.front().t_ns) / 1e9;
    s.p_D = r.p;
    s.v_D = r.v;
    s.buttons = r.buttons;
    trace.samples.push_back(s);
  }
  if (info != nullptr) *info = found;
  return trace;
}

Trace ReadAnyTrace(const std::string& path, const std::string& topic) {
  if (!IsMcapPath(path)) return ReadTrace(path);
  McapTraceOptions options;
  options.topic = topic;
  return ReadMcapTrace(path, options);
}

}  // namespace felt
