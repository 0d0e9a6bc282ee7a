#pragma once
// What every report-writing command shares (the benchmarks, `felt compare`): order statistics (the
// project's one percentile), the machine's description for a report's header (text and JSON),
// Markdown and CSV tables. Not real-time safe (everything here allocates).

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "base/json.h"

namespace felt::report {

/// The project's one percentile: nearest rank, the smallest sample with at least
/// ceil(p / 100 * n) of the n samples at or below it (`p` in [0, 100], so p = 0 gives the smallest
/// and p = 100 the largest), in the samples' unit. NaN for no samples: a caller that reports 0 for
/// none says so where it calls.
double Percentile(std::vector<double> samples, double p);

/// The median (Percentile at p = 50) of `samples`, in their unit; NaN for none.
double Median(std::vector<double> samples);

/// CPU time [ms] this thread has used so far (CLOCK_THREAD_CPUTIME_ID): unlike the wall clock it
/// does not advance while the thread is preempted, which matters on a shared, loaded machine.
double ThreadCpuMs();

/// Wall time [ms] on the monotonic clock.
double WallMs();

/// What a report says about where it was measured.
struct MachineInfo {
  long cpus_online = 0;      ///< sysconf(_SC_NPROCESSORS_ONLN), i.e. `nproc` without affinity
  std::string cpu_model;     ///< first "model name" line of /proc/cpuinfo
  std::string date_utc;      ///< ISO 8601, e.g. "2026-11-21T15:20:00Z"
  std::string load_average;  ///< the first three fields of /proc/loadavg
  int niceness = 0;          ///< getpriority(PRIO_PROCESS, 0)
  std::string affinity;      ///< CPUs this process may run on, e.g. "0-1" or "1"
  /// The widest vector kernels the sim's run-time dispatch picks on this CPU: "avx512f+avx2"
  /// (Provot's families across rows on AVX-512F, the rest on AVX2), "avx2" or "portable".
  std::string vector_kernels;
};

/// Reads the machine's description now.
MachineInfo ReadMachineInfo();

/// The first three fields of /proc/loadavg ("1.23 1.10 0.98"), or "unknown".
std::string LoadAverage();

/// The Markdown header lines every cloth benchmark report starts with: the exact command, the
/// machine, the date and the load averages at the start and the end of the run.
std::string ReportHeader(std::string_view title, std::string_view command, const MachineInfo& start,
                         std::string_view load_at_end);

/// `value` with `digits` significant digits ("%.*g"), or "-" when not finite.
std::string Sig(double value, int digits = 4);

/// `value` with `decimals` decimals ("%.*f"), or "-" when not finite.
std::string Fixed(double value, int decimals = 3);

/// A JSON object of the machine's description (cpus_online, cpu_model, date_utc, load_average,
/// niceness, affinity, vector_kernels).
Json MachineJson(const MachineInfo& machine);

/// Appends what every report's JSON says about where it ran to the object `report`: "machine"
/// (MachineJson of `machine`, read at the start) and "load_average_end" (`load_at_end`, the
/// LoadAverage() text at the end), in that order after the members it already has.
void AppendMachineJson(const MachineInfo& machine, std::string_view load_at_end, Json* report);

/// A Markdown table: a header row, the alignment row (numbers right-aligned: `right` per column),
/// then the rows. Cells must not contain '|'.
std::string MarkdownTable(const std::vector<std::string>& header, const std::vector<bool>& right,
                          const std::vector<std::vector<std::string>>& rows);

/// CSV text: the header, then the rows; cells holding a comma or a quote are quoted.
std::string CsvTable(const std::vector<std::string>& header,
                     const std::vector<std::vector<std::string>>& rows);

/// Writes `text` to `path`, creating its parent directory. Throws std::runtime_error naming the
/// path when it cannot be written.
void WriteTextFile(const std::string& path, const std::string& text);

}  // namespace felt::report
