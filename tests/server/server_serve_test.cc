// `felt serve` as a child process: SIGTERM stops it cleanly (exit 0, the final statistics
// printed, the stats JSON written); a trace run touches the cloth. Needs the `felt` binary of the
// same build (built with the `felt` target); skipped where it was not built (the TSan CI build
// compiles only the test executables).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

namespace {

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
  pid_t pid = -1;
  std::string log;  // stdout and stderr of the child
};

// Starts `felt serve <args>` with its output in a file of its own.
Child StartServe(const std::string& args, const std::string& name) {
  Child child;
  child.log = (std::filesystem::path(testing::TempDir()) / (name + ".log")).string();
  // A log left by an earlier run must not be mistaken for this child's output (the shell truncates
  // it only once the child runs).
  std::filesystem::remove(child.log);
  const std::string command = "exec " + kFelt + " serve " + args + " > " + child.log + " 2>&1";
  child.pid = fork();
  if (child.pid == 0) {
    execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  return child;
}

// Waits up to `timeout` for the child to exit; returns its exit code (-1: still running or
// killed by a signal).
int WaitExit(pid_t pid, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) {
      return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return -1;
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
  ASSERT_GT(child.pid, 0);
  // Wait (deadline) until the loops have run: the monitor's first once-a-second line, then SIGTERM.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (ReadFile(child.log).find("[info] haptic: ") == std::string::npos &&
         std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_EQ(kill(child.pid, SIGTERM), 0);
  const int code = WaitExit(child.pid, std::chrono::seconds(10));
  if (code == -1) kill(child.pid, SIGKILL);
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
  const int code = WaitExit(child.pid, std::chrono::seconds(30));
  if (code == -1) kill(child.pid, SIGKILL);
  const std::string log = ReadFile(child.log);
  ASSERT_EQ(code, 0) << log;
  EXPECT_NE(log.find("stopped after the duration"), std::string::npos) << log;
  const std::string stats = ReadFile(json);
  EXPECT_EQ(stats.find("\"contacts\": 0,"), std::string::npos) << stats;
  EXPECT_EQ(stats.find("\"peak_force_N\": 0,"), std::string::npos) << stats;
}

TEST_F(ServeTest, BadSceneExitsTwoAndStartsNothing) {
  const std::string scene = (std::filesystem::path(testing::TempDir()) / "bad_haptic.toml");
  std::ofstream(scene) << ReadFile(kScene) << "\n[haptic]\nstale_input_ms = -1\n";
  Child child = StartServe("--scene " + scene + " --trace " + kTrace, "serve_bad");
  EXPECT_EQ(WaitExit(child.pid, std::chrono::seconds(20)), 2);
  const std::string log = ReadFile(child.log);
  EXPECT_NE(log.find("haptic.stale_input_ms"), std::string::npos) << log;
  EXPECT_EQ(log.find("serve: scene"), std::string::npos) << log;
}

}  // namespace
