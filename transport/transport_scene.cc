#include "transport/transport_scene.h"

#include <array>
#include <optional>
#include <set>
#include <span>
#include <stdexcept>
#include <string>

namespace felt::transport {
namespace {

std::array<double, 3> ToArray(const Vec3& v) { return {v.x(), v.y(), v.z()}; }
Vec3 ToVec(const std::array<double, 3>& a) { return Vec3(a[0], a[1], a[2]); }

// The device limits keys of `table` over `limits` (the defaults).
DeviceLimits ReadLimits(const SceneTable& table, DeviceLimits limits) {
  limits.workspace_min_m_D =
      ToArray(table.Vector("workspace_min_m", ToVec(limits.workspace_min_m_D)));
  limits.workspace_max_m_D =
      ToArray(table.Vector("workspace_max_m", ToVec(limits.workspace_max_m_D)));
  for (int axis = 0; axis < 3; ++axis) {
    if (!(limits.workspace_min_m_D[axis] < limits.workspace_max_m_D[axis])) {
      table.Fail(table.Has("workspace_max_m") ? "workspace_max_m" : "workspace_min_m",
                 "the workspace box is empty: min must be below max on every axis");
    }
  }
  limits.max_rate_hz = table.Number("max_rate_hz", limits.max_rate_hz, InRange(1.0, 1e6));
  limits.burst_samples = table.Number("burst_samples", limits.burst_samples, InRange(1.0, 1e6));
  static constexpr NamedValue<TransportProfile> kProfiles[] = {{"felt", TransportProfile::kFelt},
                                                               {"ros2", TransportProfile::kRos2}};
  limits.profile = table.Choice<TransportProfile>(
      "profile", limits.profile, std::span<const NamedValue<TransportProfile>>(kProfiles));
  return limits;
}

// The ROS 2 keys of a [[transport.devices]] entry over `topics` (its device's defaults, or its
// ros2_preset's); each name must be a valid ROS 2 topic name (checked here, so the error names
// the line). Choosing pose_type = "OmniState" drops the twist topic and sets length_scale to the
// Touch driver's millimetres unless those keys are given; "PoseStamped" sets length_scale to 1.
void ReadRos2Topics(const SceneTable& entry, Ros2DeviceTopics* topics) {
  static constexpr NamedValue<Ros2PoseType> kPoseTypes[] = {
      {"PoseStamped", Ros2PoseType::kPoseStamped}, {"OmniState", Ros2PoseType::kOmniState}};
  static constexpr NamedValue<Ros2WrenchType> kWrenchTypes[] = {
      {"WrenchStamped", Ros2WrenchType::kWrenchStamped},
      {"OmniFeedback", Ros2WrenchType::kOmniFeedback},
      {"Float64MultiArray", Ros2WrenchType::kFloat64MultiArray}};
  const Ros2PoseType before = topics->pose_type;
  topics->pose_type = entry.Choice<Ros2PoseType>(
      "pose_type", topics->pose_type, std::span<const NamedValue<Ros2PoseType>>(kPoseTypes));
  if (topics->pose_type != before) {
    const bool omni = topics->pose_type == Ros2PoseType::kOmniState;
    topics->length_scale = omni ? kOmniStateMillimetre_m : 1.0;
    if (omni) topics->twist.clear();
  }
  topics->wrench_type =
      entry.Choice<Ros2WrenchType>("wrench_type", topics->wrench_type,
                                   std::span<const NamedValue<Ros2WrenchType>>(kWrenchTypes));
  topics->length_scale = entry.Number("length_scale", topics->length_scale, InRange(1e-6, 1e6));
  topics->velocity_scale =
      entry.Number("velocity_scale", topics->velocity_scale, InRange(1e-6, 1e6));
  const auto name = [&](const char* key, std::string* value, bool may_be_empty) {
    *value = entry.String(key, *value);
    if (value->empty() && may_be_empty) return;
    try {
      (void)Ros2DdsTopic(*value, key);
    } catch (const std::invalid_argument& e) {
      entry.Fail(key, e.what());
    }
  };
  name("pose_topic", &topics->pose, false);
  name("twist_topic", &topics->twist, true);
  name("wrench_topic", &topics->wrench, false);
  if (topics->pose_type == Ros2PoseType::kOmniState && !topics->twist.empty()) {
    entry.Fail("twist_topic",
               "an OmniState carries its own velocity: pose_type = \"OmniState\" reads no "
               "twist topic (leave twist_topic out)");
  }
  topics->frame_id = entry.String("frame_id", topics->frame_id);
  if (topics->wrench_type != Ros2WrenchType::kWrenchStamped && !topics->frame_id.empty()) {
    const bool vowel = topics->wrench_type == Ros2WrenchType::kOmniFeedback;
    entry.Fail("frame_id", std::string(vowel ? "an " : "a ") +
                               Ros2WrenchTypeName(topics->wrench_type) +
                               " has no header: frame_id needs wrench_type = \"WrenchStamped\"");
  }
  if (entry.Has("wrench_array_length") &&
      topics->wrench_type != Ros2WrenchType::kFloat64MultiArray) {
    entry.Fail("wrench_array_length",
               "only a Float64MultiArray wrench has a length: it needs wrench_type = "
               "\"Float64MultiArray\" (or ros2_preset = \"fd\")");
  }
  topics->wrench_array_length = static_cast<uint32_t>(entry.Integer(
      "wrench_array_length", static_cast<int32_t>(topics->wrench_array_length), InRange(3, 16)));
}

// The [transport] ros2_markers* keys (the cloth and proxies as RViz markers).
void ReadRos2Markers(const SceneTable& table, const std::vector<DeviceSpec>& devices,
                     Ros2MarkerSettings* markers) {
  if (table.Has("ros2_markers")) markers->enabled = table.Bool("ros2_markers", kRequired);
  markers->topic = table.String("ros2_markers_topic", markers->topic);
  try {
    (void)Ros2DdsTopic(markers->topic, "ros2_markers_topic");
  } catch (const std::invalid_argument& e) {
    table.Fail("ros2_markers_topic", e.what());
  }
  markers->frame_id = table.String("ros2_markers_frame_id", markers->frame_id, /*non_empty=*/true);
  markers->max_rate_hz =
      table.Number("ros2_markers_max_rate_hz", markers->max_rate_hz, InRange(1.0, 1000.0));
  markers->rate_hz =
      table.Number("ros2_markers_rate_hz", markers->rate_hz, InRangeOpenMin(0.0, 1000.0));
  if (markers->rate_hz > markers->max_rate_hz) {
    table.Fail("ros2_markers_rate_hz",
               "must be at most ros2_markers_max_rate_hz (" + std::to_string(markers->max_rate_hz) +
                   " Hz; RViz and Foxglove need no more than 30): raise ros2_markers_max_rate_hz "
                   "to publish faster");
  }
  markers->device = table.String("ros2_markers_device", markers->device);
  if (!markers->device.empty()) {
    std::string known;
    bool found = false;
    for (const DeviceSpec& d : devices) {
      known += (known.empty() ? "" : ", ") + d.id;
      found = found || d.id == markers->device;
    }
    if (!found) {
      table.Fail(
          "ros2_markers_device",
          "'" + markers->device + "' is not a device of this scene (devices: " + known + ")");
    }
  }
}

}  // namespace

ServerTransportConfig ParseTransportConfig(const SceneDocument& doc,
                                           const std::vector<DeviceSpec>& devices) {
  ServerTransportConfig config;
  DeviceLimits defaults;
  const std::optional<SceneTable> table = SceneTable::Section(doc, "transport");
  std::vector<DeviceLimits> limits(devices.size());
  if (table) {
    table->ExpectKeys({"domain", "dds_config", "security", "identity", "receive_mode",
                       "force_queue_capacity", "workspace_min_m", "workspace_max_m", "max_rate_hz",
                       "burst_samples", "profile", "devices", "ros2_diagnostics", "ros2_markers",
                       "ros2_markers_topic", "ros2_markers_frame_id", "ros2_markers_rate_hz",
                       "ros2_markers_max_rate_hz", "ros2_markers_device"});
    config.dds.domain_id = static_cast<uint32_t>(table->Integer("domain", 0, InRange(0, 230)));
    config.dds.config_file = table->String("dds_config", std::string());
    config.dds.security_dir = table->String("security", std::string());
    config.dds.identity = table->String("identity", std::string());
    static constexpr NamedValue<ReceiveMode> kModes[] = {{"listener", ReceiveMode::kListener},
                                                         {"waitset", ReceiveMode::kWaitset}};
    config.receive_mode = table->Choice<ReceiveMode>(
        "receive_mode", ReceiveMode::kListener, std::span<const NamedValue<ReceiveMode>>(kModes));
    config.force_queue_capacity =
        static_cast<size_t>(table->Integer("force_queue_capacity", 256, InRange(1, 65536)));
    defaults = ReadLimits(*table, defaults);
    config.ros2_diagnostics = table->Bool("ros2_diagnostics", false);
    ReadRos2Markers(*table, devices, &config.ros2_markers);
  }
  for (size_t i = 0; i < devices.size(); ++i) {
    limits[i] = defaults;
    limits[i].device_id = devices[i].id;
    limits[i].ros2 = DefaultRos2Topics(devices[i].id);
  }
  if (table) {
    std::set<std::string> seen;
    for (const SceneTable& entry : table->ArrayOfTables("devices")) {
      entry.ExpectKeys({"id", "workspace_min_m", "workspace_max_m", "max_rate_hz", "burst_samples",
                        "profile", "pose_topic", "twist_topic", "wrench_topic", "frame_id",
                        "ros2_preset", "pose_type", "wrench_type", "length_scale", "velocity_scale",
                        "wrench_array_length"});
      const std::string id = entry.String("id", kRequired, /*non_empty=*/true);
      if (!seen.insert(id).second) entry.Fail("id", "device '" + id + "' is listed twice");
      size_t index = devices.size();
      for (size_t i = 0; i < devices.size(); ++i) {
        if (devices[i].id == id) index = i;
      }
      if (index == devices.size()) {
        std::string known;
        for (const DeviceSpec& d : devices) known += (known.empty() ? "" : ", ") + d.id;
        entry.Fail("id", "'" + id + "' is not a device of this scene (devices: " + known + ")");
      }
      limits[index] = ReadLimits(entry, defaults);
      limits[index].device_id = id;
      limits[index].ros2 = DefaultRos2Topics(id);
      // A preset sets the topics and types at once (and the ROS 2 profile); keys override it.
      if (entry.Has("ros2_preset")) {
        static constexpr NamedValue<Ros2Preset> kPresets[] = {
            {"crtk", Ros2Preset::kCrtk}, {"omni", Ros2Preset::kOmni}, {"fd", Ros2Preset::kFd}};
        const Ros2Preset preset = entry.Choice<Ros2Preset>(
            "ros2_preset", std::nullopt, std::span<const NamedValue<Ros2Preset>>(kPresets));
        limits[index].ros2 = Ros2PresetTopics(preset, id);
        if (!entry.Has("profile")) {
          limits[index].profile = TransportProfile::kRos2;
        } else if (limits[index].profile != TransportProfile::kRos2) {
          entry.Fail("ros2_preset", "a ROS 2 preset needs profile = \"ros2\" (or no profile key)");
        }
      }
      ReadRos2Topics(entry, &limits[index].ros2);
    }
  }
  // A device on the ROS 2 profile with the default names needs an id that makes a ROS 2 name.
  if (table) {
    for (const DeviceLimits& l : limits) {
      if (l.profile != TransportProfile::kRos2) continue;
      try {
        (void)Ros2DdsTopic(l.ros2.pose, "pose_topic");
        (void)Ros2DdsTopic(l.ros2.wrench, "wrench_topic");
        if (!l.ros2.twist.empty()) (void)Ros2DdsTopic(l.ros2.twist, "twist_topic");
      } catch (const std::invalid_argument& e) {
        table->Fail("profile", std::string(e.what()) + ": device '" + l.device_id +
                                   "' needs its topics named in [[transport.devices]]");
      }
    }
  }
  config.devices = std::move(limits);
  return config;
}

}  // namespace felt::transport
