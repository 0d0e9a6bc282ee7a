#include "compare/compare_plot.h"

#include <spdlog/fmt/fmt.h>

#include <filesystem>
#include <stdexcept>
#include <system_error>

#include "base/gnuplot.h"
#include "base/report.h"

namespace felt {
namespace {

// A variant's name as a CSV column prefix: characters other than letters, digits and '_' become
// '_' (gnuplot reads the columns by number; the header is for people and other tools).
std::string ColumnName(const std::string& name) {
  std::string out = name;
  for (char& c : out) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9');
    if (!ok) c = '_';
  }
  return out;
}

}  // namespace

std::string ComparePlotCsv(const CompareResult& result, uint32_t device) {
  if (result.runs.empty()) throw std::invalid_argument("compare plot: no variant ran");
  const LockstepRun& ref = result.runs.front();
  if (device >= ref.devices) {
    throw std::invalid_argument(fmt::format("compare plot: device {} of {}", device, ref.devices));
  }
  for (const LockstepRun& run : result.runs) {
    if (run.ticks != ref.ticks || run.devices != ref.devices) {
      throw std::invalid_argument("compare plot: variant '" + run.name +
                                  "' cannot be paired with the reference tick by tick");
    }
  }
  std::string out = "t_s";
  for (const LockstepRun& run : result.runs) {
    const std::string c = ColumnName(run.name);
    out += fmt::format(",{0}_force_N,{0}_error_N,{0}_contact", c);
  }
  out += '\n';
  for (int64_t k = 0; k < ref.ticks; ++k) {
    const size_t i = static_cast<size_t>(k) * ref.devices + device;
    out += fmt::format("{:.6f}", static_cast<double>(k) * ref.tick_dt_s);
    for (const LockstepRun& run : result.runs) {
      const Vec3& f = run.force_D_N[i];
      out += fmt::format(",{:.6g},{:.6g},{}", f.norm(), (f - ref.force_D_N[i]).norm(),
                         static_cast<int>(run.in_contact[i]));
    }
    out += '\n';
  }
  return out;
}

std::string ComparePlotScript(const std::vector<std::string>& names, const std::string& csv,
                              const std::string& png, const std::string& title) {
  if (names.empty()) throw std::invalid_argument("compare plot: no variant to draw");
  const size_t force_panels = names.size() == 1 ? 1 : names.size() - 1;
  const size_t panels = force_panels + 1;
  using report::GnuplotQuoted;
  // Columns: 1 t_s; variant v (0-based): 2 + 3v |F|, 3 + 3v error, 4 + 3v contact.
  std::string gp = fmt::format(
      "# felt compare --plot: force against time per variant, the reference behind it, the error\n"
      "# below, and every variant's contact state. Data: {0} (ComparePlotCsv's columns).\n"
      "set datafile separator ','\n"
      "set terminal pngcairo size 1100,{1} font ',9'\n"
      "set output {2}\n"
      "set multiplot layout {3},1 title {4} noenhanced\n"
      "set grid\n"
      "set key outside right top noenhanced\n"
      "set lmargin 10\n"
      "set rmargin 28\n",
      csv, 140 + 210 * panels, GnuplotQuoted(png), panels, GnuplotQuoted(title));
  const std::string data = GnuplotQuoted(csv);
  for (size_t p = 0; p < force_panels; ++p) {
    const size_t v = names.size() == 1 ? 0 : p + 1;
    gp += fmt::format("set title {} noenhanced\nset ylabel '|F| [N]'\nunset xlabel\n",
                      GnuplotQuoted(names[v]));
    std::string plot = "plot ";
    if (v != 0) {
      plot += fmt::format("{} using 1:{} skip 1 with lines lw 3 lc rgb '#b0b0b0' title {}, ", data,
                          2, GnuplotQuoted(names[0] + " (reference)"));
    }
    plot += fmt::format("{} using 1:{} skip 1 with lines lw 1 lc rgb '#1f5fbf' title {}", data,
                        2 + 3 * v, GnuplotQuoted(names[v]));
    if (v != 0) {
      plot += fmt::format(", {} using 1:{} skip 1 with lines lw 1 lc rgb '#d62728' title {}", data,
                          3 + 3 * v, GnuplotQuoted("|F - F_ref|"));
    }
    gp += plot + "\n";
  }
  gp += "set title 'contact state (up: the proxy touches the cloth)'\n";
  gp += "set xlabel 'virtual time [s]'\nunset ylabel\n";
  gp += fmt::format("set yrange [-0.5:{}]\nset ytics (", static_cast<double>(names.size()) - 0.1);
  for (size_t v = 0; v < names.size(); ++v) {
    gp += fmt::format("{}{} {}", v == 0 ? "" : ", ", GnuplotQuoted(names[v]), v);
  }
  gp += ")\nplot ";
  for (size_t v = 0; v < names.size(); ++v) {
    gp += fmt::format("{}{} using 1:(${} * 0.8 + {}) skip 1 with steps lw 1 notitle",
                      v == 0 ? "" : ", ", data, 4 + 3 * v, v);
  }
  gp += "\nunset multiplot\n";
  return gp;
}

ComparePlotFiles WriteComparePlots(const std::string& dir, const CompareResult& result,
                                   const std::string& title) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec)
    throw std::runtime_error("--plot " + dir + ": cannot create the directory: " + ec.message());
  std::vector<std::string> names;
  for (const LockstepRun& run : result.runs) names.push_back(run.name);
  ComparePlotFiles files;
  files.drawn = true;
  const uint32_t devices = result.runs.empty() ? 0 : result.runs.front().devices;
  for (uint32_t d = 0; d < devices; ++d) {
    const std::string stem = (std::filesystem::path(dir) / fmt::format("forces_d{}", d)).string();
    files.csv.push_back(stem + ".csv");
    files.script.push_back(stem + ".gp");
    files.png.push_back(stem + ".png");
    report::WriteTextFile(files.csv.back(), ComparePlotCsv(result, d));
    report::WriteTextFile(files.script.back(),
                          ComparePlotScript(names, files.csv.back(), files.png.back(),
                                            fmt::format("{} (device {})", title, d)));
    const report::GnuplotOutcome outcome =
        report::RunGnuplot("felt compare --plot",
                           "gnuplot " + report::ShellQuoted(files.script.back()), files.png.back());
    files.drawn = files.drawn && outcome == report::GnuplotOutcome::kDrawn;
  }
  return files;
}

}  // namespace felt
