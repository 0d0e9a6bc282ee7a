// `felt replay FILE [--rate R] [--loop N | --duration S] [--forces-out FILE] [--json FILE]
// [--device ID] [--late-us US] [--domain N] [--dds-config FILE]`: publishes a felt-trace v1 file
// on felt/pointer at its recorded timing (absolute deadlines) as a stand-in device, takes the
// forces that come back, and reports end-to-end latency percentiles, lost and late samples
// (issue 7, docs/replay.md). SIGINT/SIGTERM end the replay early; the report is still printed.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "app/command.h"
#include "app/command_util.h"
#include "recordings/mcap_trace.h"
#include "recordings/trace.h"
#include "transport/replayer.h"

namespace felt::app::cmd_replay {
namespace {

struct ReplayArgs {
  std::string trace;
  double rate = 1.0;
  uint32_t loops = 1;
  std::optional<double> duration_s;
  std::string forces_out;
  std::string json;
  std::string device = "default";
  double late_us = 1000.0;
  double discovery_timeout_s = 15.0;
  std::string security, identity;  // DDS Security (default identity "device-<device>")
  uint32_t domain = 0;
  std::string dds_config;
  std::string topic;
};

int Replay(const ReplayArgs& args) {
  // Set-up: the whole trace is read and checked before anything is published.
  if (!(args.rate > 0.0 && args.rate <= 100.0)) {
    throw std::invalid_argument(fmt::format("--rate must be in (0, 100], got {}", args.rate));
  }
  CheckDurationOption(args.duration_s);
  Trace trace = ReadAnyTrace(args.trace, args.topic);
  transport::ReplayConfig config;
  config.dds.domain_id = args.domain;
  config.dds.config_file = args.dds_config;
  config.dds.security_dir = args.security;
  config.dds.identity = args.identity;
  config.device_id = args.device;
  config.rate = args.rate;
  config.loops = args.loops;
  config.duration_s = args.duration_s.value_or(0.0);
  config.late_threshold_us = args.late_us;
  config.discovery_timeout =
      std::chrono::nanoseconds(static_cast<int64_t>(args.discovery_timeout_s * 1e9));
  config.forces_out = args.forces_out;
  const size_t samples = trace.samples.size();
  std::unique_ptr<transport::Replayer> made;
  try {
    made = std::make_unique<transport::Replayer>(std::move(trace), config);
  } catch (const std::invalid_argument& e) {  // the trace's schedule: name the file
    throw std::invalid_argument(args.trace + ": " + e.what());
  }
  transport::Replayer& replayer = *made;

  InstallStopHandlers();

  // Discovery: a server must be there before the first sample goes out.
  std::printf("felt replay: %s (%zu samples) as device %s on DDS domain %u, waiting for a server\n",
              args.trace.c_str(), samples, args.device.c_str(), args.domain);
  std::fflush(stdout);
  if (!replayer.WaitForServer(&StopRequested())) {
    if (StopRequested().load()) {
      std::printf("felt replay: stopped by signal before a server was found\n");
      return 1;
    }
    std::fprintf(stderr,
                 "felt replay: no server found on DDS domain %u within %.0f s (is `felt serve` "
                 "running with the same --domain?)\n",
                 args.domain, args.discovery_timeout_s);
    return 1;
  }

  // The replay; the "publishing" line tells a watcher (felt soak) that the samples start now.
  const transport::ReplayReport report = replayer.Run(&StopRequested(), [] {
    std::printf("felt replay: publishing\n");
    std::fflush(stdout);
  });
  std::printf("%s", transport::FormatReplayReport(report).c_str());
  if (!args.json.empty()) {
    WriteOptionFile("--json", args.json, transport::ReplayReportJson(report));
  }
  std::fflush(stdout);
  return 0;
}

CommandRun Setup(CLI::App& cmd) {
  auto args = std::make_shared<ReplayArgs>();
  cmd.add_option("trace", args->trace,
                 "the felt-trace v1 file to publish, or an MCAP file (.mcap: a PoseStamped or "
                 "OmniState topic)")
      ->required();
  cmd.add_option("--topic", args->topic,
                 "MCAP: the pose topic (default: the first PoseStamped, else OmniState)");
  cmd.add_option("--rate", args->rate, "time scale: 2 plays twice as fast (default 1)");
  auto* loop = cmd.add_option("--loop", args->loops, "play the trace N times back to back")
                   ->check(CLI::Range(1u, 1000000u));
  cmd.add_option("--duration", args->duration_s,
                 "loop the trace until this many seconds of replay time")
      ->excludes(loop);
  cmd.add_option("--forces-out", args->forces_out,
                 "write every force received here (felt-forces v1)");
  cmd.add_option("--json", args->json, "write the report as JSON here");
  cmd.add_option("--device", args->device, "publish as this device id (default \"default\")");
  cmd.add_option("--late-us", args->late_us,
                 "count a sample late when published more than this after its deadline (us)")
      ->check(CLI::PositiveNumber);
  cmd.add_option("--discovery-timeout", args->discovery_timeout_s,
                 "seconds to wait for a server (default 15)")
      ->check(CLI::PositiveNumber);
  AddDdsOptions(cmd, &args->domain, &args->dds_config);
  AddSecurityOptions(cmd, &args->security, &args->identity);
  return [args]() -> int { return Replay(*args); };
}

const bool kRegistered = RegisterCommand(
    {"", "replay",
     "publish a pointer trace over DDS at its recorded timing; report latency, lost, late", Setup});

}  // namespace
}  // namespace felt::app::cmd_replay
