#include "transport/ros2_profile.h"

#include <cmath>
#include <stdexcept>

namespace felt::transport {

const char* TransportProfileName(TransportProfile profile) {
  return profile == TransportProfile::kRos2 ? "ros2" : "felt";
}

Ros2DeviceTopics DefaultRos2Topics(const std::string& device_id) {
  Ros2DeviceTopics t;
  t.pose = "/" + device_id + "/measured_cp";
  t.twist = "/" + device_id + "/measured_cv";
  t.wrench = "/" + device_id + "/servo_cf";
  return t;
}

const char* Ros2PoseTypeName(Ros2PoseType type) {
  return type == Ros2PoseType::kOmniState ? "OmniState" : "PoseStamped";
}

const char* Ros2WrenchTypeName(Ros2WrenchType type) {
  switch (type) {
    case Ros2WrenchType::kOmniFeedback:
      return "OmniFeedback";
    case Ros2WrenchType::kFloat64MultiArray:
      return "Float64MultiArray";
    case Ros2WrenchType::kWrenchStamped:
      break;
  }
  return "WrenchStamped";
}

Ros2DeviceTopics Ros2PresetTopics(Ros2Preset preset, const std::string& device_id) {
  if (preset == Ros2Preset::kCrtk) return DefaultRos2Topics(device_id);
  if (preset == Ros2Preset::kFd) {
    // forcedimension_ros2: fd_bringup/launch/fd.launch.py runs the controller manager in
    // namespace "fd"; its ee_pose_broadcaster publishes the relative "ee_pose" (/fd/ee_pose) and
    // the forward command controller fd_controller subscribes "~/commands"
    // (/fd/fd_controller/commands), fd_controllers.yaml's joints fd_x, fd_y, fd_z.
    Ros2DeviceTopics t;
    t.pose = "/fd/ee_pose";
    t.wrench = "/fd/fd_controller/commands";
    t.wrench_type = Ros2WrenchType::kFloat64MultiArray;
    t.wrench_array_length = 3;
    return t;
  }
  // omni_common's omni_state.cpp: "<omni_name>/state" and "<omni_name>/force_feedback", relative
  // names resolved in the root namespace, omni_name "phantom" in its launch file.
  Ros2DeviceTopics t;
  t.pose = "/phantom/state";
  t.wrench = "/phantom/force_feedback";
  t.pose_type = Ros2PoseType::kOmniState;
  t.wrench_type = Ros2WrenchType::kOmniFeedback;
  t.length_scale = kOmniStateMillimetre_m;
  return t;
}

std::string Ros2DdsTopic(const std::string& ros_name, const std::string& what) {
  const auto bad = [&](const std::string& why) {
    return std::invalid_argument(what + " \"" + ros_name +
                                 "\": not a fully qualified ROS 2 topic "
                                 "name (" +
                                 why + ")");
  };
  if (ros_name.size() < 2 || ros_name.front() != '/') throw bad("it must start with '/'");
  if (ros_name.back() == '/') throw bad("it must not end with '/'");
  bool token_start = true;
  for (size_t i = 1; i < ros_name.size(); ++i) {
    const char c = ros_name[i];
    if (c == '/') {
      if (token_start) throw bad("an empty token, '//'");
      token_start = true;
      continue;
    }
    const bool digit = c >= '0' && c <= '9';
    const bool ok = digit || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_';
    if (!ok) throw bad(std::string("the character '") + c + "': only letters, digits, '_', '/'");
    if (token_start && digit) throw bad("a token starts with a digit");
    token_start = false;
  }
  return "rt" + ros_name;
}

void Ros2PointerAssembler::Twist(int64_t stamp_ns, const double (&linear_m_per_s)[3]) {
  has_twist_ = true;
  twist_stamp_ns_ = stamp_ns;
  for (int k = 0; k < 3; ++k) twist_[k] = linear_m_per_s[k];
}

Ros2Pointer Ros2PointerAssembler::Pose(int64_t stamp_ns, const double (&position_m)[3]) {
  Ros2Pointer out;
  out.seq = ++seq_;
  out.device_time_ns = stamp_ns;
  for (int k = 0; k < 3; ++k) out.position_m[k] = position_m[k];
  const int64_t twist_age = stamp_ns - twist_stamp_ns_;
  if (has_twist_ && twist_age >= -kRos2TwistMaxAge_ns && twist_age <= kRos2TwistMaxAge_ns) {
    for (int k = 0; k < 3; ++k) out.velocity_m_per_s[k] = twist_[k];
    out.velocity_from_twist = true;
  } else if (has_pose_ && stamp_ns > pose_stamp_ns_ &&
             stamp_ns - pose_stamp_ns_ <= kRos2TwistMaxAge_ns) {
    // Backward difference over the stamps (device clock), m/s.
    const double dt_s = static_cast<double>(stamp_ns - pose_stamp_ns_) * 1e-9;
    for (int k = 0; k < 3; ++k) out.velocity_m_per_s[k] = (position_m[k] - pose_[k]) / dt_s;
  }
  has_pose_ = true;
  pose_stamp_ns_ = stamp_ns;
  for (int k = 0; k < 3; ++k) pose_[k] = position_m[k];
  return out;
}

void Ros2PointerAssembler::Reset() {
  has_twist_ = false;
  has_pose_ = false;
}

}  // namespace felt::transport
