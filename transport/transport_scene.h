#pragma once
// The [transport] section of a scene (docs/transport.md, "Scene section"): the DDS domain and
// configuration, the receive mode, and what the server accepts from each device (workspace box,
// flood limit). `felt serve` reads it; --domain, --dds-config, --security and --identity override
// the scene's values.
//
//   [transport]
//   domain = 0                          # DDS domain id, 0..230
//   dds_config = ""                     # Cyclone XML file ("" = CYCLONEDDS_URI, else loopback)
//   security = ""                       # DDS Security dir of `felt security init` ("" = off)
//   identity = ""                       # its identity the server uses ("" = "server")
//   receive_mode = "listener"           # or "waitset"
//   force_queue_capacity = 256          # forces between the haptic thread and the writer
//   workspace_min_m = [-0.2, -0.2, -0.2]  # default workspace box of every device, device frame
//   workspace_max_m = [0.2, 0.2, 0.2]
//   max_rate_hz = 2000.0                # default flood limit: sustained samples per second
//   burst_samples = 50.0                # default flood limit: samples back to back
//   profile = "felt"                    # or "ros2": every device's topics (ros2_profile.h)
//   ros2_diagnostics = false            # status also on ROS 2's /diagnostics (DiagnosticArray,
//                                       # 1 Hz); on anyway when a device uses the ROS 2 profile
//   ros2_markers = true                 # the cloth and proxies as a visualization_msgs/
//                                       # MarkerArray; default: on when a device uses ROS 2
//   ros2_markers_topic = "/felt/markers"
//   ros2_markers_frame_id = "world"     # header.frame_id of the markers
//   ros2_markers_rate_hz = 30.0         # (0, ros2_markers_max_rate_hz]
//   ros2_markers_max_rate_hz = 30.0     # raise it (up to 1000) to allow a faster rate
//   ros2_markers_device = ""            # "": Felt's world frame; a device id: that device's
//                                       # frame (inverse workspace map), where its pose lives
//   [[transport.devices]]               # optional per-device overrides
//   id = "left"                         # one of the scene's device ids
//   workspace_min_m = [-0.1, -0.2, -0.2]
//   profile = "ros2"                    # this device's profile
//   pose_topic = "/left/measured_cp"    # ROS 2 names (these are the defaults for id "left")
//   twist_topic = "/left/measured_cv"   # "" = none: velocity by finite difference
//   wrench_topic = "/left/servo_cf"
//   frame_id = ""                       # of each force; "" echoes the answered pose's
//   ros2_preset = "omni"                # "crtk" (the defaults above) or "omni": the Geomagic
//                                       # Touch driver's /phantom/state (OmniState, mm) in and
//                                       # /phantom/force_feedback (OmniFeedback) out; or "fd":
//                                       # the Force Dimension ros2_control driver's /fd/ee_pose
//                                       # in, /fd/fd_controller/commands out; implies
//                                       # profile "ros2"; the keys below override it
//   pose_type = "PoseStamped"           # or "OmniState" (then no twist topic: it has velocity)
//   wrench_type = "WrenchStamped"       # or "OmniFeedback" (no header: no stamp, no frame_id),
//                                       # or "Float64MultiArray" ([fx, fy, fz, 0...], no header)
//   wrench_array_length = 3             # Float64MultiArray: the controller's joints, 3..16
//   length_scale = 1.0                  # m per unit of the pose's position (OmniState: 0.001)
//   velocity_scale = 1.0                # m/s per unit of the velocity read (twist or OmniState)

#include <vector>

#include "proxy/proxy_spec.h"
#include "scene/scene_file.h"
#include "transport/server_transport.h"

namespace felt::transport {

/// Reads [transport] (absent: the defaults of ServerTransportConfig and DeviceLimits) into the
/// server transport's configuration for `devices` (the scene's devices, in order: device_index =
/// position). Throws SceneError naming file, line and field: a bad value, an empty box (min not
/// below max on every axis), an id in [[transport.devices]] that is not a scene device or is
/// listed twice.
ServerTransportConfig ParseTransportConfig(const SceneDocument& doc,
                                           const std::vector<DeviceSpec>& devices);

}  // namespace felt::transport
