// `felt bench transport --security-cost` runs briefly (1 s per condition, its own DDS domain) and
// writes both conditions, with answered round trips, into its JSON and Markdown. No timing is
// asserted beyond "positive and finite".
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "base/json.h"
#include "tests/app/felt_process.h"
#include "tests/test_domain.h"
#include "transport/security.h"

namespace {

using felt::test::Outcome;
using felt::test::ReadFile;
using felt::test::RunFelt;

TEST(BenchTransportSecurity, WritesBothConditionsAndTheRatio) {
  if (felt::transport::SecurityPluginDir().empty()) {
    GTEST_SKIP() << "Cyclone's security plugins (libdds_security_auth.so) were not found";
  }
  const std::string prefix =
      (std::filesystem::path(::testing::TempDir()) / "felt_bench_security").string();
  std::filesystem::remove(prefix + ".json");
  const Outcome outcome =
      RunFelt("bench transport --security-cost --seconds 1 --domain " +
              std::to_string(felt::testing::ExclusiveDdsDomain()) + " --security-out " + prefix);
  ASSERT_EQ(outcome.exit_code, 0) << outcome.output;
  EXPECT_NE(outcome.output.find("| ratio on/off |"), std::string::npos) << outcome.output;
  const felt::Json json = felt::ParseJson(ReadFile(prefix + ".json"), prefix + ".json");
  for (const char* condition : {"security_off", "security_on"}) {
    const felt::Json& c = json.at(condition);
    for (const char* key : {"p50_us", "p99_us"}) {
      const double v = c.at(key).get<double>();
      EXPECT_TRUE(std::isfinite(v) && v > 0.0) << condition << "." << key << "\n" << json;
    }
    // 1 s at 1 kHz after the warm-ups, in 4 runs (each may round up a ping); loose: a loaded
    // machine still answers most pings.
    const auto sent = c.at("pings_sent").get<uint64_t>();
    EXPECT_TRUE(sent >= 1000u && sent <= 1004u) << json;
    EXPECT_GT(c.at("pongs_received").get<uint64_t>(), 500u) << json;
  }
  EXPECT_GT(json.at("ratio_p50").get<double>(), 0.0);
  EXPECT_NE(ReadFile(prefix + ".md").find("Command: `felt bench transport --security-cost"),
            std::string::npos);
}

}  // namespace
