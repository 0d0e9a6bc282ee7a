// `felt serve --scene FILE [--duration S] [--stats-json FILE] [--trace FILE] [--domain N]
// [--dds-config FILE] [--view PORT [--view-bind ADDR]] [--no-realtime]`: the real-time server
// (issue 5, docs/server.md). Devices connect over the DDS transport (issue 6, docs/transport.md)
// unless --trace replays a pointer trace in-process to every device of the scene. SIGINT/SIGTERM
// stop it cleanly: a signal-safe flag, the loops stop, the final statistics are printed and spdlog
// is flushed.
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "app/command.h"
#include "app/command_util.h"
#include "haptic_loop/pointer_source.h"
#include "recordings/trace.h"
#include "rt/periodic_loop.h"
#include "scene/scene_file.h"
#include "server/ros2_marker_feed.h"
#include "server/server.h"
#include "server/server_spec.h"
#include "server/transport_io.h"
#include "transport/server_transport.h"
#include "transport/transport_scene.h"
#include "view/view_server.h"

namespace felt::app::cmd_serve {
namespace {

struct ServeArgs {
  std::string scene;
  std::optional<double> duration_s;
  std::string stats_json;
  std::string trace;
  std::optional<uint32_t> domain;  // overrides [transport] domain
  std::string dds_config;          // overrides [transport] dds_config when not empty
  std::string security;            // overrides [transport] security when not empty
  std::string identity;            // overrides [transport] identity when not empty
  bool no_realtime = false;
  std::optional<uint16_t> view_port;    // --view PORT: serve the live view (docs/view.md)
  std::string view_bind = "127.0.0.1";  // --view-bind ADDR
};

// The ServerStatus the monitor publishes once a second (transport fields are the transport's).
transport::ServerStatusView StatusOf(const ServerReport& r, const std::string& server_id) {
  transport::ServerStatusView s;
  auto percentiles = [](const HistogramSnapshot& h, double ns_per_unit) {
    transport::PercentilesView p;
    p.p50 = static_cast<double>(h.PercentileNs(0.5)) / ns_per_unit;
    p.p99 = static_cast<double>(h.PercentileNs(0.99)) / ns_per_unit;
    p.p999 = static_cast<double>(h.PercentileNs(0.999)) / ns_per_unit;
    p.max = static_cast<double>(h.max_ns) / ns_per_unit;
    return p;
  };
  s.server_id = server_id;
  s.realtime = r.realtime;
  s.haptic_ticks = r.haptic.ticks;
  s.haptic_overruns = r.haptic.overruns;
  s.haptic_lateness_us = percentiles(r.haptic.lateness, 1e3);
  s.haptic_compute_us = percentiles(r.haptic.compute, 1e3);
  s.sim_frames = r.sim.ticks;
  s.sim_frame_ms = percentiles(r.sim.compute, 1e6);
  s.snapshot_age_ms = percentiles(r.haptic.snapshot_age, 1e6);
  s.sim_stalled = r.sim_stalled;
  s.nan_events = r.nan_events;
  s.devices_connected = r.devices_connected;
  s.passivity_energy_J = r.energy_J;
  return s;
}

int Serve(const ServeArgs& args) {
  // Set-up: the scene (a bad one exits 2 before anything starts).
  ServerSpec spec;
  transport::ServerTransportConfig config;
  try {
    const SceneDocument doc = LoadSceneDocument(args.scene);
    spec = ParseServerSpec(doc);
    config = transport::ParseTransportConfig(doc, spec.devices);
    // A device's owner may fall silent for as long as the loop calls its input stale.
    config.ownership_timeout_ns = static_cast<int64_t>(spec.haptic.stale_input_s * 1e9);
  } catch (const SceneError& e) {
    std::fprintf(stderr, "felt serve: %s\n", e.what());
    return 2;
  }
  if (args.no_realtime) {
    spec.haptic.haptic_realtime = RealtimeSettings{};
    spec.haptic.sim_realtime = RealtimeSettings{};
  }
  const auto device_count = static_cast<uint32_t>(spec.devices.size());

  // Input and output: a trace in-process, or the DDS transport.
  std::unique_ptr<transport::ServerTransport> dds;
  transport::Ros2MarkerSettings marker_settings;
  std::unique_ptr<PointerSource> source;
  std::unique_ptr<ForceSink> sink;
  std::optional<double> duration_s = args.duration_s;
  if (!args.trace.empty()) {
    const Trace trace = ReadTrace(args.trace);
    source = std::make_unique<TracePointerSource>(
        std::vector<std::vector<TraceSample>>(device_count, trace.samples));
    sink = std::make_unique<CapturingForceSink>(device_count);
    const double length_s = trace.samples.back().t_s - trace.samples.front().t_s;
    if (!duration_s) duration_s = length_s + 0.5;  // the trace, then its ramp-out
    spdlog::info("serve: trace {} ({} samples, {:.2f} s) to {} device(s)", args.trace,
                 trace.samples.size(), length_s, device_count);
  } else {
    if (args.domain) config.dds.domain_id = *args.domain;
    if (!args.dds_config.empty()) config.dds.config_file = args.dds_config;
    if (!args.security.empty()) config.dds.security_dir = args.security;
    if (!args.identity.empty()) config.dds.identity = args.identity;
    const uint32_t domain = config.dds.domain_id;
    marker_settings = config.ros2_markers;
    const std::string security = config.dds.security_dir;
    dds = std::make_unique<transport::ServerTransport>(std::move(config));
    source = std::make_unique<TransportPointerSource>(dds.get());
    sink = std::make_unique<TransportForceSink>(dds.get());
    spdlog::info("serve: DDS domain {}{}, devices:{}", domain,
                 security.empty() ? std::string() : ", DDS Security " + security, [&] {
                   std::string ids;
                   for (const DeviceSpec& d : spec.devices) ids += " " + d.id;
                   return ids;
                 }());
  }
  if (duration_s && !(*duration_s > 0.0)) throw std::invalid_argument("--duration must be > 0");

  // The server; the monitor publishes the status through the transport when there is one.
  ServerOptions options;
  options.apply_realtime = true;
  const std::string server_id = "felt-" + std::to_string(getpid());
  transport::ServerTransport* dds_ptr = dds.get();
  if (dds_ptr != nullptr) {
    options.on_report = [dds_ptr, server_id](const ServerReport& r) {
      dds_ptr->PublishStatus(StatusOf(r, server_id));
    };
  }
  Server server(std::move(spec), source.get(), sink.get(), options);
  // The cloth and proxies as ROS 2 markers, when the transport publishes them (a ROS 2 device,
  // or [transport] ros2_markers = true): a tap of its own, before Start.
  std::unique_ptr<Ros2MarkerFeed> markers;
  if (dds_ptr != nullptr && dds_ptr->markers_enabled()) {
    markers = std::make_unique<Ros2MarkerFeed>(&server, dds_ptr, marker_settings);
    spdlog::info("serve: ROS 2 markers on {} at {} Hz (frame '{}')", marker_settings.topic,
                 marker_settings.rate_hz, marker_settings.frame_id);
  }
  // The live view: before Start, so the loops publish into its tap from the first frame.
  std::unique_ptr<ViewServer> view;
  if (args.view_port) {
    ViewOptions view_options;
    view_options.port = *args.view_port;
    view_options.bind = args.view_bind;
    view = std::make_unique<ViewServer>(&server, view_options);
    std::printf("felt serve: live view at %s\n", view->url().c_str());
    std::fflush(stdout);
  }
  InstallStopHandlers();
  spdlog::info("serve: scene {} ({} x {} cloth), {} Hz haptic, {} Hz sim{}",
               server.spec().scene_name, server.model().width, server.model().height,
               server.spec().haptic.haptic_rate_hz, server.spec().sim.integration.frame_rate_hz,
               duration_s ? fmt::format(", {:.1f} s", *duration_s) : ", until SIGINT/SIGTERM");
  server.Start();
  if (markers) markers->Start();

  // Wait for the end: the duration or a signal.
  const int64_t end_ns =
      duration_s ? MonotonicNowNs() + static_cast<int64_t>(*duration_s * 1e9) : INT64_MAX;
  while (!StopRequested().load() && MonotonicNowNs() < end_ns) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const bool by_signal = StopRequested().load();
  if (markers) markers->Stop();
  server.Stop();
  if (view) {
    const ViewStats vs = view->stats();
    std::printf("view: %llu clients, %llu frames sent, %llu dropped for slow clients, %.1f MB\n",
                static_cast<unsigned long long>(vs.clients_total),
                static_cast<unsigned long long>(vs.frames_sent),
                static_cast<unsigned long long>(vs.frames_dropped),
                static_cast<double>(vs.bytes_sent) / 1e6);
    view.reset();
  }

  // Final statistics: the realtime outcome, the whole run's lines and the JSON.
  const std::unique_ptr<ServerReport> report = server.Report();
  if (!report->realtime) {
    spdlog::warn("serve: the haptic thread ran WITHOUT SCHED_FIFO ({}): stats say realtime false",
                 report->haptic_realtime_summary);
  }
  if (dds_ptr != nullptr) dds_ptr->PublishStatus(StatusOf(*report, server_id));
  std::printf("felt serve: stopped %s\n", by_signal ? "by signal" : "after the duration");
  std::printf("final: %s\n",
              FormatMonitorLine(report->haptic, nullptr, report->sim, nullptr).c_str());
  std::printf("final: %s\n", Server::FormatCounters(*report).c_str());
  std::printf("final: realtime %s (haptic: %s; sim: %s)\n", report->realtime ? "true" : "false",
              report->haptic_realtime_summary.c_str(), report->sim_realtime_summary.c_str());
  const std::string json = Server::ReportJson(*report);
  if (!args.stats_json.empty()) {
    WriteOptionFile("--stats-json", args.stats_json, json + "\n");
  }
  std::fflush(stdout);
  dds.reset();
  spdlog::default_logger()->flush();
  return 0;
}

CommandRun Setup(CLI::App& cmd) {
  auto args = std::make_shared<ServeArgs>();
  cmd.add_option("--scene", args->scene, "scene file (TOML)")->required();
  cmd.add_option("--duration", args->duration_s,
                 "run this many seconds (default: until SIGINT/SIGTERM; with --trace, the trace)");
  cmd.add_option("--stats-json", args->stats_json, "write the final statistics as JSON here");
  cmd.add_option("--trace", args->trace,
                 "replay this felt-trace in-process to every device instead of DDS input");
  cmd.add_option("--domain", args->domain, "DDS domain id (default: [transport] domain, else 0)")
      ->check(CLI::Range(0, 230));
  cmd.add_option("--dds-config", args->dds_config,
                 "Cyclone DDS configuration file (default: [transport] dds_config, else "
                 "CYCLONEDDS_URI, else loopback)");
  cmd.add_option("--security", args->security,
                 "DDS Security directory from `felt security init` (default: [transport] security, "
                 "else none)");
  cmd.add_option("--identity", args->identity,
                 "identity in the security directory (default: [transport] identity, else server)");
  cmd.add_option("--view", args->view_port,
                 "serve the live 3-D view on this TCP port (http://127.0.0.1:PORT/; docs/view.md)");
  cmd.add_option("--view-bind", args->view_bind,
                 "address the view listens on (default 127.0.0.1; 0.0.0.0 exposes it on the LAN)");
  cmd.add_flag("--no-realtime", args->no_realtime,
               "normal scheduling: no SCHED_FIFO, spin, pinning or mlockall");
  return [args]() -> int { return Serve(*args); };
}

const bool kRegistered = RegisterCommand(
    {"", "serve", "run the real-time server: 60 Hz cloth, 1 kHz haptic loop, devices over DDS",
     Setup});

}  // namespace
}  // namespace felt::app::cmd_serve
