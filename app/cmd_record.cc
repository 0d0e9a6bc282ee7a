// `felt record --out FILE [--duration S] [--forces-out FILE] [--device ID] [--domain N]
// [--dds-config FILE]`: records one device's pointer samples from felt/pointer into a felt-trace
// v1 file and the forces it receives from felt/force into a felt-forces v1 file, counting gaps by
// sequence number (issue 7, docs/replay.md). With `--out FILE.mcap` it writes one ROS 2-profile
// MCAP file instead: pointer samples, forces and felt/status as CRTK topics and /diagnostics
// (issue 24, docs/mcap.md). Runs until the duration or SIGINT/SIGTERM.
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
#include "rt/clock.h"
#include "transport/mcap_recorder.h"
#include "transport/recorder.h"

namespace felt::app::cmd_record {
namespace {

struct RecordArgs {
  std::string out;
  std::optional<double> duration_s;
  std::string forces_out;
  bool no_forces = false;
  std::string device;
  uint32_t domain = 0;
  std::string dds_config;
  std::string security, identity;  // DDS Security (default identity "recorder")
  double rate_hz = 1000.0;
};

// --out FILE.mcap: one MCAP file of the device's pointer samples, its forces and the status.
int RecordMcap(const RecordArgs& args) {
  CheckDurationOption(args.duration_s);
  if (!args.forces_out.empty()) {
    throw std::invalid_argument("--forces-out: an MCAP recording holds the forces (servo_cf)");
  }
  transport::McapRecorderConfig config;
  config.dds.domain_id = args.domain;
  config.dds.config_file = args.dds_config;
  config.out_path = args.out;
  config.device_id = args.device;
  config.forces = !args.no_forces;
  transport::McapRecorder recorder(config);

  InstallStopHandlers();
  std::printf("felt record: listening on DDS domain %u for %s%s, to MCAP %s\n", args.domain,
              args.device.empty() ? "the first device heard" : ("device " + args.device).c_str(),
              args.duration_s ? fmt::format(", {:g} s", *args.duration_s).c_str()
                              : ", until SIGINT/SIGTERM",
              args.out.c_str());
  std::fflush(stdout);

  // Record until the duration (counted from the first sample) or a signal.
  int64_t end_ns = INT64_MAX;
  while (!StopRequested().load() && MonotonicNowNs() < end_ns) {
    recorder.Poll(std::chrono::milliseconds(50));
    if (args.duration_s && end_ns == INT64_MAX && recorder.Stats().pointers_received > 0) {
      end_ns = MonotonicNowNs() + static_cast<int64_t>(*args.duration_s * 1e9);
    }
  }
  recorder.Close();

  // Summary.
  const transport::McapRecorderStats s = recorder.Stats();
  const transport::McapTopics topics = transport::McapTopics::ForDevice(s.device_id);
  std::printf("felt record: stopped %s\n",
              StopRequested().load() ? "by signal" : "after the duration");
  std::printf(
      "device %s: %llu samples written to %s (%s, %s; %llu received, %llu missing by seq, %llu "
      "out of order; %llu of other devices)\n",
      s.device_id.empty() ? "(none heard)" : s.device_id.c_str(),
      static_cast<unsigned long long>(s.sink.pointers_written), args.out.c_str(),
      topics.pose.c_str(), topics.twist.c_str(),
      static_cast<unsigned long long>(s.pointers_received),
      static_cast<unsigned long long>(s.pointer_seq_gaps),
      static_cast<unsigned long long>(s.pointers_out_of_order),
      static_cast<unsigned long long>(s.pointers_other_device));
  std::printf(
      "forces: %llu written (%s; %llu received, %llu missing by seq, %llu before the first "
      "sample); status: %llu written (/diagnostics)\n",
      static_cast<unsigned long long>(s.sink.forces_written), topics.wrench.c_str(),
      static_cast<unsigned long long>(s.forces_received),
      static_cast<unsigned long long>(s.force_seq_gaps),
      static_cast<unsigned long long>(s.forces_before_first_pointer),
      static_cast<unsigned long long>(s.sink.statuses_written));
  std::printf("mcap: %llu bytes in %llu chunks; queue: %llu dropped, at most %llu waiting\n",
              static_cast<unsigned long long>(s.sink.bytes),
              static_cast<unsigned long long>(s.sink.chunks),
              static_cast<unsigned long long>(s.sink.queue_drops),
              static_cast<unsigned long long>(s.sink.max_queue_depth));
  if (s.pointers_received == 0) {
    std::fprintf(stderr, "felt record: no pointer sample received: %s was not written\n",
                 args.out.c_str());
    return 1;
  }
  return s.sink.queue_drops == 0 ? 0 : 3;
}

int Record(const RecordArgs& args) {
  if (IsMcapPath(args.out)) return RecordMcap(args);
  // Set-up: the options, then the DDS readers.
  CheckDurationOption(args.duration_s);
  transport::RecorderConfig config;
  config.dds.domain_id = args.domain;
  config.dds.config_file = args.dds_config;
  config.dds.security_dir = args.security;
  config.dds.identity = args.identity;
  config.out_path = args.out;
  config.forces_path = args.no_forces
                           ? std::string()
                           : (args.forces_out.empty() ? args.out + ".forces.csv" : args.forces_out);
  config.device_id = args.device;
  config.rate_hz = args.rate_hz;
  transport::Recorder recorder(config);

  InstallStopHandlers();
  std::printf("felt record: listening on DDS domain %u for %s%s%s\n", args.domain,
              args.device.empty() ? "the first device heard" : ("device " + args.device).c_str(),
              args.duration_s ? fmt::format(", {:g} s", *args.duration_s).c_str()
                              : ", until SIGINT/SIGTERM",
              config.forces_path.empty() ? "" : (", forces to " + config.forces_path).c_str());
  std::fflush(stdout);

  // Record until the duration (counted from the first sample) or a signal.
  int64_t end_ns = INT64_MAX;
  while (!StopRequested().load() && MonotonicNowNs() < end_ns) {
    recorder.Poll(std::chrono::milliseconds(50));
    if (args.duration_s && end_ns == INT64_MAX && recorder.Stats().pointers_written > 0) {
      end_ns = MonotonicNowNs() + static_cast<int64_t>(*args.duration_s * 1e9);
    }
  }
  recorder.Close();

  // Summary.
  const transport::RecorderStats s = recorder.Stats();
  std::printf("felt record: stopped %s\n",
              StopRequested().load() ? "by signal" : "after the duration");
  std::printf(
      "device %s: %llu samples written to %s (%llu received, %llu missing by seq, %llu out "
      "of order, %llu with time not increasing; %llu of other devices)\n",
      s.device_id.empty() ? "(none heard)" : s.device_id.c_str(),
      static_cast<unsigned long long>(s.pointers_written), args.out.c_str(),
      static_cast<unsigned long long>(s.pointers_received),
      static_cast<unsigned long long>(s.pointer_seq_gaps),
      static_cast<unsigned long long>(s.pointers_out_of_order),
      static_cast<unsigned long long>(s.pointers_time_not_increasing),
      static_cast<unsigned long long>(s.pointers_other_device));
  if (!config.forces_path.empty()) {
    std::printf(
        "forces: %llu written to %s (%llu received, %llu missing by seq; %llu for other "
        "devices)\n",
        static_cast<unsigned long long>(s.forces_written), config.forces_path.c_str(),
        static_cast<unsigned long long>(s.forces_received),
        static_cast<unsigned long long>(s.force_seq_gaps),
        static_cast<unsigned long long>(s.forces_other_device));
  }
  if (s.pointers_written == 0) {
    std::fprintf(stderr, "felt record: no pointer sample received: %s was not written\n",
                 args.out.c_str());
    return 1;
  }
  return 0;
}

CommandRun Setup(CLI::App& cmd) {
  auto args = std::make_shared<RecordArgs>();
  cmd.add_option("--out", args->out,
                 "the felt-trace v1 file to write, or FILE.mcap: ROS 2 MCAP of the samples, "
                 "forces and status")
      ->required();
  cmd.add_option("--duration", args->duration_s,
                 "stop this many seconds after the first sample (default: SIGINT/SIGTERM)");
  cmd.add_option("--forces-out", args->forces_out,
                 "the felt-forces v1 file for the forces (default: OUT.forces.csv)");
  cmd.add_flag("--no-forces", args->no_forces, "do not record the forces");
  cmd.add_option("--device", args->device, "record this device id (default: the first heard)");
  AddDdsOptions(cmd, &args->domain, &args->dds_config);
  AddSecurityOptions(cmd, &args->security, &args->identity);
  cmd.add_option("--rate-hz", args->rate_hz, "nominal rate written into the trace header")
      ->check(CLI::PositiveNumber);
  return [args]() -> int { return Record(*args); };
}

const bool kRegistered = RegisterCommand(
    {"", "record", "record a device's pointer samples (and forces) from DDS into a trace", Setup});

}  // namespace
}  // namespace felt::app::cmd_record
