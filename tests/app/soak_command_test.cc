// `felt soak` as a user runs it: a short run (two seconds of replay) produces every field of its
// JSON and markdown and exits 3 when a threshold is crossed; SIGTERM stops it and both children
// (no orphan left); bad input exits 2 naming the file and line. Real processes, real Cyclone DDS
// on loopback, a DDS domain of this test process's own.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "tests/app/felt_process.h"
#include "tests/test_domain.h"

namespace felt::test {
namespace {

const std::string kScene = kSource + "/scenes/curtain.toml";

// A DDS domain of this test process's own (tests/test_domain.h).
std::string Domain() { return std::to_string(felt::testing::ExclusiveDdsDomain()); }

// Pids of the live children of `parent` (from /proc/*/stat's ppid field).
std::set<pid_t> ChildrenOf(pid_t parent) {
  std::set<pid_t> children;
  for (const auto& entry : std::filesystem::directory_iterator("/proc")) {
    const std::string name = entry.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    const std::string stat = ReadFile(entry.path().string() + "/stat");
    const size_t close = stat.rfind(')');
    if (close == std::string::npos) continue;
    std::istringstream fields(stat.substr(close + 2));
    std::string state;
    pid_t ppid = 0;
    fields >> state >> ppid;
    if (ppid == parent) children.insert(std::stoi(name));
  }
  return children;
}

bool Alive(pid_t pid) { return kill(pid, 0) == 0; }

class SoakCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(kFelt)) GTEST_SKIP() << kFelt << " not built";
  }
};

TEST_F(SoakCommand, ShortRunWritesEveryFieldAndACrossedThresholdExitsThree) {
  // Lenient limits, except a haptic lateness p99 of 0 us, which no real loop meets.
  const std::string json = TempPath("soak_short.json");
  const std::string md = TempPath("soak_short.md");
  std::filesystem::remove(json);
  std::filesystem::remove(md);
  const Outcome outcome =
      RunFelt("soak --minutes 0.03 --scene " + kScene + " --trace " + kPokeHoldTrace +
              " --domain " + Domain() + " --no-realtime --json " + json +
              " --max-dropped 1e9 --max-rss-growth-kb 1e9 "
              "--max-lateness-p999-us 1e9 --max-lateness-p99-us 0");
  EXPECT_EQ(outcome.exit_code, 3) << outcome.output;
  EXPECT_NE(outcome.output.find("check         FAIL haptic lateness p99 us"), std::string::npos)
      << outcome.output;
  EXPECT_NE(outcome.output.find("check         ok   server RSS growth kB"), std::string::npos)
      << outcome.output;
  EXPECT_NE(outcome.output.find("felt soak: FAIL: a threshold was crossed"), std::string::npos)
      << outcome.output;

  // Every field of the JSON (values vary by machine; their presence and a few invariants do not).
  const std::string written = ReadFile(json);
  for (const char* key : {"\"command\": ",
                          "\"load_average_start\": ",
                          "\"load_average_end\": ",
                          "\"window_s\": ",
                          "\"children_ok\": true",
                          "\"interrupted\": false",
                          "\"rss_start_kB\": ",
                          "\"rss_end_kB\": ",
                          "\"rss_max_kB\": ",
                          "\"rss_growth_kB\": ",
                          "\"cpu_percent\": ",
                          "\"stats\": {",
                          "\"lateness_us\": {",
                          "\"period_us\": {",
                          "\"frame_ms\": {",
                          "\"overruns\": ",
                          "\"contacts\": ",
                          "\"peak_force_N\": ",
                          "\"report\": {",
                          "\"latency_us\": {",
                          "\"published\": ",
                          "\"late\": ",
                          "\"forces_lost\": ",
                          "\"pointer_lost\": ",
                          "\"server_counts\": true",
                          "\"thresholds\": {",
                          "\"max_haptic_lateness_p99_us\": 0",
                          "\"checks\": {",
                          "\"pass\": false"}) {
    EXPECT_NE(written.find(key), std::string::npos) << key << " missing in\n" << written;
  }
  EXPECT_EQ(written.find("null"), std::string::npos) << "an unknown value in\n" << written;
  EXPECT_NE(written.find("\"exit_code\": 0"), std::string::npos) << written;

  // The markdown table next to it.
  const std::string table = ReadFile(md);
  EXPECT_NE(table.find("Command: `felt soak --minutes 0.03"), std::string::npos) << table;
  EXPECT_NE(table.find("| haptic lateness (us) |"), std::string::npos) << table;
  EXPECT_NE(table.find("| end-to-end latency (us) |"), std::string::npos) << table;
  EXPECT_NE(table.find("| haptic lateness p99 us | "), std::string::npos) << table;
  EXPECT_NE(table.find("Load average"), std::string::npos) << table;
  std::filesystem::remove(json);
  std::filesystem::remove(md);
}

TEST_F(SoakCommand, ReportOnlyReportsACrossedThresholdAndExitsZero) {
  // The `make run` demo's mode: the same crossed threshold is reported as such, not as a failure.
  const Outcome outcome = RunFelt("soak --minutes 0.03 --scene " + kScene + " --trace " +
                                  kPokeHoldTrace + " --domain " + Domain() +
                                  " --no-realtime --report-only --max-dropped 1e9 "
                                  "--max-rss-growth-kb 1e9 --max-lateness-p999-us 1e9 "
                                  "--max-lateness-p99-us 0");
  EXPECT_EQ(outcome.exit_code, 0) << outcome.output;
  EXPECT_NE(outcome.output.find("check         over haptic lateness p99 us"), std::string::npos)
      << outcome.output;
  EXPECT_NE(
      outcome.output.find("felt soak: over a threshold, reported only (--report-only: exit 0)"),
      std::string::npos)
      << outcome.output;
  EXPECT_EQ(outcome.output.find("FAIL"), std::string::npos) << outcome.output;
}

TEST_F(SoakCommand, SigtermStopsBothChildrenAndLeavesNoOrphan) {
  // Start a long soak, wait (deadline) until both children run, then SIGTERM it.
  const std::string log = TempPath("soak_sigterm.log");
  felt::SpawnOptions options;
  options.output = felt::SpawnOptions::Output::kFile;
  options.output_file = log;
  felt::Process soak =
      felt::Process::Spawn({kFelt, "soak", "--minutes", "5", "--scene", kScene, "--trace",
                            kPokeHoldTrace, "--domain", Domain(), "--no-realtime"},
                           options);
  std::set<pid_t> children;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while ((children = ChildrenOf(soak.pid())).size() < 2 &&
         std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_EQ(children.size(), 2u) << ReadFile(log);
  soak.Signal(SIGTERM);

  // The soak exits 130 (interrupted) after stopping both; the children are gone.
  if (!soak.Wait(std::chrono::seconds(30))) {
    soak.Terminate(std::chrono::milliseconds(0));
    FAIL() << "soak did not stop within 30 s after SIGTERM\n" << ReadFile(log);
  }
  EXPECT_EQ(soak.exit_code(), 130) << soak.Outcome() << "\n" << ReadFile(log);
  for (const pid_t child : children) EXPECT_FALSE(Alive(child)) << "child " << child << " left";
  EXPECT_NE(ReadFile(log).find("felt soak: interrupted"), std::string::npos) << ReadFile(log);
  std::filesystem::remove(log);
}

TEST_F(SoakCommand, BadInputExitsTwoNamingWhatWasWrong) {
  // A missing trace.
  ExpectFeltError("soak --minutes 0.1 --scene " + kScene + " --trace /nonexistent/felt_no.trace",
                  "/nonexistent/felt_no.trace: cannot open for reading: No such file or directory");

  // A malformed trace: the file and the line.
  const std::string bad = TempPath("soak_bad.trace");
  std::ofstream(bad) << "# felt-trace v1\n# units: m, s, m/s\n# rate_hz: 1000\n# device: d\n"
                        "# source: test\n# frame: device\nt_s,x,y,z,vx,vy,vz,buttons\n"
                        "0,0,0,0,0,0,0,0\n0.001,0,zero,0,0,0,0,0\n";
  Outcome outcome = RunFelt("soak --minutes 0.1 --scene " + kScene + " --trace " + bad);
  EXPECT_EQ(outcome.exit_code, 2) << outcome.output;
  EXPECT_EQ(outcome.output.rfind("felt: error: " + bad + ":9: ", 0), 0u) << outcome.output;
  std::filesystem::remove(bad);

  // A missing scene; a bad duration.
  outcome =
      RunFelt("soak --minutes 0.1 --scene /nonexistent/felt_no.toml --trace " + kPokeHoldTrace);
  EXPECT_EQ(outcome.exit_code, 2) << outcome.output;
  EXPECT_NE(outcome.output.find("felt: error: /nonexistent/felt_no.toml: cannot read scene file"),
            std::string::npos)
      << outcome.output;
  outcome = RunFelt("soak --minutes 0 --scene " + kScene + " --trace " + kPokeHoldTrace);
  EXPECT_EQ(outcome.exit_code, 2) << outcome.output;
  EXPECT_EQ(outcome.output, "felt: error: --minutes must be in (0, 1440], got 0\n");
}

}  // namespace
}  // namespace felt::test
