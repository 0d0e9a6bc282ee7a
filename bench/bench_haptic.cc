// `felt bench haptic`: the god-object proxy's snapshot modes against the truth (issues 4 and 20;
// 001_0f9f1b7fedff7723.txt §6.4 and §7: force discontinuities when the cloth changes outside the
// haptic loop, and the remedy of rendering against two cloths; §6: every algorithm gets the same
// input).
//
// Built on `felt compare`'s engine (compare/lockstep.h): for each pointer trace, the real server
// runs in lock-step virtual time once per variant, on this thread. The reference is the truth
// (TruthVariant: the cloth stepped every 1 ms haptic tick, coupled both ways with the proxy, which
// renders the exact cloth); the variants are the scene with proxy.snapshot_mode set to each mode
// of kSnapshotModes (60 Hz frames). Per trace and mode: force error against the truth, force
// spikes above the truth's peak, pop-through and reach into the cloth (proxy/proxy_probe.h),
// contact mismatches, tick cost (thread CPU time), NaN events. Then a per-mode summary (error
// against tick cost) judged against the targets, and the hard traces (recordings/hard/)
// on their own. Writes Markdown, CSV, JSON and a PNG (gnuplot on bench/haptic.gp).
#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/command.h"
#include "base/gnuplot.h"
#include "base/json.h"
#include "bench/bench_util.h"
#include "compare/lockstep.h"
#include "proxy/proxy_spec.h"
#include "recordings/generate.h"
#include "recordings/trace.h"
#include "scene/scene_file.h"
#include "server/server_spec.h"

namespace felt::bench::bench_haptic {
namespace {

/// The targets for a snapshot mode (issue 20), each judged per mode over a set of traces.
struct Targets {
  double rms_error_N = 0.15;     ///< worst RMS force error against the truth over traces, N
  double peak_excess_N = 0.5;    ///< largest peak |F| above the truth's peak, N
  uint64_t pop_through = 0;      ///< pop-through ticks, all traces
  uint64_t nan_events = 0;       ///< NaN events (safety and cloth), all traces
  double tick_us_median = 10.0;  ///< median tick thread CPU time over all ticks, us
  double tick_us_p99 = 40.0;     ///< 99th percentile of the same, us
};
constexpr Targets kTargets;

/// A trace judges the force targets only where its reference is converged: the truth at twice the
/// rate (TruthVariant(2)) within this RMS of the truth [N], half the RMS target, so that the
/// reference's own discretisation error is at most half of what a mode is allowed. On fast or
/// folding motion the truth is chaotic (its contact state flips with any perturbation) and a
/// finer truth lands 0.2 N and more away; no approximation can be judged against it there.
constexpr double kConvergedSpread_N = 0.5 * kTargets.rms_error_N;

/// Virtual seconds of each trace replayed with --quick: poke_hold's tip meets the cloth at about
/// 1.68 s, so 2.5 s gives every bundled trace some contact.
constexpr double kQuickDuration_s = 2.5;

struct Args {
  std::string json_path;
  std::string csv_path;
  std::string md_path;
  std::string scene = "scenes/curtain.toml";
  std::string recordings = "recordings";
  std::string gnuplot_script = "bench/haptic.gp";
  std::vector<std::string> traces;  // --trace FILE...
  int grid = 64;
  bool quick = false;
  double duration_s = 0.0;
  bool no_bundled = false;
  bool no_plot = false;
  bool no_convergence = false;
};

/// One pointer trace and where it came from.
struct TraceInput {
  std::string name;   ///< file stem ("(generated)" appended when made in place of a missing file)
  std::string group;  ///< "bundled" (recordings/*.trace), "hard" (recordings/hard/), "user"
  std::string path;   ///< the file read ("" when generated)
  std::vector<TraceSample> samples;
};

/// One trace's comparison: the truth's and every mode's summary, and each variant's tick times.
struct TraceResult {
  const TraceInput* trace = nullptr;
  /// The truth at twice the rate against the truth: RMS force difference [N] (-1: not run).
  double reference_spread_N = -1.0;
  /// The force targets are judged on this trace (its reference converged, or not checked).
  bool judged() const { return reference_spread_N <= kConvergedSpread_N; }
  std::vector<VariantSummary> summaries;         ///< [0] the truth, then kSnapshotModes' order
  std::vector<std::vector<double>> tick_cpu_us;  ///< per variant, every tick, us
};

/// One variant's figures over a set of traces.
struct ModeSummary {
  std::string name;                 ///< "truth" or the mode's name
  int traces = 0;                   ///< traces in the set
  double rms_worst_N = 0.0;         ///< largest force_rms_error_N over the traces, N
  std::string rms_worst_trace;      ///< the trace it was on
  double rms_median_N = 0.0;        ///< median force_rms_error_N over the traces, N
  double max_error_N = 0.0;         ///< largest force_max_error_N, N
  double peak_excess_N = 0.0;       ///< largest peak_minus_ref_peak_N, N
  uint64_t pop_through = 0;         ///< sum of pop_through, ticks
  double max_reach_mm = 0.0;        ///< largest max_reach_mm, mm
  uint64_t contact_mismatches = 0;  ///< sum, ticks
  uint64_t nan_events = 0;          ///< sum, events
  double tick_us_median = 0.0;      ///< median over every tick of every trace, us
  double tick_us_p99 = 0.0;         ///< 99th percentile of the same, us
  int64_t ticks = 0;                ///< ticks pooled
};

// The command as it can be typed again.
std::string CommandLine(const Args& a) {
  std::string line = "felt bench haptic";
  if (a.quick) line += " --quick";
  if (a.duration_s > 0.0) line += " --duration " + FormatSceneNumber(a.duration_s);
  if (a.grid != 64) line += " --grid " + std::to_string(a.grid);
  if (a.scene != "scenes/curtain.toml") line += " --scene " + a.scene;
  if (a.recordings != "recordings") line += " --recordings " + a.recordings;
  if (a.no_bundled) line += " --no-bundled";
  for (const std::string& t : a.traces) line += " --trace " + t;
  if (!a.json_path.empty()) line += " --json " + a.json_path;
  if (!a.csv_path.empty()) line += " --csv " + a.csv_path;
  if (!a.md_path.empty()) line += " --md " + a.md_path;
  if (a.no_plot) line += " --no-plot";
  if (a.no_convergence) line += " --no-convergence";
  return line;
}

// The scene of every run: the file, its cloth resized to grid x grid over the same square
// (bench/bench_util.h's ResizedCurtain rule) unless grid is 0.
SceneDocument BenchScene(const Args& args) {
  SceneDocument doc = LoadSceneDocument(args.scene);
  CheckWholeScene(doc);  // the scene as written must be valid (errors with line and column)
  if (args.grid == 0) return doc;
  const SimSpec resized = ResizedCurtain(args.scene, args.grid);
  toml::table* cloth = doc.root["cloth"].as_table();
  if (cloth == nullptr) throw std::invalid_argument(args.scene + ": no [cloth] table to resize");
  cloth->insert_or_assign("width", static_cast<int64_t>(resized.cloth.width));
  cloth->insert_or_assign("height", static_cast<int64_t>(resized.cloth.height));
  cloth->insert_or_assign("spacing_m", resized.cloth.spacing_m);
  cloth->insert_or_assign("drag_N_s_per_m", resized.cloth.drag_N_s_per_m);
  return doc;
}

// The *.trace files of `dir`, sorted by name (none when the folder does not exist).
std::vector<std::string> TraceFilesIn(const std::string& dir) {
  std::vector<std::string> files;
  if (!std::filesystem::is_directory(dir)) return files;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (entry.is_regular_file() && entry.path().extension() == ".trace") {
      files.push_back(entry.path().string());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

// The traces: the bundled ones (generated when a file is missing), the hard ones, the user's.
std::vector<TraceInput> LoadTraces(const Args& args) {
  std::vector<TraceInput> traces;
  if (!args.no_bundled) {
    for (const std::string& name : BundledTraceNames()) {
      const std::string path = args.recordings + "/" + name + ".trace";
      if (std::filesystem::exists(path)) {
        traces.push_back({name, "bundled", path, ReadTrace(path).samples});
      } else {
        traces.push_back(
            {name + "(generated)", "bundled", "", GenerateTrace(name, kDefaultTraceSeed).samples});
      }
    }
    for (const std::string& path : TraceFilesIn(args.recordings + "/hard")) {
      traces.push_back(
          {std::filesystem::path(path).stem().string(), "hard", path, ReadTrace(path).samples});
    }
  }
  for (const std::string& path : args.traces) {
    traces.push_back(
        {std::filesystem::path(path).stem().string(), "user", path, ReadTrace(path).samples});
  }
  if (traces.empty()) throw std::invalid_argument("no traces (--no-bundled without --trace)");
  return traces;
}

// The name of the truth at twice the rate (TruthVariant(2)), the reference's own check.
const std::string& TwiceTruthName() {
  static const std::string name = TruthVariant(2).name;
  return name;
}

// The variants after the truth: one per snapshot mode, the scene with that mode, then (unless
// --no-convergence) the truth at twice the rate.
std::vector<LockstepVariant> ModeVariants(bool convergence) {
  std::vector<LockstepVariant> variants;
  for (SnapshotMode mode : kSnapshotModes) {
    const std::string name = SnapshotModeName(mode);
    variants.push_back(LockstepVariant{name, {{"proxy.snapshot_mode", name}}});
  }
  if (convergence) variants.push_back(TruthVariant(2));
  return variants;
}

// Every variant's summary over the traces of `results` (all of one group set), variant by variant.
std::vector<ModeSummary> Summarize(const std::vector<const TraceResult*>& results) {
  std::vector<ModeSummary> out;
  if (results.empty()) return out;
  const size_t variants = results.front()->summaries.size();
  for (size_t v = 0; v < variants; ++v) {
    ModeSummary m;
    m.name = results.front()->summaries[v].name;
    std::vector<double> rms;
    std::vector<double> ticks;
    for (const TraceResult* r : results) {
      const VariantSummary& s = r->summaries[v];
      ++m.traces;
      rms.push_back(s.force_rms_error_N);
      if (m.rms_worst_trace.empty() || s.force_rms_error_N > m.rms_worst_N) {
        m.rms_worst_N = s.force_rms_error_N;
        m.rms_worst_trace = r->trace->name;
      }
      m.max_error_N = std::max(m.max_error_N, s.force_max_error_N);
      m.peak_excess_N = std::max(m.peak_excess_N, s.peak_minus_ref_peak_N);
      m.pop_through += s.pop_through;
      m.max_reach_mm = std::max(m.max_reach_mm, s.max_reach_mm);
      m.contact_mismatches += s.contact_mismatches;
      m.nan_events += s.nan_events;
      ticks.insert(ticks.end(), r->tick_cpu_us[v].begin(), r->tick_cpu_us[v].end());
    }
    m.rms_median_N = Median(rms);
    m.ticks = static_cast<int64_t>(ticks.size());
    m.tick_us_median = ticks.empty() ? 0.0 : Percentile(ticks, 50.0);
    m.tick_us_p99 = ticks.empty() ? 0.0 : Percentile(ticks, 99.0);
    out.push_back(std::move(m));
  }
  return out;
}

// One target's verdict.
struct Verdict {
  std::string name;  ///< e.g. "force_rms_error_N <= 0.15"
  std::string value;
  bool met = false;
};

// The six targets of a snapshot mode's summary.
std::vector<Verdict> Judge(const ModeSummary& m) {
  return {
      {"rms_error_worst_N <= " + Sig(kTargets.rms_error_N), Sig(m.rms_worst_N),
       m.rms_worst_N <= kTargets.rms_error_N},
      {"peak_minus_truth_peak_N <= " + Sig(kTargets.peak_excess_N), Sig(m.peak_excess_N),
       m.peak_excess_N <= kTargets.peak_excess_N},
      {"pop_through == 0", std::to_string(m.pop_through), m.pop_through == kTargets.pop_through},
      {"nan_events == 0", std::to_string(m.nan_events), m.nan_events == kTargets.nan_events},
      {"tick_us_median <= " + Sig(kTargets.tick_us_median), Fixed(m.tick_us_median, 2),
       m.tick_us_median <= kTargets.tick_us_median},
      {"tick_us_p99 <= " + Sig(kTargets.tick_us_p99), Fixed(m.tick_us_p99, 2),
       m.tick_us_p99 <= kTargets.tick_us_p99},
  };
}

// "Host: ..." line that precedes every table.
std::string HostLine(const MachineInfo& machine, const std::string& load_end) {
  return fmt::format("Host: {} ({} CPUs online, affinity {}), load {} -> {}, {}.\n\n",
                     machine.cpu_model, machine.cpus_online, machine.affinity, machine.load_average,
                     load_end, machine.date_utc);
}

// The per-trace table of `results`: the truth's row, then each mode's.
std::string TraceTable(const std::vector<const TraceResult*>& results) {
  std::vector<std::vector<std::string>> rows;
  for (const TraceResult* r : results) {
    for (const VariantSummary& s : r->summaries) {
      rows.push_back({r->trace->name, s.name, Sig(s.force_rms_error_N), Sig(s.force_max_error_N),
                      Sig(s.peak_force_N), Sig(s.peak_minus_ref_peak_N), Sig(s.max_jump_N),
                      std::to_string(s.pop_through), Fixed(s.max_reach_mm, 3),
                      std::to_string(s.contact_mismatches), Fixed(s.tick_us_median, 2),
                      Fixed(s.tick_us_p99, 2), std::to_string(s.nan_events)});
    }
  }
  return MarkdownTable(
      {"trace", "variant", "force_rms_error_N", "force_max_error_N", "peak_force_N",
       "peak_minus_ref_peak_N", "max_jump_N", "pop_through", "max_reach_mm", "contact_mismatches",
       "tick_us_median", "tick_us_p99", "nan_events"},
      {false, false, true, true, true, true, true, true, true, true, true, true, true}, rows);
}

// The per-mode summary table (error against tick cost).
std::string SummaryTable(const std::vector<ModeSummary>& modes) {
  std::vector<std::vector<std::string>> rows;
  for (const ModeSummary& m : modes) {
    rows.push_back({m.name, std::to_string(m.traces),
                    Sig(m.rms_worst_N) + " (" + m.rms_worst_trace + ")", Sig(m.rms_median_N),
                    Sig(m.max_error_N), Sig(m.peak_excess_N), std::to_string(m.pop_through),
                    Fixed(m.max_reach_mm, 3), std::to_string(m.contact_mismatches),
                    std::to_string(m.nan_events), Fixed(m.tick_us_median, 2),
                    Fixed(m.tick_us_p99, 2), std::to_string(m.ticks)});
  }
  return MarkdownTable(
      {"variant", "traces", "rms_error_worst_N (trace)", "rms_error_median_N", "force_max_error_N",
       "peak_minus_truth_peak_max_N", "pop_through", "max_reach_mm", "contact_mismatches",
       "nan_events", "tick_us_median", "tick_us_p99", "ticks"},
      {false, true, true, true, true, true, true, true, true, true, true, true, true}, rows);
}

// `all` with its force figures (RMS, peak) taken from `judged`, the same variant over the traces
// whose reference converged (none: no force figure counts against it).
ModeSummary Mixed(const ModeSummary& all, const ModeSummary* judged) {
  ModeSummary m = all;
  m.rms_worst_N = judged != nullptr ? judged->rms_worst_N : 0.0;
  m.peak_excess_N = judged != nullptr ? judged->peak_excess_N : 0.0;
  return m;
}

// The targets table: one row per snapshot mode (the truths are the yardstick, not judged). The
// force verdicts (RMS, peak) come from `judged` (the traces whose reference converged), the rest
// from `all`; both summarise the same variants in the same order.
std::string TargetTable(const std::vector<ModeSummary>& all,
                        const std::vector<ModeSummary>& judged) {
  std::vector<std::string> header = {"mode"};
  for (const Verdict& v : Judge(ModeSummary{})) header.push_back(v.name);
  header.push_back("all met");
  std::vector<std::vector<std::string>> rows;
  for (size_t i = 0; i < all.size(); ++i) {
    const ModeSummary& m = all[i];
    if (m.name == kTruthName || m.name == TwiceTruthName()) continue;
    const ModeSummary mixed = Mixed(m, i < judged.size() ? &judged[i] : nullptr);
    std::vector<std::string> row = {m.name};
    bool all_met = true;
    for (const Verdict& v : Judge(mixed)) {
      row.push_back(v.value + (v.met ? " met" : " **missed**"));
      all_met = all_met && v.met;
    }
    row.push_back(all_met ? "yes" : "no");
    rows.push_back(std::move(row));
  }
  return MarkdownTable(header, std::vector<bool>(header.size(), false), rows);
}

// One sentence on which traces of `set` judge the force targets: those whose reference did not
// converge are named with their spread (or every trace judged, or the check not run).
std::string SetAside(const std::vector<const TraceResult*>& set) {
  std::string list;
  int checked = 0;
  for (const TraceResult* r : set) {
    if (r->reference_spread_N < 0.0) continue;
    ++checked;
    if (r->judged()) continue;
    if (!list.empty()) list += ", ";
    list += r->trace->name + " (" + Sig(r->reference_spread_N) + " N)";
  }
  if (checked == 0)
    return "Reference convergence not checked (--no-convergence): every trace judged.\n";
  if (list.empty()) {
    return fmt::format(
        "Every trace judged: the truth at twice the rate is within {} N RMS of "
        "the truth on each.\n",
        Sig(kConvergedSpread_N));
  }
  return fmt::format(
      "Force targets (RMS, peak) judged on the traces whose truth converged (`{}` within {} N RMS "
      "of the truth); set aside, where the truth at twice the rate is farther (chaotic contact): "
      "{}. Every trace counts for pop-through, NaN and cost, and appears in the tables below.\n",
      TwiceTruthName(), Sig(kConvergedSpread_N), list);
}

// One variant's summary over a set; `judged` is the same variant over the set's traces whose
// reference converged (nullptr: none), which decides the force targets.
Json SummaryJson(const ModeSummary& m, const ModeSummary* judged) {
  Json j{{"variant", m.name},
         {"traces", m.traces},
         {"rms_error_worst_N", m.rms_worst_N},
         {"rms_error_worst_trace", m.rms_worst_trace},
         {"rms_error_median_N", m.rms_median_N},
         {"force_max_error_N", m.max_error_N},
         {"peak_minus_truth_peak_max_N", m.peak_excess_N},
         {"pop_through", static_cast<int64_t>(m.pop_through)},
         {"max_reach_mm", m.max_reach_mm},
         {"contact_mismatches", static_cast<int64_t>(m.contact_mismatches)},
         {"nan_events", static_cast<int64_t>(m.nan_events)},
         {"tick_us_median", m.tick_us_median},
         {"tick_us_p99", m.tick_us_p99},
         {"ticks", m.ticks}};
  if (m.name != kTruthName && m.name != TwiceTruthName()) {
    j["judged_traces"] = judged != nullptr ? judged->traces : 0;
    j["judged_rms_error_worst_N"] = judged != nullptr ? judged->rms_worst_N : 0.0;
    j["judged_peak_minus_truth_peak_max_N"] = judged != nullptr ? judged->peak_excess_N : 0.0;
    Json targets = Json::object();
    for (const Verdict& v : Judge(Mixed(m, judged))) targets[v.name] = v.met;
    j["targets_met"] = targets;
  }
  return j;
}

// The CSV: one row per trace and variant, with the host (the plot reads it: bench/haptic.gp).
std::string Csv(const std::vector<TraceResult>& results, const MachineInfo& machine) {
  std::vector<std::vector<std::string>> rows;
  const auto number = [](double v) { return fmt::format("{}", v); };
  for (const TraceResult& r : results) {
    for (const VariantSummary& s : r.summaries) {
      rows.push_back({r.trace->group, r.trace->name, s.name, std::to_string(s.ticks),
                      number(s.force_rms_error_N), number(s.force_max_error_N),
                      number(s.peak_force_N), number(s.peak_minus_ref_peak_N), number(s.max_jump_N),
                      std::to_string(s.pop_through), number(s.max_reach_mm),
                      std::to_string(s.contact_mismatches), number(s.tick_us_median),
                      number(s.tick_us_p99), std::to_string(s.nan_events), machine.cpu_model});
    }
  }
  return CsvTable(
      {"group", "trace", "variant", "ticks", "force_rms_error_N", "force_max_error_N",
       "peak_force_N", "peak_minus_ref_peak_N", "max_jump_N", "pop_through", "max_reach_mm",
       "contact_mismatches", "tick_us_median", "tick_us_p99", "nan_events", "host"},
      rows);
}

// gnuplot on the CSV: the PNG next to it. Returns false when gnuplot failed.
bool Plot(const Args& args, bool have_hard) {
  const std::string png = std::filesystem::path(args.csv_path).replace_extension(".png").string();
  std::string modes;
  for (SnapshotMode mode : kSnapshotModes) {
    modes += std::string(modes.empty() ? "" : " ") + SnapshotModeName(mode);
  }
  const std::string command = "gnuplot -e \"csv='" + args.csv_path + "'; png='" + png +
                              "'; modes='" + modes + "'; hard=" + (have_hard ? "1" : "0") + "\" " +
                              args.gnuplot_script;
  return report::RunGnuplot("felt bench haptic", command, png) != report::GnuplotOutcome::kFailed;
}

int Run(const Args& args) {
  // Set-up: every input is checked before anything runs.
  const MachineInfo machine = ReadMachineInfo();
  const std::string command = CommandLine(args);
  const SceneDocument scene = BenchScene(args);
  const ServerSpec spec = ParseServerSpec(scene);
  const ClothSpec written = ParseServerSpec(LoadSceneDocument(args.scene)).sim.cloth;
  const std::vector<TraceInput> traces = LoadTraces(args);
  const std::vector<LockstepVariant> variants = ModeVariants(!args.no_convergence);
  LockstepOptions options;
  options.prepend_truth = true;
  options.max_duration_s = args.duration_s > 0.0 ? args.duration_s
                           : args.quick          ? kQuickDuration_s
                                                 : 0.0;
  const int32_t triangles = 2 * (spec.sim.cloth.width - 1) * (spec.sim.cloth.height - 1);
  std::printf("%s\nload average %s\n", command.c_str(), machine.load_average.c_str());
  std::fflush(stdout);

  // Every trace: the truth, then every mode.
  std::vector<TraceResult> results;
  for (const TraceInput& trace : traces) {
    spdlog::info("bench haptic: {} ({})", trace.name, trace.group);
    CompareResult compared = CompareVariants(scene, trace.samples, variants, options);
    TraceResult r;
    r.trace = &trace;
    r.summaries = std::move(compared.summaries);
    for (LockstepRun& run : compared.runs) r.tick_cpu_us.push_back(std::move(run.tick_cpu_us));
    for (const VariantSummary& v : r.summaries) {
      if (v.name == TwiceTruthName()) r.reference_spread_N = v.force_rms_error_N;
    }
    results.push_back(std::move(r));
  }
  const std::string load_end = LoadAverage();

  // The main set (bundled and user traces) and the hard traces.
  std::vector<const TraceResult*> main_set, hard_set;
  for (const TraceResult& r : results) {
    (r.trace->group == "hard" ? hard_set : main_set).push_back(&r);
  }
  const std::vector<ModeSummary> main_modes = Summarize(main_set);
  const std::vector<ModeSummary> hard_modes = Summarize(hard_set);
  const auto judged_of = [](const std::vector<const TraceResult*>& set) {
    std::vector<const TraceResult*> out;
    for (const TraceResult* r : set) {
      if (r->judged()) out.push_back(r);
    }
    return out;
  };
  const std::vector<ModeSummary> main_judged = Summarize(judged_of(main_set));
  const std::vector<ModeSummary> hard_judged = Summarize(judged_of(hard_set));

  // Markdown: what ran, the targets, the summaries, the per-trace tables.
  const std::string host = HostLine(machine, load_end);
  std::string md = fmt::format(
      "Scene `{}` with its cloth at {} x {} particles ({} triangles; the file has {} x {}{}), {} "
      "device(s), {} Hz haptic rate, in lock-step virtual time (docs/compare.md); {}. Reference: "
      "the truth (`{}`: the "
      "cloth stepped every haptic tick, {} Hz, coupled both ways with the proxy, which renders "
      "the exact cloth of its tick in mode newest). Variants: the scene at its {} Hz frame rate "
      "with `proxy.snapshot_mode` set to each mode. Tick costs are thread CPU time of one "
      "`HapticTick` (all devices), pooled over every tick of every trace of the set for the "
      "summaries. pop_through and max_reach_mm come from ProbeProxy after every tick (the cloth "
      "the proxy was rendered on). Targets (issue 20): worst RMS force error <= {} N, no force "
      "more than {} N above the truth's peak, zero pop-through, no NaN, tick median <= {} us and "
      "p99 <= {} us.\n\n",
      args.scene, spec.sim.cloth.width, spec.sim.cloth.height, triangles, written.width,
      written.height,
      args.grid == 0 ? ""
                     : ", resized over the same square with the same total drag: "
                       "bench/bench_util.h's ResizedCurtain",
      spec.devices.size(), FormatSceneNumber(spec.haptic.haptic_rate_hz),
      options.max_duration_s > 0.0
          ? "the first " + FormatSceneNumber(options.max_duration_s) + " s of each trace"
          : std::string("every trace whole"),
      TruthVariant().OverridesText(), FormatSceneNumber(spec.haptic.haptic_rate_hz),
      FormatSceneNumber(spec.sim.integration.frame_rate_hz), Sig(kTargets.rms_error_N),
      Sig(kTargets.peak_excess_N), Sig(kTargets.tick_us_median), Sig(kTargets.tick_us_p99));
  std::string tables;
  if (!main_set.empty()) {
    tables += "## Targets per mode (bundled and --trace traces)\n\n" + host +
              TargetTable(main_modes, main_judged) + "\n" + SetAside(main_set) +
              "\n## Per mode: error against tick cost\n\n" + host + SummaryTable(main_modes) +
              "\n## Per trace\n\n" + host + TraceTable(main_set);
  }
  tables += "\n## Hard traces (" + args.recordings + "/hard/)\n\n";
  if (hard_set.empty()) {
    tables += "None: no " + args.recordings + "/hard/*.trace" +
              (args.no_bundled ? " read (--no-bundled)" : " found") + ".\n";
  } else {
    tables += host + TargetTable(hard_modes, hard_judged) + "\n" + SetAside(hard_set) + "\n" +
              host + SummaryTable(hard_modes) + "\n" + host + TraceTable(hard_set);
  }
  std::printf("\n%s", tables.c_str());
  std::fflush(stdout);
  if (!args.md_path.empty()) {
    WriteTextFile(args.md_path,
                  ReportHeader("`felt bench haptic`: snapshot modes against the truth", command,
                               machine, load_end) +
                      "\n" + md + tables);
  }

  // JSON: the set-up, the targets, every trace's variants, the summaries.
  if (!args.json_path.empty()) {
    Json trace_items = Json::array();
    for (const TraceResult& r : results) {
      Json items = Json::array();
      for (const VariantSummary& s : r.summaries) items.push_back(VariantSummaryJson(s));
      trace_items.push_back(Json{{"name", r.trace->name},
                                 {"group", r.trace->group},
                                 {"path", r.trace->path},
                                 {"reference_spread_N", r.reference_spread_N},
                                 {"judged", r.judged()},
                                 {"variants", items}});
    }
    Json main_items = Json::array(), hard_items = Json::array();
    for (size_t i = 0; i < main_modes.size(); ++i) {
      main_items.push_back(
          SummaryJson(main_modes[i], i < main_judged.size() ? &main_judged[i] : nullptr));
    }
    for (size_t i = 0; i < hard_modes.size(); ++i) {
      hard_items.push_back(
          SummaryJson(hard_modes[i], i < hard_judged.size() ? &hard_judged[i] : nullptr));
    }
    Json top{{"command", command}};
    AppendMachineJson(machine, load_end, &top);
    top["scene"] = args.scene;
    top["grid"] = Json{spec.sim.cloth.width, spec.sim.cloth.height};
    top["triangles"] = triangles;
    top["duration_s"] = options.max_duration_s;
    top["reference"] = Json{{"name", kTruthName}, {"overrides", TruthVariant().OverridesText()}};
    top["converged_spread_N"] = kConvergedSpread_N;
    top["targets"] = Json{{"rms_error_worst_N", kTargets.rms_error_N},
                          {"peak_minus_truth_peak_N", kTargets.peak_excess_N},
                          {"pop_through", kTargets.pop_through},
                          {"nan_events", kTargets.nan_events},
                          {"tick_us_median", kTargets.tick_us_median},
                          {"tick_us_p99", kTargets.tick_us_p99}};
    top["traces"] = trace_items;
    top["summary"] = Json{{"main", main_items}, {"hard", hard_items}};
    WriteTextFile(args.json_path, JsonText(top));
  }
  if (!args.csv_path.empty()) {
    WriteTextFile(args.csv_path, Csv(results, machine));
    if (!args.no_plot && !Plot(args, !hard_set.empty())) return 1;
  }
  return 0;
}

const bool kRegistered = app::RegisterCommand(app::CommandEntry{
    "bench", "haptic",
    "the proxy's snapshot modes against the truth (the cloth stepped every haptic tick) on "
    "pointer traces: force error, spikes, pop-through, tick cost",
    [](CLI::App& cmd) -> app::CommandRun {
      auto args = std::make_shared<Args>();
      cmd.add_option("--json", args->json_path, "write every figure as JSON to this file");
      cmd.add_option("--csv", args->csv_path,
                     "write the per-trace table as CSV to this file (and the plot next to it, "
                     "same name .png)");
      cmd.add_option("--md", args->md_path, "write the tables, with a header, as Markdown here");
      cmd.add_option("--trace", args->traces,
                     "also run these traces (felt-trace v1; repeatable, several per option)");
      cmd.add_flag("--no-bundled", args->no_bundled,
                   "skip the bundled and hard traces (RECORDINGS/*.trace, RECORDINGS/hard/)");
      cmd.add_option("--recordings", args->recordings,
                     "folder of the bundled traces; its hard/ subfolder holds the hard ones")
          ->capture_default_str();
      cmd.add_option("--scene", args->scene, "the scene every variant starts from")
          ->capture_default_str();
      cmd.add_option("--grid", args->grid,
                     "resize the scene's cloth to GRID x GRID particles over the same square "
                     "(0: as written)")
          ->capture_default_str()
          ->check(CLI::IsMember({0}) | CLI::Range(8, 256));
      cmd.add_flag("--quick", args->quick, "only the first 2.5 s of each trace");
      cmd.add_option("--duration", args->duration_s,
                     "only the first S seconds of each trace (overrides --quick)")
          ->check(CLI::NonNegativeNumber);
      cmd.add_option("--gnuplot-script", args->gnuplot_script, "the gnuplot script for the plot")
          ->capture_default_str();
      cmd.add_flag("--no-plot", args->no_plot, "do not run gnuplot");
      cmd.add_flag("--no-convergence", args->no_convergence,
                   "do not run the truth at twice the rate; every trace then judges the force "
                   "targets, converged or not");
      return [args] { return Run(*args); };
    }});

}  // namespace
}  // namespace felt::bench::bench_haptic
