// `felt serve` as a child process: SIGTERM stops it cleanly (exit 0, the final statistics
// printed, the stats JSON written); a trace run touches the cloth. Needs the `felt` binary of the
// same build (built with the `felt` target); skipped where it was not built (the TSan CI build
// compiles only the test executables).
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

#include "base/json.h"
#include "base/process.h"

namespace {

using felt::Json;
using felt::ParseJson;
using felt::Process;
using felt::SpawnOptions;

const std::string kFelt = std::string(FELT_BINARY_DIR) + "/felt";
const std::string kScene = std::string(FELT_SOURCE_DIR "/scenes/curtain.toml");
const std::string kTrace = std::string(FELT_SOURCE_DIR "/recordings/poke_hold.trace");

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

struct Child {
  Process process;
  std::string log;  // stdout and stderr of the child
};

// Starts `felt serve <args>` with its output in a file of its own.
Child StartServe(const std::string& args, const std::string& name) {
  Child child;
  child.log = (std::filesystem::path(testing::TempDir()) / (name + ".log")).string();
  SpawnOptions options;
  options.output = SpawnOptions::Output::kFile;
  options.output_file = child.log;
  child.process = Process::Spawn({"/bin/sh", "-c", "exec " + kFelt + " serve " + args}, options);
  return child;
}

// Waits up to `timeout` for the child to exit; returns its exit code (-1: still running, then
// killed, or ended by a signal).
int WaitExit(Process& process, std::chrono::milliseconds timeout) {
  if (!process.Wait(timeout)) process.Terminate(std::chrono::milliseconds(0));
  return process.exit_code();
}

class ServeTest : public testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(kFelt)) GTEST_SKIP() << kFelt << " not built";
  }
};

TEST_F(ServeTest, SigtermStopsCleanlyWithTheFinalStats) {
  const std::string json = (std::filesystem::path(testing::TempDir()) / "serve_sigterm.json");
  std::filesystem::remove(json);
  Child child = StartServe("--scene " + kScene + " --trace " + kTrace +
                               " --duration 60 --no-realtime --stats-json " + json,
                           "serve_sigterm");
  ASSERT_GT(child.process.pid(), 0);
  // Wait (deadline) until the loops have run: the monitor's first once-a-second line, then SIGTERM.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (ReadFile(child.log).find("[info] haptic: ") == std::string::npos &&
         std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  child.process.Signal(SIGTERM);
  const int code = WaitExit(child.process, std::chrono::seconds(10));
  const std::string log = ReadFile(child.log);
  EXPECT_EQ(code, 0) << log;
  EXPECT_NE(log.find("stopped by signal"), std::string::npos) << log;
  EXPECT_NE(log.find("final: haptic:"), std::string::npos) << log;
  EXPECT_NE(log.find("final: realtime false"), std::string::npos) << log;
  const std::string stats = ReadFile(json);
  for (const char* key : {"\"lateness_us\"", "\"frame_ms\"", "\"p999\"", "\"overruns\"",
                          "\"ticks\"", "\"frames\"", "\"realtime\": false"}) {
    EXPECT_NE(stats.find(key), std::string::npos) << key << "\n" << stats;
  }
}

TEST_F(ServeTest, TraceRunTouchesTheCloth) {
  const std::string json = (std::filesystem::path(testing::TempDir()) / "serve_trace.json");
  Child child = StartServe("--scene " + kScene + " --trace " + kTrace +
                               " --duration 3 --no-realtime --stats-json " + json,
                           "serve_trace");
  const int code = WaitExit(child.process, std::chrono::seconds(30));
  const std::string log = ReadFile(child.log);
  ASSERT_EQ(code, 0) << log;
  EXPECT_NE(log.find("stopped after the duration"), std::string::npos) << log;
  const Json stats = ParseJson(ReadFile(json), json);
  EXPECT_GT(stats.value("contacts", 0), 0) << stats;
  EXPECT_GT(stats.value("peak_force_N", 0.0), 0.0) << stats;
}

TEST_F(ServeTest, BadSceneExitsTwoAndStartsNothing) {
  const std::string scene = (std::filesystem::path(testing::TempDir()) / "bad_haptic.toml");
  std::ofstream(scene) << ReadFile(kScene) << "\n[haptic]\nstale_input_ms = -1\n";
  Child child = StartServe("--scene " + scene + " --trace " + kTrace, "serve_bad");
  EXPECT_EQ(WaitExit(child.process, std::chrono::seconds(20)), 2);
  const std::string log = ReadFile(child.log);
  EXPECT_NE(log.find("haptic.stale_input_ms"), std::string::npos) << log;
  EXPECT_EQ(log.find("serve: scene"), std::string::npos) << log;
}

}  // namespace
