// `felt bench view [--seconds S] [--rounds N] [--grids LIST] [--md FILE] [--csv FILE]`: what one
// connected viewer costs the loops (issue 25). For each cloth grid (the default curtain resized,
// bench_util.h), one server run with its real threads and a pointer pressing and stroking the
// cloth from a feeder thread; phases of S seconds alternate with no viewer and with one viewer (a
// WebSocket client in this process that reads every frame as a browser does, without drawing),
// N rounds. Per phase: haptic lateness and sim frame time percentiles over the phase (windows of
// the server's own statistics), and the bytes per second the viewer received.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <spdlog/fmt/fmt.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "app/command.h"
#include "app/command_util.h"
#include "bench/bench_util.h"
#include "haptic_loop/pointer_source.h"
#include "rt/clock.h"
#include "scene/scene_file.h"
#include "server/server.h"
#include "server/server_spec.h"
#include "view/view_server.h"

namespace felt::bench::bench_view {
namespace {

struct Args {
  std::string scene = "scenes/curtain.toml";
  double seconds = 10.0;
  int rounds = 2;
  std::string grids = "64,128";
  std::string md_path;
  std::string csv_path;
};

// A viewer without a screen: connects, upgrades to a WebSocket and reads everything until told
// to stop, counting the bytes (RFC 6455 handshake; the frames are not parsed).
class ReadingViewer {
 public:
  explicit ReadingViewer(uint16_t port) {
    fd_ = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(port);
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (fd_ < 0 || connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0) {
      throw std::runtime_error("bench view: cannot connect to the view");
    }
    timeval tv{0, 200'000};
    setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv));
    const std::string request =
        "GET /ws HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n";
    if (send(fd_, request.data(), request.size(), MSG_NOSIGNAL) !=
        static_cast<ssize_t>(request.size())) {
      throw std::runtime_error("bench view: cannot send the upgrade request");
    }
    thread_ = std::thread([this] {
      std::vector<char> buffer(1 << 16);
      while (!stop_.load()) {
        const ssize_t n = recv(fd_, buffer.data(), buffer.size(), 0);
        if (n > 0) bytes_.fetch_add(static_cast<uint64_t>(n));
        if (n == 0) break;
      }
    });
  }
  ~ReadingViewer() {
    stop_.store(true);
    thread_.join();
    close(fd_);
  }
  uint64_t bytes() const { return bytes_.load(); }

 private:
  int fd_ = -1;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> bytes_{0};
  std::thread thread_;
};

struct PhaseRow {
  int grid = 0;
  int round = 0;
  bool viewer = false;
  LoopStatsSnapshot haptic;
  LoopStatsSnapshot sim;
  double seconds = 0;
  double viewer_bytes_per_s = 0;
  double viewer_frames_per_s = 0;
};

double Us(int64_t ns) { return static_cast<double>(ns) * 1e-3; }
double Ms(int64_t ns) { return static_cast<double>(ns) * 1e-6; }

std::vector<PhaseRow> RunGrid(const Args& args, int grid) {
  ServerSpec spec = ParseServerSpec(LoadSceneDocument(args.scene));
  spec.sim = ResizedCurtain(args.scene, grid);
  spec.sim.integration = ParseServerSpec(LoadSceneDocument(args.scene)).sim.integration;
  const auto devices = static_cast<uint32_t>(spec.devices.size());
  LatestPointerSource source(devices);
  CapturingForceSink sink(devices);
  ServerOptions options;
  options.monitor_log = false;
  auto server = std::make_unique<Server>(spec, &source, &sink, options);
  ViewOptions view_options;
  auto view = std::make_unique<ViewServer>(server.get(), view_options);
  const size_t frame_bytes = ViewFrameBytes(server->model().num_particles(), devices);
  server->Start();
  // The hand: presses the middle 12 mm deep in the device (36 mm in the world) every 4 s while
  // stroking +-20 mm sideways every 3 s, sampled at ~1 kHz.
  std::atomic<bool> stop_feed{false};
  std::thread feeder([&] {
    const int64_t t0 = MonotonicNowNs();
    uint64_t seq = 0;
    while (!stop_feed.load()) {
      const int64_t now = MonotonicNowNs();
      const double t = static_cast<double>(now - t0) * 1e-9;
      PointerInput in;
      in.seq = ++seq;
      in.device_time_ns = now;
      in.receive_time_ns = now;
      in.p_D_m = Vec3(0.020 * std::sin(2 * std::numbers::pi * t / 3.0), 0.0,
                      0.004 - 0.016 * (0.5 - 0.5 * std::cos(2 * std::numbers::pi * t / 4.0)));
      for (uint32_t d = 0; d < devices; ++d) source.Set(d, in);
      std::this_thread::sleep_for(std::chrono::microseconds(1000));
    }
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // ramp-in out of every window
  std::vector<PhaseRow> rows;
  for (int round = 1; round <= args.rounds && !app::StopRequested().load(); ++round) {
    for (const bool with_viewer : {false, true}) {
      std::unique_ptr<ReadingViewer> viewer;
      if (with_viewer) {
        viewer = std::make_unique<ReadingViewer>(view->port());
        std::this_thread::sleep_for(std::chrono::milliseconds(300));  // connected and reading
      }
      const std::unique_ptr<ServerReport> a = server->Report();
      const uint64_t bytes_a = viewer ? viewer->bytes() : 0;
      const uint64_t sent_a = view->stats().frames_sent;
      const int64_t wall_a = MonotonicNowNs();
      std::this_thread::sleep_for(
          std::chrono::milliseconds(static_cast<int64_t>(args.seconds * 1e3)));
      const std::unique_ptr<ServerReport> b = server->Report();
      const double seconds = static_cast<double>(MonotonicNowNs() - wall_a) * 1e-9;
      PhaseRow row;
      row.grid = grid;
      row.round = round;
      row.viewer = with_viewer;
      row.haptic = b->haptic.Minus(a->haptic);
      row.sim = b->sim.Minus(a->sim);
      row.seconds = seconds;
      if (viewer) {
        row.viewer_bytes_per_s = static_cast<double>(viewer->bytes() - bytes_a) / seconds;
        row.viewer_frames_per_s = static_cast<double>(view->stats().frames_sent - sent_a) / seconds;
      }
      std::printf(
          "grid %d round %d %-9s lateness p99 %.1f us max %.1f us, sim frame p50 %.2f ms "
          "p99 %.2f ms, viewer %.2f MB/s (%.1f frames/s, frame %zu B)\n",
          grid, round, with_viewer ? "viewer" : "no viewer",
          Us(row.haptic.lateness.PercentileNs(0.99)), Us(row.haptic.lateness.max_ns),
          Ms(row.sim.compute.PercentileNs(0.5)), Ms(row.sim.compute.PercentileNs(0.99)),
          row.viewer_bytes_per_s / 1e6, row.viewer_frames_per_s, frame_bytes);
      std::fflush(stdout);
      rows.push_back(std::move(row));
    }
  }
  stop_feed.store(true);
  feeder.join();
  server->Stop();
  view.reset();
  return rows;
}

int Run(const Args& args, const std::string& command) {
  app::InstallStopHandlers();
  const MachineInfo machine = ReadMachineInfo();
  std::vector<int> grids;
  std::stringstream list(args.grids);
  for (std::string item; std::getline(list, item, ',');) grids.push_back(std::stoi(item));
  std::vector<PhaseRow> rows;
  for (int grid : grids) {
    for (PhaseRow& r : RunGrid(args, grid)) rows.push_back(std::move(r));
  }
  const std::vector<std::string> header = {"grid",
                                           "round",
                                           "viewer",
                                           "seconds",
                                           "haptic_ticks",
                                           "lateness_p50_us",
                                           "lateness_p99_us",
                                           "lateness_p999_us",
                                           "lateness_max_us",
                                           "overruns",
                                           "sim_frames",
                                           "sim_frame_p50_ms",
                                           "sim_frame_p99_ms",
                                           "sim_frame_max_ms",
                                           "viewer_MB_per_s",
                                           "viewer_frames_per_s"};
  std::vector<std::vector<std::string>> cells;
  for (const PhaseRow& r : rows) {
    cells.push_back({std::to_string(r.grid), std::to_string(r.round), r.viewer ? "yes" : "no",
                     Fixed(r.seconds, 1), std::to_string(r.haptic.ticks),
                     Fixed(Us(r.haptic.lateness.PercentileNs(0.5)), 1),
                     Fixed(Us(r.haptic.lateness.PercentileNs(0.99)), 1),
                     Fixed(Us(r.haptic.lateness.PercentileNs(0.999)), 1),
                     Fixed(Us(r.haptic.lateness.max_ns), 1), std::to_string(r.haptic.overruns),
                     std::to_string(r.sim.ticks), Fixed(Ms(r.sim.compute.PercentileNs(0.5)), 2),
                     Fixed(Ms(r.sim.compute.PercentileNs(0.99)), 2),
                     Fixed(Ms(r.sim.compute.max_ns), 2),
                     r.viewer ? Fixed(r.viewer_bytes_per_s / 1e6, 2) : "-",
                     r.viewer ? Fixed(r.viewer_frames_per_s, 1) : "-"});
  }
  std::string md = ReportHeader("`felt bench view`: the loops with one viewer against none",
                                command, machine, LoadAverage());
  md += "\n" + MarkdownTable(header, std::vector<bool>(header.size(), true), cells);
  std::printf("%s", md.c_str());
  if (!args.md_path.empty()) WriteTextFile(args.md_path, md);
  if (!args.csv_path.empty()) {
    // Each CSV row also names the command, the date and the host CPU.
    std::vector<std::string> csv_header = {"command", "date_utc", "cpu_model"};
    csv_header.insert(csv_header.end(), header.begin(), header.end());
    std::vector<std::vector<std::string>> csv_cells;
    for (const std::vector<std::string>& row : cells) {
      std::vector<std::string> r = {command, machine.date_utc, machine.cpu_model};
      r.insert(r.end(), row.begin(), row.end());
      csv_cells.push_back(std::move(r));
    }
    WriteTextFile(args.csv_path, CsvTable(csv_header, csv_cells));
  }
  return 0;
}

app::CommandRun Setup(CLI::App& cmd) {
  auto args = std::make_shared<Args>();
  cmd.add_option("--scene", args->scene,
                 "the curtain scene to resize (default scenes/curtain.toml)");
  cmd.add_option("--seconds", args->seconds, "seconds per phase (default 10)");
  cmd.add_option("--rounds", args->rounds, "rounds of (no viewer, viewer) per grid (default 2)");
  cmd.add_option("--grids", args->grids, "cloth grids, comma-separated (default 64,128)");
  cmd.add_option("--md", args->md_path, "write the Markdown report here");
  cmd.add_option("--csv", args->csv_path, "write the table as CSV here");
  return [args]() -> int {
    std::string line = "felt bench view";
    for (const std::string& a :
         {std::string("--seconds ") + fmt::format("{}", args->seconds),
          "--rounds " + std::to_string(args->rounds), "--grids " + args->grids}) {
      line += " " + a;
    }
    if (!args->md_path.empty()) line += " --md " + args->md_path;
    if (!args->csv_path.empty()) line += " --csv " + args->csv_path;
    return Run(*args, line);
  };
}

const bool kRegistered = felt::app::RegisterCommand(
    {"bench", "view", "haptic lateness and sim frame time with one viewer connected against none",
     Setup});

}  // namespace
}  // namespace felt::bench::bench_view
