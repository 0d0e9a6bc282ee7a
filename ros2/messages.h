#pragma once
// The ROS 2 messages Felt reads and writes (issue 24): plain structs with the field layout of the
// ROS 2 .msg definitions (Humble and later), their CDR serialisation (ros2/cdr.h) and parsing,
// and each type's name and `ros2msg` schema text (the concatenated .msg definitions, as `ros2 bag`
// writes them into MCAP). Nothing here knows DDS or files: the MCAP recorder (recordings/mcap.h)
// and a ROS 2 DDS transport profile can both use these bytes.
//
// Units are those of the ROS messages (REP 103: metres, seconds, newtons, radians), except
// omni_msgs/OmniState, whose pose the Geomagic Touch driver publishes in millimetres (its
// velocity in m/s); see OmniState.

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace felt::ros2 {

/// The names of one message type.
struct MessageType {
  std::string_view name;      ///< ROS 2 name, e.g. "geometry_msgs/msg/PoseStamped"
  std::string_view dds_name;  ///< DDS type name, e.g. "geometry_msgs::msg::dds_::PoseStamped_"
  std::string_view schema;    ///< ros2msg text: the .msg, then each dependency after a separator
};

/// builtin_interfaces/Time: seconds and nanoseconds since an epoch (ROS time: Unix epoch or the
/// publisher's clock).
struct Time {
  int32_t sec = 0;       ///< s
  uint32_t nanosec = 0;  ///< ns, in [0, 1e9)
  bool operator==(const Time&) const = default;
};
/// Time of `ns` nanoseconds (floor division, so nanosec stays in [0, 1e9)). Throws
/// std::out_of_range when the seconds do not fit an int32 (year 2038 for Unix time).
Time TimeFromNs(int64_t ns);
/// Nanoseconds of a Time.
int64_t NsFromTime(const Time& t);

/// builtin_interfaces/Duration.
struct Duration {
  int32_t sec = 0;       ///< s
  uint32_t nanosec = 0;  ///< ns
  bool operator==(const Duration&) const = default;
};

/// std_msgs/Header (ROS 2: no seq).
struct Header {
  Time stamp;            ///< when the data was measured
  std::string frame_id;  ///< the frame the data is expressed in
  bool operator==(const Header&) const = default;
};

/// geometry_msgs/Vector3 and geometry_msgs/Point (the same bytes: three float64).
struct Vector3 {
  double x = 0, y = 0, z = 0;
  bool operator==(const Vector3&) const = default;
};

/// geometry_msgs/Quaternion (x, y, z, w); identity by default.
struct Quaternion {
  double x = 0, y = 0, z = 0, w = 1;
  bool operator==(const Quaternion&) const = default;
};

/// geometry_msgs/Pose: position [m] (a Point) and orientation.
struct Pose {
  Vector3 position;
  Quaternion orientation;
  bool operator==(const Pose&) const = default;
};

/// geometry_msgs/Twist: linear [m/s] and angular [rad/s] velocity.
struct Twist {
  Vector3 linear, angular;
  bool operator==(const Twist&) const = default;
};

/// geometry_msgs/Wrench: force [N] and torque [N m].
struct Wrench {
  Vector3 force, torque;
  bool operator==(const Wrench&) const = default;
};

/// geometry_msgs/PoseStamped (CRTK measured_cp).
struct PoseStamped {
  Header header;
  Pose pose;
  bool operator==(const PoseStamped&) const = default;
};

/// geometry_msgs/TwistStamped (CRTK measured_cv).
struct TwistStamped {
  Header header;
  Twist twist;
  bool operator==(const TwistStamped&) const = default;
};

/// geometry_msgs/WrenchStamped (CRTK servo_cf, measured_cf).
struct WrenchStamped {
  Header header;
  Wrench wrench;
  bool operator==(const WrenchStamped&) const = default;
};

/// diagnostic_msgs/KeyValue.
struct KeyValue {
  std::string key, value;
  bool operator==(const KeyValue&) const = default;
};

/// diagnostic_msgs/DiagnosticStatus.
struct DiagnosticStatus {
  static constexpr uint8_t kOk = 0, kWarn = 1, kError = 2, kStale = 3;  ///< level values
  uint8_t level = kOk;
  std::string name;         ///< what is reported on, e.g. "felt: server"
  std::string message;      ///< a short summary
  std::string hardware_id;  ///< the hardware or process
  std::vector<KeyValue> values;
  bool operator==(const DiagnosticStatus&) const = default;
};

/// diagnostic_msgs/DiagnosticArray (on /diagnostics).
struct DiagnosticArray {
  Header header;
  std::vector<DiagnosticStatus> status;
  bool operator==(const DiagnosticArray&) const = default;
};

/// std_msgs/ColorRGBA, components in [0, 1].
struct ColorRGBA {
  float r = 0, g = 0, b = 0, a = 0;
  bool operator==(const ColorRGBA&) const = default;
};

/// visualization_msgs/Marker, the fields Felt uses. Serialised as the whole Humble+ message:
/// texture_resource, texture (sensor_msgs/CompressedImage), uv_coordinates, mesh_file
/// (visualization_msgs/MeshFile) are written empty and, when parsed, checked and skipped.
struct Marker {
  static constexpr int32_t kSphere = 2, kTriangleList = 11;        ///< type values
  static constexpr int32_t kAdd = 0, kDelete = 2, kDeleteAll = 3;  ///< action values
  Header header;
  std::string ns;
  int32_t id = 0;
  int32_t type = kSphere;
  int32_t action = kAdd;
  Pose pose;
  Vector3 scale;  ///< [m]; a sphere's diameters, or (1, 1, 1) for a triangle list
  ColorRGBA color;
  Duration lifetime;  ///< 0 = forever
  bool frame_locked = false;
  std::vector<Vector3> points;    ///< triangle list: 3 points per triangle [m]
  std::vector<ColorRGBA> colors;  ///< empty, or one per point
  std::string text;
  std::string mesh_resource;
  bool mesh_use_embedded_materials = false;
  bool operator==(const Marker&) const = default;
};

/// visualization_msgs/MarkerArray: several markers in one message (RViz's "MarkerArray" display;
/// Foxglove's 3D panel).
struct MarkerArray {
  std::vector<Marker> markers;
  bool operator==(const MarkerArray&) const = default;
};

/// std_msgs/MultiArrayDimension: one dimension of a multi-array's layout.
struct MultiArrayDimension {
  std::string label;
  uint32_t size = 0;
  uint32_t stride = 0;
  bool operator==(const MultiArrayDimension&) const = default;
};

/// std_msgs/Float64MultiArray: what ros2_control's forward command controllers
/// (effort_controllers/JointGroupEffortController) read on `~/commands`, one value per joint of
/// the controller, in its joint order (the Force Dimension driver: [fx, fy, fz, ...] in N).
struct Float64MultiArray {
  std::vector<MultiArrayDimension> dim;  ///< layout.dim (empty: a plain vector)
  uint32_t data_offset = 0;              ///< layout.data_offset
  std::vector<double> data;
  bool operator==(const Float64MultiArray&) const = default;
};

/// omni_msgs/OmniState (Geomagic Touch ROS 2 driver, `phantom/state`). Its pose is in
/// MILLIMETRES (the driver's default `units` parameter "mm", despite the .msg comment "meters");
/// its velocity in m/s (the driver divides its mm/s estimate by 1000); current in A.
struct OmniState {
  Header header;
  bool locked = false;         ///< the white button latch (driver: buttons[1])
  bool close_gripper = false;  ///< the grey button (driver: buttons[0])
  Pose pose;                   ///< position [mm], orientation
  Vector3 current;             ///< [A]
  Vector3 velocity;            ///< [m/s]
  bool operator==(const OmniState&) const = default;
};

/// omni_msgs/OmniFeedback (`phantom/force_feedback`): force [N] and a lock position.
struct OmniFeedback {
  Vector3 force;     ///< [N]
  Vector3 position;  ///< the driver's lock position (unused by the driver unless locked)
  bool operator==(const OmniFeedback&) const = default;
};

/// The type names and schema of message `M` (specialised for each struct above).
template <class M>
const MessageType& TypeOf();
template <>
const MessageType& TypeOf<PoseStamped>();
template <>
const MessageType& TypeOf<TwistStamped>();
template <>
const MessageType& TypeOf<WrenchStamped>();
template <>
const MessageType& TypeOf<DiagnosticArray>();
template <>
const MessageType& TypeOf<Marker>();
template <>
const MessageType& TypeOf<MarkerArray>();
template <>
const MessageType& TypeOf<Float64MultiArray>();
template <>
const MessageType& TypeOf<OmniState>();
template <>
const MessageType& TypeOf<OmniFeedback>();

// Serialisation: clears `*out` and writes the CDR message (encapsulation header included).
// Throws std::invalid_argument for a string holding NUL.
void Serialize(const PoseStamped& m, std::vector<uint8_t>* out);
void Serialize(const TwistStamped& m, std::vector<uint8_t>* out);
void Serialize(const WrenchStamped& m, std::vector<uint8_t>* out);
void Serialize(const DiagnosticArray& m, std::vector<uint8_t>* out);
void Serialize(const Marker& m, std::vector<uint8_t>* out);
void Serialize(const MarkerArray& m, std::vector<uint8_t>* out);
void Serialize(const Float64MultiArray& m, std::vector<uint8_t>* out);
void Serialize(const OmniState& m, std::vector<uint8_t>* out);
void Serialize(const OmniFeedback& m, std::vector<uint8_t>* out);

// Parsing: the whole message from its CDR bytes; throws CdrError (type, field, byte offset) for
// truncated or malformed bytes. Never reads past the span.
PoseStamped ParsePoseStamped(std::span<const uint8_t> cdr);
TwistStamped ParseTwistStamped(std::span<const uint8_t> cdr);
WrenchStamped ParseWrenchStamped(std::span<const uint8_t> cdr);
DiagnosticArray ParseDiagnosticArray(std::span<const uint8_t> cdr);
Marker ParseMarker(std::span<const uint8_t> cdr);
MarkerArray ParseMarkerArray(std::span<const uint8_t> cdr);
Float64MultiArray ParseFloat64MultiArray(std::span<const uint8_t> cdr);
OmniState ParseOmniState(std::span<const uint8_t> cdr);
OmniFeedback ParseOmniFeedback(std::span<const uint8_t> cdr);

/// Parses `cdr` as message `M` (dispatches to the Parse* above).
template <class M>
M Parse(std::span<const uint8_t> cdr);
template <>
PoseStamped Parse<PoseStamped>(std::span<const uint8_t> cdr);
template <>
TwistStamped Parse<TwistStamped>(std::span<const uint8_t> cdr);
template <>
WrenchStamped Parse<WrenchStamped>(std::span<const uint8_t> cdr);
template <>
DiagnosticArray Parse<DiagnosticArray>(std::span<const uint8_t> cdr);
template <>
Marker Parse<Marker>(std::span<const uint8_t> cdr);
template <>
MarkerArray Parse<MarkerArray>(std::span<const uint8_t> cdr);
template <>
Float64MultiArray Parse<Float64MultiArray>(std::span<const uint8_t> cdr);
template <>
OmniState Parse<OmniState>(std::span<const uint8_t> cdr);
template <>
OmniFeedback Parse<OmniFeedback>(std::span<const uint8_t> cdr);

/// Every type above, for tests and tools that walk all of them.
std::span<const MessageType* const> AllTypes();

}  // namespace felt::ros2
