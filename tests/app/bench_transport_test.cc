// `felt bench transport` runs as a user would run it, briefly (1 s per part, its own DDS domain):
// exit code 0, and the JSON holds every key issue 6 names with sane values. No timing is asserted
// beyond "the latencies are positive and finite".
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

#include "base/json.h"
#include "tests/app/felt_process.h"
#include "tests/test_domain.h"

namespace {

using felt::test::kSource;
using felt::test::Outcome;
using felt::test::ReadFile;
using felt::test::RunFelt;

// The number after `"key": ` at the first occurrence of the key inside the object `object`.
double NumberIn(const std::string& json, const std::string& object, const std::string& key) {
  const size_t at = json.find("\"" + object + "\":");
  if (at == std::string::npos) return NAN;
  const std::regex pattern("\"" + key + "\": *(-?[0-9.eE+-]+)");
  std::smatch match;
  const std::string rest = json.substr(at);
  if (!std::regex_search(rest, match, pattern)) return NAN;
  return std::stod(match[1]);
}

TEST(BenchTransport, EndToEndRunWritesEveryKey) {
  const std::string json =
      (std::filesystem::path(::testing::TempDir()) / "felt_bench_transport.json").string();
  std::filesystem::remove(json);
  const Outcome outcome = RunFelt("bench transport --seconds 1 --domain " +
                                  std::to_string(felt::testing::ExclusiveDdsDomain()) + " --json " +
                                  json + " --scene " + kSource + "/scenes/curtain.toml --trace " +
                                  kSource + "/recordings/poke_hold.trace");
  ASSERT_EQ(outcome.exit_code, 0) << outcome.output;
  EXPECT_NE(outcome.output.find("end to end: publish -> force received"), std::string::npos)
      << outcome.output;
  const std::string text = ReadFile(json);
  for (const char* object : {"e2e_us", "sample_age_us", "raw_roundtrip_us"}) {
    for (const char* key : {"p50", "p99", "p999", "max"}) {
      const double v = NumberIn(text, object, key);
      EXPECT_TRUE(std::isfinite(v) && v > 0.0) << object << "." << key << " = " << v << "\n"
                                               << text;
    }
  }
  const std::regex sent("\"samples_sent\": ([0-9]+)");
  const std::regex received("\"forces_received\": ([0-9]+)");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(text, m, sent)) << text;
  EXPECT_EQ(std::stoull(m[1]), 1000u);  // 1 s at 1 kHz after the warm-up
  ASSERT_TRUE(std::regex_search(text, m, received)) << text;
  EXPECT_GT(std::stoull(m[1]), 100u);  // loose: a loaded CI machine still answers most samples

  // The ROS 2 profile's run (issue 24): a PoseStamped driver answered with stamped wrenches.
  EXPECT_NE(outcome.output.find("end to end, ROS 2 profile (PoseStamped)"), std::string::npos)
      << outcome.output;
  const felt::Json doc = felt::ParseJson(text, json);
  const felt::Json& ros2 = doc.at("profiles").at("ros2");
  for (const char* key : {"p50", "p99", "max"}) {
    const double v = ros2.at("e2e_us").at(key).get<double>();
    EXPECT_TRUE(std::isfinite(v) && v > 0.0) << "profiles.ros2.e2e_us." << key << " = " << v;
  }
  EXPECT_EQ(ros2.at("samples_sent").get<uint64_t>(), 1000u);
  EXPECT_GT(ros2.at("samples_answered").get<uint64_t>(), 100u);
  EXPECT_TRUE(std::isfinite(doc.at("profiles").at("e2e_p50_difference_us").get<double>()));
}

TEST(BenchTransport, BadTraceIsRefusedBeforeMeasuring) {
  const Outcome outcome =
      RunFelt("bench transport --seconds 1 --domain " +
              std::to_string(felt::testing::ExclusiveDdsDomain()) +
              " --trace /nonexistent/x.trace --scene " + kSource + "/scenes/curtain.toml");
  EXPECT_NE(outcome.exit_code, 0);
  EXPECT_NE(outcome.output.find("/nonexistent/x.trace"), std::string::npos) << outcome.output;
}

}  // namespace
