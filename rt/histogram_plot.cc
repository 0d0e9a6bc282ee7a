#include "rt/histogram_plot.h"

#include <spdlog/fmt/fmt.h>

#include <filesystem>
#include <stdexcept>
#include <system_error>

#include "base/gnuplot.h"
#include "base/json.h"
#include "base/report.h"

namespace felt {

std::vector<PlotBin> PlotBinsOf(const HistogramSnapshot& h, double ns_per_unit) {
  std::vector<PlotBin> bins;
  const double unit = static_cast<double>(h.unit_ns) / ns_per_unit;
  for (int i = 0; i <= HistogramBins::kCount; ++i) {
    const uint64_t n = h.bins[static_cast<size_t>(i)];
    if (n == 0) continue;
    PlotBin b;
    b.lower = static_cast<double>(HistogramBins::Lower(i)) * unit;
    b.upper = i == HistogramBins::kOverflow
                  ? static_cast<double>(h.max_ns) / ns_per_unit
                  : b.lower + static_cast<double>(HistogramBins::Width(i)) * unit;
    if (b.upper < b.lower) b.upper = b.lower;
    b.count = n;
    bins.push_back(b);
  }
  return bins;
}

Json PlotBinsJson(const HistogramSnapshot& h, double ns_per_unit) {
  Json out = Json::array();
  for (const PlotBin& b : PlotBinsOf(h, ns_per_unit))
    out.push_back(Json{b.lower, b.upper, b.count});
  return out;
}

std::vector<PlotBin> PlotBinsFromJson(const Json& json, const std::string& what) {
  if (!json.is_array()) throw std::invalid_argument(what + ": not an array of bins");
  std::vector<PlotBin> bins;
  for (size_t i = 0; i < json.size(); ++i) {
    const Json& e = json[i];
    const bool shape = e.is_array() && e.size() == 3 && e[0].is_number() && e[1].is_number() &&
                       e[2].is_number_unsigned();
    if (!shape || !(e[0].get<double>() >= 0.0) || !(e[1].get<double>() >= e[0].get<double>())) {
      throw std::invalid_argument(
          fmt::format("{}: bin {} is not [lower, upper, count] with 0 <= lower <= upper", what, i));
    }
    bins.push_back(PlotBin{e[0].get<double>(), e[1].get<double>(), e[2].get<uint64_t>()});
  }
  return bins;
}

std::string HistogramPlotData(const std::vector<PlotSeries>& series) {
  std::string out;
  for (size_t s = 0; s < series.size(); ++s) {
    if (s > 0) out += "\n\n";
    out += "# " + series[s].label + ": lower upper density survival\n";
    uint64_t total = 0;
    for (const PlotBin& b : series[s].bins) total += b.count;
    if (total == 0) {
      out += "NaN NaN NaN NaN\n";  // an empty block keeps the index of the next series
      continue;
    }
    uint64_t at_or_above = total;
    for (const PlotBin& b : series[s].bins) {
      const double width = b.upper - b.lower;
      const double fraction = static_cast<double>(b.count) / static_cast<double>(total);
      out += fmt::format("{:.6g} {:.6g} {:.6g} {:.6g}\n", b.lower, b.upper,
                         width > 0.0 ? fraction / width : fraction,
                         static_cast<double>(at_or_above) / static_cast<double>(total));
      at_or_above -= b.count;
    }
  }
  return out;
}

std::string HistogramPlotScript(const std::vector<PlotSeries>& series, const std::string& data,
                                const std::string& png, const std::string& title,
                                const std::string& xlabel) {
  using report::GnuplotQuoted;
  std::string gp = fmt::format(
      "# Lateness histograms (rt/histogram_plot.h). Data: {0}, one block per series: lower upper\n"
      "# density survival. Bins are those of rt/loop_stats.h (1 unit exact below 256, then 1/128 "
      "of\n# each power of two); a value of 0 is drawn at the axis' lowest edge (log axis).\n"
      "set terminal pngcairo size 1000,820 font ',9'\n"
      "set output {1}\n"
      "set multiplot layout 2,1 title {2} noenhanced\n"
      "set logscale xy\n"
      "set grid\n"
      "set key outside right top noenhanced\n"
      "set rmargin 30\n"
      "set xlabel {3} noenhanced\n",
      data, GnuplotQuoted(png), GnuplotQuoted(title), GnuplotQuoted(xlabel));
  const std::string file = GnuplotQuoted(data);
  // x at a bin's middle; 0 (an empty loop's exact bin) drawn at 0.5 of the unit.
  const std::string x = "((($1 + $2) / 2) > 0 ? (($1 + $2) / 2) : 0.5)";
  gp +=
      "set title 'density: fraction of samples per unit of x (a lateness of 0 is drawn at "
      "0.5)'\nset ylabel 'fraction / unit'\n";
  gp += "plot ";
  for (size_t s = 0; s < series.size(); ++s) {
    gp += fmt::format("{}{} index {} using {}:3 with linespoints pt 7 ps 0.4 lw 1 title {}",
                      s == 0 ? "" : ", ", file, s, x, GnuplotQuoted(series[s].label));
  }
  gp += "\nset title 'survival: fraction of samples at least this late'\n";
  gp += "set ylabel 'fraction >= x'\nplot ";
  for (size_t s = 0; s < series.size(); ++s) {
    gp += fmt::format("{}{} index {} using ($1 > 0 ? $1 : 0.5):4 with steps lw 1 title {}",
                      s == 0 ? "" : ", ", file, s, GnuplotQuoted(series[s].label));
  }
  gp += "\nunset multiplot\n";
  return gp;
}

std::string WriteHistogramPlot(const std::string& dir, const std::string& stem,
                               const std::vector<PlotSeries>& series, const std::string& title,
                               const std::string& xlabel) {
  bool any = false;
  for (const PlotSeries& s : series) any = any || !s.bins.empty();
  if (!any) throw std::invalid_argument("plot " + stem + ": no series has a value");
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec)
    throw std::runtime_error("--plot " + dir + ": cannot create the directory: " + ec.message());
  const std::string base = (std::filesystem::path(dir) / stem).string();
  const std::string data = base + ".dat";
  const std::string script = base + ".gp";
  const std::string png = base + ".png";
  report::WriteTextFile(data, HistogramPlotData(series));
  report::WriteTextFile(script, HistogramPlotScript(series, data, png, title, xlabel));
  report::RunGnuplot("plot " + stem, "gnuplot " + report::ShellQuoted(script), png);
  return png;
}

}  // namespace felt
