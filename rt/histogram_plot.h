#pragma once
// Lateness histograms as pictures (issue 25: `felt soak --plot`, `felt bench loops --plot`): the
// non-empty bins of a rt/loop_stats.h histogram as JSON (so a child process's report carries
// them) and back, and a gnuplot script drawing several distributions on one figure: the density
// (fraction of samples per unit of the axis, log-log) above, and the fraction of samples at least
// as late as x (the survival function, log-log: where the tail is) below. Not real-time safe.

#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "rt/loop_stats.h"

namespace felt {

/// One bin of a histogram, in the plot's unit (us for lateness).
struct PlotBin {
  double lower = 0.0;  ///< lower edge (values are >= it)
  double upper = 0.0;  ///< upper edge (values are < it; the overflow bin: the exact max)
  uint64_t count = 0;  ///< values in the bin
};

/// One distribution of a plot.
struct PlotSeries {
  std::string label;          ///< its key in the plot
  std::vector<PlotBin> bins;  ///< non-empty bins, ascending
};

/// The non-empty bins of `h` in units of `ns_per_unit` ns (1e3: us), ascending. Not real-time
/// safe.
std::vector<PlotBin> PlotBinsOf(const HistogramSnapshot& h, double ns_per_unit);

/// PlotBinsOf as JSON: [[lower, upper, count], ...]. Not real-time safe.
nlohmann::ordered_json PlotBinsJson(const HistogramSnapshot& h, double ns_per_unit);

/// The bins of a PlotBinsJson array. Throws std::invalid_argument naming `what` and the entry when
/// it is not an array of [lower, upper, count] with 0 <= lower <= upper and a count >= 0.
std::vector<PlotBin> PlotBinsFromJson(const nlohmann::ordered_json& json, const std::string& what);

/// The data file of `series` for HistogramPlotScript: per series a block (two blank lines between
/// blocks, gnuplot's `index`) of rows `lower upper density survival`: density = count / (total *
/// (upper - lower)) per unit (a bin of zero width: count / total), survival = the fraction of
/// the series' values in this bin or above.
std::string HistogramPlotData(const std::vector<PlotSeries>& series);

/// The gnuplot script drawing a HistogramPlotData file `data` into `png`: density (top) and
/// survival (bottom) against `xlabel`, log-log, one colour per series, `title` on top.
std::string HistogramPlotScript(const std::vector<PlotSeries>& series, const std::string& data,
                                const std::string& png, const std::string& title,
                                const std::string& xlabel);

/// Creates `dir`, writes `dir/<stem>.dat` and `<stem>.gp`, runs gnuplot on it (base/gnuplot.h; a
/// missing gnuplot prints the command). Returns the PNG's path. Throws std::runtime_error when the
/// directory or a file cannot be written, std::invalid_argument when no series has a value.
std::string WriteHistogramPlot(const std::string& dir, const std::string& stem,
                               const std::vector<PlotSeries>& series, const std::string& title,
                               const std::string& xlabel);

}  // namespace felt
