// `felt trace import` and `felt trace generate`: the pointer-trace tools (recordings/README.md).
#include <CLI/CLI.hpp>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>

#include "app/command.h"
#include "recordings/generate.h"
#include "recordings/import.h"
#include "recordings/trace.h"

namespace felt::app::cmd_trace {
namespace {

// "x,y,z" as three finite numbers; throws std::invalid_argument naming the option.
Vec3 ParseVec3(const std::string& text, const char* option) {
  Vec3 out;
  size_t start = 0;
  for (int i = 0; i < 3; ++i) {
    const size_t comma = text.find(',', start);
    if ((i < 2) != (comma != std::string::npos)) {
      throw std::invalid_argument(std::string(option) + " '" + text + "' must be x,y,z");
    }
    const std::string item = text.substr(start, i < 2 ? comma - start : std::string::npos);
    const auto [ptr, ec] = std::from_chars(item.data(), item.data() + item.size(), out[i]);
    if (ec != std::errc() || ptr != item.data() + item.size() || !std::isfinite(out[i])) {
      throw std::invalid_argument(std::string(option) + " '" + text + "': '" + item +
                                  "' is not a finite number");
    }
    start = comma + 1;
  }
  return out;
}

struct ImportArgs {
  std::string in, format, out, columns, trial_column, offset, axes = "xyz", device = "imported";
  int64_t select = 0;
  double time_scale = 1.0, scale = 1.0, rate_hz = 1000.0, trial_gap_s = 0.5, max_gap_s = 0.0;
  int decimals = -1;
  std::string topic, time = "header";
};

CommandRun SetupImport(CLI::App& cmd) {
  auto args = std::make_shared<ImportArgs>();
  cmd.add_option("--in", args->in, "source recording")->required();
  cmd.add_option("--format", args->format,
                 "devicelog (H3D/HAPI DeviceLog text), csv, or mcap (a PoseStamped or OmniState "
                 "topic; `ros2 bag`, `felt record --out X.mcap`)")
      ->required();
  cmd.add_option("--out", args->out, "trace file to write (felt-trace v1)")->required();
  cmd.add_option("--columns", args->columns,
                 "CSV columns, e.g. t=t_ms,x=x_m,y=y_m,z=z (default: automatic)");
  cmd.add_option("--trial-column", args->trial_column,
                 "CSV trial/stroke id column (default: rep, trial or stroke if present)");
  CLI::Option* select =
      cmd.add_option("--select", args->select, "keep only this trial id (default: concatenate)");
  cmd.add_option("--trial-gap", args->trial_gap_s,
                 "seconds between concatenated trials (default 0.5)");
  CLI::Option* time_scale = cmd.add_option(
      "--time-scale", args->time_scale, "seconds per source time unit (default 1; 0.001 for t_ms)");
  cmd.add_option("--scale", args->scale, "device metres per source position unit (default 1)");
  cmd.add_option("--offset", args->offset, "x,y,z added after scaling [m, device frame]");
  cmd.add_option("--axes", args->axes,
                 "device axes from source axes, signed permutation, e.g. xyz, xzy, \"x,-z,y\"");
  cmd.add_option("--rate", args->rate_hz, "output rate [Hz] (default 1000)");
  cmd.add_option("--max-gap", args->max_gap_s,
                 "source step [s] treated as a gap (default: 10 x median step)");
  cmd.add_option("--device", args->device, "the header's device value (default 'imported')");
  cmd.add_option("--topic", args->topic,
                 "mcap: the pose topic (default: the first PoseStamped, else OmniState)");
  cmd.add_option("--time", args->time, "mcap: sample time from the header stamp or log time")
      ->check(CLI::IsMember({"header", "log"}));
  cmd.add_option("--decimals", args->decimals,
                 "fixed decimals in the output (default: shortest exact round trip)");
  return [args, select, time_scale]() {
    ImportOptions options;
    options.format = ParseImportFormat(args->format);
    if (!args->columns.empty()) options.SetColumns(args->columns);
    options.trial_column = args->trial_column;
    if (select->count() > 0) options.select_trial = args->select;
    options.trial_gap_s = args->trial_gap_s;
    if (time_scale->count() > 0) options.time_scale = args->time_scale;
    options.scale = args->scale;
    if (!args->offset.empty()) options.offset_D_m = ParseVec3(args->offset, "--offset");
    options.axes = ParseAxisMap(args->axes);
    options.rate_hz = args->rate_hz;
    options.max_gap_s = args->max_gap_s;
    options.device = args->device;
    options.mcap_topic = args->topic;
    options.mcap_time = args->time == "log" ? McapTraceTime::kLogTime : McapTraceTime::kHeaderStamp;

    const Trace trace = ImportTrace(args->in, options);
    WriteTrace(args->out, trace, TraceWriteOptions{args->decimals});
    std::printf("wrote %s: %zu samples at %s Hz (%.3f s) from %s (%s samples, %s Hz)\n",
                args->out.c_str(), trace.samples.size(), trace.header.Get("rate_hz")->c_str(),
                trace.samples.back().t_s, args->in.c_str(),
                trace.header.Get("source_samples")->c_str(),
                trace.header.Get("source_rate_hz")->c_str());
    return 0;
  };
}

struct GenerateArgs {
  std::string out_dir = "recordings";
  uint64_t seed = kDefaultTraceSeed;
  std::string real_motion;
  int64_t real_trials = 1;
};

void PrintWritten(const std::string& path) {
  std::printf("wrote %s (%ju bytes)\n", path.c_str(),
              static_cast<uintmax_t>(std::filesystem::file_size(path)));
}

CommandRun SetupGenerate(CLI::App& cmd) {
  auto args = std::make_shared<GenerateArgs>();
  cmd.add_option("--out-dir", args->out_dir,
                 "directory for the .trace files, hard ones in OUT_DIR/hard (default recordings)");
  cmd.add_option("--seed", args->seed, "noise seed (default 1, the bundled traces' seed)");
  cmd.add_option("--real-motion", args->real_motion,
                 "also write OUT_DIR/real_pen.trace from this directory's handwriting recording "
                 "(GPL data: never commit the result)");
  cmd.add_option("--real-trials", args->real_trials,
                 "with --real-motion: write trials 1..N of the handwriting, trial 1 as "
                 "real_pen.trace and trial k > 1 as real_pen_k.trace (default 1)")
      ->check(CLI::Range(int64_t{1}, kRealPenTrials));
  return [args]() {
    const std::string hard_dir = args->out_dir + "/hard";
    std::filesystem::create_directories(hard_dir);
    for (const std::string& path : WriteBundledTraces(args->out_dir, args->seed)) {
      PrintWritten(path);
    }
    for (const std::string& path : WriteHardTraces(hard_dir, args->seed)) PrintWritten(path);
    for (int64_t trial = 1; !args->real_motion.empty() && trial <= args->real_trials; ++trial) {
      const std::string path = args->out_dir + "/real_pen" +
                               (trial == 1 ? std::string() : "_" + std::to_string(trial)) +
                               ".trace";
      WriteTrace(path, RealPenTrace(args->real_motion, trial), TraceWriteOptions{kBundledDecimals});
      PrintWritten(path);
      std::printf("%s derives from GPL data (%s/%s): do not commit it\n", path.c_str(),
                  args->real_motion.c_str(), kRealPenFile);
    }
    return 0;
  };
}

const bool kRegisteredImport =
    RegisterCommand({"trace", "import",
                     "convert a DeviceLog or CSV recording into a 1 kHz felt-trace", SetupImport});
const bool kRegisteredGenerate = RegisterCommand(
    {"trace", "generate", "write the bundled and hard pointer traces (deterministic from --seed)",
     SetupGenerate});

}  // namespace
}  // namespace felt::app::cmd_trace
