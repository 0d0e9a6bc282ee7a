#include "base/process.h"

#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace felt {
namespace {

using namespace std::chrono_literals;

TEST(ProcessTest, ExitStatus) {
  Process child = Process::Spawn({"/bin/sh", "-c", "exit 3"});
  EXPECT_GT(child.pid(), 0);
  child.Wait();
  EXPECT_FALSE(child.running());
  EXPECT_EQ(child.exit_code(), 3);
  EXPECT_EQ(child.term_signal(), 0);
  EXPECT_EQ(child.Outcome(), "exit code 3");
}

TEST(ProcessTest, CapturesOutputThroughAPipe) {
  const CapturedRun run = RunCaptured({"/bin/sh", "-c", "echo out; echo err >&2; exit 2"});
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_FALSE(run.timed_out);
  EXPECT_EQ(run.output, "out\nerr\n");
}

TEST(ProcessTest, CapturesOutputToAFile) {
  const std::string path = (std::filesystem::path(testing::TempDir()) / "process_test.log");
  SpawnOptions options;
  options.output = SpawnOptions::Output::kFile;
  options.output_file = path;
  options.env = {"FELT_PROCESS_TEST=hello"};
  Process child = Process::Spawn({"/bin/sh", "-c", "echo $FELT_PROCESS_TEST"}, options);
  ASSERT_TRUE(child.Wait(10s));
  EXPECT_EQ(child.exit_code(), 0);
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str(), "hello\n");
  std::filesystem::remove(path);
}

TEST(ProcessTest, WaitTimesOutThenTerminateStopsIt) {
  Process child = Process::Spawn({"/bin/sleep", "30"});
  EXPECT_FALSE(child.Wait(50ms));
  EXPECT_TRUE(child.running());
  child.Terminate(2s);
  EXPECT_FALSE(child.running());
  EXPECT_EQ(child.term_signal(), SIGTERM);
  EXPECT_EQ(child.exit_code(), -1);
}

TEST(ProcessTest, TerminateKillsAChildThatIgnoresSigterm) {
  SpawnOptions options;
  options.output = SpawnOptions::Output::kPipe;
  Process child = Process::Spawn(
      {"/bin/sh", "-c", "trap '' TERM; echo ready; while :; do sleep 0.1; done"}, options);
  std::string output;
  while (output.find("ready") == std::string::npos && child.ReadOutput(&output)) {
  }
  child.Terminate(100ms);
  EXPECT_EQ(child.term_signal(), SIGKILL);
}

TEST(ProcessTest, RunCapturedKillsAtTheTimeout) {
  const auto start = std::chrono::steady_clock::now();
  const CapturedRun run = RunCaptured({"/bin/sh", "-c", "echo started; exec sleep 30"}, 200ms);
  EXPECT_TRUE(run.timed_out);
  EXPECT_EQ(run.exit_code, -1);
  EXPECT_EQ(run.output, "started\n");
  EXPECT_LT(std::chrono::steady_clock::now() - start, 10s);
}

TEST(ProcessTest, ForkRunsAFunction) {
  Process child = Process::Fork([] { return 7; });
  child.Wait();
  EXPECT_EQ(child.exit_code(), 7);
}

TEST(ProcessTest, ExecFailureExits127) {
  Process child = Process::Spawn({"/nonexistent/felt-process-test"});
  child.Wait();
  EXPECT_EQ(child.exit_code(), 127);
}

}  // namespace
}  // namespace felt
