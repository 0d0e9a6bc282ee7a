// felt compare --plot (compare/compare_plot.h): the per-tick CSV against hand-made runs, the
// script's columns, and a PNG drawn by the real gnuplot when it is installed.
#include "compare/compare_plot.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "base/gnuplot.h"

namespace felt {
namespace {

// A run of `ticks` ticks on `devices` devices whose forces and contacts are given per entry.
LockstepRun MakeRun(const std::string& name, uint32_t devices, std::vector<Vec3> forces,
                    std::vector<uint8_t> contact) {
  LockstepRun run;
  run.name = name;
  run.devices = devices;
  run.tick_dt_s = 0.001;
  run.ticks = static_cast<int64_t>(forces.size() / devices);
  run.force_D_N = std::move(forces);
  run.in_contact = std::move(contact);
  return run;
}

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

TEST(ComparePlotTest, OneRowPerTickWithEachVariantsForceErrorAndContact) {
  CompareResult result;
  result.runs.push_back(MakeRun("truth", 1, {Vec3(0, 0, 0), Vec3(3, 4, 0)}, {0, 1}));
  result.runs.push_back(MakeRun("patch mode", 1, {Vec3(0, 0, 1), Vec3(3, 4, 12)}, {1, 1}));
  const std::vector<std::string> lines = Lines(ComparePlotCsv(result, 0));
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[0],
            "t_s,truth_force_N,truth_error_N,truth_contact,patch_mode_force_N,patch_mode_error_N,"
            "patch_mode_contact");
  EXPECT_EQ(lines[1], "0.000000,0,0,0,1,1,1");
  EXPECT_EQ(lines[2], "0.001000,5,0,1,13,12,1");
}

TEST(ComparePlotTest, EachDeviceGetsItsOwnEntries) {
  CompareResult result;
  // Ticks 0 and 1, devices 0 and 1: entries [tick * 2 + device].
  result.runs.push_back(MakeRun(
      "ref", 2, {Vec3(1, 0, 0), Vec3(2, 0, 0), Vec3(3, 0, 0), Vec3(4, 0, 0)}, {0, 1, 0, 1}));
  const std::vector<std::string> d1 = Lines(ComparePlotCsv(result, 1));
  ASSERT_EQ(d1.size(), 3u);
  EXPECT_EQ(d1[1], "0.000000,2,0,1");
  EXPECT_EQ(d1[2], "0.001000,4,0,1");
  EXPECT_THROW(ComparePlotCsv(result, 2), std::invalid_argument);
}

TEST(ComparePlotTest, RunsThatCannotBePairedAreRefused) {
  CompareResult result;
  result.runs.push_back(MakeRun("ref", 1, {Vec3::Zero(), Vec3::Zero()}, {0, 0}));
  result.runs.push_back(MakeRun("short", 1, {Vec3::Zero()}, {0}));
  EXPECT_THROW(ComparePlotCsv(result, 0), std::invalid_argument);
  EXPECT_THROW(ComparePlotCsv(CompareResult{}, 0), std::invalid_argument);
}

TEST(ComparePlotTest, TheScriptDrawsEachVariantsColumnsOverTheReference) {
  const std::string gp = ComparePlotScript({"truth", "a", "b"}, "/d/f.csv", "/d/f.png", "t");
  // Variant 1 (a): |F| column 5, error 6, contact 7; variant 2 (b): 8, 9, 10; reference |F| 2.
  EXPECT_NE(gp.find("using 1:5 "), std::string::npos);
  EXPECT_NE(gp.find("using 1:6 "), std::string::npos);
  EXPECT_NE(gp.find("using 1:8 "), std::string::npos);
  EXPECT_NE(gp.find("using 1:9 "), std::string::npos);
  EXPECT_NE(gp.find("using 1:2 "), std::string::npos);
  EXPECT_NE(gp.find("($10 * 0.8 + 2)"), std::string::npos);
  EXPECT_NE(gp.find("set multiplot layout 3,1"), std::string::npos);  // a, b, contact
  EXPECT_NE(gp.find("set output '/d/f.png'"), std::string::npos);
  // A lone reference gets its own force panel.
  EXPECT_NE(ComparePlotScript({"only"}, "f.csv", "f.png", "t").find("set multiplot layout 2,1"),
            std::string::npos);
}

TEST(ComparePlotTest, GnuplotDrawsAPngPerDevice) {
  if (!report::GnuplotInstalled()) GTEST_SKIP() << "gnuplot is not installed";
  CompareResult result;
  std::vector<Vec3> ref, var;
  std::vector<uint8_t> c0, c1;
  for (int k = 0; k < 200; ++k) {
    const double f = k > 50 && k < 150 ? 1.0 + 0.01 * (k - 50) : 0.0;
    ref.push_back(Vec3(0, 0, f));
    var.push_back(Vec3(0, 0, f * 1.1));
    c0.push_back(f > 0 ? 1 : 0);
    c1.push_back(f > 0 ? 1 : 0);
  }
  result.runs.push_back(MakeRun("truth", 1, ref, c0));
  result.runs.push_back(MakeRun("patch", 1, var, c1));
  const std::string dir =
      (std::filesystem::temp_directory_path() / ("felt_compare_plot_" + std::to_string(::getpid())))
          .string();
  const ComparePlotFiles files = WriteComparePlots(dir + "/sub", result, "test's plot");
  ASSERT_EQ(files.png.size(), 1u);
  EXPECT_TRUE(files.drawn);
  std::ifstream png(files.png[0], std::ios::binary);
  char magic[8] = {};
  png.read(magic, 8);
  EXPECT_EQ(std::string(magic + 1, 3), "PNG");
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace felt
