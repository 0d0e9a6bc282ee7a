// ROS 2 messages in CDR (ros2/messages.h): layout against hand-computed bytes, round trips,
// truncated and malformed bytes refused with the type, field and offset, and every type's bytes
// equal to an independent serializer's (npm @foxglove/rosmsg2-serialization via
// tools/npm/check_cdr.mjs; skipped with the reason when it is not installed).
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "ros2/cdr.h"
#include "ros2/messages.h"
#include "tests/npm_check.h"

namespace felt::ros2 {
namespace {

using Json = nlohmann::json;

// ---- Sample messages (frame ids of several lengths, so that padding differs) ----

Header SampleHeader(const std::string& frame) { return Header{Time{1700000000, 123456789}, frame}; }

PoseStamped SamplePose(const std::string& frame) {
  PoseStamped m;
  m.header = SampleHeader(frame);
  m.pose.position = {0.012, -0.034, 0.0567};
  m.pose.orientation = {0.1, -0.2, 0.3, 0.9273618495495704};
  return m;
}

TwistStamped SampleTwist() {
  TwistStamped m;
  m.header = SampleHeader("touch_base");
  m.twist.linear = {0.5, -0.25, 1e-9};
  m.twist.angular = {0, 0, -3.5};
  return m;
}

WrenchStamped SampleWrench() {
  WrenchStamped m;
  m.header = SampleHeader("abc");
  m.wrench.force = {1.5, -2.25, 0.125};
  m.wrench.torque = {0, 0, 0};
  return m;
}

DiagnosticArray SampleDiagnostics() {
  DiagnosticArray m;
  m.header = SampleHeader("");
  DiagnosticStatus a;
  a.level = DiagnosticStatus::kWarn;
  a.name = "felt: server";
  a.message = "sim stalled";
  a.hardware_id = "felt";
  a.values = {{"haptic_ticks", "1000"}, {"haptic_lateness_us.p99", "12.5"}, {"x", ""}};
  DiagnosticStatus b;
  b.name = "e";
  m.status = {a, b};
  return m;
}

Marker SampleTriangles() {
  Marker m;
  m.header = SampleHeader("world");
  m.ns = "felt_cloth";
  m.id = 7;
  m.type = Marker::kTriangleList;
  m.scale = {1, 1, 1};
  m.color = {0.25f, 0.5f, 0.75f, 1.0f};
  m.points = {{0, 0, 0}, {0.1, 0, 0}, {0, 0.1, 0}, {0.1, 0.1, 0.01}, {0.2, 0, 0}, {0, 0.2, 0}};
  m.colors = {};
  m.frame_locked = true;
  return m;
}

Marker SampleSphere() {
  Marker m;
  m.header = SampleHeader("world");
  m.ns = "felt_proxy";
  m.type = Marker::kSphere;
  m.pose.position = {0.01, 0.2, -0.03};
  m.scale = {0.01, 0.01, 0.01};
  m.color = {1, 0, 0, 0.5f};
  m.lifetime = {0, 100000000};
  m.colors = {{1, 1, 1, 1}};
  m.points = {{1, 2, 3}};
  m.text = "proxy";
  return m;
}

// The array Felt publishes: a cloth triangle list and two proxy spheres (their lengths differ, so
// the alignment of each marker's doubles differs).
MarkerArray SampleMarkerArray() {
  MarkerArray a;
  a.markers = {SampleTriangles(), SampleSphere(), SampleSphere()};
  a.markers[2].ns = "felt_proxy_b";
  a.markers[2].id = 1;
  a.markers[2].text = "";
  a.markers[2].colors.clear();
  a.markers[2].points.clear();
  return a;
}

// The Force Dimension controller's command: [fx, fy, fz] and, with an Omega.7's joints, zeros.
Float64MultiArray SampleCommand(size_t n) {
  Float64MultiArray m;
  m.data.assign(n, 0.0);
  m.data[0] = 0.5;
  m.data[1] = -1.25;
  m.data[2] = 2.0;
  return m;
}

// A layout with dimensions (labels of several lengths), as other publishers send.
Float64MultiArray SampleLaidOutArray() {
  Float64MultiArray m;
  m.dim = {{"joints", 7, 7}, {"ab", 1, 1}};
  m.data_offset = 3;
  m.data = {1e-300, -0.0, 3.5, 1e10};
  return m;
}

OmniState SampleOmni() {
  OmniState m;
  m.header = SampleHeader("map");
  m.locked = true;
  m.close_gripper = false;
  m.pose.position = {12.5, -40.25, 88};  // mm
  m.pose.orientation = {0, 0, 0.7071067811865476, 0.7071067811865476};
  m.current = {0, 0.1, 0};
  m.velocity = {0.01, 0.02, -0.03};
  return m;
}

OmniFeedback SampleFeedback() {
  OmniFeedback m;
  m.force = {0.5, -1, 2};
  m.position = {0, 0, 0};
  return m;
}

// ---- JSON values in @foxglove/rosmsg2-serialization's shape ----

Json J(const Time& t) { return {{"sec", t.sec}, {"nanosec", t.nanosec}}; }
Json J(const Header& h) { return {{"stamp", J(h.stamp)}, {"frame_id", h.frame_id}}; }
Json J(const Vector3& v) { return {{"x", v.x}, {"y", v.y}, {"z", v.z}}; }
Json J(const Quaternion& q) { return {{"x", q.x}, {"y", q.y}, {"z", q.z}, {"w", q.w}}; }
Json J(const Pose& p) { return {{"position", J(p.position)}, {"orientation", J(p.orientation)}}; }
Json J(const ColorRGBA& c) { return {{"r", c.r}, {"g", c.g}, {"b", c.b}, {"a", c.a}}; }
Json J(const PoseStamped& m) { return {{"header", J(m.header)}, {"pose", J(m.pose)}}; }
Json J(const TwistStamped& m) {
  return {{"header", J(m.header)},
          {"twist", {{"linear", J(m.twist.linear)}, {"angular", J(m.twist.angular)}}}};
}
Json J(const WrenchStamped& m) {
  return {{"header", J(m.header)},
          {"wrench", {{"force", J(m.wrench.force)}, {"torque", J(m.wrench.torque)}}}};
}
Json J(const DiagnosticArray& m) {
  Json status = Json::array();
  for (const DiagnosticStatus& s : m.status) {
    Json values = Json::array();
    for (const KeyValue& kv : s.values) values.push_back({{"key", kv.key}, {"value", kv.value}});
    status.push_back({{"level", s.level},
                      {"name", s.name},
                      {"message", s.message},
                      {"hardware_id", s.hardware_id},
                      {"values", values}});
  }
  return {{"header", J(m.header)}, {"status", status}};
}
Json J(const Marker& m) {
  Json points = Json::array(), colors = Json::array();
  for (const Vector3& p : m.points) points.push_back(J(p));
  for (const ColorRGBA& c : m.colors) colors.push_back(J(c));
  return {{"header", J(m.header)},
          {"ns", m.ns},
          {"id", m.id},
          {"type", m.type},
          {"action", m.action},
          {"pose", J(m.pose)},
          {"scale", J(m.scale)},
          {"color", J(m.color)},
          {"lifetime", {{"sec", m.lifetime.sec}, {"nanosec", m.lifetime.nanosec}}},
          {"frame_locked", m.frame_locked},
          {"points", points},
          {"colors", colors},
          {"texture_resource", ""},
          {"texture", {{"header", J(Header{})}, {"format", ""}, {"data", Json::array()}}},
          {"uv_coordinates", Json::array()},
          {"text", m.text},
          {"mesh_resource", m.mesh_resource},
          {"mesh_file", {{"filename", ""}, {"data", Json::array()}}},
          {"mesh_use_embedded_materials", m.mesh_use_embedded_materials}};
}
Json J(const MarkerArray& m) {
  Json markers = Json::array();
  for (const Marker& marker : m.markers) markers.push_back(J(marker));
  return {{"markers", markers}};
}
Json J(const Float64MultiArray& m) {
  Json dim = Json::array();
  for (const MultiArrayDimension& d : m.dim) {
    dim.push_back({{"label", d.label}, {"size", d.size}, {"stride", d.stride}});
  }
  return {{"layout", {{"dim", dim}, {"data_offset", m.data_offset}}}, {"data", m.data}};
}
Json J(const OmniState& m) {
  return {{"header", J(m.header)}, {"locked", m.locked},      {"close_gripper", m.close_gripper},
          {"pose", J(m.pose)},     {"current", J(m.current)}, {"velocity", J(m.velocity)}};
}
Json J(const OmniFeedback& m) { return {{"force", J(m.force)}, {"position", J(m.position)}}; }

template <class M>
std::vector<uint8_t> Bytes(const M& m) {
  std::vector<uint8_t> out;
  Serialize(m, &out);
  return out;
}

std::string Hex(const std::vector<uint8_t>& b) {
  static const char* d = "0123456789abcdef";
  std::string s;
  for (uint8_t x : b) {
    s += d[x >> 4];
    s += d[x & 15];
  }
  return s;
}

// Every sample, as (label, type, bytes, JSON value).
struct Case {
  std::string label;
  const MessageType* type;
  std::vector<uint8_t> bytes;
  Json value;
};

template <class M>
Case MakeCase(const std::string& label, const M& m) {
  return Case{label, &TypeOf<M>(), Bytes(m), J(m)};
}

std::vector<Case> AllCases() {
  std::vector<Case> cases;
  for (const char* frame : {"", "a", "ab", "abc", "world", "touch_stylus_tip"}) {
    cases.push_back(MakeCase(std::string("frame '") + frame + "'", SamplePose(frame)));
  }
  cases.push_back(MakeCase("twist", SampleTwist()));
  cases.push_back(MakeCase("wrench", SampleWrench()));
  cases.push_back(MakeCase("two statuses", SampleDiagnostics()));
  cases.push_back(MakeCase("empty", DiagnosticArray{}));
  cases.push_back(MakeCase("triangle list", SampleTriangles()));
  cases.push_back(MakeCase("sphere", SampleSphere()));
  cases.push_back(MakeCase("cloth and two proxies", SampleMarkerArray()));
  cases.push_back(MakeCase("empty", MarkerArray{}));
  cases.push_back(MakeCase("Omega.3 [fx, fy, fz]", SampleCommand(3)));
  cases.push_back(MakeCase("Omega.7, 7 joints", SampleCommand(7)));
  cases.push_back(MakeCase("with a layout", SampleLaidOutArray()));
  cases.push_back(MakeCase("Touch state", SampleOmni()));
  cases.push_back(MakeCase("feedback", SampleFeedback()));
  return cases;
}

// ---- Tests ----

TEST(Ros2Cdr, PoseStampedLayoutMatchesHandComputedBytes) {
  // Header 4 bytes; sec, nanosec; frame_id "ab" = length 3 + 'a' 'b' NUL ends at byte 19; the
  // first float64 aligns to 8 past the header: byte 20 (one pad byte); 7 float64 end at 76.
  const std::vector<uint8_t> b = Bytes(SamplePose("ab"));
  ASSERT_EQ(b.size(), 76u);
  EXPECT_EQ(b[0], 0x00);
  EXPECT_EQ(b[1], 0x01);
  EXPECT_EQ(b[2], 0x00);
  EXPECT_EQ(b[3], 0x00);
  int32_t sec;
  uint32_t nsec, len;
  std::memcpy(&sec, &b[4], 4);
  std::memcpy(&nsec, &b[8], 4);
  std::memcpy(&len, &b[12], 4);
  EXPECT_EQ(sec, 1700000000);
  EXPECT_EQ(nsec, 123456789u);
  EXPECT_EQ(len, 3u);
  EXPECT_EQ(b[16], 'a');
  EXPECT_EQ(b[17], 'b');
  EXPECT_EQ(b[18], 0);
  EXPECT_EQ(b[19], 0);  // padding
  double x;
  std::memcpy(&x, &b[20], 8);
  EXPECT_EQ(x, 0.012);
  // With frame "abc" the string ends at 20: no padding, same size.
  EXPECT_EQ(Bytes(SamplePose("abc")).size(), 76u);
  // With "" (length 1) it ends at 17: 3 pad bytes, the doubles start at 20.
  EXPECT_EQ(Bytes(SamplePose("")).size(), 76u);
  EXPECT_EQ(Bytes(SamplePose("abcd")).size(), 84u);
}

TEST(Ros2Cdr, EveryTypeRoundTrips) {
  EXPECT_EQ(ParsePoseStamped(Bytes(SamplePose("world"))), SamplePose("world"));
  EXPECT_EQ(ParseTwistStamped(Bytes(SampleTwist())), SampleTwist());
  EXPECT_EQ(ParseWrenchStamped(Bytes(SampleWrench())), SampleWrench());
  EXPECT_EQ(ParseDiagnosticArray(Bytes(SampleDiagnostics())), SampleDiagnostics());
  EXPECT_EQ(ParseMarker(Bytes(SampleTriangles())), SampleTriangles());
  EXPECT_EQ(ParseMarker(Bytes(SampleSphere())), SampleSphere());
  EXPECT_EQ(ParseMarkerArray(Bytes(SampleMarkerArray())), SampleMarkerArray());
  EXPECT_EQ(ParseFloat64MultiArray(Bytes(SampleCommand(7))), SampleCommand(7));
  EXPECT_EQ(ParseFloat64MultiArray(Bytes(SampleLaidOutArray())), SampleLaidOutArray());
  EXPECT_EQ(ParseOmniState(Bytes(SampleOmni())), SampleOmni());
  EXPECT_EQ(ParseOmniFeedback(Bytes(SampleFeedback())), SampleFeedback());
}

TEST(Ros2Cdr, EveryTruncationIsRefusedWithTypeFieldAndOffset) {
  // Every prefix of every sample is refused (ASan checks no read goes past the span).
  for (const Case& c : AllCases()) {
    for (size_t n = 0; n < c.bytes.size(); ++n) {
      const std::span<const uint8_t> prefix(c.bytes.data(), n);
      try {
        const std::string_view name = c.type->name;
        if (name == "geometry_msgs/msg/PoseStamped") (void)ParsePoseStamped(prefix);
        if (name == "geometry_msgs/msg/TwistStamped") (void)ParseTwistStamped(prefix);
        if (name == "geometry_msgs/msg/WrenchStamped") (void)ParseWrenchStamped(prefix);
        if (name == "diagnostic_msgs/msg/DiagnosticArray") (void)ParseDiagnosticArray(prefix);
        if (name == "visualization_msgs/msg/Marker") (void)ParseMarker(prefix);
        if (name == "visualization_msgs/msg/MarkerArray") (void)ParseMarkerArray(prefix);
        if (name == "std_msgs/msg/Float64MultiArray") (void)ParseFloat64MultiArray(prefix);
        if (name == "omni_msgs/msg/OmniState") (void)ParseOmniState(prefix);
        if (name == "omni_msgs/msg/OmniFeedback") (void)ParseOmniFeedback(prefix);
        ADD_FAILURE() << c.type->name << " (" << c.label << "): prefix of " << n << " of "
                      << c.bytes.size() << " bytes was accepted";
      } catch (const CdrError& e) {
        EXPECT_EQ(e.type(), c.type->name);
        EXPECT_LE(e.offset(), n);
      }
    }
  }
}

TEST(Ros2Cdr, ErrorsNameTypeFieldAndOffset) {
  std::vector<uint8_t> b = Bytes(SamplePose("ab"));
  b.resize(40);  // position.z occupies bytes 36..43
  try {
    (void)ParsePoseStamped(b);
    FAIL() << "accepted";
  } catch (const CdrError& e) {
    EXPECT_STREQ(e.what(),
                 "geometry_msgs/msg/PoseStamped: field pose.position.z at byte 36: needs 8 bytes, "
                 "4 left (message of 40 bytes is truncated)");
  }
  // A string length past the end.
  b = Bytes(SamplePose("ab"));
  const uint32_t huge = 1000;
  std::memcpy(&b[12], &huge, 4);
  EXPECT_THROW(
      {
        try {
          (void)ParsePoseStamped(b);
        } catch (const CdrError& e) {
          EXPECT_NE(std::string(e.what()).find("field header.frame_id at byte 12: string length "
                                               "1000 runs past the end"),
                    std::string::npos)
              << e.what();
          throw;
        }
      },
      CdrError);
  // A bool byte of 2.
  b = Bytes(SampleOmni());
  b[20] = 2;  // header "map" ends at 20; locked is the next byte
  EXPECT_THROW(
      {
        try {
          (void)ParseOmniState(b);
        } catch (const CdrError& e) {
          EXPECT_STREQ(e.what(),
                       "omni_msgs/msg/OmniState: field locked at byte 20: bool byte is 2, not 0 "
                       "or 1");
          throw;
        }
      },
      CdrError);
  // A sequence count that cannot fit is refused before anything is sized.
  b = Bytes(DiagnosticArray{});
  const uint32_t many = 0xFFFFFFF0u;
  std::memcpy(&b[b.size() - 4], &many, 4);
  EXPECT_THROW((void)ParseDiagnosticArray(b), CdrError);
  // Big-endian CDR is refused; trailing garbage beyond padding too.
  b = Bytes(SampleFeedback());
  b[1] = 0x00;
  EXPECT_THROW((void)ParseOmniFeedback(b), CdrError);
  b = Bytes(SampleFeedback());
  b.insert(b.end(), 4, 0);
  EXPECT_THROW((void)ParseOmniFeedback(b), CdrError);
  b.resize(b.size() - 1);  // 3 bytes of padding are accepted
  EXPECT_EQ(ParseOmniFeedback(b), SampleFeedback());
}

TEST(Ros2Cdr, Float64MultiArrayLayoutMatchesHandComputedBytes) {
  // Header 4; dim count 0 (4..7); data_offset (8..11); data count 3 (12..15); the first float64
  // aligns to 8 past the header: byte 20 (4 pad bytes); three doubles end at 44.
  const std::vector<uint8_t> b = Bytes(SampleCommand(3));
  ASSERT_EQ(b.size(), 44u);
  uint32_t dims, offset, count;
  std::memcpy(&dims, &b[4], 4);
  std::memcpy(&offset, &b[8], 4);
  std::memcpy(&count, &b[12], 4);
  EXPECT_EQ(dims, 0u);
  EXPECT_EQ(offset, 0u);
  EXPECT_EQ(count, 3u);
  double fx, fz;
  std::memcpy(&fx, &b[20], 8);
  std::memcpy(&fz, &b[36], 8);
  EXPECT_EQ(fx, 0.5);
  EXPECT_EQ(fz, 2.0);
}

TEST(Ros2Cdr, TimeFromNsFloorsAndRoundTrips) {
  EXPECT_EQ(TimeFromNs(1'500'000'000), (Time{1, 500'000'000}));
  EXPECT_EQ(TimeFromNs(-1), (Time{-1, 999'999'999}));
  for (int64_t ns : {int64_t{0}, int64_t{-1}, int64_t{123456789012345}, int64_t{-987654321}}) {
    EXPECT_EQ(NsFromTime(TimeFromNs(ns)), ns);
  }
  EXPECT_THROW((void)TimeFromNs(int64_t{1} << 62), std::out_of_range);
}

TEST(Ros2Schema, SchemasAreTheMsgTextsWithTheirDependencies) {
  const std::string_view s = TypeOf<PoseStamped>().schema;
  EXPECT_EQ(s.substr(0, 46), "std_msgs/Header header\ngeometry_msgs/Pose pose");
  EXPECT_NE(s.find("\n" + std::string(80, '=') + "\nMSG: std_msgs/Header\n"), std::string::npos);
  EXPECT_NE(s.find("MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"), std::string::npos);
  for (const MessageType* t : AllTypes()) {
    EXPECT_FALSE(t->schema.empty()) << t->name;
    EXPECT_NE(t->dds_name.find("::msg::dds_::"), std::string_view::npos) << t->dds_name;
  }
  EXPECT_EQ(TypeOf<WrenchStamped>().dds_name, "geometry_msgs::msg::dds_::WrenchStamped_");
  EXPECT_EQ(TypeOf<MarkerArray>().dds_name, "visualization_msgs::msg::dds_::MarkerArray_");
  EXPECT_NE(TypeOf<MarkerArray>().schema.find("MSG: visualization_msgs/Marker\n"),
            std::string_view::npos);
  EXPECT_EQ(TypeOf<Float64MultiArray>().dds_name, "std_msgs::msg::dds_::Float64MultiArray_");
}

TEST(Ros2Independent, EveryTypeMatchesFoxgloveRosmsg2Serialization) {
  FELT_SKIP_WITHOUT_NPM();
  Json cases = Json::array();
  std::set<std::string> types;
  for (const Case& c : AllCases()) {
    cases.push_back({{"type", c.type->name},
                     {"label", c.label},
                     {"schema", c.type->schema},
                     {"value", c.value},
                     {"hex", Hex(c.bytes)}});
    types.insert(std::string(c.type->name));
  }
  EXPECT_EQ(types.size(), AllTypes().size()) << "a type has no sample";
  const std::filesystem::path dir =
      std::filesystem::path(FELT_BINARY_DIR) / "test_scratch" / "ros2";
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "cdr_cases.json").string();
  std::ofstream(path) << cases.dump(1);
  std::string output;
  const int code = felt::testing::RunNpmCheck("check_cdr.mjs", "'" + path + "'", &output);
  EXPECT_EQ(code, 0) << output;
  EXPECT_NE(output.find(std::to_string(cases.size()) + " of " + std::to_string(cases.size()) +
                        " cases agree"),
            std::string::npos)
      << output;
}

}  // namespace
}  // namespace felt::ros2
