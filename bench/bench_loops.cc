// `felt bench loops`: the lateness of a 1 kHz loop under each timing setting (issue 5, "Target").
// The empty loop measures the machine's own floor; the server half then runs the real server
// (server/server.h: its 1 kHz haptic thread with the fifo_spin setting, its 60 Hz sim thread)
// on the 64 x 64 curtain with a bundled trace replayed in-process (looped for the whole run), and
// both lateness distributions are printed side by side.
#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>
#include <sys/utsname.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "app/command.h"
#include "app/command_util.h"
#include "base/json.h"
#include "haptic_loop/pointer_source.h"
#include "recordings/trace.h"
#include "rt/histogram_plot.h"
#include "rt/loop_runner.h"
#include "rt/loop_stats.h"
#include "rt/realtime.h"
#include "scene/scene_file.h"
#include "server/server.h"
#include "server/server_spec.h"

namespace felt::bench::bench_loops {
namespace {

constexpr int64_t kPeriodNs = 1'000'000;  // 1 kHz
constexpr int64_t kLateNs = 1'000'000;    // "later than 1 ms"

/// One timing setting of the table.
struct TimingSetting {
  std::string name;  ///< table row and JSON key
  RealtimeSettings realtime;
};

/// What one run of a loop gave.
struct LoopResult {
  TimingSetting setting;
  RealtimeReport report;
  std::unique_ptr<LoopStatsSnapshot> stats = std::make_unique<LoopStatsSnapshot>();
};

struct Args {
  bool empty_only = false;
  bool server_setting_only = false;  // the empty loop under the server's setting only
  std::string scene = "scenes/curtain.toml";
  std::string trace = "recordings/poke_hold.trace";
  double minutes = 0.0;
  double seconds = 0.0;
  std::string json_path;
  std::string plot_dir;
  int priority = 80;
  int cpu = -1;
  int spin_us = 50;
  bool hold_dma_latency = false;
};

// The three settings of the notes' table: normal, SCHED_FIFO, SCHED_FIFO + sleep-then-spin.
std::vector<TimingSetting> Settings(const Args& args) {
  TimingSetting normal{"normal", {}};
  normal.realtime.cpu = args.cpu;
  TimingSetting fifo{"fifo", {}};
  fifo.realtime.fifo_priority = args.priority;
  fifo.realtime.cpu = args.cpu;
  fifo.realtime.lock_memory = true;
  fifo.realtime.timer_slack_ns = 1;
  TimingSetting spin = fifo;
  spin.name = "fifo_spin";
  spin.realtime.spin_us = args.spin_us;
  if (args.server_setting_only) return {spin};
  return {normal, fifo, spin};
}

/// Runs `body(const TickInfo&)` at 1 kHz for `duration_ns` under `setting` on a thread of its
/// own, logging a windowed summary every 10 s from this thread, and returns the statistics.
/// The empty loop passes an empty body; the server half passes the server's tick.
template <typename Body>
LoopResult RunTimedLoop(const TimingSetting& setting, int64_t duration_ns, Body&& body) {
  LoopResult result;
  result.setting = setting;
  auto stats = std::make_unique<LoopStats>(kPeriodNs);
  LoopRunOptions options;
  options.period_ns = kPeriodNs;
  options.duration_ns = duration_ns;
  options.realtime = setting.realtime;

  // The loop on its own thread; this thread is the monitor.
  std::atomic<bool> done{false};
  std::thread loop([&] {
    result.report = RunLoop(options, stats.get(), std::forward<Body>(body));
    done.store(true, std::memory_order_release);
  });
  auto previous = std::make_unique<LoopStatsSnapshot>();
  auto current = std::make_unique<LoopStatsSnapshot>();
  stats->Snapshot(previous.get());
  int64_t next_log = MonotonicNowNs() + 10'000'000'000;
  while (!done.load(std::memory_order_acquire)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    if (MonotonicNowNs() >= next_log) {
      stats->Snapshot(current.get());
      spdlog::info("{}: {}", setting.name, FormatHapticSummary(*current, previous.get()));
      std::swap(previous, current);
      next_log += 10'000'000'000;
    }
  }
  loop.join();
  stats->Snapshot(result.stats.get());
  return result;
}

std::string Us(int64_t ns) { return fmt::format("{:.1f}", static_cast<double>(ns) / 1e3); }

void PrintTable(const std::vector<LoopResult>& results, double seconds, const char* dma) {
  utsname name{};
  uname(&name);
  std::printf("felt bench loops: empty 1 kHz loop, %.0f s per setting, %ld CPUs, Linux %s\n",
              seconds, sysconf(_SC_NPROCESSORS_ONLN), name.release);
  std::printf("/dev/cpu_dma_latency held at 0: %s\n", dma);
  std::printf("lateness of wake-up in us (percentiles: bin upper edge, < 1 us or 0.8 %% above)\n");
  std::printf("%-10s %-8s %8s %8s %8s %8s %9s %8s %8s %8s\n", "setting", "realtime", "ticks", "p50",
              "p99", "p99.9", "max", "overruns", "skipped", ">1ms");
  for (const LoopResult& r : results) {
    const HistogramSnapshot& late = r.stats->lateness;
    std::printf("%-10s %-8s %8llu %8s %8s %8s %9s %8llu %8llu %8llu\n", r.setting.name.c_str(),
                r.report.fifo_granted ? "yes" : "no",
                static_cast<unsigned long long>(r.stats->ticks), Us(late.PercentileNs(0.5)).c_str(),
                Us(late.PercentileNs(0.99)).c_str(), Us(late.PercentileNs(0.999)).c_str(),
                Us(late.max_ns).c_str(), static_cast<unsigned long long>(r.stats->overruns),
                static_cast<unsigned long long>(r.stats->skipped_periods),
                static_cast<unsigned long long>(late.CountAtLeastNs(kLateNs)));
  }
  for (const LoopResult& r : results) {
    std::printf("%-10s %s\n", r.setting.name.c_str(), r.report.Summary().c_str());
  }
  std::fflush(stdout);
}

// One setting's JSON: ticks, overruns, skipped, >1 ms count, realtime steps, lateness.
Json SettingJson(const LoopResult& r) {
  return Json{{"realtime", r.report.fifo_granted},
              {"realtime_steps", r.report.Summary()},
              {"spin_us", r.setting.realtime.spin_us},
              {"ticks", r.stats->ticks},
              {"overruns", r.stats->overruns},
              {"skipped_periods", r.stats->skipped_periods},
              {"late_over_1ms", r.stats->lateness.CountAtLeastNs(kLateNs)},
              {"lateness_us", HistogramJson(r.stats->lateness, 1e3)},
              {"period_us", HistogramJson(r.stats->period, 1e3)}};
}

// {"seconds_per_setting", "empty": {<the fifo_spin row as lateness_us, overruns, ticks>,
// "settings": {normal, fifo, fifo_spin}}, "server": {lateness_us, overruns, ticks, ...}}.
std::string BenchJson(const std::vector<LoopResult>& results, double seconds, const char* dma,
                      const ServerReport* server) {
  const LoopResult& server_like = results.back();  // the setting the server runs with
  Json settings = Json::object();
  for (const LoopResult& r : results) settings[r.setting.name] = SettingJson(r);
  Json json{{"seconds_per_setting", seconds},
            {"period_us", static_cast<double>(kPeriodNs) / 1e3},
            {"cpu_dma_latency_held", dma},
            {"empty", Json{{"setting", server_like.setting.name},
                           {"realtime", server_like.report.fifo_granted},
                           {"ticks", server_like.stats->ticks},
                           {"overruns", server_like.stats->overruns},
                           {"skipped_periods", server_like.stats->skipped_periods},
                           {"lateness_us", HistogramJson(server_like.stats->lateness, 1e3)},
                           {"settings", settings}}}};
  if (server != nullptr) {
    json["server"] = Json{{"setting", server_like.setting.name},
                          {"cloth", "64 x 64 curtain"},
                          {"realtime", server->realtime},
                          {"ticks", server->haptic.ticks},
                          {"overruns", server->haptic.overruns},
                          {"skipped_periods", server->haptic.skipped_periods},
                          {"late_over_1ms", server->haptic.lateness.CountAtLeastNs(kLateNs)},
                          {"lateness_us", HistogramJson(server->haptic.lateness, 1e3)},
                          {"compute_us", HistogramJson(server->haptic.compute, 1e3)},
                          {"snapshot_age_us", HistogramJson(server->haptic.snapshot_age, 1e3)},
                          {"sim_frames", server->sim.ticks},
                          {"sim_overruns", server->sim.overruns},
                          {"sim_frame_ms", HistogramJson(server->sim.compute, 1e6)},
                          {"contacts", server->contacts},
                          {"peak_force_N", server->peak_force_N}};
  }
  return JsonText(json);
}

/// What the server half gave.
struct ServerResult {
  std::unique_ptr<ServerReport> report;
  double seconds = 0;
};

/// The server on the 64 x 64 curtain (the scene's cloth resampled to 64 x 64 particles over the
/// same 0.496 m) with `args.trace` looped to every device, under `setting`, for `duration_ns`.
ServerResult RunServer(const Args& args, const TimingSetting& setting, int64_t duration_ns) {
  ServerSpec spec = ParseServerSpec(LoadSceneDocument(args.scene));
  const double size_m = spec.sim.cloth.spacing_m * (spec.sim.cloth.width - 1);
  spec.sim.cloth.width = 64;
  spec.sim.cloth.height = 64;
  spec.sim.cloth.spacing_m = size_m / 63.0;
  spec.haptic.haptic_realtime = setting.realtime;
  spec.haptic.sim_realtime = setting.realtime;
  spec.haptic.sim_realtime.fifo_priority = std::max(1, setting.realtime.fifo_priority - 10);
  spec.haptic.sim_realtime.spin_us = 0;
  spec.haptic.monitor_period_s = 10.0;
  // The trace, repeated back to back for the whole run (preloaded: no I/O in the tick).
  const Trace trace = ReadTrace(args.trace);
  const double length_s = trace.samples.back().t_s - trace.samples.front().t_s + 1e-3;
  std::vector<TraceSample> looped;
  const double run_s = static_cast<double>(duration_ns) * 1e-9 + 1.0;
  for (int k = 0; static_cast<double>(k) * length_s < run_s; ++k) {
    for (TraceSample sample : trace.samples) {
      sample.t_s += static_cast<double>(k) * length_s;
      looped.push_back(sample);
    }
  }
  const auto devices = static_cast<uint32_t>(spec.devices.size());
  TracePointerSource source(std::vector<std::vector<TraceSample>>(devices, looped));
  CapturingForceSink sink(devices);
  ServerOptions options;
  Server server(std::move(spec), &source, &sink, options);
  spdlog::info("bench loops: server, {} x {} curtain, trace {}, setting {}, {:.0f} s",
               server.model().width, server.model().height, args.trace, setting.name,
               static_cast<double>(duration_ns) * 1e-9);
  ServerResult result;
  const int64_t start = MonotonicNowNs();
  server.Start();
  while (MonotonicNowNs() - start < duration_ns) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  server.Stop();
  result.seconds = static_cast<double>(MonotonicNowNs() - start) * 1e-9;
  result.report = server.Report();
  return result;
}

// The empty loop's fifo_spin row and the server next to each other.
void PrintSideBySide(const LoopResult& empty, const ServerResult& server) {
  const HistogramSnapshot& a = empty.stats->lateness;
  const HistogramSnapshot& b = server.report->haptic.lateness;
  std::printf("\nhaptic lateness, us: empty loop vs server (64 x 64 curtain, trace), setting %s\n",
              empty.setting.name.c_str());
  std::printf("%-10s %12s %12s\n", "", "empty", "server");
  std::printf("%-10s %12llu %12llu\n", "ticks", static_cast<unsigned long long>(empty.stats->ticks),
              static_cast<unsigned long long>(server.report->haptic.ticks));
  std::printf("%-10s %12s %12s\n", "realtime", empty.report.fifo_granted ? "yes" : "no",
              server.report->realtime ? "yes" : "no");
  const double qs[] = {0.5, 0.99, 0.999};
  const char* names[] = {"p50", "p99", "p99.9"};
  for (int i = 0; i < 3; ++i) {
    std::printf("%-10s %12s %12s\n", names[i], Us(a.PercentileNs(qs[i])).c_str(),
                Us(b.PercentileNs(qs[i])).c_str());
  }
  std::printf("%-10s %12s %12s\n", "max", Us(a.max_ns).c_str(), Us(b.max_ns).c_str());
  std::printf("%-10s %12llu %12llu\n", "overruns",
              static_cast<unsigned long long>(empty.stats->overruns),
              static_cast<unsigned long long>(server.report->haptic.overruns));
  std::printf("%-10s %12llu %12llu\n", ">1ms",
              static_cast<unsigned long long>(a.CountAtLeastNs(kLateNs)),
              static_cast<unsigned long long>(b.CountAtLeastNs(kLateNs)));
  const HistogramSnapshot& frame = server.report->sim.compute;
  std::printf(
      "server: compute p50 %s us p99 %s us; sim frame p50 %.2f ms p99 %.2f ms max %.2f ms, "
      "%llu frames, %llu overruns; contacts %llu, peak force %.2f N\n",
      Us(server.report->haptic.compute.PercentileNs(0.5)).c_str(),
      Us(server.report->haptic.compute.PercentileNs(0.99)).c_str(),
      static_cast<double>(frame.PercentileNs(0.5)) / 1e6,
      static_cast<double>(frame.PercentileNs(0.99)) / 1e6, static_cast<double>(frame.max_ns) / 1e6,
      static_cast<unsigned long long>(server.report->sim.ticks),
      static_cast<unsigned long long>(server.report->sim.overruns),
      static_cast<unsigned long long>(server.report->contacts), server.report->peak_force_N);
  std::printf("server realtime: haptic %s; sim %s\n",
              server.report->haptic_realtime_summary.c_str(),
              server.report->sim_realtime_summary.c_str());
  std::fflush(stdout);
}

app::CommandRun Setup(CLI::App& cmd) {
  auto args = std::make_shared<Args>();
  cmd.add_flag("--empty-only", args->empty_only, "run only the empty loop");
  cmd.add_flag("--server-setting-only", args->server_setting_only,
               "run the empty loop only under the server's setting (fifo_spin), not also under "
               "normal and fifo: a 10-minute comparison then takes 20 minutes, not 40");
  cmd.add_option("--scene", args->scene, "scene of the server half (default scenes/curtain.toml)");
  cmd.add_option("--trace", args->trace,
                 "trace replayed (looped) in the server half (default recordings/poke_hold.trace)");
  auto* minutes = cmd.add_option("--minutes", args->minutes, "minutes per setting");
  cmd.add_option("--seconds", args->seconds, "seconds per setting (default 30)")->excludes(minutes);
  cmd.add_option("--json", args->json_path, "write the results as JSON to this file");
  cmd.add_option("--plot", args->plot_dir,
                 "draw every setting's lateness histogram into DIR/loops_lateness.png (gnuplot)");
  cmd.add_option("--priority", args->priority, "SCHED_FIFO priority (default 80)")
      ->check(CLI::Range(1, 99));
  cmd.add_option("--cpu", args->cpu, "pin the loop to this CPU (default: no pinning)");
  cmd.add_option("--spin-us", args->spin_us, "spin before each deadline, us (default 50)")
      ->check(CLI::Range(1, 999));
  cmd.add_flag("--hold-dma-latency", args->hold_dma_latency,
               "hold /dev/cpu_dma_latency at 0 during the runs");
  return [args]() -> int {
    const double seconds = args->minutes > 0.0   ? args->minutes * 60.0
                           : args->seconds > 0.0 ? args->seconds
                                                 : 30.0;
    if (!(seconds >= 0.01)) throw std::invalid_argument("--seconds/--minutes must be > 0");
    const auto duration_ns = static_cast<int64_t>(seconds * 1e9);

    // Optional: keep idle cores out of deep C-states for the whole benchmark.
    std::unique_ptr<CpuDmaLatencyHold> dma;
    if (args->hold_dma_latency) dma = std::make_unique<CpuDmaLatencyHold>();

    std::vector<LoopResult> results;
    for (const TimingSetting& setting : Settings(*args)) {
      spdlog::info("bench loops: empty loop, setting {}, {:.0f} s", setting.name, seconds);
      results.push_back(RunTimedLoop(setting, duration_ns, [](const TickInfo&) {}));
    }
    const char* dma_text = dma == nullptr ? "not requested" : dma->held() ? "yes" : "refused";
    PrintTable(results, seconds, dma_text);
    ServerResult server;
    if (!args->empty_only) {
      server = RunServer(*args, results.back().setting, duration_ns);
      PrintSideBySide(results.back(), server);
    }
    if (!args->plot_dir.empty()) {
      std::vector<PlotSeries> series;
      for (const LoopResult& r : results) {
        series.push_back(
            PlotSeries{"empty loop, " + r.setting.name, PlotBinsOf(r.stats->lateness, 1e3)});
      }
      if (server.report != nullptr) {
        series.push_back(PlotSeries{"server haptic loop, " + results.back().setting.name,
                                    PlotBinsOf(server.report->haptic.lateness, 1e3)});
      }
      WriteHistogramPlot(args->plot_dir, "loops_lateness", series,
                         fmt::format("felt bench loops, {:.0f} s per setting: 1 kHz wake-up "
                                     "lateness",
                                     seconds),
                         "lateness: wake-up minus deadline [us]");
    }
    if (!args->json_path.empty()) {
      app::WriteOptionFile("--json", args->json_path,
                           BenchJson(results, seconds, dma_text, server.report.get()));
    }
    return 0;
  };
}

const bool kRegistered = felt::app::RegisterCommand(
    {"bench", "loops", "lateness of the 1 kHz loop: empty (machine floor) and server", Setup});

}  // namespace
}  // namespace felt::bench::bench_loops
