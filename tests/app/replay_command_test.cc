// `felt replay` and `felt record` as a user runs them: bad input exits 2 with one line naming
// the file and line (nothing is published), and a replay with no server gives up after its
// discovery timeout with exit 1 and a hint.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "tests/app/felt_process.h"
#include "tests/test_domain.h"

namespace felt::test {
namespace {

class ReplayCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(kFelt)) GTEST_SKIP() << kFelt << " not built";
  }
};

TEST_F(ReplayCommand, MissingTraceExitsTwo) {
  ExpectFeltError("replay /nonexistent/felt_no.trace",
                  "/nonexistent/felt_no.trace: cannot open for reading: No such file or directory");
}

TEST_F(ReplayCommand, MalformedTraceExitsTwoWithFileAndLine) {
  const std::string bad = TempPath("replay_bad.trace");
  std::ofstream(bad) << "# felt-trace v1\n# units: m, s, m/s\n# rate_hz: 1000\n# device: d\n"
                        "# source: test\n# frame: device\nt_s,x,y,z,vx,vy,vz,buttons\n"
                        "0,0,0,0,0,0,0,0\n0.002,0,0,0,0,0,0,0\n0.001,0,0,0,0,0,0,0\n";
  const Outcome outcome = RunFelt("replay " + bad);
  EXPECT_EQ(outcome.exit_code, 2) << outcome.output;
  EXPECT_EQ(outcome.output.rfind("felt: error: " + bad + ":10: ", 0), 0u) << outcome.output;
  EXPECT_EQ(outcome.output.find("publishing"), std::string::npos) << outcome.output;
  std::filesystem::remove(bad);
}

TEST_F(ReplayCommand, BadRateAndDurationExitTwo) {
  ExpectFeltError("replay " + kPokeHoldTrace + " --rate 0", "--rate must be in (0, 100], got 0");
  ExpectFeltError("replay " + kPokeHoldTrace + " --duration -2",
                  "--duration must be in (0, 86400] s, got -2");
}

TEST_F(ReplayCommand, NoServerGivesUpAfterTheDiscoveryTimeout) {
  // A domain nobody serves: this process's own.
  const std::string domain = std::to_string(felt::testing::ExclusiveDdsDomain());
  const Outcome outcome =
      RunFelt("replay " + kPokeHoldTrace + " --domain " + domain + " --discovery-timeout 0.5");
  EXPECT_EQ(outcome.exit_code, 1) << outcome.output;
  EXPECT_NE(outcome.output.find("felt replay: no server found on DDS domain " + domain),
            std::string::npos)
      << outcome.output;
  EXPECT_EQ(outcome.output.find("publishing"), std::string::npos) << outcome.output;
}

TEST_F(ReplayCommand, RecordBadDurationExitsTwo) {
  ExpectFeltError("record --out " + TempPath("record_bad.trace") + " --duration 0",
                  "--duration must be in (0, 86400] s, got 0");
}

}  // namespace
}  // namespace felt::test
