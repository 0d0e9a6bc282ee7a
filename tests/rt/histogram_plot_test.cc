// Lateness histograms as plots (rt/histogram_plot.h): the bins of a real Histogram, their JSON
// round trip and its errors, the density and survival of the data file, and a PNG from gnuplot.
#include "rt/histogram_plot.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "base/gnuplot.h"
#include "base/json.h"

namespace felt {
namespace {

HistogramSnapshot Recorded(const std::vector<int64_t>& values_ns) {
  Histogram h(1000);
  for (const int64_t v : values_ns) h.Record(v);
  HistogramSnapshot s;
  h.Snapshot(&s);
  return s;
}

TEST(HistogramPlotTest, BinsAreTheNonEmptyOnesInTheUnitAsked) {
  const HistogramSnapshot s = Recorded({0, 3'200, 3'900, 300'000});
  const std::vector<PlotBin> bins = PlotBinsOf(s, 1e3);  // us
  ASSERT_EQ(bins.size(), 3u);
  EXPECT_EQ(bins[0].lower, 0.0);
  EXPECT_EQ(bins[0].upper, 1.0);
  EXPECT_EQ(bins[0].count, 1u);
  EXPECT_EQ(bins[1].lower, 3.0);
  EXPECT_EQ(bins[1].upper, 4.0);
  EXPECT_EQ(bins[1].count, 2u);
  EXPECT_LE(bins[2].lower, 300.0);  // a log-linear bin holding 300 us
  EXPECT_GT(bins[2].upper, 300.0);
  EXPECT_EQ(bins[2].count, 1u);
}

TEST(HistogramPlotTest, JsonRoundTripAndItsErrorsNameTheEntry) {
  const HistogramSnapshot s = Recorded({1'000, 2'000, 2'500, 90'000'000'000});  // one overflows
  const Json json = PlotBinsJson(s, 1e3);
  const std::vector<PlotBin> back = PlotBinsFromJson(json, "haptic.lateness_bins_us");
  const std::vector<PlotBin> direct = PlotBinsOf(s, 1e3);
  ASSERT_EQ(back.size(), direct.size());
  for (size_t i = 0; i < back.size(); ++i) {
    EXPECT_EQ(back[i].lower, direct[i].lower);
    EXPECT_EQ(back[i].upper, direct[i].upper);
    EXPECT_EQ(back[i].count, direct[i].count);
  }
  EXPECT_EQ(back.back().upper, 90'000'000.0);  // the overflow bin ends at the exact max
  try {
    PlotBinsFromJson(Json::parse("[[0, 1, 2], [5, 4, 1]]"), "sim.lateness_bins_us");
    FAIL() << "an inverted bin was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("sim.lateness_bins_us: bin 1"), std::string::npos);
  }
  EXPECT_THROW(PlotBinsFromJson(Json::parse("{}"), "x"), std::invalid_argument);
  EXPECT_THROW(PlotBinsFromJson(Json::parse("[[0, 1, -2]]"), "x"), std::invalid_argument);
}

TEST(HistogramPlotTest, DensityIntegratesToOneAndSurvivalFallsFromOne) {
  std::vector<int64_t> values;
  for (int i = 0; i < 1000; ++i) values.push_back(static_cast<int64_t>(i) * 977);  // 0..976 us
  const PlotSeries series{"loop", PlotBinsOf(Recorded(values), 1e3)};
  std::istringstream in(HistogramPlotData({series}));
  double integral = 0.0;
  double previous_survival = 2.0;
  double first_survival = -1.0;
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream row(line);
    double lower, upper, density, survival;
    row >> lower >> upper >> density >> survival;
    integral += density * (upper - lower);
    if (first_survival < 0) first_survival = survival;
    EXPECT_LT(survival, previous_survival);
    previous_survival = survival;
  }
  EXPECT_NEAR(integral, 1.0, 1e-4);
  EXPECT_DOUBLE_EQ(first_survival, 1.0);
  EXPECT_GT(previous_survival, 0.0);
}

TEST(HistogramPlotTest, GnuplotDrawsTheFigure) {
  if (!report::GnuplotInstalled()) GTEST_SKIP() << "gnuplot is not installed";
  const std::string dir = (std::filesystem::temp_directory_path() /
                           ("felt_histogram_plot_" + std::to_string(::getpid())))
                              .string();
  const std::vector<PlotSeries> series = {
      {"a", PlotBinsOf(Recorded({0, 10'000, 12'000, 500'000}), 1e3)},
      {"empty", {}},
      {"b", PlotBinsOf(Recorded({2'000, 3'000}), 1e3)}};
  const std::string png = WriteHistogramPlot(dir, "lateness", series, "test", "us");
  std::ifstream in(png, std::ios::binary);
  char magic[8] = {};
  in.read(magic, 8);
  EXPECT_EQ(std::string(magic + 1, 3), "PNG");
  EXPECT_THROW(WriteHistogramPlot(dir, "none", {{"empty", {}}}, "t", "us"), std::invalid_argument);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace felt
