// The commands with MCAP files (issue 24), as a user runs them: a bundled trace written as a
// CRTK-style MCAP file drives `felt compare` to the same forces as the trace itself; `felt trace
// import --format mcap` converts it; bad MCAP input exits 2 naming the file, offset and record.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "recordings/mcap.h"
#include "recordings/trace.h"
#include "ros2/messages.h"
#include "tests/app/felt_process.h"

namespace felt::test {
namespace {

class McapCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(kFelt)) GTEST_SKIP() << kFelt << " not built";
  }
};

// `trace` as /touch/measured_cp + /touch/measured_cv, stamped with its times.
void WriteTraceAsMcap(const Trace& trace, const std::string& path) {
  McapWriter w(path);
  const auto& pt = ros2::TypeOf<ros2::PoseStamped>();
  const auto& tt = ros2::TypeOf<ros2::TwistStamped>();
  const uint16_t cp =
      w.AddChannel(w.AddSchema(pt.name, "ros2msg", pt.schema), "/touch/measured_cp", "cdr");
  const uint16_t cv =
      w.AddChannel(w.AddSchema(tt.name, "ros2msg", tt.schema), "/touch/measured_cv", "cdr");
  std::vector<uint8_t> b;
  uint32_t seq = 0;
  for (const TraceSample& s : trace.samples) {
    const auto ns = static_cast<int64_t>(std::llround(s.t_s * 1e9));
    ros2::PoseStamped p;
    p.header = {ros2::TimeFromNs(ns), "touch/device"};
    p.pose.position = {s.p_D.x(), s.p_D.y(), s.p_D.z()};
    ros2::Serialize(p, &b);
    w.WriteMessage(cp, seq, static_cast<uint64_t>(ns), static_cast<uint64_t>(ns), b);
    ros2::TwistStamped t;
    t.header = p.header;
    t.twist.linear = {s.v_D.x(), s.v_D.y(), s.v_D.z()};
    ros2::Serialize(t, &b);
    w.WriteMessage(cv, seq++, static_cast<uint64_t>(ns), static_cast<uint64_t>(ns), b);
  }
  w.Close();
}

TEST_F(McapCommand, CompareOnAnMcapFileGivesTheTracesForces) {
  const Trace trace = ReadTrace(kPokeHoldTrace);
  const std::string mcap = TempPath("mcap_poke_hold.mcap");
  WriteTraceAsMcap(trace, mcap);
  auto run = [&](const std::string& input, const std::string& json) {
    const Outcome out = RunFelt("compare --trace " + input + " --scene " + kSource +
                                "/scenes/curtain.toml --duration 4 --variants 'a: "
                                "snapshot=interpolate; b: snapshot=newest' --json " +
                                json);
    EXPECT_EQ(out.exit_code, 0) << out.output;
    return nlohmann::json::parse(ReadFile(json));
  };
  const nlohmann::json a = run(kPokeHoldTrace, TempPath("mcap_cmp_trace.json"));
  const nlohmann::json b = run(mcap, TempPath("mcap_cmp_mcap.json"));
  ASSERT_EQ(a["variants"].size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    for (const char* key : {"ticks", "force_rms_error_N", "force_max_error_N", "max_jump_N",
                            "peak_force_N", "contacts"}) {
      EXPECT_EQ(a["variants"][i][key], b["variants"][i][key]) << key;
    }
  }
  EXPECT_GT(a["variants"][0]["contacts"].get<int>(), 0);
}

TEST_F(McapCommand, TraceImportReadsAnMcapPoseTopic) {
  const Trace trace = ReadTrace(kPokeHoldTrace);
  const std::string mcap = TempPath("mcap_import.mcap");
  WriteTraceAsMcap(trace, mcap);
  const std::string out = TempPath("mcap_import.trace");
  const Outcome o = RunFelt("trace import --format mcap --in " + mcap + " --out " + out +
                            " --topic /touch/measured_cp");
  ASSERT_EQ(o.exit_code, 0) << o.output;
  const Trace imported = ReadTrace(out);
  ASSERT_EQ(imported.samples.size(), trace.samples.size());
  EXPECT_EQ(imported.header.Get("source_format"), "mcap");
  // 1 kHz in, 1 kHz out: the Hermite resampling passes through the knots.
  for (size_t k = 0; k < trace.samples.size(); k += 97) {
    EXPECT_NEAR((imported.samples[k].p_D - trace.samples[k].p_D).norm(), 0.0, 1e-12) << k;
  }
}

TEST_F(McapCommand, BadMcapInputExitsTwoNamingFileOffsetAndRecord) {
  const std::string bad = TempPath("mcap_bad.mcap");
  {
    std::ofstream f(bad);
    f << "not an mcap file at all";
  }
  ExpectFeltError(
      "compare --trace " + bad + " --scene " + kSource +
          "/scenes/curtain.toml --variants 'a: snapshot=newest'",
      bad + ": byte 0: magic: not an MCAP file (no leading magic 89 4D 43 41 50 30 0D 0A)");
  const Trace trace = ReadTrace(kPokeHoldTrace);
  const std::string good = TempPath("mcap_topics.mcap");
  WriteTraceAsMcap(trace, good);
  ExpectFeltError("replay " + good + " --topic /nope",
                  good +
                      ": no topic /nope in this MCAP file; its topics: /touch/measured_cp "
                      "(geometry_msgs/msg/PoseStamped), /touch/measured_cv "
                      "(geometry_msgs/msg/TwistStamped)");
  ExpectFeltError("record --out " + TempPath("x.mcap") + " --forces-out /tmp/f.csv",
                  "--forces-out: an MCAP recording holds the forces (servo_cf)");
}

}  // namespace
}  // namespace felt::test
