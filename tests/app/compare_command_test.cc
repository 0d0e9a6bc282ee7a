// `felt compare` as a user runs it: the table on stdout, the JSON file with every per-variant
// field, the reference at zero error, the same forces in two processes, and bad input exiting 2
// with a message naming the variant and key.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "tests/app/felt_process.h"

namespace felt {
namespace {

using test::RunFelt;

using test::kSource;
using test::ReadFile;

// A temporary file name unique to this process and `tag`.
std::string CompareTempPath(const std::string& tag) {
  return test::TempPath("felt_compare_" + std::to_string(getpid()) + "_" + tag);
}

// `felt compare` on the first `duration` of a bundled trace with two snapshot modes on the
// default curtain, writing JSON to `json`.
test::Outcome ShortCompare(const std::string& trace, const std::string& duration,
                           const std::string& json) {
  return RunFelt("compare --trace " + kSource + "/recordings/" + trace + ".trace --scene " +
                 kSource + "/scenes/curtain.toml --duration " + duration +
                 " --variants 'ref: snapshot=newest; blend: snapshot=blend_forces, "
                 "structure=bvh-aabb-4' --json " +
                 json);
}

// The member `key` of the variant named `name` in the JSON text `json` (null when missing).
Json VariantMember(const std::string& json, const std::string& name, const std::string& key) {
  const Json doc = Json::parse(json, nullptr, false);
  if (!doc.is_object()) return nullptr;
  for (const Json& variant : doc.value("variants", Json::array())) {
    if (variant.value("name", "") == name) return variant.value(key, Json());
  }
  return nullptr;
}

TEST(CompareCommand, PrintsTheTableAndWritesEveryJsonField) {
  const std::string json_path = CompareTempPath("a.json");
  const test::Outcome out = ShortCompare("poke_hold", "0.3", json_path);
  ASSERT_EQ(out.exit_code, 0) << out.output;
  EXPECT_NE(out.output.find("301 ticks"), std::string::npos) << out.output;
  EXPECT_NE(out.output.find("| variant | overrides | tick_us_p50 |"), std::string::npos)
      << out.output;
  EXPECT_NE(out.output.find("| ref | snapshot=newest |"), std::string::npos) << out.output;
  EXPECT_NE(out.output.find("| blend | snapshot=blend_forces,structure=bvh-aabb-4 |"),
            std::string::npos)
      << out.output;
  const std::string json = ReadFile(json_path);
  for (const char* key : {"ticks",
                          "frames",
                          "tick_us_median",
                          "tick_us_p99",
                          "frame_ms_median",
                          "frame_ms_p99",
                          "timer_overhead_us",
                          "force_rms_error_N",
                          "force_max_error_N",
                          "max_jump_N",
                          "max_jump_vs_ref_N",
                          "peak_force_N",
                          "peak_minus_ref_peak_N",
                          "contacts",
                          "contact_mismatches",
                          "pop_through",
                          "max_reach_mm",
                          "clamped_ticks",
                          "stalled_ticks",
                          "nan_events"}) {
    EXPECT_FALSE(VariantMember(json, "ref", key).is_null()) << key << "\n" << json;
    EXPECT_FALSE(VariantMember(json, "blend", key).is_null()) << key << "\n" << json;
  }
  EXPECT_NE(json.find("\"reference\": \"ref\""), std::string::npos) << json;
  EXPECT_EQ(VariantMember(json, "ref", "ticks"), Json(301));
  EXPECT_EQ(VariantMember(json, "ref", "frames"), Json(18));
  EXPECT_EQ(VariantMember(json, "ref", "force_rms_error_N"), Json(0));
  EXPECT_EQ(VariantMember(json, "ref", "force_max_error_N"), Json(0));
  EXPECT_EQ(VariantMember(json, "ref", "stalled_ticks"), Json(0));
  std::remove(json_path.c_str());
}

// --truth: the truth runs first as variant 0 and is the reference; --csv has the JSON's fields.
TEST(CompareCommand, TruthIsVariantZeroAndTheCsvHasEveryField) {
  const std::string json_path = CompareTempPath("t.json");
  const std::string csv_path = CompareTempPath("t.csv");
  const test::Outcome out =
      RunFelt("compare --trace " + kSource + "/recordings/fast_swipe.trace --scene " + kSource +
              "/scenes/curtain.toml --duration 1.2 --truth --variants 'newest: snapshot=newest' "
              "--json " +
              json_path + " --csv " + csv_path);
  ASSERT_EQ(out.exit_code, 0) << out.output;
  EXPECT_NE(out.output.find("reference 'truth'"), std::string::npos) << out.output;
  EXPECT_NE(out.output.find("| truth | truth=on |"), std::string::npos) << out.output;
  const std::string json = ReadFile(json_path);
  EXPECT_NE(json.find("\"reference\": \"truth\""), std::string::npos) << json;
  EXPECT_EQ(VariantMember(json, "truth", "frames"), Json(1201));  // a frame every tick
  EXPECT_EQ(VariantMember(json, "truth", "force_rms_error_N"), Json(0));
  EXPECT_EQ(VariantMember(json, "truth", "peak_minus_ref_peak_N"), Json(0));
  EXPECT_EQ(VariantMember(json, "newest", "pop_through"), Json(0));
  // newest's peak above the truth's, as the JSON has both peaks.
  const Json peak = VariantMember(json, "newest", "peak_force_N");
  const Json truth_peak = VariantMember(json, "truth", "peak_force_N");
  ASSERT_TRUE(peak.is_number() && truth_peak.is_number()) << json;
  EXPECT_DOUBLE_EQ(VariantMember(json, "newest", "peak_minus_ref_peak_N").get<double>(),
                   peak.get<double>() - truth_peak.get<double>());
  const std::string csv = ReadFile(csv_path);
  EXPECT_EQ(csv.rfind("name,overrides,ticks,frames,tick_us_median,", 0), 0u) << csv;
  EXPECT_NE(csv.find(",peak_minus_ref_peak_N,"), std::string::npos) << csv;
  EXPECT_NE(csv.find(",pop_through,max_reach_mm,"), std::string::npos) << csv;
  EXPECT_NE(csv.find("\ntruth,truth=on,1201,1201,"), std::string::npos) << csv;
  EXPECT_NE(csv.find("\nnewest,snapshot=newest,1201,72,"), std::string::npos) << csv;
  std::remove(json_path.c_str());
  std::remove(csv_path.c_str());
}

TEST(CompareCommand, TwoProcessesGiveTheSameForces) {
  // Force figures are printed in shortest round-trip form: equal text means equal bits. 1.2 s of
  // the fast swipe: the tip crosses the cloth's plane from 1.1 s on, so the forces are not zero.
  const std::string a_path = CompareTempPath("b1.json");
  const std::string b_path = CompareTempPath("b2.json");
  ASSERT_EQ(ShortCompare("fast_swipe", "1.2", a_path).exit_code, 0);
  ASSERT_EQ(ShortCompare("fast_swipe", "1.2", b_path).exit_code, 0);
  const std::string a = ReadFile(a_path);
  const std::string b = ReadFile(b_path);
  EXPECT_NE(VariantMember(a, "ref", "contacts"), Json(0)) << a;
  EXPECT_NE(VariantMember(a, "ref", "peak_force_N"), Json(0)) << a;
  for (const char* key :
       {"force_rms_error_N", "force_max_error_N", "max_jump_N", "peak_force_N", "contacts"}) {
    for (const char* variant : {"ref", "blend"}) {
      EXPECT_EQ(VariantMember(a, variant, key), VariantMember(b, variant, key))
          << variant << " " << key;
      EXPECT_FALSE(VariantMember(a, variant, key).is_null()) << variant << " " << key;
    }
  }
  std::remove(a_path.c_str());
  std::remove(b_path.c_str());
}

TEST(CompareCommand, BadVariantsExit2NamingTheVariantAndKey) {
  const std::string base = "compare --trace " + kSource + "/recordings/poke_hold.trace --scene " +
                           kSource + "/scenes/curtain.toml --duration 0.1 --variants ";
  const test::Outcome value = RunFelt(base + "'ref: ; bad: snapshot=sideways'");
  EXPECT_EQ(value.exit_code, 2) << value.output;
  EXPECT_NE(value.output.find("variant 2 'bad': snapshot=sideways: "), std::string::npos)
      << value.output;
  EXPECT_NE(value.output.find("proxy.snapshot_mode: unknown value 'sideways'"), std::string::npos)
      << value.output;
  EXPECT_EQ(value.output.find("| variant |"), std::string::npos) << "nothing ran";

  const std::string key = RunFelt(base + "'ref: snap=newest'").output;
  EXPECT_NE(key.find("variant 1 'ref': unknown key 'snap'"), std::string::npos) << key;

  const test::Outcome trace = RunFelt("compare --trace /nonexistent.trace --scene " + kSource +
                                      "/scenes/curtain.toml --variants scene");
  EXPECT_EQ(trace.exit_code, 2) << trace.output;
  EXPECT_NE(trace.output.find("/nonexistent.trace"), std::string::npos) << trace.output;
}

}  // namespace
}  // namespace felt
