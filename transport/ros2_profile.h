#pragma once
// The ROS 2 transport profile (issue 24): a device whose driver speaks ROS 2 (CRTK's measured_cp /
// measured_cv / servo_cf, as the dVRK, sawSensablePhantom and sawForceDimensionSDK publish, or
// any PoseStamped) connects to Felt with no bridge and nothing from ROS installed: ROS 2 is DDS,
// and Felt's server reads and writes the ROS 2 types itself (transport/ros2_types.idl; the wire
// facts in ../shared/notes/ros2-wire.md). This header holds what needs no DDS type: the names,
// the time stamps and how a pointer sample is assembled from a pose and a twist.
//
// Assembly (Ros2PointerAssembler): each PoseStamped is one pointer sample. Its position is the
// pose's position [m, device frame: the pose's frame]; its time the header stamp; its velocity the
// newest TwistStamped's linear part when that twist is at most kRos2TwistMaxAge_ns older than the
// pose (CRTK publishes both at the servo rate), else the finite difference of the last two poses
// by their stamps (zero when their stamps do not advance or lie more than kRos2TwistMaxAge_ns
// apart). ROS 2 messages carry no sequence number: the assembler numbers the poses it is given,
// +1 each, so the server's sequence rule (strictly increasing per writer) holds by construction;
// a repeated pose is a new sample. The Geomagic Touch driver's OmniState (pose_type kOmniState)
// goes through the same assembler: its velocity field as a twist at the pose's own stamp, then its
// pose; both scaled to SI first (Ros2DeviceTopics::length_scale, velocity_scale).

#include <cstdint>
#include <string>

namespace felt::transport {

/// Which topics carry a device's pointer samples and forces.
enum class TransportProfile {
  kFelt,  ///< felt/pointer, felt/force (PointerSample, ForceCommand; docs/transport.md)
  kRos2,  ///< ROS 2 topics of Ros2DeviceTopics (PoseStamped, TwistStamped in; WrenchStamped out)
};

/// The profile's name in a scene ("felt", "ros2").
const char* TransportProfileName(TransportProfile profile);

/// The message a device's pose topic carries.
enum class Ros2PoseType {
  kPoseStamped,  ///< geometry_msgs/PoseStamped (CRTK measured_cp; any driver), position [m]
  /// omni_msgs/OmniState (the Geomagic Touch driver's `phantom/state`): header, buttons, pose in
  /// the driver's units (default mm), current, velocity [m/s]. Carries its own velocity, so such
  /// a device has no twist topic.
  kOmniState,
};

/// The message a device's wrench topic carries.
enum class Ros2WrenchType {
  kWrenchStamped,  ///< geometry_msgs/WrenchStamped (CRTK servo_cf), stamped with the answered pose
  /// omni_msgs/OmniFeedback (the Touch driver's `phantom/force_feedback`): force [N] and the
  /// driver's lock position (Felt writes the proxy position there, in the driver's units). It has
  /// no header: no stamp echo, no frame.
  kOmniFeedback,
  /// std_msgs/Float64MultiArray (a ros2_control forward command controller's `~/commands`, e.g.
  /// the Force Dimension driver's /fd/fd_controller/commands): data = [fx, fy, fz] [N], then zeros
  /// up to Ros2DeviceTopics::wrench_array_length (the controller's joints: torques, gripper).
  /// No header: no stamp echo, no frame.
  kFloat64MultiArray,
};

/// The type's ROS 2 name: "PoseStamped", "OmniState"; "WrenchStamped", "OmniFeedback",
/// "Float64MultiArray".
const char* Ros2PoseTypeName(Ros2PoseType type);
const char* Ros2WrenchTypeName(Ros2WrenchType type);

/// The metres per unit of an OmniState's position with the Touch driver's default `units` "mm"
/// (omni_common's omni_state.cpp divides the OpenHaptics millimetres by a units ratio of 1).
inline constexpr double kOmniStateMillimetre_m = 0.001;

/// The ROS 2 topics of one device, as ROS 2 names them (`ros2 topic list`), fully qualified, and
/// what they carry.
struct Ros2DeviceTopics {
  std::string pose;      ///< pose_type in: position [length_scale m per unit], device frame
  std::string twist;     ///< geometry_msgs/TwistStamped in: linear velocity; "" none
  std::string wrench;    ///< wrench_type out: force [N], device frame
  std::string frame_id;  ///< header.frame_id of each force; "" echoes the answered pose's frame
  Ros2PoseType pose_type = Ros2PoseType::kPoseStamped;
  Ros2WrenchType wrench_type = Ros2WrenchType::kWrenchStamped;
  /// Metres per unit of the pose's position (> 0): 1 for PoseStamped (REP 103), 0.001 for the
  /// Touch driver's OmniState in mm (kOmniStateMillimetre_m). Forces are not scaled (N).
  double length_scale = 1.0;
  /// Metres per second per unit of the velocity read (TwistStamped's linear part, OmniState's
  /// velocity) (> 0): 1 for both (the Touch driver's velocity is m/s with its units "mm").
  double velocity_scale = 1.0;
  /// Float64MultiArray only: the array's length, the number of joints of the driver's controller
  /// (its forward command controller ignores an array of another length), 3..16; forces in the
  /// first three, zeros after.
  uint32_t wrench_array_length = 3;
};

/// CRTK's names under the device's id as namespace: /<id>/measured_cp, /<id>/measured_cv,
/// /<id>/servo_cf, frame_id "" (echo). The id must make a valid ROS 2 name (letters, digits,
/// '_'; not starting with a digit): Ros2DdsTopic says so when it does not.
Ros2DeviceTopics DefaultRos2Topics(const std::string& device_id);

/// Named sets of topics and types for drivers people run (the scene's `ros2_preset`).
enum class Ros2Preset {
  kCrtk,  ///< DefaultRos2Topics: PoseStamped + TwistStamped in, WrenchStamped out
  /// The Geomagic Touch ROS 2 driver (`omni_common`, omni_name "phantom"): OmniState in on
  /// /phantom/state (length_scale 0.001: its mm), no twist, OmniFeedback out on
  /// /phantom/force_feedback.
  kOmni,
  /// The Force Dimension ros2_control driver (ICube-Robotics/forcedimension_ros2, its fd_bringup
  /// launch, namespace "fd"): PoseStamped in on /fd/ee_pose (m, frame "fd_base"), no twist
  /// (velocity by finite difference), Float64MultiArray [fx, fy, fz] out on
  /// /fd/fd_controller/commands (its JointGroupEffortController on joints fd_x, fd_y, fd_z).
  kFd,
};

/// The topics and types of `preset` for the device `device_id`.
Ros2DeviceTopics Ros2PresetTopics(Ros2Preset preset, const std::string& device_id);

/// The DDS topic of a fully qualified ROS 2 topic name: "/a/b" -> "rt/a/b" (rmw_cyclonedds's
/// "rt" prefix). Throws std::invalid_argument naming `what` when `ros_name` is not a valid fully
/// qualified ROS 2 topic name: it must start with '/', hold only letters, digits, '_' and '/',
/// have no empty token ("//"), no token starting with a digit, and not end with '/'.
std::string Ros2DdsTopic(const std::string& ros_name, const std::string& what);

/// A ROS 2 time stamp (builtin_interfaces/Time) as nanoseconds.
inline int64_t Ros2StampNs(int32_t sec, uint32_t nanosec) {
  return static_cast<int64_t>(sec) * 1'000'000'000 + static_cast<int64_t>(nanosec);
}

/// Nanoseconds as a ROS 2 time stamp: sec = floor(ns / 1e9), nanosec in [0, 1e9).
inline void Ros2StampOf(int64_t ns, int32_t* sec, uint32_t* nanosec) {
  int64_t s = ns / 1'000'000'000;
  int64_t rest = ns % 1'000'000'000;
  if (rest < 0) {
    rest += 1'000'000'000;
    --s;
  }
  *sec = static_cast<int32_t>(s);
  *nanosec = static_cast<uint32_t>(rest);
}

/// A twist older than this against the pose it would serve is not used (the finite difference
/// is), ns: ten 1 kHz periods.
inline constexpr int64_t kRos2TwistMaxAge_ns = 10'000'000;

/// One pointer sample assembled from ROS 2 messages (device frame, SI units).
struct Ros2Pointer {
  uint64_t seq = 0;            ///< the assembler's number, +1 per pose
  int64_t device_time_ns = 0;  ///< the pose's header stamp, ns
  double position_m[3] = {0, 0, 0};
  double velocity_m_per_s[3] = {0, 0, 0};
  bool velocity_from_twist = false;  ///< true: the twist's; false: finite difference (or zero)
};

/// Per device: the newest twist and the last pose, and the sample numbering (file comment).
/// One thread at a time (the server's receive path holds its mutex). Allocation-free.
class Ros2PointerAssembler {
 public:
  /// Notes a TwistStamped: stamp [ns], linear velocity [m/s].
  void Twist(int64_t stamp_ns, const double (&linear_m_per_s)[3]);
  /// The sample of a PoseStamped: stamp [ns], position [m].
  Ros2Pointer Pose(int64_t stamp_ns, const double (&position_m)[3]);
  /// Forgets the last pose and twist (a new writer owns the device; numbering continues).
  void Reset();

 private:
  bool has_twist_ = false;
  int64_t twist_stamp_ns_ = 0;
  double twist_[3] = {0, 0, 0};
  bool has_pose_ = false;
  int64_t pose_stamp_ns_ = 0;
  double pose_[3] = {0, 0, 0};
  uint64_t seq_ = 0;
};

}  // namespace felt::transport
