// The [transport] scene section: defaults, every key, and each error naming file, line and field.
#include "transport/transport_scene.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace felt::transport {
namespace {

std::vector<DeviceSpec> Devices(std::initializer_list<const char*> ids) {
  std::vector<DeviceSpec> devices;
  for (const char* id : ids) {
    DeviceSpec d;
    d.id = id;
    devices.push_back(d);
  }
  return devices;
}

ServerTransportConfig Parse(const std::string& text, const std::vector<DeviceSpec>& devices) {
  return ParseTransportConfig(ParseSceneText(text, "t.toml"), devices);
}

// The SceneError message of parsing `text`, or "" when it parses.
std::string ErrorOf(const std::string& text, const std::vector<DeviceSpec>& devices) {
  try {
    Parse(text, devices);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

TEST(TransportSceneTest, AbsentSectionGivesTheDefaultsForEveryDevice) {
  const ServerTransportConfig c = Parse("", Devices({"left", "right"}));
  EXPECT_EQ(c.dds.domain_id, 0u);
  EXPECT_EQ(c.dds.config_file, "");
  EXPECT_EQ(c.dds.security_dir, "");  // no DDS Security unless asked for
  EXPECT_EQ(c.receive_mode, ReceiveMode::kListener);
  EXPECT_EQ(c.force_queue_capacity, 256u);
  ASSERT_EQ(c.devices.size(), 2u);
  EXPECT_EQ(c.devices[0].device_id, "left");
  EXPECT_EQ(c.devices[1].device_id, "right");
  const DeviceLimits defaults;
  EXPECT_EQ(c.devices[1].workspace_min_m_D, defaults.workspace_min_m_D);
  EXPECT_EQ(c.devices[1].workspace_max_m_D, defaults.workspace_max_m_D);
  EXPECT_EQ(c.devices[1].max_rate_hz, defaults.max_rate_hz);
  EXPECT_EQ(c.devices[1].burst_samples, defaults.burst_samples);
}

TEST(TransportSceneTest, EveryKeyIsRead) {
  const ServerTransportConfig c = Parse(R"(
[transport]
domain = 7
dds_config = "net.xml"
security = "sec"
identity = "server-2"
receive_mode = "waitset"
force_queue_capacity = 64
workspace_min_m = [-0.1, -0.2, -0.3]
workspace_max_m = [0.1, 0.2, 0.3]
max_rate_hz = 1500.0
burst_samples = 20.0
[[transport.devices]]
id = "right"
workspace_min_m = [0.0, -0.2, -0.3]
max_rate_hz = 1100.0
)",
                                        Devices({"left", "right"}));
  EXPECT_EQ(c.dds.domain_id, 7u);
  EXPECT_EQ(c.dds.config_file, "net.xml");
  EXPECT_EQ(c.dds.security_dir, "sec");
  EXPECT_EQ(c.dds.identity, "server-2");
  EXPECT_EQ(c.receive_mode, ReceiveMode::kWaitset);
  EXPECT_EQ(c.force_queue_capacity, 64u);
  const std::array<double, 3> min{-0.1, -0.2, -0.3}, max{0.1, 0.2, 0.3};
  EXPECT_EQ(c.devices[0].device_id, "left");
  EXPECT_EQ(c.devices[0].workspace_min_m_D, min);
  EXPECT_EQ(c.devices[0].workspace_max_m_D, max);
  EXPECT_EQ(c.devices[0].max_rate_hz, 1500.0);
  EXPECT_EQ(c.devices[0].burst_samples, 20.0);
  // The per-device entry overrides only what it names; the rest is the section's defaults.
  const std::array<double, 3> right_min{0.0, -0.2, -0.3};
  EXPECT_EQ(c.devices[1].device_id, "right");
  EXPECT_EQ(c.devices[1].workspace_min_m_D, right_min);
  EXPECT_EQ(c.devices[1].workspace_max_m_D, max);
  EXPECT_EQ(c.devices[1].max_rate_hz, 1100.0);
  EXPECT_EQ(c.devices[1].burst_samples, 20.0);
}

TEST(TransportSceneTest, TheRos2ProfileForEveryDeviceOrOneWithItsOwnTopics) {
  const ServerTransportConfig c = Parse(R"(
[transport]
profile = "ros2"
[[transport.devices]]
id = "right"
profile = "felt"
[[transport.devices]]
id = "left"
pose_topic = "/phantom/pose"
twist_topic = ""
wrench_topic = "/phantom/wrench"
frame_id = "base"
)",
                                        Devices({"left", "right", "arm"}));
  ASSERT_EQ(c.devices.size(), 3u);
  EXPECT_EQ(c.devices[0].profile, TransportProfile::kRos2);
  EXPECT_EQ(c.devices[0].ros2.pose, "/phantom/pose");
  EXPECT_EQ(c.devices[0].ros2.twist, "");
  EXPECT_EQ(c.devices[0].ros2.wrench, "/phantom/wrench");
  EXPECT_EQ(c.devices[0].ros2.frame_id, "base");
  EXPECT_EQ(c.devices[1].profile, TransportProfile::kFelt);
  EXPECT_EQ(c.devices[2].profile, TransportProfile::kRos2);  // the section's default
  EXPECT_EQ(c.devices[2].ros2.pose, "/arm/measured_cp");
  EXPECT_EQ(c.devices[2].ros2.twist, "/arm/measured_cv");
  EXPECT_EQ(c.devices[2].ros2.wrench, "/arm/servo_cf");
  EXPECT_EQ(c.devices[2].ros2.frame_id, "");
  // A device whose id makes no ROS 2 name needs its topics named.
  const std::string error = ErrorOf("[transport]\nprofile = \"ros2\"\n", Devices({"right-hand"}));
  EXPECT_NE(error.find("t.toml:2:1: transport.profile"), std::string::npos) << error;
  EXPECT_NE(error.find("device 'right-hand' needs its topics named"), std::string::npos) << error;
}

TEST(TransportSceneTest, TheOmniPresetReadsTheTouchDriversStateInMillimetres) {
  // The preset alone: the ROS 2 profile, the driver's topics and types, its mm to m.
  ServerTransportConfig c = Parse(R"(
[transport]
[[transport.devices]]
id = "left"
ros2_preset = "omni"
)",
                                  Devices({"left", "right"}));
  const Ros2DeviceTopics& t = c.devices[0].ros2;
  EXPECT_EQ(c.devices[0].profile, TransportProfile::kRos2);
  EXPECT_EQ(t.pose, "/phantom/state");
  EXPECT_EQ(t.twist, "");
  EXPECT_EQ(t.wrench, "/phantom/force_feedback");
  EXPECT_EQ(t.pose_type, Ros2PoseType::kOmniState);
  EXPECT_EQ(t.wrench_type, Ros2WrenchType::kOmniFeedback);
  EXPECT_EQ(t.length_scale, 0.001);
  EXPECT_EQ(t.velocity_scale, 1.0);
  EXPECT_EQ(c.devices[1].profile, TransportProfile::kFelt);  // the other device is untouched

  // A second Touch (the driver's omni_name "right_touch") and the CRTK preset spelled out; keys
  // override the preset.
  c = Parse(R"(
[transport]
[[transport.devices]]
id = "right"
ros2_preset = "omni"
pose_topic = "/right_touch/state"
wrench_topic = "/right_touch/force_feedback"
length_scale = 0.01
[[transport.devices]]
id = "left"
ros2_preset = "crtk"
wrench_type = "OmniFeedback"
)",
            Devices({"left", "right"}));
  EXPECT_EQ(c.devices[1].ros2.pose, "/right_touch/state");
  EXPECT_EQ(c.devices[1].ros2.wrench, "/right_touch/force_feedback");
  EXPECT_EQ(c.devices[1].ros2.pose_type, Ros2PoseType::kOmniState);
  EXPECT_EQ(c.devices[1].ros2.length_scale, 0.01);
  EXPECT_EQ(c.devices[0].profile, TransportProfile::kRos2);
  EXPECT_EQ(c.devices[0].ros2.pose, "/left/measured_cp");
  EXPECT_EQ(c.devices[0].ros2.twist, "/left/measured_cv");
  EXPECT_EQ(c.devices[0].ros2.pose_type, Ros2PoseType::kPoseStamped);
  EXPECT_EQ(c.devices[0].ros2.wrench_type, Ros2WrenchType::kOmniFeedback);
  EXPECT_EQ(c.devices[0].ros2.length_scale, 1.0);

  // pose_type alone: OmniState drops the CRTK twist and takes the driver's millimetres.
  EXPECT_FALSE(c.ros2_diagnostics);  // (on anyway with a ROS 2 device: ServerTransport)
  c = Parse(R"(
[transport]
profile = "ros2"
ros2_diagnostics = true
[[transport.devices]]
id = "left"
pose_type = "OmniState"
)",
            Devices({"left"}));
  EXPECT_TRUE(c.ros2_diagnostics);
  EXPECT_EQ(c.devices[0].ros2.pose, "/left/measured_cp");
  EXPECT_EQ(c.devices[0].ros2.twist, "");
  EXPECT_EQ(c.devices[0].ros2.pose_type, Ros2PoseType::kOmniState);
  EXPECT_EQ(c.devices[0].ros2.wrench_type, Ros2WrenchType::kWrenchStamped);
  EXPECT_EQ(c.devices[0].ros2.length_scale, 0.001);
}

TEST(TransportSceneTest, TheFdPresetReadsTheForceDimensionRos2ControlDriver) {
  // The preset: /fd/ee_pose (PoseStamped, m) in, no twist, the forward command controller's
  // Float64MultiArray [fx, fy, fz] out; an Omega.7's seven joints by wrench_array_length.
  ServerTransportConfig c = Parse(R"(
[transport]
[[transport.devices]]
id = "left"
ros2_preset = "fd"
[[transport.devices]]
id = "right"
ros2_preset = "fd"
pose_topic = "/fd2/ee_pose"
wrench_topic = "/fd2/fd_controller/commands"
wrench_array_length = 7
)",
                                  Devices({"left", "right"}));
  const Ros2DeviceTopics& t = c.devices[0].ros2;
  EXPECT_EQ(c.devices[0].profile, TransportProfile::kRos2);
  EXPECT_EQ(t.pose, "/fd/ee_pose");
  EXPECT_EQ(t.twist, "");
  EXPECT_EQ(t.wrench, "/fd/fd_controller/commands");
  EXPECT_EQ(t.pose_type, Ros2PoseType::kPoseStamped);
  EXPECT_EQ(t.wrench_type, Ros2WrenchType::kFloat64MultiArray);
  EXPECT_EQ(t.wrench_array_length, 3u);
  EXPECT_EQ(t.length_scale, 1.0);
  EXPECT_EQ(c.devices[1].ros2.pose, "/fd2/ee_pose");
  EXPECT_EQ(c.devices[1].ros2.wrench_array_length, 7u);
  // The markers: on by default with a ROS 2 device (the transport decides, Ros2MarkersOn).
  EXPECT_FALSE(c.ros2_markers.enabled.has_value());
  EXPECT_TRUE(Ros2MarkersOn(c));
  EXPECT_EQ(c.ros2_markers.topic, "/felt/markers");
  EXPECT_EQ(c.ros2_markers.frame_id, "world");
  EXPECT_EQ(c.ros2_markers.rate_hz, 30.0);
  EXPECT_EQ(c.ros2_markers.device, "");
}

TEST(TransportSceneTest, TheMarkerKeysAreRead) {
  ServerTransportConfig c = Parse(R"(
[transport]
ros2_markers = true
ros2_markers_topic = "/lab/felt_markers"
ros2_markers_frame_id = "felt_world"
ros2_markers_max_rate_hz = 100
ros2_markers_rate_hz = 60
ros2_markers_device = "right"
)",
                                  Devices({"left", "right"}));
  ASSERT_TRUE(c.ros2_markers.enabled.has_value());
  EXPECT_TRUE(Ros2MarkersOn(c));  // asked for, with Felt's profile only
  EXPECT_EQ(c.ros2_markers.topic, "/lab/felt_markers");
  EXPECT_EQ(c.ros2_markers.frame_id, "felt_world");
  EXPECT_EQ(c.ros2_markers.rate_hz, 60.0);
  EXPECT_EQ(c.ros2_markers.max_rate_hz, 100.0);
  EXPECT_EQ(c.ros2_markers.device, "right");
  // Off although a device speaks ROS 2; and off by default with Felt's profile only.
  c = Parse("[transport]\nprofile = \"ros2\"\nros2_markers = false\n", Devices({"left"}));
  EXPECT_FALSE(Ros2MarkersOn(c));
  EXPECT_FALSE(Ros2MarkersOn(Parse("", Devices({"left"}))));
}

TEST(TransportSceneTest, ErrorsNameFileLineAndField) {
  const auto two = Devices({"left", "right"});
  struct Case {
    const char* text;
    const char* expect;
  };
  const Case cases[] = {
      {"[transport]\ndomian = 3\n", "t.toml:2:1: transport.domian"},
      {"[transport]\ndomain = 231\n", "t.toml:2:1: transport.domain"},
      {"[transport]\nreceive_mode = \"poll\"\n", "transport.receive_mode"},
      {"[transport]\nforce_queue_capacity = 0\n", "transport.force_queue_capacity"},
      {"[transport]\nworkspace_min_m = [0.1, 0, 0]\nworkspace_max_m = [0.1, 1, 1]\n",
       "t.toml:3:1: transport.workspace_max_m: the workspace box is empty"},
      {"[transport]\nmax_rate_hz = 0\n", "transport.max_rate_hz"},
      {"[transport]\n[[transport.devices]]\nid = \"middle\"\n",
       "transport.devices[0].id: 'middle' is not a device of this scene (devices: left, right)"},
      {"[transport]\n[[transport.devices]]\nid = \"left\"\n[[transport.devices]]\nid = \"left\"\n",
       "transport.devices[1].id: device 'left' is listed twice"},
      {"[transport]\n[[transport.devices]]\nworkspace_min_m = [0, 0, 0]\n",
       "transport.devices[0].id"},
      {"[transport]\n[[transport.devices]]\nid = \"left\"\nburst = 3\n",
       "transport.devices[0].burst"},
      {"[transport]\nprofile = \"ros1\"\n", "t.toml:2:1: transport.profile"},
      {"[transport]\n[[transport.devices]]\nid = \"left\"\npose_topic = \"left/pose\"\n",
       "t.toml:4:1: transport.devices[0].pose_topic: pose_topic \"left/pose\": not a fully "
       "qualified ROS 2 topic name (it must start with '/')"},
      {"[transport]\n[[transport.devices]]\nid = \"left\"\nwrench_topic = \"/a//b\"\n",
       "transport.devices[0].wrench_topic"},
      {"[transport]\n[[transport.devices]]\nid = \"left\"\nros2_preset = \"touch\"\n",
       "t.toml:4:1: transport.devices[0].ros2_preset: unknown value 'touch'"},
      {"[transport]\n[[transport.devices]]\nid = \"left\"\nprofile = \"felt\"\n"
       "ros2_preset = \"omni\"\n",
       "t.toml:5:1: transport.devices[0].ros2_preset: a ROS 2 preset needs profile = \"ros2\""},
      {"[transport]\n[[transport.devices]]\nid = \"left\"\npose_type = \"Pose\"\n",
       "t.toml:4:1: transport.devices[0].pose_type: unknown value 'Pose'"},
      {"[transport]\n[[transport.devices]]\nid = \"left\"\nwrench_type = \"Wrench\"\n",
       "t.toml:4:1: transport.devices[0].wrench_type: unknown value 'Wrench'"},
      {"[transport]\n[[transport.devices]]\nid = \"left\"\nros2_preset = \"omni\"\n"
       "length_scale = 0\n",
       "t.toml:5:1: transport.devices[0].length_scale"},
      {"[transport]\n[[transport.devices]]\nid = \"left\"\nros2_preset = \"omni\"\n"
       "velocity_scale = -1\n",
       "t.toml:5:1: transport.devices[0].velocity_scale"},
      {"[transport]\n[[transport.devices]]\nid = \"left\"\nros2_preset = \"omni\"\n"
       "twist_topic = \"/phantom/twist\"\n",
       "t.toml:5:1: transport.devices[0].twist_topic: an OmniState carries its own velocity"},
      {"[transport]\n[[transport.devices]]\nid = \"left\"\nros2_preset = \"omni\"\n"
       "frame_id = \"base\"\n",
       "t.toml:5:1: transport.devices[0].frame_id: an OmniFeedback has no header"},
      {"[transport]\nros2_preset = \"omni\"\n", "t.toml:2:1: transport.ros2_preset"},
      {"[transport]\n[[transport.devices]]\nid = \"left\"\nros2_preset = \"fd\"\n"
       "frame_id = \"fd_base\"\n",
       "t.toml:5:1: transport.devices[0].frame_id: a Float64MultiArray has no header"},
      {"[transport]\n[[transport.devices]]\nid = \"left\"\nros2_preset = \"fd\"\n"
       "wrench_array_length = 2\n",
       "t.toml:5:1: transport.devices[0].wrench_array_length"},
      {"[transport]\n[[transport.devices]]\nid = \"left\"\nros2_preset = \"crtk\"\n"
       "wrench_array_length = 7\n",
       "t.toml:5:1: transport.devices[0].wrench_array_length: only a Float64MultiArray wrench "
       "has a length"},
      {"[transport]\nros2_markers = 1\n", "t.toml:2:1: transport.ros2_markers"},
      {"[transport]\nros2_markers_rate_hz = 60\n",
       "t.toml:2:1: transport.ros2_markers_rate_hz: must be at most ros2_markers_max_rate_hz"},
      {"[transport]\nros2_markers_rate_hz = 0\n", "t.toml:2:1: transport.ros2_markers_rate_hz"},
      {"[transport]\nros2_markers_max_rate_hz = 5000\nros2_markers_rate_hz = 60\n",
       "t.toml:2:1: transport.ros2_markers_max_rate_hz"},
      {"[transport]\nros2_markers_topic = \"felt/markers\"\n",
       "t.toml:2:1: transport.ros2_markers_topic: ros2_markers_topic \"felt/markers\": not a "
       "fully qualified ROS 2 topic name"},
      {"[transport]\nros2_markers_frame_id = \"\"\n",
       "t.toml:2:1: transport.ros2_markers_frame_id"},
      {"[transport]\nros2_markers_device = \"middle\"\n",
       "t.toml:2:1: transport.ros2_markers_device: 'middle' is not a device of this scene "
       "(devices: left, right)"},
      {"[transport]\nros2_marker_rate_hz = 10\n", "t.toml:2:1: transport.ros2_marker_rate_hz"},
  };
  for (const Case& c : cases) {
    const std::string error = ErrorOf(c.text, two);
    EXPECT_NE(error.find(c.expect), std::string::npos)
        << "scene:\n" << c.text << "error: '" << error << "'\nexpected: " << c.expect;
  }
}

}  // namespace
}  // namespace felt::transport
