// The ROS 2 transport profile (transport/ros2_profile.h): names, stamps and sample assembly as pure
// functions; then the server transport against a plain Cyclone participant that knows only the
// ROS 2 types (transport/ros2_types.idl, as rmw_cyclonedds lays them out): a PoseStamped
// publisher with ROS 2's default QoS (reliable, keep-last 10) or SensorDataQoS (best-effort)
// drives a device, and a WrenchStamped subscriber with ROS 2's default QoS reads its forces, each
// stamped with the stamp of the pose it answers.

#include "transport/ros2_profile.h"

#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "dds/ddsi/ddsi_serdata.h"
#include "ros2/markers.h"
#include "ros2/messages.h"
#include "ros2_types.h"
#include "tests/transport/transport_test_util.h"
#include "transport/dds_config.h"
#include "transport/server_transport.h"

namespace felt::transport {
namespace {

using namespace ::felt::transport::testing;  // tests/transport/transport_test_util.h

// Writes `sample` (a ROS 2 message of the writer's type) until the server holds a pointer sample
// for device `index` (best-effort: the first writes may precede the match); false after kWait.
template <typename Sample>
bool WriteUntilHeard(const Entity& writer, const Sample& sample, ServerTransport& server,
                     uint32_t index, PointerSampleView* view) {
  return WaitUntil(
      [&] {
        (void)dds_write(writer.get(), &sample);
        return server.LatestPointer(index, view);
      },
      kWait);
}

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
  ASSERT_TRUE(WriteUntilHeard(pose_writer, pose, server, 1, &view));
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

TEST(Ros2ProfileTest, TheOmniPresetNamesTheTouchDriversTopicsAndMillimetres) {
  const Ros2DeviceTopics omni = Ros2PresetTopics(Ros2Preset::kOmni, "left");
  EXPECT_EQ(Ros2DdsTopic(omni.pose, "pose"), "rt/phantom/state");
  EXPECT_EQ(Ros2DdsTopic(omni.wrench, "wrench"), "rt/phantom/force_feedback");
  EXPECT_EQ(omni.twist, "");
  EXPECT_EQ(omni.length_scale, 0.001);
  EXPECT_STREQ(Ros2PoseTypeName(omni.pose_type), "OmniState");
  EXPECT_STREQ(Ros2WrenchTypeName(omni.wrench_type), "OmniFeedback");
  const Ros2DeviceTopics crtk = Ros2PresetTopics(Ros2Preset::kCrtk, "left");
  EXPECT_EQ(crtk.pose, DefaultRos2Topics("left").pose);
  EXPECT_STREQ(Ros2PoseTypeName(crtk.pose_type), "PoseStamped");
  EXPECT_STREQ(Ros2WrenchTypeName(crtk.wrench_type), "WrenchStamped");
}

// The Geomagic Touch driver (omni_common) as a participant that knows only omni_msgs' IDL types:
// OmniState with its pose in millimetres and velocity in m/s on <ns>/state, OmniFeedback read
// on <ns>/force_feedback, both with the driver's QoS (rclcpp's default with depth 1: reliable,
// keep-last 1). The server sees metres; the driver reads newtons and the proxy in millimetres.
TEST(Ros2ProfileTest, ATouchDriverSpeakingOmniMsgsDrivesADeviceInMillimetres) {
  const std::string ns = "/phantom" + UniqueSuffix();
  ServerTransportConfig config;
  config.dds = TestDds();
  config.topics = UniqueTopics();
  config.devices = {TestDevice("touch")};
  DeviceLimits& touch = config.devices[0];
  touch.profile = TransportProfile::kRos2;
  touch.ros2 = Ros2PresetTopics(Ros2Preset::kOmni, "touch");
  touch.ros2.pose = ns + "/state";
  touch.ros2.wrench = ns + "/force_feedback";
  ServerTransport server(config);

  Participant driver(AcquireDomain(TestDds()));
  const Entity state_topic =
      CreateTopic(driver, &omni_msgs_msg_dds__OmniState__desc, "rt" + ns + "/state");
  const Entity feedback_topic =
      CreateTopic(driver, &omni_msgs_msg_dds__OmniFeedback__desc, "rt" + ns + "/force_feedback");
  Qos qos(dds_create_qos());
  dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, 1);
  dds_qset_durability(qos.get(), DDS_DURABILITY_VOLATILE);
  const Entity state_writer = CreateWriter(driver, state_topic, qos.get(), "state");
  const Entity feedback_reader = CreateReader(driver, feedback_topic, qos.get(), nullptr, "fb");
  ASSERT_TRUE(WaitUntil(
      [&] { return server.MatchedPointerWriters() >= 1 && server.MatchedForceReaders() >= 1; },
      kWait));

  // The driver's message: header.frame_id left empty (as omni_state.cpp does), pose in mm.
  omni_msgs_msg_dds__OmniState_ state{};
  char empty[] = "";
  state.header.frame_id = empty;
  state.header.stamp = {1'764'000'001, 500'000};
  state.locked = false;
  state.close_gripper = true;
  state.pose.position = {12.5, -30.0, 45.0};  // mm
  state.pose.orientation.w = 1.0;
  state.current = {0.1, 0.2, 0.3};
  state.velocity = {0.05, -0.25, 0.125};  // m/s
  PointerSampleView view;
  ASSERT_TRUE(WriteUntilHeard(state_writer, state, server, 0, &view));
  EXPECT_DOUBLE_EQ(view.position_m_D[0], 0.0125);
  EXPECT_DOUBLE_EQ(view.position_m_D[1], -0.030);
  EXPECT_DOUBLE_EQ(view.position_m_D[2], 0.045);
  EXPECT_EQ(view.velocity_m_per_s_D[0], 0.05);  // the message's velocity, not a difference
  EXPECT_EQ(view.velocity_m_per_s_D[1], -0.25);
  EXPECT_EQ(view.velocity_m_per_s_D[2], 0.125);
  EXPECT_EQ(view.device_time_ns, 1'764'000'001'000'500'000);

  // A pose 600 mm out is outside the workspace box (0.5 m): the gate sees metres.
  const uint64_t workspace = server.Stats().rejected_workspace;
  state.pose.position.x = 600.0;
  state.header.stamp.nanosec += 1'000'000;
  (void)dds_write(state_writer.get(), &state);
  EXPECT_TRUE(WaitUntil([&] { return server.Stats().rejected_workspace > workspace; }, kWait));

  // A force reaches the driver in newtons; the lock position is the proxy's, in mm.
  ForceCommandView force;
  force.device_index = 0;
  force.answers_device_time_ns = view.device_time_ns;
  force.force_N_D = {0.5, -1.0, 2.0};
  force.proxy_position_m_D = {0.0125, -0.0295, 0.045};
  omni_msgs_msg_dds__OmniFeedback_ got{};
  void* ptrs[1] = {&got};
  dds_sample_info_t info{};
  ASSERT_TRUE(WaitUntil(
      [&] {
        server.PushForce(force);
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
        return dds_take(feedback_reader.get(), ptrs, &info, 1, 1) == 1 && info.valid_data;
      },
      kWait));
  EXPECT_EQ(got.force.x, 0.5);
  EXPECT_EQ(got.force.y, -1.0);
  EXPECT_EQ(got.force.z, 2.0);
  EXPECT_DOUBLE_EQ(got.position.x, 12.5);
  EXPECT_DOUBLE_EQ(got.position.y, -29.5);
  EXPECT_DOUBLE_EQ(got.position.z, 45.0);
}

// The bytes Cyclone puts on the wire for `sample` of the IDL type `desc`: written by a local
// writer, taken serialised (dds_takecdr), encapsulation header included.
std::vector<uint8_t> CycloneBytes(const dds_topic_descriptor_t* desc, const void* sample) {
  Participant p(AcquireDomain(TestDds()));
  const Entity topic = CreateTopic(p, desc, "felt_idl_bytes" + UniqueSuffix());
  Qos qos(dds_create_qos());
  dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_ALL, 0);
  const Entity reader = CreateReader(p, topic, qos.get(), nullptr, "bytes reader");
  const Entity writer = CreateWriter(p, topic, qos.get(), "bytes writer");
  EXPECT_GE(dds_write(writer.get(), sample), 0);
  ddsi_serdata* data = nullptr;
  dds_sample_info_t info{};
  std::vector<uint8_t> bytes;
  EXPECT_TRUE(WaitUntil([&] { return dds_takecdr(reader.get(), &data, 1, &info, 0) == 1; }, kWait));
  if (data == nullptr) return bytes;
  bytes.resize(ddsi_serdata_size(data));
  ddsi_serdata_to_ser(data, 0, bytes.size(), bytes.data());
  ddsi_serdata_unref(data);
  return bytes;
}

// Compares Cyclone's bytes with the ros2 serializer's (checked against npm's
// @foxglove/rosmsg2-serialization in tests/ros2): the same encapsulation kind (CDR little-endian),
// the same body; Cyclone may pad the body to a multiple of 4 (the padding is zero).
void ExpectSameCdr(const std::vector<uint8_t>& cyclone, const std::vector<uint8_t>& ros2) {
  ASSERT_GE(cyclone.size(), 4u);
  ASSERT_GE(ros2.size(), 4u);
  EXPECT_EQ(cyclone[0], ros2[0]);
  EXPECT_EQ(cyclone[1], ros2[1]);  // 0x01: CDR little-endian (XCDR1)
  ASSERT_GE(cyclone.size(), ros2.size());
  EXPECT_LT(cyclone.size() - ros2.size(), 4u);
  EXPECT_TRUE(std::equal(ros2.begin() + 4, ros2.end(), cyclone.begin() + 4))
      << "the IDL type's layout differs from the ROS 2 message's";
  for (size_t i = ros2.size(); i < cyclone.size(); ++i) EXPECT_EQ(cyclone[i], 0) << i;
}

TEST(Ros2ProfileTest, TheOmniAndDiagnosticIdlTypesHaveTheRos2MessagesBytes) {
  // OmniState: odd values in every field, a frame_id whose length forces padding.
  ros2::OmniState r;
  r.header.stamp = {1'764'000'002, 123'456'789};
  r.header.frame_id = "touch";
  r.locked = true;
  r.close_gripper = false;
  r.pose.position = {12.5, -30.25, 45.125};
  r.pose.orientation = {0.1, 0.2, 0.3, 0.9};
  r.current = {0.5, 0.25, -0.75};
  r.velocity = {0.01, -0.02, 0.03};
  omni_msgs_msg_dds__OmniState_ c{};
  char frame[] = "touch";
  c.header.stamp = {1'764'000'002, 123'456'789};
  c.header.frame_id = frame;
  c.locked = true;
  c.close_gripper = false;
  c.pose.position = {12.5, -30.25, 45.125};
  c.pose.orientation = {0.1, 0.2, 0.3, 0.9};
  c.current = {0.5, 0.25, -0.75};
  c.velocity = {0.01, -0.02, 0.03};
  std::vector<uint8_t> expected;
  ros2::Serialize(r, &expected);
  ExpectSameCdr(CycloneBytes(&omni_msgs_msg_dds__OmniState__desc, &c), expected);

  ros2::OmniFeedback rf;
  rf.force = {0.5, -1.0, 2.0};
  rf.position = {12.5, -29.5, 45.0};
  const omni_msgs_msg_dds__OmniFeedback_ cf{{0.5, -1.0, 2.0}, {12.5, -29.5, 45.0}};
  ros2::Serialize(rf, &expected);
  ExpectSameCdr(CycloneBytes(&omni_msgs_msg_dds__OmniFeedback__desc, &cf), expected);

  // DiagnosticArray: two statuses, the second with no values; strings of lengths 1..5.
  ros2::DiagnosticArray rd;
  rd.header.stamp = {7, 8};
  rd.header.frame_id = "";
  rd.status.resize(2);
  rd.status[0] = {1, "felt", "ok", "srv", {{"a", "1"}, {"bb", "22"}, {"ccc", "333"}}};
  rd.status[1] = {3, "x", "stale", "hw", {}};
  ros2::Serialize(rd, &expected);
  char empty[] = "", felt[] = "felt", ok[] = "ok", srv[] = "srv", x[] = "x", stale[] = "stale",
       hw[] = "hw", a[] = "a", one[] = "1", bb[] = "bb", two[] = "22", ccc[] = "ccc",
       three[] = "333";
  diagnostic_msgs_msg_dds__KeyValue_ kv[3] = {{a, one}, {bb, two}, {ccc, three}};
  diagnostic_msgs_msg_dds__DiagnosticStatus_ st[2] = {};
  st[0] = {1, felt, ok, srv, {3, 3, kv, false}};
  st[1] = {3, x, stale, hw, {0, 0, nullptr, false}};
  diagnostic_msgs_msg_dds__DiagnosticArray_ cd{};
  cd.header.stamp = {7, 8};
  cd.header.frame_id = empty;
  cd.status = {2, 2, st, false};
  ExpectSameCdr(CycloneBytes(&diagnostic_msgs_msg_dds__DiagnosticArray__desc, &cd), expected);
}

TEST(Ros2ProfileTest, TheMarkerAndMultiArrayIdlTypesHaveTheRos2MessagesBytes) {
  // Float64MultiArray: the Omega.7 command (7 joints) with a layout of one dimension.
  ros2::Float64MultiArray ra;
  ra.dim = {{"joints", 7, 7}};
  ra.data_offset = 0;
  ra.data = {0.5, -1.25, 2.0, 0, 0, 0, 0.125};
  std::vector<uint8_t> expected;
  ros2::Serialize(ra, &expected);
  char joints[] = "joints";
  std_msgs_msg_dds__MultiArrayDimension_ dim[1] = {{joints, 7, 7}};
  double data[7] = {0.5, -1.25, 2.0, 0, 0, 0, 0.125};
  std_msgs_msg_dds__Float64MultiArray_ ca{};
  ca.layout.dim = {1, 1, dim, false};
  ca.layout.data_offset = 0;
  ca.data = {7, 7, data, false};
  ExpectSameCdr(CycloneBytes(&std_msgs_msg_dds__Float64MultiArray__desc, &ca), expected);

  // MarkerArray: a triangle list of two triangles and a sphere, frame ids of odd lengths.
  ros2::MarkerArray rm;
  rm.markers.resize(2);
  ros2::Marker& cloth = rm.markers[0];
  cloth.header = {{1'764'000'004, 5}, "world"};
  cloth.ns = "felt_cloth";
  cloth.type = ros2::Marker::kTriangleList;
  cloth.scale = {1, 1, 1};
  cloth.color = {0.9f, 0.55f, 0.2f, 1.0f};
  cloth.lifetime = {1, 0};
  cloth.points = {{0, 0, 0}, {0.1, 0, 0}, {0, 0.1, 0}, {0.1, 0.1, 0.01}, {0.2, 0, 0}, {0, 0.2, 0}};
  ros2::Marker& proxy = rm.markers[1];
  proxy.header = {{1'764'000'004, 5}, "abc"};
  proxy.ns = "felt_proxy";
  proxy.id = 3;
  proxy.type = ros2::Marker::kSphere;
  proxy.pose.position = {0.01, 0.2, -0.03};
  proxy.scale = {0.008, 0.008, 0.008};
  proxy.color = {0.9f, 0.15f, 0.1f, 1.0f};
  ros2::Serialize(rm, &expected);
  char world[] = "world", abc[] = "abc", felt_cloth[] = "felt_cloth", felt_proxy[] = "felt_proxy",
       empty[] = "";
  geometry_msgs_msg_dds__Point_ points[6] = {{0, 0, 0},        {0.1, 0, 0}, {0, 0.1, 0},
                                             {0.1, 0.1, 0.01}, {0.2, 0, 0}, {0, 0.2, 0}};
  visualization_msgs_msg_dds__Marker_ cm[2] = {};
  for (auto& m : cm) {
    m.texture_resource = empty;
    m.texture.header.frame_id = empty;
    m.texture.format = empty;
    m.text = empty;
    m.mesh_resource = empty;
    m.mesh_file.filename = empty;
    m.pose.orientation.w = 1.0;
  }
  cm[0].header = {{1'764'000'004, 5}, world};
  cm[0].ns = felt_cloth;
  cm[0].type = 11;
  cm[0].scale = {1, 1, 1};
  cm[0].color = {0.9f, 0.55f, 0.2f, 1.0f};
  cm[0].lifetime = {1, 0};
  cm[0].points = {6, 6, points, false};
  cm[1].header = {{1'764'000'004, 5}, abc};
  cm[1].ns = felt_proxy;
  cm[1].id = 3;
  cm[1].type = 2;
  cm[1].pose.position = {0.01, 0.2, -0.03};
  cm[1].scale = {0.008, 0.008, 0.008};
  cm[1].color = {0.9f, 0.15f, 0.1f, 1.0f};
  visualization_msgs_msg_dds__MarkerArray_ ca2{};
  ca2.markers = {2, 2, cm, false};
  ExpectSameCdr(CycloneBytes(&visualization_msgs_msg_dds__MarkerArray__desc, &ca2), expected);
}

TEST(Ros2ProfileTest, TheFdPresetNamesTheForceDimensionDriversTopics) {
  const Ros2DeviceTopics fd = Ros2PresetTopics(Ros2Preset::kFd, "left");
  EXPECT_EQ(Ros2DdsTopic(fd.pose, "pose"), "rt/fd/ee_pose");
  EXPECT_EQ(Ros2DdsTopic(fd.wrench, "wrench"), "rt/fd/fd_controller/commands");
  EXPECT_EQ(fd.twist, "");
  EXPECT_EQ(fd.length_scale, 1.0);
  EXPECT_STREQ(Ros2PoseTypeName(fd.pose_type), "PoseStamped");
  EXPECT_STREQ(Ros2WrenchTypeName(fd.wrench_type), "Float64MultiArray");
  EXPECT_EQ(fd.wrench_array_length, 3u);
}

// The Force Dimension ros2_control driver as a participant that knows only the ROS 2 types: its
// ee_pose_broadcaster's PoseStamped (SystemDefaultsQoS: Cyclone's default writer, reliable
// keep-last 1) on <ns>/ee_pose, its forward command controller's Float64MultiArray subscription
// (SystemDefaultsQoS: Cyclone's default reader, best-effort) on <ns>/fd_controller/commands,
// with 3 joints (Omega.3) and 7 (Omega.7: roll, pitch, yaw and the gripper after the forces).
TEST(Ros2ProfileTest, TheForceDimensionDriverReadsItsForcesAsAFloat64MultiArray) {
  for (const uint32_t joints : {3u, 7u}) {
    SCOPED_TRACE(joints);
    const std::string ns = "/fd" + UniqueSuffix();
    ServerTransportConfig config;
    config.dds = TestDds();
    config.topics = UniqueTopics();
    config.devices = {TestDevice("omega")};
    DeviceLimits& omega = config.devices[0];
    omega.profile = TransportProfile::kRos2;
    omega.ros2 = Ros2PresetTopics(Ros2Preset::kFd, "omega");
    omega.ros2.pose = ns + "/ee_pose";
    omega.ros2.wrench = ns + "/fd_controller/commands";
    omega.ros2.wrench_array_length = joints;
    ServerTransport server(config);

    Participant driver(AcquireDomain(TestDds()));
    const Entity pose_topic =
        CreateTopic(driver, &geometry_msgs_msg_dds__PoseStamped__desc, "rt" + ns + "/ee_pose");
    const Entity command_topic = CreateTopic(driver, &std_msgs_msg_dds__Float64MultiArray__desc,
                                             "rt" + ns + "/fd_controller/commands");
    const Entity pose_writer = CreateWriter(driver, pose_topic, nullptr, "ee_pose");
    const Entity command_reader = CreateReader(driver, command_topic, nullptr, nullptr, "commands");
    ASSERT_TRUE(WaitUntil(
        [&] { return server.MatchedPointerWriters() >= 1 && server.MatchedForceReaders() >= 1; },
        kWait));

    // The broadcaster's message: frame "fd_base", position in m, stamp = its clock's now.
    geometry_msgs_msg_dds__PoseStamped_ pose{};
    char frame[] = "fd_base";
    pose.header.frame_id = frame;
    pose.header.stamp = {1'764'000'005, 1'000'000};
    pose.pose.position = {0.02, -0.01, 0.03};
    pose.pose.orientation.w = 1.0;
    PointerSampleView view;
    ASSERT_TRUE(WriteUntilHeard(pose_writer, pose, server, 0, &view));
    EXPECT_EQ(view.position_m_D[0], 0.02);
    EXPECT_EQ(view.position_m_D[2], 0.03);

    ForceCommandView force;
    force.device_index = 0;
    force.answers_device_time_ns = view.device_time_ns;
    force.force_N_D = {0.5, -1.0, 2.0};
    void* ptrs[1] = {nullptr};
    dds_sample_info_t info{};
    const std_msgs_msg_dds__Float64MultiArray_* got = nullptr;
    ASSERT_TRUE(WaitUntil(
        [&] {
          server.PushForce(force);
          std::this_thread::sleep_for(std::chrono::milliseconds(2));
          const dds_return_t n = dds_take(command_reader.get(), ptrs, &info, 1, 1);
          if (n == 1 && info.valid_data) {
            got = static_cast<const std_msgs_msg_dds__Float64MultiArray_*>(ptrs[0]);
            return true;
          }
          if (n > 0) (void)dds_return_loan(command_reader.get(), ptrs, n);
          return false;
        },
        kWait));
    // The controller takes an array of exactly its joints' count: [fx, fy, fz, 0...] in N.
    ASSERT_EQ(got->data._length, joints);
    EXPECT_EQ(got->data._buffer[0], 0.5);
    EXPECT_EQ(got->data._buffer[1], -1.0);
    EXPECT_EQ(got->data._buffer[2], 2.0);
    for (uint32_t k = 3; k < joints; ++k) EXPECT_EQ(got->data._buffer[k], 0.0) << k;
    EXPECT_EQ(got->layout.dim._length, 0u);
    EXPECT_EQ(got->layout.data_offset, 0u);
    (void)dds_return_loan(command_reader.get(), ptrs, 1);
    EXPECT_GE(server.Stats().forces_published, 1u);
  }
}

// The markers' writer: absent with Felt's profile only (nothing built); with a ROS 2 device it
// matches RViz's default marker subscription (reliable, volatile, keep-last 5), one set to
// transient-local (which also gets the last array on joining late), and a best-effort one.
TEST(Ros2ProfileTest, TheMarkerWriterMatchesRvizDefaultsAndExistsOnlyWhenOn) {
  {
    ServerTransportConfig config;
    config.dds = TestDds();
    config.topics = UniqueTopics();
    config.devices = {TestDevice("left")};
    config.ros2_markers.topic = "/felt" + UniqueSuffix() + "/markers";
    ServerTransport server(config);
    EXPECT_FALSE(server.markers_enabled());
    EXPECT_FALSE(server.PublishMarkers(ros2::MarkerArray{}));
    EXPECT_EQ(server.MatchedMarkerReaders(), 0u);
  }
  const std::string ns = "/felt" + UniqueSuffix();
  ServerTransportConfig config;
  config.dds = TestDds();
  config.topics = UniqueTopics();
  config.devices = {TestDevice("left")};
  config.devices[0].profile = TransportProfile::kRos2;
  config.devices[0].ros2.pose = ns + "/measured_cp";
  config.devices[0].ros2.wrench = ns + "/servo_cf";
  config.ros2_markers.topic = ns + "/markers";
  ServerTransport server(config);
  ASSERT_TRUE(server.markers_enabled());

  Participant rviz(AcquireDomain(TestDds()));
  const Entity topic =
      CreateTopic(rviz, &visualization_msgs_msg_dds__MarkerArray__desc, "rt" + ns + "/markers");
  Qos qos(dds_create_qos());
  dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, 5);
  dds_qset_durability(qos.get(), DDS_DURABILITY_VOLATILE);
  const Entity reader = CreateReader(rviz, topic, qos.get(), nullptr, "rviz markers");
  Qos best_effort(dds_create_qos());
  dds_qset_reliability(best_effort.get(), DDS_RELIABILITY_BEST_EFFORT, 0);
  const Entity sensor_reader = CreateReader(rviz, topic, best_effort.get(), nullptr, "be");
  ASSERT_TRUE(WaitUntil([&] { return server.MatchedMarkerReaders() >= 2; }, kWait));

  ros2::MarkerStyle style;
  ros2::MarkerArray a = ros2::MakeMarkerArray(2, 1, style);
  const std::vector<float> xyz = {0, 0, 0, 0.1f, 0, 0, 0, 0.1f, 0, 0.1f, 0.1f, 0.01f};
  const std::vector<std::array<int32_t, 3>> tris = {{0, 1, 3}, {0, 3, 2}};
  ros2::FillClothMarker(xyz, tris, ros2::MarkerMap{}, &a.markers[0]);
  ros2::FillProxyMarker({0.05, 0.05, 0.02}, 0.004, true, ros2::MarkerMap{}, style, &a.markers[1]);
  ros2::StampMarkers(ros2::Time{1'764'000'006, 7}, &a);
  ASSERT_TRUE(server.PublishMarkers(a));
  void* ptrs[1] = {nullptr};
  dds_sample_info_t info{};
  ASSERT_TRUE(WaitUntil([&] { return dds_take(reader.get(), ptrs, &info, 1, 1) == 1; }, kWait));
  const auto* got = static_cast<const visualization_msgs_msg_dds__MarkerArray_*>(ptrs[0]);
  ASSERT_EQ(got->markers._length, 2u);
  EXPECT_EQ(got->markers._buffer[0].type, 11);
  EXPECT_EQ(got->markers._buffer[0].points._length, 6u);
  EXPECT_DOUBLE_EQ(got->markers._buffer[0].points._buffer[4].y, static_cast<double>(0.1f));
  EXPECT_STREQ(got->markers._buffer[1].ns, "felt_proxy");
  EXPECT_EQ(got->markers._buffer[1].scale.x, 0.008);
  EXPECT_EQ(got->markers._buffer[1].header.stamp.sec, 1'764'000'006);
  EXPECT_STREQ(got->markers._buffer[1].header.frame_id, "world");
  (void)dds_return_loan(reader.get(), ptrs, 1);
  ASSERT_TRUE(
      WaitUntil([&] { return dds_take(sensor_reader.get(), ptrs, &info, 1, 1) == 1; }, kWait));
  (void)dds_return_loan(sensor_reader.get(), ptrs, 1);

  // A transient-local subscriber joining now gets the last array.
  Qos late(dds_create_qos());
  dds_qset_reliability(late.get(), DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_durability(late.get(), DDS_DURABILITY_TRANSIENT_LOCAL);
  const Entity late_reader = CreateReader(rviz, topic, late.get(), nullptr, "late");
  ASSERT_TRUE(
      WaitUntil([&] { return dds_take(late_reader.get(), ptrs, &info, 1, 1) == 1; }, kWait));
  (void)dds_return_loan(late_reader.get(), ptrs, 1);
  EXPECT_EQ(server.Stats().markers_published, 1u);
  EXPECT_EQ(server.Stats().incompatible_qos, 0u);
}

// The value of `key` in a DiagnosticStatus, or "<absent>".
std::string DiagnosticValue(const diagnostic_msgs_msg_dds__DiagnosticStatus_& s, const char* key) {
  for (uint32_t i = 0; i < s.values._length; ++i) {
    if (std::string(s.values._buffer[i].key) == key) return s.values._buffer[i].value;
  }
  return "<absent>";
}

// Felt's status on ROS 2's /diagnostics: a subscriber with the diagnostic_msgs IDL types only and
// ROS 2's default QoS reads felt/status's fields as KeyValue strings, the transport counters
// filled in; on with a ROS 2 device, or asked for with Felt's profile only, else absent.
TEST(Ros2ProfileTest, StatusReachesRos2DiagnosticsWithEveryFieldAsText) {
  for (const bool ros2_device : {true, false}) {
    SCOPED_TRACE(ros2_device ? "a ROS 2 device" : "ros2_diagnostics = true");
    const std::string ns = "/felt" + UniqueSuffix();
    ServerTransportConfig config;
    config.dds = TestDds();
    config.topics = UniqueTopics();
    config.devices = {TestDevice("left")};
    if (ros2_device) {
      config.devices[0].profile = TransportProfile::kRos2;
      config.devices[0].ros2.pose = ns + "/measured_cp";
      config.devices[0].ros2.wrench = ns + "/servo_cf";
    } else {
      config.ros2_diagnostics = true;
    }
    config.ros2_diagnostics_topic = ns + "/diagnostics";
    ServerTransport server(config);

    Participant tool(AcquireDomain(TestDds()));
    const Entity topic = CreateTopic(tool, &diagnostic_msgs_msg_dds__DiagnosticArray__desc,
                                     "rt" + ns + "/diagnostics");
    const Qos qos = RosQos(false);
    const Entity reader = CreateReader(tool, topic, qos.get(), nullptr, "diagnostics");
    ASSERT_TRUE(WaitUntil([&] { return MatchedWriters(reader) >= 1; }, kWait));

    ServerStatusView status;
    status.server_id = "felt-7";
    status.wall_time_ns = 1'764'000'003'000'000'042;
    status.realtime = true;
    status.haptic_ticks = 12345;
    status.haptic_lateness_us = {3.5, 20.25, 40.0, 81.0};
    status.sim_stalled = true;
    status.pointer_accepted = 999;  // replaced by the transport's own count (0)
    status.devices_connected = 1;
    status.passivity_energy_J = -0.125;
    void* ptrs[1] = {nullptr};
    dds_sample_info_t info{};
    const diagnostic_msgs_msg_dds__DiagnosticArray_* got = nullptr;
    ASSERT_TRUE(WaitUntil(
        [&] {
          EXPECT_TRUE(server.PublishStatus(status));
          std::this_thread::sleep_for(std::chrono::milliseconds(2));
          if (dds_take(reader.get(), ptrs, &info, 1, 1) != 1) return false;
          if (info.valid_data) {
            got = static_cast<const diagnostic_msgs_msg_dds__DiagnosticArray_*>(ptrs[0]);
            return true;
          }
          (void)dds_return_loan(reader.get(), ptrs, 1);
          return false;
        },
        kWait));
    EXPECT_EQ(got->header.stamp.sec, 1'764'000'003);
    EXPECT_EQ(got->header.stamp.nanosec, 42u);
    ASSERT_EQ(got->status._length, 1u);
    const diagnostic_msgs_msg_dds__DiagnosticStatus_& st = got->status._buffer[0];
    EXPECT_STREQ(st.name, "felt: server felt-7");
    EXPECT_STREQ(st.hardware_id, "felt-7");
    EXPECT_EQ(st.level, 1);  // WARN: the sim stalled
    EXPECT_STREQ(st.message, "sim stalled");
    EXPECT_EQ(DiagnosticValue(st, "realtime"), "true");
    EXPECT_EQ(DiagnosticValue(st, "haptic_ticks"), "12345");
    EXPECT_EQ(DiagnosticValue(st, "haptic_lateness_us.p50"), "3.5");
    EXPECT_EQ(DiagnosticValue(st, "haptic_lateness_us.p99"), "20.25");
    EXPECT_EQ(DiagnosticValue(st, "haptic_lateness_us.max"), "81");
    EXPECT_EQ(DiagnosticValue(st, "pointer_accepted"), "0");
    EXPECT_EQ(DiagnosticValue(st, "devices_connected"), "1");
    EXPECT_EQ(DiagnosticValue(st, "passivity_energy_J"), "-0.125");
    // Every felt/status field is there: 23 fields, 4 of them percentiles of 4 keys.
    EXPECT_EQ(st.values._length, 23u - 4u + 4u * 4u);
    (void)dds_return_loan(reader.get(), ptrs, 1);
  }

  // Felt's profile only, not asked for: no diagnostics writer.
  const std::string ns = "/felt" + UniqueSuffix();
  ServerTransportConfig config;
  config.dds = TestDds();
  config.topics = UniqueTopics();
  config.devices = {TestDevice("left")};
  config.ros2_diagnostics_topic = ns + "/diagnostics";
  ServerTransport server(config);
  Participant tool(AcquireDomain(TestDds()));
  const Entity topic = CreateTopic(tool, &diagnostic_msgs_msg_dds__DiagnosticArray__desc,
                                   "rt" + ns + "/diagnostics");
  const Qos qos = RosQos(false);
  const Entity reader = CreateReader(tool, topic, qos.get(), nullptr, "diagnostics");
  ServerStatusView status;
  status.server_id = "felt-8";
  EXPECT_TRUE(server.PublishStatus(status));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(MatchedWriters(reader), 0u);
}

INSTANTIATE_TEST_SUITE_P(DefaultAndSensorDataQos, Ros2DriverTest, ::testing::Bool(),
                         [](const ::testing::TestParamInfo<bool>& p) {
                           return p.param ? std::string("SensorData") : std::string("Default");
                         });

}  // namespace
}  // namespace felt::transport
