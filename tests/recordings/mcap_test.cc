// MCAP writer and reader (recordings/mcap.h) and MCAP pose traces (recordings/mcap_trace.h):
// round trips through the index and through the linear scan, every corruption refused with the
// file, offset and record, and every file read back by an independent reader (npm @mcap/core,
// tools/npm/check_mcap.mjs; skipped with the reason when it is not installed).
#include "recordings/mcap.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "recordings/mcap_trace.h"
#include "ros2/messages.h"
#include "tests/npm_check.h"
#include "tests/recordings/test_util.h"

namespace felt {
namespace {

using ros2::TypeOf;

std::vector<uint8_t> McapBytesOf(const ros2::PoseStamped& m) {
  std::vector<uint8_t> b;
  ros2::Serialize(m, &b);
  return b;
}

// A CRTK-style recording: measured_cp + measured_cv at 1 kHz, servo_cf, a status each 100
// samples; small chunks so that the file has many. Returns every payload per channel id.
std::vector<std::vector<std::vector<uint8_t>>> WriteSampleMcap(const std::string& path, int n,
                                                               size_t chunk_bytes) {
  McapWriterOptions options;
  options.chunk_size_bytes = chunk_bytes;
  McapWriter w(path, options);
  const uint16_t s_pose =
      w.AddSchema(TypeOf<ros2::PoseStamped>().name, "ros2msg", TypeOf<ros2::PoseStamped>().schema);
  const uint16_t s_twist = w.AddSchema(TypeOf<ros2::TwistStamped>().name, "ros2msg",
                                       TypeOf<ros2::TwistStamped>().schema);
  const uint16_t s_wrench = w.AddSchema(TypeOf<ros2::WrenchStamped>().name, "ros2msg",
                                        TypeOf<ros2::WrenchStamped>().schema);
  const uint16_t s_diag = w.AddSchema(TypeOf<ros2::DiagnosticArray>().name, "ros2msg",
                                      TypeOf<ros2::DiagnosticArray>().schema);
  const uint16_t c_pose = w.AddChannel(s_pose, "/dev/measured_cp", "cdr", {{"k", "v"}});
  const uint16_t c_twist = w.AddChannel(s_twist, "/dev/measured_cv", "cdr");
  const uint16_t c_wrench = w.AddChannel(s_wrench, "/dev/servo_cf", "cdr");
  const uint16_t c_diag = w.AddChannel(s_diag, "/diagnostics", "cdr");
  std::vector<std::vector<std::vector<uint8_t>>> payloads(4);
  std::vector<uint8_t> b;
  for (int i = 0; i < n; ++i) {
    const int64_t t_ns = 1'000'000'000 + int64_t{i} * 1'000'000;
    ros2::PoseStamped p;
    p.header = {ros2::TimeFromNs(t_ns), "dev/device"};
    p.pose.position = {0.01 * std::sin(i * 0.01), 0.002 * i, -0.03};
    ros2::Serialize(p, &b);
    w.WriteMessage(c_pose, i, t_ns + 5, t_ns, b);
    payloads[c_pose].push_back(b);
    ros2::TwistStamped tw;
    tw.header = p.header;
    tw.twist.linear = {0.01 * std::cos(i * 0.01), 2.0, 0};
    ros2::Serialize(tw, &b);
    w.WriteMessage(c_twist, i, t_ns + 6, t_ns, b);
    payloads[c_twist].push_back(b);
    ros2::WrenchStamped f;
    f.header = p.header;
    f.wrench.force = {0, 0.1 * i, 0};
    ros2::Serialize(f, &b);
    w.WriteMessage(c_wrench, i, t_ns + 9, t_ns, b);
    payloads[c_wrench].push_back(b);
    if (i % 100 == 0) {
      ros2::DiagnosticArray d;
      d.header.stamp = ros2::TimeFromNs(t_ns);
      d.status.push_back({0, "felt", "ok", "felt", {{"i", std::to_string(i)}}});
      ros2::Serialize(d, &b);
      w.WriteMessage(c_diag, i / 100, t_ns + 7, t_ns, b);
      payloads[c_diag].push_back(b);
    }
  }
  w.Close();
  return payloads;
}

// Every message of a reader, per channel, in the order read.
std::vector<std::vector<std::vector<uint8_t>>> ReadAllPayloads(McapReader& r) {
  std::vector<std::vector<std::vector<uint8_t>>> out(r.channels().size());
  r.ReadMessages([&](const McapMessage& m) {
    out.at(m.channel_id).emplace_back(m.data.begin(), m.data.end());
  });
  return out;
}

void PatchFile(const std::string& path, uint64_t offset, const void* bytes, size_t n) {
  std::string all = test::ReadFile(path);
  std::memcpy(all.data() + offset, bytes, n);
  test::WriteFile(path, all);
}

TEST(Mcap, Crc32MatchesTheCheckValue) {
  // The CRC-32/ISO-HDLC check value of "123456789" (Williams 1993 catalogue: 0xCBF43926).
  const std::string s = "123456789";
  EXPECT_EQ(Crc32({reinterpret_cast<const uint8_t*>(s.data()), s.size()}), 0xCBF43926u);
  // Continuing a CRC over two pieces equals the CRC of the whole.
  const auto* p = reinterpret_cast<const uint8_t*>(s.data());
  EXPECT_EQ(Crc32({p + 4, 5}, Crc32({p, 4})), 0xCBF43926u);
}

TEST(Mcap, RoundTripThroughTheIndexAndThroughTheScan) {
  const std::string dir = test::ScratchDir("mcap_round_trip");
  const std::string path = dir + "/a.mcap";
  const auto written = WriteSampleMcap(path, 2000, 16 * 1024);
  McapReader r(path);
  EXPECT_TRUE(r.indexed());
  EXPECT_EQ(r.profile(), "ros2");
  EXPECT_EQ(r.message_count(), 2000u * 3 + 20);
  ASSERT_EQ(r.channels().size(), 4u);
  EXPECT_EQ(r.channels().at(0).topic, "/dev/measured_cp");
  EXPECT_EQ(r.channels().at(0).metadata.at(0), (std::pair<std::string, std::string>{"k", "v"}));
  EXPECT_EQ(r.schemas().at(r.channels().at(3).schema_id).name,
            "diagnostic_msgs/msg/DiagnosticArray");
  EXPECT_EQ(ReadAllPayloads(r), written);
  // One channel only, through the index.
  uint64_t n = 0;
  r.ReadMessages([&](const McapMessage& m) { n += m.channel_id == 3 ? 1 : 1000; }, {3});
  EXPECT_EQ(n, 20u);

  // Without a summary (summary_start = 0 in the Footer) the reader scans, with the same result.
  const uint64_t size = std::filesystem::file_size(path);
  const std::string scan = dir + "/scan.mcap";
  std::filesystem::copy_file(path, scan);
  const uint64_t zero = 0;
  const uint32_t zero32 = 0;
  PatchFile(scan, size - 8 - 29 + 9, &zero, 8);
  PatchFile(scan, size - 8 - 4, &zero32, 4);
  McapReader s(scan);
  EXPECT_FALSE(s.indexed());
  EXPECT_EQ(s.message_count(), 2000u * 3 + 20);
  EXPECT_EQ(ReadAllPayloads(s), written);
}

TEST(Mcap, WriterHoldsOneChunkAtATime) {
  const std::string dir = test::ScratchDir("mcap_bounded");
  McapWriterOptions options;
  options.chunk_size_bytes = 8192;
  McapWriter w(dir + "/b.mcap", options);
  const uint16_t s =
      w.AddSchema("geometry_msgs/msg/PoseStamped", "ros2msg", TypeOf<ros2::PoseStamped>().schema);
  const uint16_t c = w.AddChannel(s, "/x/measured_cp", "cdr");
  const std::vector<uint8_t> b = McapBytesOf(ros2::PoseStamped{});
  for (int i = 0; i < 20000; ++i) w.WriteMessage(c, i, i, i, b);
  // The file grows while writing: chunks leave memory as they fill.
  EXPECT_GT(std::filesystem::file_size(dir + "/b.mcap"), 1'000'000u);
  EXPECT_LE(w.stats().max_chunk_bytes, 8192 + 200u);
  w.Close();
  EXPECT_GE(w.stats().chunks, 20000u * 90 / 8192);
}

TEST(Mcap, CorruptionsAreRefusedWithFileOffsetAndRecord) {
  const std::string dir = test::ScratchDir("mcap_corrupt");
  const std::string good = dir + "/good.mcap";
  (void)WriteSampleMcap(good, 300, 4096);
  const std::string bytes = test::ReadFile(good);
  auto expect_error = [&](const std::string& name, const std::string& content,
                          const std::string& part) {
    const std::string path = dir + "/" + name + ".mcap";
    test::WriteFile(path, content);
    try {
      McapReader r(path);
      r.ReadMessages([](const McapMessage&) {});
      ADD_FAILURE() << name << ": accepted";
    } catch (const McapError& e) {
      EXPECT_NE(std::string(e.what()).find(path + ": byte "), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << name << ": " << e.what();
    }
  };
  std::string bad = bytes;
  bad[0] = 'X';
  expect_error("magic", bad, "byte 0: magic: not an MCAP file");
  // A byte inside the first chunk's records: that chunk's CRC (the summary still matches).
  bad = bytes;
  const size_t chunk = bad.find(std::string("/dev/measured_cp"));
  bad[chunk + 40] ^= 0x5A;
  expect_error("chunk_crc", bad, "Chunk: CRC32 of the records is");
  // A byte of the summary: its CRC.
  bad = bytes;
  bad[bad.size() - 60] ^= 0x01;
  expect_error("summary_crc", bad, "Footer: summary CRC32 is");
  // Truncated (a recorder killed before Close): the scan names where it stops.
  expect_error("truncated", bytes.substr(0, bytes.size() / 2), "truncated");
  expect_error("empty", "", "magic");
}

TEST(McapTrace, PoseTopicWithItsTwistBecomesATrace) {
  const std::string dir = test::ScratchDir("mcap_trace");
  const std::string path = dir + "/t.mcap";
  (void)WriteSampleMcap(path, 500, 8192);
  McapTraceInfo info;
  const Trace t = ReadMcapTrace(path, {}, &info);
  EXPECT_EQ(info.topic, "/dev/measured_cp");
  EXPECT_EQ(info.velocity_topic, "/dev/measured_cv");
  EXPECT_EQ(info.frame_id, "dev/device");
  EXPECT_EQ(info.velocity_from_differences, 0u);
  ASSERT_EQ(t.samples.size(), 500u);
  EXPECT_EQ(t.header.Get("device"), "dev");
  EXPECT_NEAR(t.header.rate_hz(), 1000.0, 1e-9);
  for (int i = 0; i < 500; ++i) {
    EXPECT_EQ(t.samples[i].t_s, static_cast<double>(int64_t{i} * 1'000'000) / 1e9);
    EXPECT_EQ(t.samples[i].p_D.x(), 0.01 * std::sin(i * 0.01));
    EXPECT_EQ(t.samples[i].v_D.x(), 0.01 * std::cos(i * 0.01));
  }
  // Log time instead of the header stamp: the same spacing here.
  McapTraceOptions by_log;
  by_log.time = McapTraceTime::kLogTime;
  EXPECT_EQ(ReadMcapTrace(path, by_log).samples.size(), 500u);
  // Unknown topic: the error lists the file's topics.
  McapTraceOptions other;
  other.topic = "/nope";
  try {
    (void)ReadMcapTrace(path, other);
    FAIL();
  } catch (const TraceError& e) {
    EXPECT_NE(std::string(e.what()).find("no topic /nope in this MCAP file; its topics: "
                                         "/dev/measured_cp (geometry_msgs/msg/PoseStamped)"),
              std::string::npos)
        << e.what();
  }
  other.topic = "/dev/servo_cf";
  EXPECT_THROW((void)ReadMcapTrace(path, other), TraceError);
  EXPECT_TRUE(IsMcapPath("a/b.MCAP"));
  EXPECT_FALSE(IsMcapPath("a.trace"));
}

TEST(McapTrace, OmniStateMillimetresBecomeMetres) {
  const std::string dir = test::ScratchDir("mcap_omni");
  const std::string path = dir + "/touch.mcap";
  {
    McapWriter w(path);
    const uint16_t s =
        w.AddSchema(TypeOf<ros2::OmniState>().name, "ros2msg", TypeOf<ros2::OmniState>().schema);
    const uint16_t c = w.AddChannel(s, "/phantom/state", "cdr");
    std::vector<uint8_t> b;
    for (int i = 0; i < 10; ++i) {
      ros2::OmniState m;
      m.header.stamp = ros2::TimeFromNs(5'000'000'000 + i * 1'000'000);
      m.pose.position = {10.0 * i, -20.0, 30.0};  // mm
      m.velocity = {0.01, 0, 0};                  // m/s
      m.close_gripper = i % 2 == 1;
      m.locked = i >= 5;
      ros2::Serialize(m, &b);
      w.WriteMessage(c, i, i, i, b);
    }
    w.Close();
  }
  McapTraceInfo info;
  const Trace t = ReadMcapTrace(path, {}, &info);
  EXPECT_EQ(info.type, "omni_msgs/msg/OmniState");
  ASSERT_EQ(t.samples.size(), 10u);
  EXPECT_DOUBLE_EQ(t.samples[3].p_D.x(), 0.03);
  EXPECT_DOUBLE_EQ(t.samples[3].p_D.y(), -0.02);
  EXPECT_EQ(t.samples[3].v_D.x(), 0.01);
  EXPECT_EQ(t.samples[3].buttons, 1u);
  EXPECT_EQ(t.samples[6].buttons, 2u);
}

// Chained CRC32 of payloads, as tools/npm/check_mcap.mjs computes it.
uint32_t McapChain(uint32_t prev, const std::vector<uint8_t>& bytes) {
  std::array<uint8_t, 4> le{};
  std::memcpy(le.data(), &prev, 4);
  return Crc32(bytes, Crc32(le));
}

TEST(McapIndependent, McapCoreReadsWhatFeltWrites) {
  FELT_SKIP_WITHOUT_NPM();
  const std::string dir = test::ScratchDir("mcap_independent");
  const std::string path = dir + "/felt.mcap";
  const auto written = WriteSampleMcap(path, 3000, 32 * 1024);
  std::string output;
  const int code = felt::testing::RunNpmCheck("check_mcap.mjs", "'" + path + "'", &output);
  ASSERT_EQ(code, 0) << output;
  const nlohmann::json j = nlohmann::json::parse(output);
  EXPECT_TRUE(j["ok"].get<bool>()) << output;
  EXPECT_EQ(j["profile"], "ros2");
  EXPECT_EQ(j["messages"], 3000 * 3 + 30);
  EXPECT_EQ(j["indexedMessages"], 3000 * 3 + 30);
  EXPECT_TRUE(j["dataSectionCrcChecked"].get<bool>());
  EXPECT_TRUE(j["summaryCrcChecked"].get<bool>());
  EXPECT_GT(j["chunks"].get<int>(), 5);
  McapReader r(path);
  ASSERT_EQ(j["topics"].size(), r.channels().size());
  for (const auto& [id, c] : r.channels()) {
    const auto& t = j["topics"][c.topic];
    EXPECT_EQ(t["schema"], r.schemas().at(c.schema_id).name);
    EXPECT_EQ(t["schemaEncoding"], "ros2msg");
    EXPECT_EQ(t["messageEncoding"], "cdr");
    EXPECT_EQ(t["count"].get<size_t>(), written[id].size());
    uint32_t crc = 0;
    for (const auto& b : written[id]) crc = McapChain(crc, b);
    EXPECT_EQ(t["crc"].get<uint32_t>(), crc) << c.topic;
  }
}

}  // namespace
}  // namespace felt
