// `felt bench mcap [--minutes M | --seconds S] [--json FILE] [--mcap FILE] [--keep]`: the MCAP
// recorder's endurance (issue 24 target: it keeps up with 1 kHz pointer and force plus status for
// 10 minutes with zero drops, never blocks the loops, and the file replays with every sample in
// order). A feeding thread plays the DDS thread's part on absolute 1 ms deadlines: each tick
// offers a pointer sample and a force to transport::McapSink (the queue and writer thread behind
// `felt record --out FILE.mcap`), and a status every 1000 ticks; then the file is read back as a
// trace (recordings/mcap_trace.h) and every sample is checked in order. Writes the markdown table
// next to the JSON (FILE with .md).
#include <spdlog/fmt/fmt.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "app/command.h"
#include "app/command_util.h"
#include "base/json.h"
#include "base/report.h"
#include "recordings/mcap.h"
#include "recordings/mcap_trace.h"
#include "transport/mcap_recorder.h"

namespace felt::bench::bench_mcap {
namespace {

struct Args {
  double minutes = 0.0;
  double seconds = 0.0;
  std::string json;
  std::string mcap = "/tmp/felt_bench_mcap.mcap";
  bool keep = false;
};

int64_t BenchMcapNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

int Run(const Args& args) {
  const double seconds = args.minutes > 0.0   ? args.minutes * 60.0
                         : args.seconds > 0.0 ? args.seconds
                                              : 10.0;
  if (!(seconds >= 0.01)) throw std::invalid_argument("--seconds/--minutes must be > 0");
  const report::MachineInfo machine = report::ReadMachineInfo();
  const auto ticks = static_cast<int64_t>(seconds * 1000.0);
  std::string command = args.minutes > 0.0
                            ? fmt::format("felt bench mcap --minutes {:g}", args.minutes)
                            : fmt::format("felt bench mcap --seconds {:g}", seconds);
  if (!args.json.empty()) command += " --json " + args.json;

  // Feed: on absolute 1 ms deadlines, a pointer sample and a force per tick, a status per second.
  std::vector<double> offer_ns;  // cost of the producer's calls per tick [ns]
  std::vector<double> late_us;   // the feeding loop's lateness per tick [us]
  offer_ns.reserve(static_cast<size_t>(ticks));
  late_us.reserve(static_cast<size_t>(ticks));
  auto sink = std::make_unique<transport::McapSink>(args.mcap, "touch");
  std::printf("felt bench mcap: %.0f s of 1 kHz pointer + 1 kHz force + 1 Hz status into %s\n",
              seconds, args.mcap.c_str());
  std::fflush(stdout);
  const double wall_start_ms = report::WallMs();
  int64_t deadline = BenchMcapNowNs();
  for (int64_t i = 0; i < ticks; ++i) {
    deadline += 1'000'000;
    std::this_thread::sleep_until(
        std::chrono::steady_clock::time_point(std::chrono::nanoseconds(deadline)));
    const int64_t woke = BenchMcapNowNs();
    late_us.push_back(static_cast<double>(woke - deadline) / 1e3);
    transport::PointerSampleView p;
    p.seq = static_cast<uint64_t>(i + 1);
    p.device_time_ns = 1'000'000'000 + i * 1'000'000;
    p.position_m_D = {0.05 * std::sin(i * 1e-3), 0.001 * static_cast<double>(i % 1000), 0.01};
    p.velocity_m_per_s_D = {0.05 * std::cos(i * 1e-3), 1.0, 0};
    p.receive_time_ns = woke;
    transport::ForceCommandView f;
    f.seq = p.seq;
    f.answers_seq = p.seq;
    f.answers_device_time_ns = p.device_time_ns;
    f.force_N_D = {0.1, -0.2, 0.3};
    f.receive_time_ns = woke;
    const int64_t t0 = BenchMcapNowNs();
    sink->OfferPointer(p);
    sink->OfferForce(f);
    offer_ns.push_back(static_cast<double>(BenchMcapNowNs() - t0));
    if (i % 1000 == 0) {
      transport::ServerStatusView s;
      s.server_id = "bench";
      s.wall_time_ns = 1'700'000'000'000'000'000 + i * 1'000'000;
      s.haptic_ticks = static_cast<uint64_t>(i);
      sink->OfferStatus(s);
    }
  }
  const double feed_ms = report::WallMs() - wall_start_ms;
  const double close_start_ms = report::WallMs();
  sink->Close();
  const double close_ms = report::WallMs() - close_start_ms;
  const transport::McapSinkStats st = sink->Stats();

  // Read back: every sample, in order, with the positions offered.
  const double read_start_ms = report::WallMs();
  const Trace trace = ReadMcapTrace(args.mcap);
  const double read_ms = report::WallMs() - read_start_ms;
  int64_t out_of_place = 0;
  for (size_t k = 0; k < trace.samples.size(); ++k) {
    const double want_t = static_cast<double>(static_cast<int64_t>(k) * 1'000'000) / 1e9;
    const double want_x = 0.05 * std::sin(static_cast<double>(k) * 1e-3);
    if (trace.samples[k].t_s != want_t || trace.samples[k].p_D.x() != want_x) ++out_of_place;
  }
  const bool replay_ok = static_cast<int64_t>(trace.samples.size()) == ticks && out_of_place == 0;
  const uint64_t bytes = std::filesystem::file_size(args.mcap);
  if (!args.keep) std::filesystem::remove(args.mcap);
  const std::string load_end = report::LoadAverage();

  // The table.
  using report::Fixed;
  using report::Sig;
  const std::vector<std::vector<std::string>> rows = {
      {"duration fed [s]", Fixed(feed_ms / 1e3, 1)},
      {"pointer samples offered / written", fmt::format("{} / {}", ticks, st.pointers_written)},
      {"forces offered / written", fmt::format("{} / {}", ticks, st.forces_written)},
      {"statuses written", std::to_string(st.statuses_written)},
      {"queue drops", std::to_string(st.queue_drops)},
      {"most samples waiting in the queue (of 16384)", std::to_string(st.max_queue_depth)},
      {"producer cost per tick (2 offers) p50 / p99 / max [ns]",
       Sig(report::Percentile(offer_ns, 50)) + " / " + Sig(report::Percentile(offer_ns, 99)) +
           " / " + Sig(report::Percentile(offer_ns, 100))},
      {"feeding loop lateness p50 / p99 / max [us]",
       Sig(report::Percentile(late_us, 50)) + " / " + Sig(report::Percentile(late_us, 99)) + " / " +
           Sig(report::Percentile(late_us, 100))},
      {"file size [MB]", Fixed(static_cast<double>(bytes) / 1e6, 1)},
      {"chunks", std::to_string(st.chunks)},
      {"close (last chunk + summary) [ms]", Fixed(close_ms, 1)},
      {"read back as a trace [ms]", Fixed(read_ms, 0)},
      {"samples read back / out of place",
       fmt::format("{} / {}", trace.samples.size(), out_of_place)},
      {"verdict",
       st.queue_drops == 0 && replay_ok ? "zero drops, every sample in order" : "FAILED"},
  };
  std::string md =
      report::ReportHeader("felt bench mcap: MCAP recorder endurance", command, machine, load_end);
  md +=
      "\nThreads: the feeding thread (the DDS thread's part: two queue offers per 1 ms tick, a "
      "status per second) and the sink's writer thread (CDR, MCAP chunks, file). Lateness and "
      "producer-cost maxima are the machine's scheduling under its load (see the load "
      "averages), not waits: the producer never waits on the queue.\n\n";
  md += report::MarkdownTable({"quantity", "value"}, {false, true}, rows);
  std::printf("%s", md.c_str());
  if (!args.json.empty()) {
    Json j{{"command", command},
           {"seconds", seconds},
           {"ticks", ticks},
           {"pointers_written", st.pointers_written},
           {"forces_written", st.forces_written},
           {"statuses_written", st.statuses_written},
           {"queue_drops", st.queue_drops},
           {"max_queue_depth", st.max_queue_depth},
           {"offer_ns",
            {{"p50", report::Percentile(offer_ns, 50)},
             {"p99", report::Percentile(offer_ns, 99)},
             {"max", report::Percentile(offer_ns, 100)}}},
           {"feed_lateness_us",
            {{"p50", report::Percentile(late_us, 50)},
             {"p99", report::Percentile(late_us, 99)},
             {"max", report::Percentile(late_us, 100)}}},
           {"file_bytes", bytes},
           {"chunks", st.chunks},
           {"close_ms", close_ms},
           {"read_back_ms", read_ms},
           {"samples_read_back", trace.samples.size()},
           {"out_of_place", out_of_place},
           {"ok", st.queue_drops == 0 && replay_ok}};
    report::AppendMachineJson(machine, load_end, &j);
    app::WriteOptionFile("--json", args.json, JsonText(j));
    std::filesystem::path md_path(args.json);
    md_path.replace_extension(".md");
    report::WriteTextFile(md_path.string(), md);
  }
  return st.queue_drops == 0 && replay_ok ? 0 : 3;
}

app::CommandRun Setup(CLI::App& cmd) {
  auto args = std::make_shared<Args>();
  auto* minutes = cmd.add_option("--minutes", args->minutes, "minutes to feed (issue 24: 10)");
  cmd.add_option("--seconds", args->seconds, "seconds to feed (default 10)")->excludes(minutes);
  cmd.add_option("--json", args->json, "write the results as JSON here (and FILE.md beside it)");
  cmd.add_option("--mcap", args->mcap, "the MCAP file written (default /tmp/felt_bench_mcap.mcap)");
  cmd.add_flag("--keep", args->keep, "keep the MCAP file");
  return [args]() -> int { return Run(*args); };
}

const bool kRegistered = app::RegisterCommand(
    {"bench", "mcap", "MCAP recorder endurance: 1 kHz pointer + force + 1 Hz status, drops, replay",
     Setup});

}  // namespace
}  // namespace felt::bench::bench_mcap
