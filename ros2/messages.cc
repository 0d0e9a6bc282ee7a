#include "ros2/messages.h"

#include <array>
#include <stdexcept>
#include <utility>

#include "ros2/cdr.h"

namespace felt::ros2 {
namespace {

// ---- The .msg definitions (ROS 2 Humble common_interfaces, omni_msgs of the Geomagic Touch ROS 2
// driver), comments left out. A schema is the top-level text, then each dependency after the
// separator line and "MSG: pkg/Type", as rosbag2 writes `ros2msg` schemas into MCAP.

constexpr std::string_view kTimeMsg = "int32 sec\nuint32 nanosec\n";
constexpr std::string_view kDurationMsg = "int32 sec\nuint32 nanosec\n";
constexpr std::string_view kHeaderMsg = "builtin_interfaces/Time stamp\nstring frame_id\n";
constexpr std::string_view kXyzMsg = "float64 x\nfloat64 y\nfloat64 z\n";
constexpr std::string_view kQuaternionMsg = "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n";
constexpr std::string_view kPoseMsg =
    "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n";
constexpr std::string_view kTwistMsg =
    "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n";
constexpr std::string_view kWrenchMsg =
    "geometry_msgs/Vector3 force\ngeometry_msgs/Vector3 torque\n";
constexpr std::string_view kPoseStampedMsg = "std_msgs/Header header\ngeometry_msgs/Pose pose\n";
constexpr std::string_view kTwistStampedMsg = "std_msgs/Header header\ngeometry_msgs/Twist twist\n";
constexpr std::string_view kWrenchStampedMsg =
    "std_msgs/Header header\ngeometry_msgs/Wrench wrench\n";
constexpr std::string_view kKeyValueMsg = "string key\nstring value\n";
constexpr std::string_view kDiagnosticStatusMsg =
    "byte OK=0\nbyte WARN=1\nbyte ERROR=2\nbyte STALE=3\nbyte level\nstring name\nstring "
    "message\nstring hardware_id\ndiagnostic_msgs/KeyValue[] values\n";
constexpr std::string_view kDiagnosticArrayMsg =
    "std_msgs/Header header\ndiagnostic_msgs/DiagnosticStatus[] status\n";
constexpr std::string_view kColorRgbaMsg = "float32 r\nfloat32 g\nfloat32 b\nfloat32 a\n";
constexpr std::string_view kCompressedImageMsg =
    "std_msgs/Header header\nstring format\nuint8[] data\n";
constexpr std::string_view kUvCoordinateMsg = "float32 u\nfloat32 v\n";
constexpr std::string_view kMeshFileMsg = "string filename\nuint8[] data\n";
constexpr std::string_view kMarkerMsg =
    "int32 ARROW=0\nint32 CUBE=1\nint32 SPHERE=2\nint32 CYLINDER=3\nint32 LINE_STRIP=4\n"
    "int32 LINE_LIST=5\nint32 CUBE_LIST=6\nint32 SPHERE_LIST=7\nint32 POINTS=8\n"
    "int32 TEXT_VIEW_FACING=9\nint32 MESH_RESOURCE=10\nint32 TRIANGLE_LIST=11\n"
    "int32 ARROW_STRIP=12\nint32 ADD=0\nint32 MODIFY=0\nint32 DELETE=2\nint32 DELETEALL=3\n"
    "std_msgs/Header header\nstring ns\nint32 id\nint32 type\nint32 action\n"
    "geometry_msgs/Pose pose\ngeometry_msgs/Vector3 scale\nstd_msgs/ColorRGBA color\n"
    "builtin_interfaces/Duration lifetime\nbool frame_locked\ngeometry_msgs/Point[] points\n"
    "std_msgs/ColorRGBA[] colors\nstring texture_resource\nsensor_msgs/CompressedImage texture\n"
    "visualization_msgs/UVCoordinate[] uv_coordinates\nstring text\nstring mesh_resource\n"
    "visualization_msgs/MeshFile mesh_file\nbool mesh_use_embedded_materials\n";
constexpr std::string_view kMarkerArrayMsg = "visualization_msgs/Marker[] markers\n";
constexpr std::string_view kMultiArrayDimensionMsg = "string label\nuint32 size\nuint32 stride\n";
constexpr std::string_view kMultiArrayLayoutMsg =
    "std_msgs/MultiArrayDimension[] dim\nuint32 data_offset\n";
constexpr std::string_view kFloat64MultiArrayMsg =
    "std_msgs/MultiArrayLayout layout\nfloat64[] data\n";
constexpr std::string_view kOmniStateMsg =
    "std_msgs/Header header\nbool locked\nbool close_gripper\ngeometry_msgs/Pose pose\n"
    "geometry_msgs/Vector3 current\ngeometry_msgs/Vector3 velocity\n";
constexpr std::string_view kOmniFeedbackMsg =
    "geometry_msgs/Vector3 force\ngeometry_msgs/Vector3 position\n";

struct Dep {
  std::string_view name;  // "pkg/Type"
  std::string_view text;
};

constexpr Dep kDepTime{"builtin_interfaces/Time", kTimeMsg};
constexpr Dep kDepDuration{"builtin_interfaces/Duration", kDurationMsg};
constexpr Dep kDepHeader{"std_msgs/Header", kHeaderMsg};
constexpr Dep kDepPoint{"geometry_msgs/Point", kXyzMsg};
constexpr Dep kDepVector3{"geometry_msgs/Vector3", kXyzMsg};
constexpr Dep kDepQuaternion{"geometry_msgs/Quaternion", kQuaternionMsg};
constexpr Dep kDepPose{"geometry_msgs/Pose", kPoseMsg};
constexpr Dep kDepTwist{"geometry_msgs/Twist", kTwistMsg};
constexpr Dep kDepWrench{"geometry_msgs/Wrench", kWrenchMsg};
constexpr Dep kDepKeyValue{"diagnostic_msgs/KeyValue", kKeyValueMsg};
constexpr Dep kDepDiagnosticStatus{"diagnostic_msgs/DiagnosticStatus", kDiagnosticStatusMsg};
constexpr Dep kDepColorRgba{"std_msgs/ColorRGBA", kColorRgbaMsg};
constexpr Dep kDepCompressedImage{"sensor_msgs/CompressedImage", kCompressedImageMsg};
constexpr Dep kDepUvCoordinate{"visualization_msgs/UVCoordinate", kUvCoordinateMsg};
constexpr Dep kDepMeshFile{"visualization_msgs/MeshFile", kMeshFileMsg};
constexpr Dep kDepMarker{"visualization_msgs/Marker", kMarkerMsg};
constexpr Dep kDepMultiArrayLayout{"std_msgs/MultiArrayLayout", kMultiArrayLayoutMsg};
constexpr Dep kDepMultiArrayDimension{"std_msgs/MultiArrayDimension", kMultiArrayDimensionMsg};

// The schema text: top, then "\n" + 80 '=' + "\nMSG: pkg/Type\n" + text per dependency
// (rosbag2's message definition format, also what @foxglove/rosmsg parses).
std::string ComposeSchema(std::string_view top, std::initializer_list<Dep> deps) {
  std::string s(top);
  for (const Dep& d : deps) {
    s += "\n" + std::string(80, '=') + "\nMSG: ";
    s += d.name;
    s += '\n';
    s += d.text;
  }
  return s;
}

MessageType MakeType(std::string_view name, std::string_view dds_name, const std::string& schema) {
  return MessageType{name, dds_name, schema};
}

// ---- Field writers and readers shared by the messages.

void Put(CdrWriter& w, const Time& t) {
  w.I32(t.sec);
  w.U32(t.nanosec);
}
void Put(CdrWriter& w, const Header& h) {
  Put(w, h.stamp);
  w.String(h.frame_id);
}
void Put(CdrWriter& w, const Vector3& v) {
  w.F64(v.x);
  w.F64(v.y);
  w.F64(v.z);
}
void Put(CdrWriter& w, const Quaternion& q) {
  w.F64(q.x);
  w.F64(q.y);
  w.F64(q.z);
  w.F64(q.w);
}
void Put(CdrWriter& w, const Pose& p) {
  Put(w, p.position);
  Put(w, p.orientation);
}
void Put(CdrWriter& w, const ColorRGBA& c) {
  w.F32(c.r);
  w.F32(c.g);
  w.F32(c.b);
  w.F32(c.a);
}

// Readers take the field's path prefix so errors name e.g. "pose.position.x".
Time GetTime(CdrReader& r, const char* sec, const char* nanosec) {
  Time t;
  t.sec = r.I32(sec);
  t.nanosec = r.U32(nanosec);
  return t;
}
Header GetHeader(CdrReader& r) {
  Header h;
  h.stamp = GetTime(r, "header.stamp.sec", "header.stamp.nanosec");
  h.frame_id = r.String("header.frame_id");
  return h;
}
// `names` holds the x, y, z field paths.
Vector3 GetXyz(CdrReader& r, const std::array<const char*, 3>& names) {
  Vector3 v;
  v.x = r.F64(names[0]);
  v.y = r.F64(names[1]);
  v.z = r.F64(names[2]);
  return v;
}
Pose GetPose(CdrReader& r) {
  Pose p;
  p.position = GetXyz(r, {"pose.position.x", "pose.position.y", "pose.position.z"});
  p.orientation.x = r.F64("pose.orientation.x");
  p.orientation.y = r.F64("pose.orientation.y");
  p.orientation.z = r.F64("pose.orientation.z");
  p.orientation.w = r.F64("pose.orientation.w");
  return p;
}
ColorRGBA GetColor(CdrReader& r, const char* field) {
  ColorRGBA c;
  c.r = r.F32(field);
  c.g = r.F32(field);
  c.b = r.F32(field);
  c.a = r.F32(field);
  return c;
}

void PutMarker(CdrWriter& w, const Marker& m) {
  Put(w, m.header);
  w.String(m.ns);
  w.I32(m.id);
  w.I32(m.type);
  w.I32(m.action);
  Put(w, m.pose);
  Put(w, m.scale);
  Put(w, m.color);
  w.I32(m.lifetime.sec);
  w.U32(m.lifetime.nanosec);
  w.Bool(m.frame_locked);
  w.SequenceLength(m.points.size());
  for (const Vector3& p : m.points) Put(w, p);
  w.SequenceLength(m.colors.size());
  for (const ColorRGBA& c : m.colors) Put(w, c);
  w.String("");      // texture_resource
  Put(w, Header{});  // texture: sensor_msgs/CompressedImage {header, format, data}
  w.String("");
  w.SequenceLength(0);
  w.SequenceLength(0);  // uv_coordinates
  w.String(m.text);
  w.String(m.mesh_resource);
  w.String("");  // mesh_file: visualization_msgs/MeshFile {filename, data}
  w.SequenceLength(0);
  w.Bool(m.mesh_use_embedded_materials);
}

// One Marker from `r` (its fields; the message end is the caller's).
Marker GetMarker(CdrReader& r) {
  Marker m;
  m.header = GetHeader(r);
  m.ns = r.String("ns");
  m.id = r.I32("id");
  m.type = r.I32("type");
  m.action = r.I32("action");
  m.pose = GetPose(r);
  m.scale = GetXyz(r, {"scale.x", "scale.y", "scale.z"});
  m.color = GetColor(r, "color");
  m.lifetime.sec = r.I32("lifetime.sec");
  m.lifetime.nanosec = r.U32("lifetime.nanosec");
  m.frame_locked = r.Bool("frame_locked");
  m.points.resize(r.SequenceLength("points", 24));
  for (Vector3& p : m.points) p = GetXyz(r, {"points[].x", "points[].y", "points[].z"});
  m.colors.resize(r.SequenceLength("colors", 16));
  for (ColorRGBA& c : m.colors) c = GetColor(r, "colors[]");
  (void)r.String("texture_resource");
  (void)GetTime(r, "texture.header.stamp.sec", "texture.header.stamp.nanosec");
  (void)r.String("texture.header.frame_id");
  (void)r.String("texture.format");
  r.SkipBytes("texture.data", r.SequenceLength("texture.data", 1));
  const uint32_t uv = r.SequenceLength("uv_coordinates", 8);
  for (uint32_t i = 0; i < uv; ++i) {
    (void)r.F32("uv_coordinates[].u");
    (void)r.F32("uv_coordinates[].v");
  }
  m.text = r.String("text");
  m.mesh_resource = r.String("mesh_resource");
  (void)r.String("mesh_file.filename");
  r.SkipBytes("mesh_file.data", r.SequenceLength("mesh_file.data", 1));
  m.mesh_use_embedded_materials = r.Bool("mesh_use_embedded_materials");
  return m;
}

}  // namespace

Time TimeFromNs(int64_t ns) {
  // Floor division so that nanosec is in [0, 1e9) for negative times too.
  int64_t sec = ns / 1'000'000'000;
  int64_t rem = ns % 1'000'000'000;
  if (rem < 0) {
    rem += 1'000'000'000;
    --sec;
  }
  if (sec < INT32_MIN || sec > INT32_MAX) {
    throw std::out_of_range("builtin_interfaces/Time: " + std::to_string(ns) +
                            " ns does not fit int32 seconds");
  }
  return Time{static_cast<int32_t>(sec), static_cast<uint32_t>(rem)};
}

int64_t NsFromTime(const Time& t) {
  return static_cast<int64_t>(t.sec) * 1'000'000'000 + static_cast<int64_t>(t.nanosec);
}

// ---- Types ----

template <>
const MessageType& TypeOf<PoseStamped>() {
  static const std::string schema =
      ComposeSchema(kPoseStampedMsg, {kDepHeader, kDepTime, kDepPose, kDepPoint, kDepQuaternion});
  static const MessageType type =
      MakeType("geometry_msgs/msg/PoseStamped", "geometry_msgs::msg::dds_::PoseStamped_", schema);
  return type;
}
template <>
const MessageType& TypeOf<TwistStamped>() {
  static const std::string schema =
      ComposeSchema(kTwistStampedMsg, {kDepHeader, kDepTime, kDepTwist, kDepVector3});
  static const MessageType type =
      MakeType("geometry_msgs/msg/TwistStamped", "geometry_msgs::msg::dds_::TwistStamped_", schema);
  return type;
}
template <>
const MessageType& TypeOf<WrenchStamped>() {
  static const std::string schema =
      ComposeSchema(kWrenchStampedMsg, {kDepHeader, kDepTime, kDepWrench, kDepVector3});
  static const MessageType type = MakeType("geometry_msgs/msg/WrenchStamped",
                                           "geometry_msgs::msg::dds_::WrenchStamped_", schema);
  return type;
}
template <>
const MessageType& TypeOf<DiagnosticArray>() {
  static const std::string schema = ComposeSchema(
      kDiagnosticArrayMsg, {kDepHeader, kDepTime, kDepDiagnosticStatus, kDepKeyValue});
  static const MessageType type = MakeType("diagnostic_msgs/msg/DiagnosticArray",
                                           "diagnostic_msgs::msg::dds_::DiagnosticArray_", schema);
  return type;
}
template <>
const MessageType& TypeOf<Marker>() {
  static const std::string schema =
      ComposeSchema(kMarkerMsg, {kDepHeader, kDepTime, kDepPose, kDepPoint, kDepQuaternion,
                                 kDepVector3, kDepColorRgba, kDepDuration, kDepCompressedImage,
                                 kDepUvCoordinate, kDepMeshFile});
  static const MessageType type =
      MakeType("visualization_msgs/msg/Marker", "visualization_msgs::msg::dds_::Marker_", schema);
  return type;
}
template <>
const MessageType& TypeOf<MarkerArray>() {
  static const std::string schema =
      ComposeSchema(kMarkerArrayMsg, {kDepMarker, kDepHeader, kDepTime, kDepPose, kDepPoint,
                                      kDepQuaternion, kDepVector3, kDepColorRgba, kDepDuration,
                                      kDepCompressedImage, kDepUvCoordinate, kDepMeshFile});
  static const MessageType type = MakeType("visualization_msgs/msg/MarkerArray",
                                           "visualization_msgs::msg::dds_::MarkerArray_", schema);
  return type;
}
template <>
const MessageType& TypeOf<Float64MultiArray>() {
  static const std::string schema =
      ComposeSchema(kFloat64MultiArrayMsg, {kDepMultiArrayLayout, kDepMultiArrayDimension});
  static const MessageType type =
      MakeType("std_msgs/msg/Float64MultiArray", "std_msgs::msg::dds_::Float64MultiArray_", schema);
  return type;
}
template <>
const MessageType& TypeOf<OmniState>() {
  static const std::string schema = ComposeSchema(
      kOmniStateMsg, {kDepHeader, kDepTime, kDepPose, kDepPoint, kDepQuaternion, kDepVector3});
  static const MessageType type =
      MakeType("omni_msgs/msg/OmniState", "omni_msgs::msg::dds_::OmniState_", schema);
  return type;
}
template <>
const MessageType& TypeOf<OmniFeedback>() {
  static const std::string schema = ComposeSchema(kOmniFeedbackMsg, {kDepVector3});
  static const MessageType type =
      MakeType("omni_msgs/msg/OmniFeedback", "omni_msgs::msg::dds_::OmniFeedback_", schema);
  return type;
}

std::span<const MessageType* const> AllTypes() {
  static const std::array<const MessageType*, 9> all = {
      &TypeOf<PoseStamped>(),       &TypeOf<TwistStamped>(), &TypeOf<WrenchStamped>(),
      &TypeOf<DiagnosticArray>(),   &TypeOf<Marker>(),       &TypeOf<MarkerArray>(),
      &TypeOf<Float64MultiArray>(), &TypeOf<OmniState>(),    &TypeOf<OmniFeedback>()};
  return all;
}

// ---- Serialize ----

void Serialize(const PoseStamped& m, std::vector<uint8_t>* out) {
  CdrWriter w(out);
  Put(w, m.header);
  Put(w, m.pose);
}

void Serialize(const TwistStamped& m, std::vector<uint8_t>* out) {
  CdrWriter w(out);
  Put(w, m.header);
  Put(w, m.twist.linear);
  Put(w, m.twist.angular);
}

void Serialize(const WrenchStamped& m, std::vector<uint8_t>* out) {
  CdrWriter w(out);
  Put(w, m.header);
  Put(w, m.wrench.force);
  Put(w, m.wrench.torque);
}

void Serialize(const DiagnosticArray& m, std::vector<uint8_t>* out) {
  CdrWriter w(out);
  Put(w, m.header);
  w.SequenceLength(m.status.size());
  for (const DiagnosticStatus& s : m.status) {
    w.U8(s.level);
    w.String(s.name);
    w.String(s.message);
    w.String(s.hardware_id);
    w.SequenceLength(s.values.size());
    for (const KeyValue& kv : s.values) {
      w.String(kv.key);
      w.String(kv.value);
    }
  }
}

void Serialize(const Marker& m, std::vector<uint8_t>* out) {
  CdrWriter w(out);
  PutMarker(w, m);
}

void Serialize(const MarkerArray& m, std::vector<uint8_t>* out) {
  CdrWriter w(out);
  w.SequenceLength(m.markers.size());
  for (const Marker& marker : m.markers) PutMarker(w, marker);
}

void Serialize(const Float64MultiArray& m, std::vector<uint8_t>* out) {
  CdrWriter w(out);
  w.SequenceLength(m.dim.size());
  for (const MultiArrayDimension& d : m.dim) {
    w.String(d.label);
    w.U32(d.size);
    w.U32(d.stride);
  }
  w.U32(m.data_offset);
  w.SequenceLength(m.data.size());
  for (double v : m.data) w.F64(v);
}

void Serialize(const OmniState& m, std::vector<uint8_t>* out) {
  CdrWriter w(out);
  Put(w, m.header);
  w.Bool(m.locked);
  w.Bool(m.close_gripper);
  Put(w, m.pose);
  Put(w, m.current);
  Put(w, m.velocity);
}

void Serialize(const OmniFeedback& m, std::vector<uint8_t>* out) {
  CdrWriter w(out);
  Put(w, m.force);
  Put(w, m.position);
}

// ---- Parse ----

PoseStamped ParsePoseStamped(std::span<const uint8_t> cdr) {
  CdrReader r(cdr, TypeOf<PoseStamped>().name);
  PoseStamped m;
  m.header = GetHeader(r);
  m.pose = GetPose(r);
  r.Finish();
  return m;
}

TwistStamped ParseTwistStamped(std::span<const uint8_t> cdr) {
  CdrReader r(cdr, TypeOf<TwistStamped>().name);
  TwistStamped m;
  m.header = GetHeader(r);
  m.twist.linear = GetXyz(r, {"twist.linear.x", "twist.linear.y", "twist.linear.z"});
  m.twist.angular = GetXyz(r, {"twist.angular.x", "twist.angular.y", "twist.angular.z"});
  r.Finish();
  return m;
}

WrenchStamped ParseWrenchStamped(std::span<const uint8_t> cdr) {
  CdrReader r(cdr, TypeOf<WrenchStamped>().name);
  WrenchStamped m;
  m.header = GetHeader(r);
  m.wrench.force = GetXyz(r, {"wrench.force.x", "wrench.force.y", "wrench.force.z"});
  m.wrench.torque = GetXyz(r, {"wrench.torque.x", "wrench.torque.y", "wrench.torque.z"});
  r.Finish();
  return m;
}

DiagnosticArray ParseDiagnosticArray(std::span<const uint8_t> cdr) {
  CdrReader r(cdr, TypeOf<DiagnosticArray>().name);
  DiagnosticArray m;
  m.header = GetHeader(r);
  // A status takes at least 1 + 3 * 5 + 4 bytes (level, three empty strings, a count).
  const uint32_t n = r.SequenceLength("status", 20);
  m.status.resize(n);
  for (DiagnosticStatus& s : m.status) {
    s.level = r.U8("status[].level");
    s.name = r.String("status[].name");
    s.message = r.String("status[].message");
    s.hardware_id = r.String("status[].hardware_id");
    const uint32_t k = r.SequenceLength("status[].values", 10);
    s.values.resize(k);
    for (KeyValue& kv : s.values) {
      kv.key = r.String("status[].values[].key");
      kv.value = r.String("status[].values[].value");
    }
  }
  r.Finish();
  return m;
}

Marker ParseMarker(std::span<const uint8_t> cdr) {
  CdrReader r(cdr, TypeOf<Marker>().name);
  Marker m = GetMarker(r);
  r.Finish();
  return m;
}

MarkerArray ParseMarkerArray(std::span<const uint8_t> cdr) {
  CdrReader r(cdr, TypeOf<MarkerArray>().name);
  MarkerArray m;
  // A marker takes well over 100 bytes; 100 bounds the count before anything is sized.
  m.markers.resize(r.SequenceLength("markers", 100));
  for (Marker& marker : m.markers) marker = GetMarker(r);
  r.Finish();
  return m;
}

Float64MultiArray ParseFloat64MultiArray(std::span<const uint8_t> cdr) {
  CdrReader r(cdr, TypeOf<Float64MultiArray>().name);
  Float64MultiArray m;
  m.dim.resize(r.SequenceLength("layout.dim", 13));  // empty label (5) + size + stride
  for (MultiArrayDimension& d : m.dim) {
    d.label = r.String("layout.dim[].label");
    d.size = r.U32("layout.dim[].size");
    d.stride = r.U32("layout.dim[].stride");
  }
  m.data_offset = r.U32("layout.data_offset");
  m.data.resize(r.SequenceLength("data", 8));
  for (double& v : m.data) v = r.F64("data[]");
  r.Finish();
  return m;
}

OmniState ParseOmniState(std::span<const uint8_t> cdr) {
  CdrReader r(cdr, TypeOf<OmniState>().name);
  OmniState m;
  m.header = GetHeader(r);
  m.locked = r.Bool("locked");
  m.close_gripper = r.Bool("close_gripper");
  m.pose = GetPose(r);
  m.current = GetXyz(r, {"current.x", "current.y", "current.z"});
  m.velocity = GetXyz(r, {"velocity.x", "velocity.y", "velocity.z"});
  r.Finish();
  return m;
}

OmniFeedback ParseOmniFeedback(std::span<const uint8_t> cdr) {
  CdrReader r(cdr, TypeOf<OmniFeedback>().name);
  OmniFeedback m;
  m.force = GetXyz(r, {"force.x", "force.y", "force.z"});
  m.position = GetXyz(r, {"position.x", "position.y", "position.z"});
  r.Finish();
  return m;
}

template <>
PoseStamped Parse<PoseStamped>(std::span<const uint8_t> cdr) {
  return ParsePoseStamped(cdr);
}
template <>
TwistStamped Parse<TwistStamped>(std::span<const uint8_t> cdr) {
  return ParseTwistStamped(cdr);
}
template <>
WrenchStamped Parse<WrenchStamped>(std::span<const uint8_t> cdr) {
  return ParseWrenchStamped(cdr);
}
template <>
DiagnosticArray Parse<DiagnosticArray>(std::span<const uint8_t> cdr) {
  return ParseDiagnosticArray(cdr);
}
template <>
Marker Parse<Marker>(std::span<const uint8_t> cdr) {
  return ParseMarker(cdr);
}
template <>
MarkerArray Parse<MarkerArray>(std::span<const uint8_t> cdr) {
  return ParseMarkerArray(cdr);
}
template <>
Float64MultiArray Parse<Float64MultiArray>(std::span<const uint8_t> cdr) {
  return ParseFloat64MultiArray(cdr);
}
template <>
OmniState Parse<OmniState>(std::span<const uint8_t> cdr) {
  return ParseOmniState(cdr);
}
template <>
OmniFeedback Parse<OmniFeedback>(std::span<const uint8_t> cdr) {
  return ParseOmniFeedback(cdr);
}

}  // namespace felt::ros2
