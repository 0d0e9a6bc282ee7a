// `felt compare --trace FILE --scene FILE --variants LIST [--truth] [--json FILE] [--csv FILE]
// [--md FILE] [--plot DIR] [--duration S]`: variants of a scene on the same recorded pointer
// motion, offline (issues 7 and 20; docs/compare.md). The trace drives the real server code
// (compare/lockstep.h) in lock-step virtual time, one variant after the other, on this thread,
// without DDS; the first variant is the reference (with --truth: the truth, the cloth stepped every
// haptic tick, as variant 0). Prints a Markdown table (costs per tick and per frame, force error
// against the reference, force jumps and spikes, contacts, pop-through and reach into the cloth)
// and writes the same per-variant fields as JSON and CSV.
#include <spdlog/fmt/fmt.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <system_error>
#include <vector>

#include "app/command.h"
#include "base/report.h"
#include "compare/compare_plot.h"
#include "compare/lockstep.h"
#include "recordings/mcap_trace.h"
#include "recordings/trace.h"
#include "scene/scene_file.h"

namespace felt::app::cmd_compare {
namespace {

struct CompareArgs {
  std::string trace;
  std::string scene;
  std::string variants;
  std::string json;
  std::string csv;
  std::string md;
  std::string plot_dir;
  double duration_s = 0.0;
  bool truth = false;
  std::string topic;
};

// The command as it can be typed again (for report headers).
std::string CommandLine(const CompareArgs& a) {
  std::string line = "felt compare --trace " + a.trace + " --scene " + a.scene + " --variants '" +
                     a.variants + "'";
  if (!a.topic.empty()) line += " --topic " + a.topic;
  if (a.truth) line += " --truth";
  if (a.duration_s > 0.0) line += " --duration " + FormatSceneNumber(a.duration_s);
  if (!a.json.empty()) line += " --json " + a.json;
  if (!a.csv.empty()) line += " --csv " + a.csv;
  if (!a.md.empty()) line += " --md " + a.md;
  if (!a.plot_dir.empty()) line += " --plot " + a.plot_dir;
  return line;
}

// The table of docs/compare.md, one row per variant.
std::string Table(const std::vector<VariantSummary>& summaries) {
  using report::Fixed;
  using report::Sig;
  std::vector<std::vector<std::string>> rows;
  for (const VariantSummary& s : summaries) {
    rows.push_back({s.name, s.overrides.empty() ? "(scene)" : s.overrides,
                    Fixed(s.tick_us_median, 1), Fixed(s.tick_us_p99, 1),
                    Fixed(s.frame_ms_median, 3), Fixed(s.frame_ms_p99, 3), Sig(s.force_rms_error_N),
                    Sig(s.force_max_error_N), Sig(s.max_jump_N), Sig(s.max_jump_vs_ref_N),
                    Sig(s.peak_force_N), Sig(s.peak_minus_ref_peak_N), std::to_string(s.contacts),
                    std::to_string(s.contact_mismatches), std::to_string(s.pop_through),
                    Fixed(s.max_reach_mm, 3), std::to_string(s.clamped_ticks),
                    std::to_string(s.stalled_ticks), std::to_string(s.nan_events)});
  }
  return report::MarkdownTable(
      {"variant", "overrides", "tick_us_p50", "tick_us_p99", "frame_ms_p50", "frame_ms_p99",
       "force_rms_error_N", "force_max_error_N", "max_jump_N", "max_jump_vs_ref_N", "peak_force_N",
       "peak_minus_ref_peak_N", "contacts", "contact_mismatches", "pop_through", "max_reach_mm",
       "clamped", "stalled", "nan"},
      {false, false, true, true, true, true, true, true, true, true, true, true, true, true, true,
       true, true, true, true},
      rows);
}

// Every per-variant field of the JSON file, one row per variant, as CSV (the JSON field names as
// the header; numbers in shortest round-trip form).
std::string CompareCsv(const CompareResult& result) {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  for (const VariantSummary& s : result.summaries) {
    const Json j = VariantSummaryJson(s);
    std::vector<std::string> row;
    for (const auto& [key, value] : j.items()) {
      if (rows.empty()) header.push_back(key);
      row.push_back(value.is_string() ? value.get<std::string>() : value.dump());
    }
    rows.push_back(std::move(row));
  }
  return report::CsvTable(header, rows);
}

std::string CompareJson(const CompareArgs& args, const report::MachineInfo& machine,
                        const std::string& load_end, const CompareResult& result) {
  Json variants = Json::array();
  for (const VariantSummary& s : result.summaries) variants.push_back(VariantSummaryJson(s));
  Json top{{"command", CommandLine(args)},
           {"trace", args.trace},
           {"scene", args.scene},
           {"reference", result.summaries.front().name},
           {"truth", args.truth},
           {"devices", result.runs.front().devices},
           {"tick_dt_s", result.runs.front().tick_dt_s}};
  report::AppendMachineJson(machine, load_end, &top);
  top["variants"] = variants;
  return JsonText(top);
}

int Compare(const CompareArgs& args) {
  // Set-up: every input is checked before anything runs (errors exit 2 through main).
  const report::MachineInfo machine = report::ReadMachineInfo();
  const Trace trace = ReadAnyTrace(args.trace, args.topic);
  const SceneDocument scene = LoadSceneDocument(args.scene);
  // The scene as written must be valid (errors with line and column).
  const double haptic_rate_hz = CheckWholeScene(scene).haptic.haptic_rate_hz;
  try {
    (void)LockstepTicks(trace.samples, haptic_rate_hz, args.duration_s);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(args.trace + ": " + e.what());
  }
  const std::vector<LockstepVariant> variants = ParseVariantList(args.variants);
  LockstepOptions options;
  options.max_duration_s = args.duration_s;
  options.prepend_truth = args.truth;
  if (!args.plot_dir.empty()) {  // before the run: a directory that cannot be made fails now
    std::error_code ec;
    std::filesystem::create_directories(args.plot_dir, ec);
    if (ec) throw std::invalid_argument("--plot " + args.plot_dir + ": " + ec.message());
  }
  std::vector<std::string> warnings;
  if (args.truth) warnings = TruthClothMismatches(variants);
  for (const std::string& w : warnings)
    std::fprintf(stderr, "felt compare: warning: %s\n", w.c_str());

  const CompareResult result = CompareVariants(scene, trace.samples, variants, options);
  const std::string load_end = report::LoadAverage();

  // Stdout: what ran, then the table.
  const LockstepRun& ref = result.runs.front();
  const std::string table = Table(result.summaries);
  std::printf(
      "felt compare: %s on %s, %lld ticks (%.3f s virtual), %lld frames, %u device(s); "
      "reference '%s'; timer overhead %.2f us (in every cost); load %s -> %s\n\n%s",
      args.trace.c_str(), args.scene.c_str(), static_cast<long long>(ref.ticks),
      static_cast<double>(ref.ticks) * ref.tick_dt_s, static_cast<long long>(ref.frames),
      ref.devices, ref.name.c_str(), result.summaries.front().timer_overhead_us,
      machine.load_average.c_str(), load_end.c_str(), table.c_str());
  std::fflush(stdout);
  if (!args.json.empty())
    report::WriteTextFile(args.json, CompareJson(args, machine, load_end, result));
  if (!args.csv.empty()) report::WriteTextFile(args.csv, CompareCsv(result));
  if (!args.md.empty()) {
    const std::string header =
        report::ReportHeader("felt compare: " + args.trace, CommandLine(args), machine, load_end);
    const std::string what = fmt::format(
        "Trace `{}` on scene `{}`: {} haptic ticks ({:.3f} s of virtual time), {} sim frames, {} "
        "device(s), in lock-step virtual time (docs/compare.md). Reference: `{}`{}. Costs are "
        "thread CPU time and vary from run to run (each includes one timer read: {:.2f} us "
        "measured between two back-to-back reads); forces are bit-identical run to run.\n\n",
        args.trace, args.scene, ref.ticks, static_cast<double>(ref.ticks) * ref.tick_dt_s,
        ref.frames, ref.devices, ref.name,
        args.truth ? " (the truth: the cloth stepped every haptic tick, the proxy on the exact "
                     "cloth)"
                   : "",
        result.summaries.front().timer_overhead_us);
    std::string warned;
    for (const std::string& w : warnings) warned.append("**Warning**: ").append(w).append(".\n\n");
    report::WriteTextFile(args.md, header + "\n" + what + warned + table);
  }
  if (!args.plot_dir.empty()) {
    const ComparePlotFiles plots = WriteComparePlots(
        args.plot_dir, result, "felt compare: " + args.trace + " on " + args.scene);
    for (size_t d = 0; d < plots.csv.size(); ++d) {
      std::printf("plot data %s, script %s\n", plots.csv[d].c_str(), plots.script[d].c_str());
    }
  }
  return 0;
}

CommandRun Setup(CLI::App& cmd) {
  auto args = std::make_shared<CompareArgs>();
  std::string shorthands;
  for (const auto& [key, scene_key] : VariantShorthands()) {
    shorthands += "\n  " + key + " -> " + scene_key;
  }
  cmd.add_option("--trace", args->trace,
                 "pointer trace (felt-trace v1, or .mcap: a PoseStamped or OmniState topic), fed "
                 "to every device")
      ->required();
  cmd.add_option("--topic", args->topic,
                 "MCAP trace: the pose topic (default: the first PoseStamped, else OmniState)");
  cmd.add_option("--scene", args->scene, "scene file (TOML) the variants start from")->required();
  cmd.add_option("--variants", args->variants,
                 "variants separated by ';', each [NAME:] key=value[,key=value...]; the first is "
                 "the reference; keys are scene paths (proxy.max_iterations) or shorthands:" +
                     shorthands +
                     "\n  a bare 'truth' is the variant truth=on; e.g. 'newest: snapshot=newest; "
                     "blend: snapshot=blend_forces'")
      ->required();
  cmd.add_flag("--truth", args->truth,
               "run the truth first, as variant 0 and the reference: the scene with "
               "integration.frame_rate_hz = haptic.haptic_rate_hz and snapshot=newest (the cloth "
               "stepped every haptic tick, the proxy on the exact cloth)");
  cmd.add_option("--json", args->json, "write the per-variant figures as JSON here");
  cmd.add_option("--csv", args->csv, "write the per-variant figures as CSV here");
  cmd.add_option("--md", args->md, "write the table with the command and machine header here");
  cmd.add_option("--plot", args->plot_dir,
                 "draw force against time per variant (the reference behind it, the error below) "
                 "and contact state into this directory: per device forces_d<N>.csv, .gp and .png "
                 "(gnuplot)");
  cmd.add_option("--duration", args->duration_s,
                 "replay at most this many seconds of the trace (default: all of it)")
      ->check(CLI::NonNegativeNumber);
  return [args]() -> int { return Compare(*args); };
}

const bool kRegistered = RegisterCommand(
    {"", "compare",
     "replay a trace through variants of a scene in lock-step virtual time and compare forces "
     "and costs",
     Setup});

}  // namespace
}  // namespace felt::app::cmd_compare
