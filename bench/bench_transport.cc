// `felt bench transport`: the DDS transport's latency on loopback (docs/transport.md, issue 6).
// Now: --raw-only, the raw Cyclone round trip (an echo process answering each 1 kHz ping, with
// Felt's configuration, types and QoS) for both receive modes, plus the cost of each transport hop
// measured through ServerTransport/ClientTransport in this process. The end-to-end half (pointer
// sample -> force answering it, through the 1 kHz haptic loop) needs the server (issue 5); its
// JSON keys (e2e_us, sample_age_us) are reserved and written as null until then.

#include <fcntl.h>
#include <sched.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "app/command.h"
#include "transport/client_transport.h"
#include "transport/raw_roundtrip.h"
#include "transport/server_transport.h"

namespace felt::bench {
namespace {

using transport::ReceiveMode;

// p50/p99/p99.9/max of `values` (sorted in place), in their unit.
struct Percentiles {
  double p50 = NAN, p99 = NAN, p999 = NAN, max = NAN;
  size_t count = 0;
};

Percentiles Summarise(std::vector<double>* values) {
  Percentiles p;
  p.count = values->size();
  if (values->empty()) return p;
  std::sort(values->begin(), values->end());
  const auto at = [&](double q) {
    return (
        *values)[static_cast<size_t>(std::llround(q * static_cast<double>(values->size() - 1)))];
  };
  p.p50 = at(0.5);
  p.p99 = at(0.99);
  p.p999 = at(0.999);
  p.max = values->back();
  return p;
}

std::string Json(const Percentiles& p) {
  std::ostringstream out;
  out << "{\"p50\": " << p.p50 << ", \"p99\": " << p.p99 << ", \"p999\": " << p.p999
      << ", \"max\": " << p.max << ", \"count\": " << p.count << "}";
  return out.str();
}

std::string Json(const transport::HopSummary& h) {
  std::ostringstream out;
  out << "{\"p50\": " << h.p50_us << ", \"p99\": " << h.p99_us << ", \"p999\": " << h.p999_us
      << ", \"max\": " << h.max_us << ", \"mean\": " << h.mean_us << ", \"count\": " << h.count
      << "}";
  return out.str();
}

void Row(const char* name, const Percentiles& p) {
  std::printf("| %-44s | %8.1f | %8.1f | %8.1f | %8.1f | %7zu |\n", name, p.p50, p.p99, p.p999,
              p.max, p.count);
}

void Row(const char* name, const transport::HopSummary& h) {
  std::printf("| %-44s | %8.1f | %8.1f | %8.1f | %8.1f | %7llu |\n", name, h.p50_us, h.p99_us,
              h.p999_us, h.max_us, static_cast<unsigned long long>(h.count));
}

int64_t NowNs() { return transport::MonotonicNowNs(); }

void SleepUntil(int64_t deadline_ns) {
  const timespec ts{static_cast<time_t>(deadline_ns / 1000000000),
                    static_cast<long>(deadline_ns % 1000000000)};
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

// The hops of the server transport at 1 kHz: a client publishes, a stand-in haptic thread reads the
// slot and pushes a force each tick, the writer thread publishes it.
struct HopResult {
  Percentiles slot_read_us, push_us, sample_age_us;
  transport::TransportStats stats;
};

HopResult MeasureHops(const transport::DdsSettings& dds, ReceiveMode mode, double seconds) {
  const transport::TopicNames topics =
      transport::TopicNames::WithAffixes("", "/bench_hops_" + std::to_string(getpid()));
  transport::ServerTransportConfig config;
  config.dds = dds;
  config.topics = topics;
  config.devices.resize(1);
  config.devices[0].device_id = "bench-hand";
  config.receive_mode = mode;
  transport::ServerTransport server(config);
  transport::ClientTransportConfig client_config;
  client_config.dds = dds;
  client_config.topics = topics;
  client_config.device_ids = {"bench-hand"};
  client_config.subscribe_status = false;
  transport::ClientTransport client(client_config);
  if (!transport::WaitUntil([&] { return server.MatchedPointerWriters() > 0; },
                            std::chrono::seconds(10))) {
    throw std::runtime_error("bench transport: the in-process client was not matched");
  }
  const auto ticks = static_cast<size_t>(seconds * 1000.0);
  HopResult result;
  std::vector<double> read_us, push_us, age_us;
  read_us.reserve(ticks);
  push_us.reserve(ticks);
  age_us.reserve(ticks);
  std::atomic<bool> done{false};
  // The stand-in haptic thread: LatestPointer and PushForce, each timed, on 1 ms deadlines.
  std::thread haptic([&] {
    int64_t next_ns = NowNs() + 1000000;
    for (size_t i = 0; i < ticks; ++i) {
      SleepUntil(next_ns);
      next_ns += 1000000;
      transport::PointerSampleView sample;
      const int64_t t0 = NowNs();
      const bool have = server.LatestPointer(0, &sample);
      const int64_t t1 = NowNs();
      transport::ForceCommandView force;
      force.answers_seq = sample.seq;
      force.answers_device_time_ns = sample.device_time_ns;
      server.PushForce(force);
      const int64_t t2 = NowNs();
      read_us.push_back(static_cast<double>(t1 - t0) / 1e3);
      push_us.push_back(static_cast<double>(t2 - t1) / 1e3);
      if (have) age_us.push_back(static_cast<double>(t0 - sample.receive_time_ns) / 1e3);
    }
    done.store(true);
  });
  // The device: publish at 1 kHz, drain forces.
  int64_t next_ns = NowNs();
  for (uint64_t seq = 1; !done.load(); ++seq) {
    transport::PointerSampleView sample;
    sample.seq = seq;
    sample.device_time_ns = NowNs();
    client.PublishPointer(sample);
    transport::ForceCommandView force;
    while (client.TakeForce(0, &force)) {
    }
    next_ns += 1000000;
    SleepUntil(next_ns);
  }
  haptic.join();
  result.slot_read_us = Summarise(&read_us);
  result.push_us = Summarise(&push_us);
  result.sample_age_us = Summarise(&age_us);
  result.stats = server.Stats();
  return result;
}

struct Options {
  bool raw_only = false;
  double seconds = 10.0;
  std::string json;
  transport::DdsSettings dds;
  bool dma_latency = false;
  bool fifo = false;
};

int Run(const Options& options) {
  if (!options.raw_only) {
    throw std::invalid_argument(
        "bench transport: only --raw-only exists so far (the end-to-end half needs `felt serve`)");
  }
  // Optionally keep the CPUs out of deep idle states while measuring (notes: halves the p99).
  int dma_fd = -1;
  if (options.dma_latency) {
    dma_fd = open("/dev/cpu_dma_latency", O_WRONLY);
    const int32_t zero = 0;
    if (dma_fd < 0 || write(dma_fd, &zero, sizeof(zero)) != sizeof(zero)) {
      throw std::runtime_error("--cpu-dma-latency: cannot write /dev/cpu_dma_latency (root?)");
    }
  }
  // Optionally SCHED_FIFO for this thread; the echo process, Cyclone's threads and the bench's
  // threads are created afterwards and inherit it.
  if (options.fifo) {
    const sched_param param{10};
    if (sched_setscheduler(0, SCHED_FIFO, &param) != 0) {
      throw std::runtime_error("--fifo: SCHED_FIFO refused (root or CAP_SYS_NICE needed)");
    }
  }
  // The raw round trips first: they fork, which must happen before this process uses DDS.
  Percentiles raw[2];
  uint64_t sent[2] = {0, 0}, received[2] = {0, 0};
  const ReceiveMode modes[2] = {ReceiveMode::kListener, ReceiveMode::kWaitset};
  for (int m = 0; m < 2; ++m) {
    transport::RawRoundTripOptions raw_options;
    raw_options.dds = options.dds;
    raw_options.seconds = options.seconds;
    raw_options.echo_mode = modes[m];
    raw_options.topic_suffix = "/bench_raw_" + std::to_string(getpid()) + "_" + std::to_string(m);
    transport::RawRoundTripResult r = transport::RunRawRoundTrip(raw_options);
    raw[m] = Summarise(&r.roundtrip_us);
    sent[m] = r.pings_sent;
    received[m] = r.pongs_received;
  }
  // The transport's own hops, in this process, for both receive modes.
  HopResult hops[2];
  for (int m = 0; m < 2; ++m) hops[m] = MeasureHops(options.dds, modes[m], options.seconds);
  if (dma_fd >= 0) close(dma_fd);

  // The table.
  std::printf("felt bench transport --raw-only: %.0f s at 1 kHz, loopback, domain %u%s%s\n\n",
              options.seconds, options.dds.domain_id,
              options.dma_latency ? ", /dev/cpu_dma_latency held at 0" : "",
              options.fifo ? ", SCHED_FIFO 10" : "");
  std::printf("| %-44s | %8s | %8s | %8s | %8s | %7s |\n", "us", "p50", "p99", "p99.9", "max", "n");
  std::printf("|%s|---------:|---------:|---------:|---------:|--------:|\n",
              std::string(46, '-').c_str());
  Row("raw round trip, echo by listener", raw[0]);
  Row("raw round trip, echo by waitset thread", raw[1]);
  for (int m = 0; m < 2; ++m) {
    const std::string mode = m == 0 ? "listener" : "waitset";
    Row(("hop receive -> slot (" + mode + ")").c_str(), hops[m].stats.receive_hop);
    Row(("hop slot read, LatestPointer (" + mode + ")").c_str(), hops[m].slot_read_us);
    Row(("hop PushForce (" + mode + ")").c_str(), hops[m].push_us);
    Row(("hop queue -> dds_write done (" + mode + ")").c_str(), hops[m].stats.write_hop);
    Row(("sample age at a 1 kHz tick (" + mode + ")").c_str(), hops[m].sample_age_us);
  }
  std::printf(
      "\nraw pings sent/answered: listener %llu/%llu, waitset %llu/%llu\n",
      static_cast<unsigned long long>(sent[0]), static_cast<unsigned long long>(received[0]),
      static_cast<unsigned long long>(sent[1]), static_cast<unsigned long long>(received[1]));

  if (!options.json.empty()) {
    std::ofstream out(options.json);
    if (!out) throw std::runtime_error("--json " + options.json + ": cannot write the file");
    out << "{\n  \"raw_roundtrip_us\": " << Json(raw[0])
        << ",\n  \"raw_roundtrip_waitset_us\": " << Json(raw[1])
        << ",\n  \"raw_pings_sent\": " << sent[0] << ",\n  \"raw_pongs_received\": " << received[0]
        << ",\n  \"hops_us\": {\n    \"receive_to_slot\": " << Json(hops[0].stats.receive_hop)
        << ",\n    \"receive_to_slot_waitset\": " << Json(hops[1].stats.receive_hop)
        << ",\n    \"slot_read\": " << Json(hops[0].slot_read_us)
        << ",\n    \"push_force\": " << Json(hops[0].push_us)
        << ",\n    \"queue_to_dds_write\": " << Json(hops[0].stats.write_hop)
        << "\n  },\n  \"transport_sample_age_us\": " << Json(hops[0].sample_age_us)
        << ",\n  \"e2e_us\": null,\n  \"sample_age_us\": null,\n  \"samples_sent\": null,\n"
        << "  \"forces_received\": null,\n  \"seconds\": " << options.seconds
        << ",\n  \"cpu_dma_latency_zero\": " << (options.dma_latency ? "true" : "false")
        << ",\n  \"sched_fifo\": " << (options.fifo ? "true" : "false") << "\n}\n";
  }
  return 0;
}

const bool kRegistered = app::RegisterCommand({
    "bench",
    "transport",
    "DDS transport latency on loopback: raw Cyclone round trip and the transport's hops",
    [](CLI::App& cmd) -> app::CommandRun {
      auto options = std::make_shared<Options>();
      cmd.add_flag("--raw-only", options->raw_only,
                   "only the raw round trip and the hops (required until the server exists)");
      cmd.add_option("--seconds", options->seconds, "measured seconds per run (default 10)")
          ->check(CLI::PositiveNumber);
      cmd.add_option("--json", options->json, "write the results to this JSON file");
      cmd.add_option("--domain", options->dds.domain_id, "DDS domain id (default 0)")
          ->check(CLI::Range(0, 230));
      cmd.add_option("--dds-config", options->dds.config_file,
                     "Cyclone XML configuration file (default: embedded loopback, or "
                     "CYCLONEDDS_URI)");
      cmd.add_flag("--cpu-dma-latency", options->dma_latency,
                   "hold /dev/cpu_dma_latency at 0 while measuring (root)");
      cmd.add_flag("--fifo", options->fifo,
                   "run the bench, its echo process and Cyclone's threads under SCHED_FIFO 10");
      return [options] { return Run(*options); };
    },
});

}  // namespace
}  // namespace felt::bench
