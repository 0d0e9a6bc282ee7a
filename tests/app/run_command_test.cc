// `felt run`: the built binary, run as a user would. A bad scene exits 2 with the parser's
// message and starts nothing; a good scene prints its frame statistics (and JSON on request).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "tests/app/felt_process.h"

namespace felt::test {
namespace {

const std::string kScenes = kSource + "/scenes";

// Writes `text` to a file of this test's own in the test temp directory; returns its path.
std::string WriteTemp(const std::string& name, const std::string& text) {
  const std::filesystem::path path = std::filesystem::path(::testing::TempDir()) / name;
  std::ofstream(path) << text;
  return path.string();
}

// A small, cheap scene: 8 x 8 hanging from its top edge.
constexpr const char* kSmallScene = R"([scene]
name = "small"
description = "8 x 8 test cloth"
duration_s = 0.2
[cloth]
width = 8
height = 8
spacing_m = 0.02
[cloth.structural]
[cloth.shear]
[[cloth.pins]]
kind = "edge"
name = "top"
)";

TEST(RunCommand, BadSceneExitsTwoWithFileLineFieldAndStartsNothing) {
  const std::string path =
      WriteTemp("felt_run_test_bad.toml", "[scene]\nname = \"bad\"\n[cloth]\nwidth = 1\n");
  ExpectFeltError("run --scene " + path + " --fast",
                  path + ":4:1: cloth.width: must be in [2, 4096], got 1");
  std::filesystem::remove(path);
}

TEST(RunCommand, UnknownKeyExitsTwo) {
  const std::string path =
      WriteTemp("felt_run_test_typo.toml", "[cloth]\n[cloth.structural]\nstifness_N_per_m = 5\n");
  ExpectFeltError("run --scene " + path, path +
                                             ":3:1: cloth.structural.stifness_N_per_m: unknown key "
                                             "'stifness_N_per_m' in [cloth.structural] (did you "
                                             "mean 'stiffness_N_per_m'?)");
  std::filesystem::remove(path);
}

// `felt run` steps the cloth only, but a typo in a section it does not use ([device], [proxy],
// [haptic], [transport]) is still refused: the file is checked as `felt serve` reads it.
TEST(RunCommand, ATypoInASectionRunDoesNotUseExitsTwo) {
  const std::string device = WriteTemp("felt_run_test_device.toml",
                                       std::string(kSmallScene) + "[device]\nmax_force = 3\n");
  ExpectFeltError("run --scene " + device + " --fast",
                  device +
                      ":15:1: device.max_force: unknown key 'max_force' in [device] (did you "
                      "mean 'max_force_N'?)");
  std::filesystem::remove(device);
  const std::string transport = WriteTemp("felt_run_test_transport.toml",
                                          std::string(kSmallScene) + "[transport]\ndomain = 999\n");
  ExpectFeltError("run --scene " + transport + " --fast",
                  transport + ":15:1: transport.domain: must be in [0, 230], got 999");
  std::filesystem::remove(transport);
}

TEST(RunCommand, MissingSceneFileExitsTwo) {
  ExpectFeltError("run --scene /nonexistent/felt_no_scene.toml",
                  "/nonexistent/felt_no_scene.toml: cannot read scene file: No such file or "
                  "directory");
}

TEST(RunCommand, BadDurationExitsTwo) {
  const std::string path = WriteTemp("felt_run_test_duration.toml", kSmallScene);
  ExpectFeltError("run --scene " + path + " --duration -1 --fast",
                  "--duration must be in (0, 86400] s, got -1");
  std::filesystem::remove(path);
}

TEST(RunCommand, GoodScenePrintsStatisticsAndJson) {
  const std::string path = WriteTemp("felt_run_test_small.toml", kSmallScene);
  const std::string json =
      (std::filesystem::path(::testing::TempDir()) / "felt_run_test_small.json").string();
  const Outcome outcome = RunFelt("run --scene " + path + " --duration 0.5 --fast --json " + json);
  ASSERT_EQ(outcome.exit_code, 0) << outcome.output;
  EXPECT_NE(outcome.output.find("felt run: small ("), std::string::npos) << outcome.output;
  EXPECT_NE(outcome.output.find("frames             30 (0.500 s simulated"), std::string::npos)
      << outcome.output;
  EXPECT_NE(outcome.output.find("substeps           "), std::string::npos);
  EXPECT_NE(outcome.output.find("frame compute ms   p50 "), std::string::npos);
  EXPECT_NE(outcome.output.find("max stretch        "), std::string::npos);
  EXPECT_NE(outcome.output.find("energy J           start "), std::string::npos);
  EXPECT_NE(outcome.output.find("nan events         0\n"), std::string::npos);
  const std::string written = ReadFile(json);
  EXPECT_NE(written.find("\"scene\": \"small\""), std::string::npos) << written;
  EXPECT_NE(written.find("\"frames\": 30,"), std::string::npos) << written;
  EXPECT_TRUE(felt::ParseJson(written, json)["frame_ms"]["p50"].is_number()) << written;
  EXPECT_NE(written.find("\"nan_events\": 0,"), std::string::npos) << written;
  EXPECT_NE(written.find("\"realtime\": false"), std::string::npos) << written;
  // No finishing worklist declared: no limiter line, and its counters are zero.
  EXPECT_EQ(outcome.output.find("stretch limiter"), std::string::npos) << outcome.output;
  EXPECT_NE(written.find("\"limiter_finish\": false"), std::string::npos) << written;
  EXPECT_NE(written.find("\"limiter_unconverged\": 0,"), std::string::npos) << written;
  std::filesystem::remove(path);
  std::filesystem::remove(json);
}

// With provot.finish the worklist's counters are printed and written: the 8 x 8 cloth hanging
// from its top edge sags past the sweeps' aim, so the worklist has pairs to project, and none of
// its substeps runs out of budget.
TEST(RunCommand, TheFinishingLimitersCountersAreReported) {
  const std::string path =
      WriteTemp("felt_run_test_finish.toml", std::string(kSmallScene) +
                                                 "[provot]\niterations = 1\nsweep_headroom = 0.02\n"
                                                 "finish = true\n");
  const std::string json =
      (std::filesystem::path(::testing::TempDir()) / "felt_run_test_finish.json").string();
  const Outcome outcome = RunFelt("run --scene " + path + " --duration 0.5 --fast --json " + json);
  ASSERT_EQ(outcome.exit_code, 0) << outcome.output;
  EXPECT_NE(outcome.output.find("stretch limiter    worklist: "), std::string::npos)
      << outcome.output;
  EXPECT_NE(outcome.output.find(" 0 substeps out of budget (undone)\n"), std::string::npos)
      << outcome.output;
  const felt::Json written = felt::ParseJson(ReadFile(json), json);
  EXPECT_TRUE(written["limiter_finish"].get<bool>());
  EXPECT_GT(written["limiter_projections"].get<uint64_t>(), 0u);
  EXPECT_GE(written["limiter_initial"].get<uint64_t>(), 1u);
  EXPECT_EQ(written["limiter_unconverged"].get<uint64_t>(), 0u);
  EXPECT_LE(written["max_stretch"].get<double>(), 1.10 + 1e-9);
  std::filesystem::remove(path);
  std::filesystem::remove(json);
}

TEST(RunCommand, RealTimeUsesTheScenesDurationAndTakesAboutThatLong) {
  const std::string path = WriteTemp("felt_run_test_realtime.toml", kSmallScene);
  const auto start = std::chrono::steady_clock::now();
  const Outcome outcome = RunFelt("run --scene " + path);
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(outcome.exit_code, 0) << outcome.output;
  // duration_s = 0.2 at 60 Hz: 12 frames, paced to absolute deadlines (loose bound: shared CI).
  EXPECT_NE(outcome.output.find("frames             12 (0.200 s simulated"), std::string::npos)
      << outcome.output;
  EXPECT_NE(outcome.output.find("overruns           "), std::string::npos) << outcome.output;
  EXPECT_GE(wall_s, 0.18);
  std::filesystem::remove(path);
}

TEST(RunCommand, DefaultCurtainRuns) {
  const Outcome outcome =
      RunFelt("run --scene " + kScenes + "/curtain.toml --duration 0.05 --fast");
  ASSERT_EQ(outcome.exit_code, 0) << outcome.output;
  EXPECT_NE(outcome.output.find("32 x 32 particles"), std::string::npos) << outcome.output;
  EXPECT_NE(outcome.output.find("nan events         0\n"), std::string::npos) << outcome.output;
}

}  // namespace
}  // namespace felt::test
