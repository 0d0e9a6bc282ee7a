// The ROS 2 transport profile (transport/ros2_profile.h): names, stamps and sample assembly as pure
// functions; then the server transport against a plain Cyclone participant that knows only the
// ROS 2 types (transport/ros2_types.idl, as rmw_cyclonedds lays them out): a PoseStamped
// publisher with ROS 2's default QoS (reliable, keep-last 10) or SensorDataQoS (best-effort)
// drives a device, and a WrenchStamped subscriber with ROS 2's default QoS reads its forces, each
// stamped with the stamp of the pose it answers.

#include "transport/ros2_profile.h"

#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>

#include "ros2_types.h"
#include "tests/transport/transport_test_util.h"
#include "transport/dds_config.h"
#include "transport/server_transport.h"

namespace felt::transport {
namespace {

using namespace ::felt::transport::testing;  // tests/transport/transport_test_util.h

TEST(Ros2ProfileTest, RosNamesMapToRtTopicsAndBadNamesAreRefusedWithTheReason) {
  EXPECT_EQ(Ros2DdsTopic("/left/measured_cp", "pose"), "rt/left/measured_cp");
  EXPECT_EQ(Ros2DdsTopic("/phantom/force_feedback", "wrench"), "rt/phantom/force_feedback");
  for (const char* bad : {"left/measured_cp", "/", "/a//b", "/a/", "/right-hand/servo_cf",
                          "/1arm/measured_cp", "/a b"}) {
    try {
      (void)Ros2DdsTopic(bad, "pose_topic");
      ADD_FAILURE() << bad << " was accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(std::string("pose_topic \"") + bad), std::string::npos)
          << e.what();
    }
  }
  const Ros2DeviceTopics t = DefaultRos2Topics("left");
  EXPECT_EQ(t.pose, "/left/measured_cp");
  EXPECT_EQ(t.twist, "/left/measured_cv");
  EXPECT_EQ(t.wrench, "/left/servo_cf");
}

TEST(Ros2ProfileTest, StampsRoundTripIncludingBeforeTheEpoch) {
  for (const int64_t ns : {int64_t{0}, int64_t{1}, int64_t{1'999'999'999}, int64_t{-1},
                           int64_t{-1'500'000'000}, int64_t{1'764'000'000'123'456'789}}) {
    int32_t sec = 0;
    uint32_t nanosec = 0;
    Ros2StampOf(ns, &sec, &nanosec);
    EXPECT_LT(nanosec, 1'000'000'000u);
    EXPECT_EQ(Ros2StampNs(sec, nanosec), ns);
  }
}

TEST(Ros2ProfileTest, VelocityFromAFreshTwistElseFromThePosesStamps) {
  Ros2PointerAssembler a;
  const double p0[3] = {0.0, 0.0, 0.0};
  const double p1[3] = {0.001, 0.0, -0.002};
  Ros2Pointer first = a.Pose(1'000'000, p0);
  EXPECT_EQ(first.seq, 1u);
  EXPECT_FALSE(first.velocity_from_twist);
  EXPECT_EQ(first.velocity_m_per_s[0], 0.0);   // nothing to difference yet
  Ros2Pointer second = a.Pose(2'000'000, p1);  // 1 ms later
  EXPECT_EQ(second.seq, 2u);
  EXPECT_NEAR(second.velocity_m_per_s[0], 1.0, 1e-12);
  EXPECT_NEAR(second.velocity_m_per_s[2], -2.0, 1e-12);
  const double v[3] = {0.1, 0.2, 0.3};
  a.Twist(2'500'000, v);
  Ros2Pointer third = a.Pose(3'000'000, p1);
  EXPECT_TRUE(third.velocity_from_twist);
  EXPECT_EQ(third.velocity_m_per_s[1], 0.2);
  // A twist 20 ms older than the pose is not used; the poses' stamps do not advance: zero.
  Ros2Pointer stale = a.Pose(22'600'000, p1);
  EXPECT_FALSE(stale.velocity_from_twist);
  EXPECT_EQ(stale.velocity_m_per_s[0], 0.0);
  Ros2Pointer repeated = a.Pose(22'600'000, p0);
  EXPECT_EQ(repeated.velocity_m_per_s[0], 0.0);
  EXPECT_EQ(repeated.seq, 5u);
}

// ROS 2's default publisher and subscriber QoS (rclcpp's rmw_qos_profile_default): reliable,
// keep-last 10, volatile, no deadline; SensorDataQoS: best-effort, keep-last 5.
Qos RosQos(bool sensor_data) {
  Qos qos(dds_create_qos());
  dds_qset_reliability(qos.get(),
                       sensor_data ? DDS_RELIABILITY_BEST_EFFORT : DDS_RELIABILITY_RELIABLE,
                       DDS_MSECS(100));
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, sensor_data ? 5 : 10);
  dds_qset_durability(qos.get(), DDS_DURABILITY_VOLATILE);
  return qos;
}

class Ros2DriverTest : public ::testing::TestWithParam<bool> {};

TEST_P(Ros2DriverTest, ARos2OnlyDriverDrivesADeviceAndReadsStampedForces) {
  const bool sensor_data = GetParam();
  // Unique ROS 2 names: the namespace carries the test's suffix ("/test_<pid>_<n>").
  const std::string ns = "/felt" + UniqueSuffix();
  ServerTransportConfig config;
  config.dds = TestDds();
  config.topics = UniqueTopics();
  config.devices = {TestDevice("left"), TestDevice("arm")};
  DeviceLimits& arm = config.devices[1];
  arm.profile = TransportProfile::kRos2;
  arm.ros2.pose = ns + "/measured_cp";
  arm.ros2.twist = ns + "/measured_cv";
  arm.ros2.wrench = ns + "/servo_cf";
  ServerTransport server(config);

  // The driver: a participant with the ROS 2 types only.
  Participant driver(AcquireDomain(TestDds()));
  const Entity pose_topic =
      CreateTopic(driver, &geometry_msgs_msg_dds__PoseStamped__desc, "rt" + ns + "/measured_cp");
  const Entity wrench_topic =
      CreateTopic(driver, &geometry_msgs_msg_dds__WrenchStamped__desc, "rt" + ns + "/servo_cf");
  const Qos pub_qos = RosQos(sensor_data);
  const Qos sub_qos = RosQos(false);
  const Entity pose_writer = CreateWriter(driver, pose_topic, pub_qos.get(), "pose");
  const Entity wrench_reader = CreateReader(driver, wrench_topic, sub_qos.get(), nullptr, "wrench");
  ASSERT_TRUE(WaitUntil(
      [&] { return server.MatchedPointerWriters() >= 1 && server.MatchedForceReaders() >= 1; },
      kWait));

  geometry_msgs_msg_dds__PoseStamped_ pose{};
  char frame[] = "arm_base";
  pose.header.frame_id = frame;
  pose.header.stamp = {1'764'000'000, 250'000'000};
  pose.pose.position = {0.01, -0.02, 0.03};
  pose.pose.orientation.w = 1.0;
  PointerSampleView view;
  ASSERT_TRUE(WaitUntil(
      [&] {
        (void)dds_write(pose_writer.get(), &pose);
        return server.LatestPointer(1, &view);
      },
      kWait));
  EXPECT_EQ(view.position_m_D[0], 0.01);
  EXPECT_EQ(view.position_m_D[1], -0.02);
  EXPECT_EQ(view.position_m_D[2], 0.03);
  EXPECT_EQ(view.device_time_ns, 1'764'000'000'250'000'000);
  EXPECT_FALSE(server.LatestPointer(0, &view)) << "the Felt-profile device got nothing";

  // A force answering that pose reaches the driver with its stamp and frame.
  ForceCommandView force;
  force.device_index = 1;
  force.answers_device_time_ns = view.device_time_ns;
  force.force_N_D = {0.5, -1.0, 2.0};
  geometry_msgs_msg_dds__WrenchStamped_* got = nullptr;
  void* ptrs[1] = {nullptr};
  dds_sample_info_t info{};
  ASSERT_TRUE(WaitUntil(
      [&] {
        server.PushForce(force);
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
        const dds_return_t n = dds_take(wrench_reader.get(), ptrs, &info, 1, 1);
        if (n == 1 && info.valid_data) {
          got = static_cast<geometry_msgs_msg_dds__WrenchStamped_*>(ptrs[0]);
          return true;
        }
        if (n > 0) (void)dds_return_loan(wrench_reader.get(), ptrs, n);
        return false;
      },
      kWait));
  EXPECT_EQ(got->header.stamp.sec, 1'764'000'000);
  EXPECT_EQ(got->header.stamp.nanosec, 250'000'000u);
  EXPECT_STREQ(got->header.frame_id, "arm_base");
  EXPECT_EQ(got->wrench.force.x, 0.5);
  EXPECT_EQ(got->wrench.force.y, -1.0);
  EXPECT_EQ(got->wrench.force.z, 2.0);
  EXPECT_EQ(got->wrench.torque.x, 0.0);
  (void)dds_return_loan(wrench_reader.get(), ptrs, 1);

  // Bad input is rejected and counted as on Felt's own topics.
  const uint64_t nonfinite = server.Stats().rejected_nonfinite;
  pose.pose.position.x = std::numeric_limits<double>::quiet_NaN();
  pose.header.stamp.sec += 1;
  (void)dds_write(pose_writer.get(), &pose);
  EXPECT_TRUE(WaitUntil([&] { return server.Stats().rejected_nonfinite > nonfinite; }, kWait));
}

INSTANTIATE_TEST_SUITE_P(DefaultAndSensorDataQos, Ros2DriverTest, ::testing::Bool(),
                         [](const ::testing::TestParamInfo<bool>& p) {
                           return p.param ? std::string("SensorData") : std::string("Default");
                         });

}  // namespace
}  // namespace felt::transport
