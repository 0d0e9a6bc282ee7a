#pragma once
// `felt compare --plot DIR` (issue 25): what a comparison's forces look like over time. Per device,
// a CSV of every tick (time; per variant the force magnitude, its distance from the reference's
// force, the contact state) and a gnuplot script that draws it: one panel per variant with the
// reference's force behind it and the error below, then one panel of every variant's contact
// state. gnuplot draws the PNG when installed (base/gnuplot.h). Not real-time safe.

#include <cstdint>
#include <string>
#include <vector>

#include "compare/lockstep.h"

namespace felt {

/// The files WriteComparePlots wrote, per device (device order).
struct ComparePlotFiles {
  std::vector<std::string> csv;     ///< the per-tick series
  std::vector<std::string> script;  ///< the gnuplot script (runs again as `gnuplot FILE`)
  std::vector<std::string> png;     ///< the plot (listed even when gnuplot was not found)
  bool drawn = false;               ///< gnuplot drew every PNG
};

/// The per-tick series of device `device` of `result` as CSV. Columns: `t_s` (virtual time of the
/// tick [s], tick k at k tick_dt_s), then per variant v in order (reference first), with its name:
/// `<v>_force_N` (|F| [N], device frame), `<v>_error_N` (|F - F_ref| [N]; 0 for the reference) and
/// `<v>_contact` (1 when the proxy touched the cloth). Throws std::invalid_argument when `device`
/// is out of range or the runs cannot be paired (SummarizeRuns' rule).
std::string ComparePlotCsv(const CompareResult& result, uint32_t device);

/// The gnuplot script that draws a ComparePlotCsv file `csv` with `names` (its variants, the
/// reference first) into `png`: a panel per variant after the reference (its |F| over the
/// reference's, and its error), the reference alone when it is the only variant, and a last panel
/// with each variant's contact state as a step line on its own level. `title` heads the plot.
std::string ComparePlotScript(const std::vector<std::string>& names, const std::string& csv,
                              const std::string& png, const std::string& title);

/// Creates `dir` (and parents) and writes for every device d `dir/forces_d<d>.csv` and
/// `forces_d<d>.gp`, then runs gnuplot on each (base/gnuplot.h: a missing gnuplot prints the
/// command instead). `title` heads each plot (the device is added). Throws std::runtime_error
/// when `dir` cannot be made or a file cannot be written.
ComparePlotFiles WriteComparePlots(const std::string& dir, const CompareResult& result,
                                   const std::string& title);

}  // namespace felt
