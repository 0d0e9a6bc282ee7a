#pragma once
// A stand-in for a ROS 2 haptic driver (issue 24), for benchmarks: it publishes
// geometry_msgs/PoseStamped and reads geometry_msgs/WrenchStamped with ROS 2's default QoS
// (reliable, keep-last 10, volatile: what rclcpp gives a publisher or subscription created with
// depth 10), through Cyclone DDS and the types of transport/ros2_types.idl alone, as a CRTK
// driver (measured_cp in, servo_cf out) would against Felt's ROS 2 profile. Callers see no DDS
// type.

#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

#include "transport/dds_config.h"

namespace felt::transport {

/// Where the stand-in driver publishes and reads.
struct Ros2ClientConfig {
  DdsSettings dds;           ///< domain and Cyclone configuration (no DDS Security)
  std::string pose_topic;    ///< fully qualified ROS 2 name, e.g. "/arm/measured_cp"
  std::string wrench_topic;  ///< e.g. "/arm/servo_cf"
  std::string frame_id;      ///< header.frame_id of each pose
};

/// A WrenchStamped as the driver reads it.
struct Ros2WrenchReceived {
  int64_t stamp_ns = 0;             ///< header.stamp (Felt echoes the answered pose's), ns
  std::array<double, 3> force_N{};  ///< wrench.force, N
  int64_t receive_time_ns = 0;      ///< CLOCK_MONOTONIC when taken, ns
};

/// The stand-in driver. PublishPose from one thread, WaitWrench from another.
class Ros2Client {
 public:
  /// Creates the participant, topics, writer and reader. Throws std::invalid_argument for a bad
  /// ROS 2 name, std::runtime_error on a Cyclone error.
  explicit Ros2Client(const Ros2ClientConfig& config);
  ~Ros2Client();
  Ros2Client(const Ros2Client&) = delete;
  Ros2Client& operator=(const Ros2Client&) = delete;

  /// Publishes a PoseStamped: stamp [ns], position [m], identity orientation. False on a DDS
  /// error. Allocation-free.
  bool PublishPose(int64_t stamp_ns, const std::array<double, 3>& position_m);
  /// Takes the next WrenchStamped, waiting up to `timeout` for one; false when none came.
  bool WaitWrench(std::chrono::nanoseconds timeout, Ros2WrenchReceived* out);
  /// Readers matched to the pose writer; writers matched to the wrench reader.
  uint32_t MatchedPoseReaders() const;
  uint32_t MatchedWrenchWriters() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace felt::transport
