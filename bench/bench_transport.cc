// `felt bench transport`: the DDS transport's latency on loopback (docs/transport.md, issue 6).
//  1. The raw Cyclone round trip (an echo process answering each 1 kHz ping, with Felt's
//     configuration, types and QoS) for both receive modes: the floor.
//  2. The cost of each transport hop, through ServerTransport/ClientTransport in this process.
//  3. End to end (skipped with --raw-only): the real server (server/server.h, the scene's
//     cloth and proxy, SCHED_FIFO where permitted) in this process behind the DDS transport, and a
//     device client in a second process (this program re-executed with --e2e-client) publishing a
//     trace at 1 kHz on absolute deadlines. Per pointer sample: e2e = reception of the first force
//     answering it (ForceCommand.answers_device_time_ns) - its publication, on the client; and
//     its age at the first haptic tick that reads it (tick time - transport receive time), on the
//     server. With the periodic tick most of e2e is that wait for the next 1 kHz tick; the run is
//     made twice, `[haptic] tick = "periodic"` then `"arrival"` (the default: the tick runs when
//     the sample arrives, the periodic deadline as fallback), and compared side by side.

#include <fcntl.h>
#include <sched.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "app/command.h"
#include "base/json.h"
#include "base/process.h"
#include "base/report.h"
#include "bench/bench_transport_security.h"
#include "haptic_loop/pointer_source.h"
#include "recordings/trace.h"
#include "rt/periodic_loop.h"
#include "rt/phase_lock.h"
#include "scene/scene_file.h"
#include "server/server.h"
#include "server/server_spec.h"
#include "server/transport_io.h"
#include "transport/client_transport.h"
#include "transport/raw_roundtrip.h"
#include "transport/ros2_client.h"
#include "transport/server_transport.h"

namespace felt::bench::bench_transport {
namespace {

using transport::ReceiveMode;

// p50/p99/p99.9/max of samples (nearest rank, report::Percentile), in their unit; NaN for none.
struct Percentiles {
  double p50 = NAN, p99 = NAN, p999 = NAN, max = NAN;
  size_t count = 0;
};

Percentiles Summarise(const std::vector<double>& values) {
  return Percentiles{report::Percentile(values, 50.0), report::Percentile(values, 99.0),
                     report::Percentile(values, 99.9), report::Percentile(values, 100.0),
                     values.size()};
}

Json ToJson(const Percentiles& p) {
  return Json{{"p50", p.p50}, {"p99", p.p99}, {"p999", p.p999}, {"max", p.max}, {"count", p.count}};
}

Json ToJson(const transport::HopSummary& h) {
  return Json{{"p50", h.p50_us}, {"p99", h.p99_us},   {"p999", h.p999_us},
              {"max", h.max_us}, {"mean", h.mean_us}, {"count", h.count}};
}

void Row(const char* name, const Percentiles& p) {
  std::printf("| %-44s | %8.1f | %8.1f | %8.1f | %8.1f | %7zu |\n", name, p.p50, p.p99, p.p999,
              p.max, p.count);
}

void Row(const char* name, const transport::HopSummary& h) {
  std::printf("| %-44s | %8.1f | %8.1f | %8.1f | %8.1f | %7llu |\n", name, h.p50_us, h.p99_us,
              h.p999_us, h.max_us, static_cast<unsigned long long>(h.count));
}

int64_t NowNs() { return MonotonicNowNs(); }

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
  result.slot_read_us = Summarise(read_us);
  result.push_us = Summarise(push_us);
  result.sample_age_us = Summarise(age_us);
  result.stats = server.Stats();
  return result;
}

// ---- End to end -------------------------------------------------------------------------------

// Wraps the server's PointerSource and records, for every new sample (a new seq), its age at the
// first haptic tick that reads it: tick time - transport receive time. Haptic thread only; the
// vector is reserved up front and never grows past its capacity (extra samples are counted).
class AgeRecordingSource final : public PointerSource {
 public:
  AgeRecordingSource(PointerSource* inner, size_t capacity) : inner_(inner) {
    age_us_.reserve(capacity);
    arrival_ns_.reserve(capacity);
  }
  bool Latest(uint32_t device_index, int64_t now_ns, PointerInput* out) override {
    if (!inner_->Latest(device_index, now_ns, out)) return false;
    if (out->seq != last_seq_) {
      last_seq_ = out->seq;
      if (recording_.load(std::memory_order_relaxed)) {
        if (age_us_.size() < age_us_.capacity()) {
          age_us_.push_back(static_cast<double>(now_ns - out->receive_time_ns) / 1e3);
          arrival_ns_.push_back(out->receive_time_ns);  // same capacity
        } else {
          ++overflow_;
        }
      }
    }
    return true;
  }
  /// The inner source's signal (the tick on arrival wakes on it).
  const ArrivalSignal* Arrivals(uint32_t device_index) const override {
    return inner_->Arrivals(device_index);
  }
  /// Starts or stops recording (any thread).
  void SetRecording(bool on) { recording_.store(on, std::memory_order_relaxed); }
  /// The ages, us. Only after the server stopped.
  std::vector<double>* ages() { return &age_us_; }
  /// The transport receive times of the same samples, CLOCK_MONOTONIC ns. After the stop.
  const std::vector<int64_t>& arrivals() const { return arrival_ns_; }

 private:
  PointerSource* inner_;
  uint64_t last_seq_ = 0;
  std::atomic<bool> recording_{false};
  std::vector<double> age_us_;
  std::vector<int64_t> arrival_ns_;
  uint64_t overflow_ = 0;
};

// What the e2e client process reports back (a small text file).
struct E2eClientResult {
  uint64_t samples_sent = 0;     // pointer samples published while measuring
  uint64_t forces_received = 0;  // forces taken while measuring (all, including repeats)
  uint64_t answered = 0;         // samples answered by at least one force
  std::vector<double> e2e_us;    // per answered sample, us
};

struct E2eClientArgs {
  std::string out;           // result file
  std::string topic_suffix;  // appended to the topic names
  std::string device_id;     // the scene's device
  std::string trace;         // positions to publish (device frame), looped
  bool ros2 = false;         // speak ROS 2 (RunRos2E2eClient): topic_suffix is the namespace
};

// The ROS 2 topics of the e2e run on the ROS 2 profile under namespace `ns` (CRTK's names).
transport::Ros2DeviceTopics BenchRos2Topics(const std::string& ns) {
  transport::Ros2DeviceTopics t;
  t.pose = ns + "/measured_cp";
  t.twist = "";  // velocity by finite difference, as a driver without measured_cv
  t.wrench = ns + "/servo_cf";
  return t;
}

// Writes what a device process measured to `path` for ReadE2eClientResult: one line of counts,
// then one end-to-end time per line [us]. Returns 0, or 3 (after a message naming `who`) when the
// file cannot be written.
int WriteE2eClientResult(const E2eClientResult& result, const std::string& path, const char* who) {
  std::ofstream out(path);
  out << result.samples_sent << " " << result.forces_received << " " << result.answered << "\n";
  out.precision(9);
  for (double v : result.e2e_us) out << v << "\n";
  if (!out) {
    std::fprintf(stderr, "%s: cannot write %s\n", who, path.c_str());
    return 3;
  }
  return 0;
}

// The device side, run in its own process: publishes the trace at 1 kHz on absolute deadlines and
// times each sample's first answer. Writes E2eClientResult to args.out.
int RunE2eClient(const transport::DdsSettings& dds, const E2eClientArgs& args, double seconds) {
  const Trace trace = ReadTrace(args.trace);
  transport::ClientTransportConfig config;
  config.dds = dds;
  config.topics = transport::TopicNames::WithAffixes("", args.topic_suffix);
  config.device_ids = {args.device_id};
  config.subscribe_status = false;
  transport::ClientTransport client(config);
  if (!transport::WaitUntil(
          [&] { return client.MatchedPointerReaders() > 0 && client.MatchedForceWriters() > 0; },
          std::chrono::seconds(20))) {
    std::fprintf(stderr, "bench transport e2e client: the server was not discovered in 20 s\n");
    return 3;
  }
  // Sample i is published at start + i * kClientPeriodNs; its publication time is its
  // device_time_ns. The period is 100 ppm short of 1 ms, as a device's own crystal would differ
  // from the server's clock: the phase between the two 1 kHz loops then sweeps a whole period every
  // 10 s, instead of staying wherever the two processes happened to start (which alone would
  // decide the wait for the next tick, anywhere from 0 to 1 ms, for the whole run).
  constexpr int64_t kClientPeriodNs = 999900;
  const auto warmup = static_cast<uint64_t>(500);
  const auto measured = static_cast<uint64_t>(seconds * 1000.0);
  const uint64_t total = warmup + measured;
  std::vector<int64_t> published_ns(total + 1, 0);
  std::vector<double> first_answer_us(total + 1, -1.0);
  std::atomic<bool> done{false};
  std::atomic<uint64_t> forces_measured{0};
  // The force reader: the first force answering each measured sample gives its e2e latency.
  std::thread reader([&] {
    transport::ForceCommandView force;
    while (!done.load()) {
      if (!client.WaitForce(0, std::chrono::milliseconds(5), &force)) continue;
      const uint64_t seq = force.answers_seq;
      if (seq <= warmup || seq > total) continue;
      forces_measured.fetch_add(1);
      if (first_answer_us[seq] < 0.0) {
        first_answer_us[seq] =
            static_cast<double>(force.receive_time_ns - force.answers_device_time_ns) / 1e3;
      }
    }
  });
  int64_t next_ns = NowNs() + kClientPeriodNs;
  for (uint64_t seq = 1; seq <= total; ++seq) {
    SleepUntil(next_ns);
    const TraceSample& s = trace.samples[(seq - 1) % trace.samples.size()];
    transport::PointerSampleView sample;
    sample.seq = seq;
    sample.position_m_D = {s.p_D.x(), s.p_D.y(), s.p_D.z()};
    sample.velocity_m_per_s_D = {s.v_D.x(), s.v_D.y(), s.v_D.z()};
    sample.buttons = s.buttons;
    sample.device_time_ns = NowNs();
    published_ns[seq] = sample.device_time_ns;
    client.PublishPointer(sample);
    next_ns += kClientPeriodNs;
  }
  // Let the last answers arrive (a few ticks), then stop the reader.
  SleepUntil(NowNs() + 50000000);
  done.store(true);
  reader.join();
  E2eClientResult result;
  result.samples_sent = measured;
  result.forces_received = forces_measured.load();
  for (uint64_t seq = warmup + 1; seq <= total; ++seq) {
    if (first_answer_us[seq] >= 0.0) result.e2e_us.push_back(first_answer_us[seq]);
  }
  result.answered = result.e2e_us.size();
  return WriteE2eClientResult(result, args.out, "bench transport e2e client");
}

// The device side on the ROS 2 profile, in its own process: a ROS 2 driver stand-in
// (transport/ros2_client.h) publishes the trace as PoseStamped at 1 kHz on the same absolute
// deadlines as RunE2eClient (100 ppm short of 1 ms), each stamped with its publication time, and
// reads WrenchStamped. A WrenchStamped carries no sequence number: the server echoes the stamp of
// the pose it answers, so a force's stamp names its pose, and e2e = reception of the first force
// with that stamp - the stamp. Writes E2eClientResult to args.out.
int RunRos2E2eClient(const transport::DdsSettings& dds, const E2eClientArgs& args, double seconds) {
  const Trace trace = ReadTrace(args.trace);
  const transport::Ros2DeviceTopics topics = BenchRos2Topics(args.topic_suffix);
  transport::Ros2Client client({dds, topics.pose, topics.wrench, "bench_base"});
  if (!transport::WaitUntil(
          [&] { return client.MatchedPoseReaders() > 0 && client.MatchedWrenchWriters() > 0; },
          std::chrono::seconds(20))) {
    std::fprintf(stderr,
                 "bench transport ros2 e2e client: the server was not discovered in 20 s\n");
    return 3;
  }
  constexpr int64_t kClientPeriodNs = 999900;  // as RunE2eClient
  const auto warmup = static_cast<uint64_t>(500);
  const auto measured = static_cast<uint64_t>(seconds * 1000.0);
  const uint64_t total = warmup + measured;
  std::vector<int64_t> published_ns(total + 1, 0);
  // Every force's (stamp, receive time), in arrival order; matched to the poses after the run.
  std::vector<std::pair<int64_t, int64_t>> received;
  received.reserve(3 * total + 1000);
  std::atomic<bool> done{false};
  std::thread reader([&] {
    transport::Ros2WrenchReceived wrench;
    while (!done.load()) {
      if (!client.WaitWrench(std::chrono::milliseconds(5), &wrench)) continue;
      if (received.size() < received.capacity()) {
        received.emplace_back(wrench.stamp_ns, wrench.receive_time_ns);
      }
    }
  });
  int64_t next_ns = NowNs() + kClientPeriodNs;
  for (uint64_t seq = 1; seq <= total; ++seq) {
    SleepUntil(next_ns);
    const TraceSample& s = trace.samples[(seq - 1) % trace.samples.size()];
    published_ns[seq] = NowNs();
    client.PublishPose(published_ns[seq], {s.p_D.x(), s.p_D.y(), s.p_D.z()});
    next_ns += kClientPeriodNs;
  }
  SleepUntil(NowNs() + 50000000);  // the last answers
  done.store(true);
  reader.join();
  // The first answer of each measured pose: its stamp is one of published_ns[warmup + 1 ..].
  E2eClientResult result;
  result.samples_sent = measured;
  const int64_t first_measured = published_ns[warmup + 1];
  std::vector<std::pair<int64_t, int64_t>> firsts;  // (stamp, first receive)
  for (const auto& [stamp, receive] : received) {
    if (stamp < first_measured) continue;
    ++result.forces_received;
    firsts.emplace_back(stamp, receive);
  }
  std::stable_sort(firsts.begin(), firsts.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  for (size_t i = 0; i < firsts.size(); ++i) {
    if (i > 0 && firsts[i].first == firsts[i - 1].first) continue;  // a repeat: not the first
    if (!std::binary_search(published_ns.begin() + static_cast<std::ptrdiff_t>(warmup + 1),
                            published_ns.end(), firsts[i].first)) {
      continue;  // not a stamp this client sent (cannot happen unless the echo is broken)
    }
    result.e2e_us.push_back(static_cast<double>(firsts[i].second - firsts[i].first) / 1e3);
  }
  result.answered = result.e2e_us.size();
  return WriteE2eClientResult(result, args.out, "bench transport ros2 e2e client");
}

E2eClientResult ReadE2eClientResult(const std::string& path) {
  std::ifstream in(path);
  E2eClientResult r;
  if (!(in >> r.samples_sent >> r.forces_received >> r.answered)) {
    throw std::runtime_error("bench transport: the e2e client's result " + path +
                             " is missing or malformed");
  }
  r.e2e_us.reserve(r.answered);
  double v = 0;
  while (in >> v) r.e2e_us.push_back(v);
  if (r.e2e_us.size() != r.answered) {
    throw std::runtime_error("bench transport: the e2e client's result " + path + " holds " +
                             std::to_string(r.e2e_us.size()) + " latencies, not " +
                             std::to_string(r.answered));
  }
  return r;
}

struct E2eResult {
  Percentiles e2e_us, sample_age_us;
  uint64_t samples_sent = 0, forces_received = 0, answered = 0;
  bool realtime = false;
  std::string scene_name;
  int32_t cloth_w = 0, cloth_h = 0;
  HapticTickTrigger tick = HapticTickTrigger::kArrival;  // the server's tick
  std::unique_ptr<LoopStatsSnapshot> haptic;  // the haptic loop's statistics over the run
  std::vector<int64_t> arrivals_ns;           // receive times of the samples the ticks read
};

// The server's device on the ROS 2 profile with BenchRos2Topics(ns).
void ConfigureRos2Device(const std::string& ns, transport::DeviceLimits* device) {
  device->profile = transport::TransportProfile::kRos2;
  device->ros2 = BenchRos2Topics(ns);
}

// The server in this process, the client in a child process (this program re-executed: fork+exec
// is safe although Cyclone's threads already run here).
E2eResult MeasureEndToEnd(
    const transport::DdsSettings& dds, const std::string& scene, const std::string& trace,
    double seconds, bool fifo, HapticTickTrigger tick,
    transport::TransportProfile profile = transport::TransportProfile::kFelt) {
  ServerSpec spec = ParseServerSpec(LoadSceneDocument(scene));
  if (spec.devices.empty())
    throw std::runtime_error("bench transport: " + scene + " has no device");
  spec.devices.resize(1);
  spec.haptic.tick_trigger = tick;
  spec.haptic.tick_device.clear();
  const bool ros2 = profile == transport::TransportProfile::kRos2;
  const std::string suffix = "/bench_e2e_" + std::to_string(getpid()) + "_" +
                             std::to_string(static_cast<int>(tick)) + (ros2 ? "_ros2" : "");
  transport::ServerTransportConfig config;
  config.dds = dds;
  config.topics = transport::TopicNames::WithAffixes("", suffix);
  config.devices.resize(1);
  config.devices[0].device_id = spec.devices[0].id;
  if (ros2) ConfigureRos2Device(suffix, &config.devices[0]);
  transport::ServerTransport server_transport(config);
  TransportPointerSource dds_source(&server_transport);
  AgeRecordingSource source(&dds_source, static_cast<size_t>(seconds * 1000.0) + 5000);
  TransportForceSink sink(&server_transport);
  ServerOptions server_options;
  server_options.apply_realtime = true;
  server_options.monitor_log = false;
  E2eResult result;
  result.scene_name = spec.scene_name;
  Server server(std::move(spec), &source, &sink, server_options);
  result.cloth_w = server.model().width;
  result.cloth_h = server.model().height;
  server.Start();

  // The client process.
  const std::string out = (std::filesystem::temp_directory_path() /
                           ("felt_bench_e2e_" + std::to_string(getpid()) + ".txt"))
                              .string();
  std::vector<std::string> argv_s = {"/proc/self/exe",
                                     "bench",
                                     "transport",
                                     "--e2e-client",
                                     out,
                                     "--e2e-suffix",
                                     suffix,
                                     "--e2e-device",
                                     config.devices[0].device_id,
                                     "--trace",
                                     trace,
                                     "--seconds",
                                     std::to_string(seconds),
                                     "--domain",
                                     std::to_string(dds.domain_id)};
  if (!dds.config_file.empty()) {
    argv_s.push_back("--dds-config");
    argv_s.push_back(dds.config_file);
  }
  if (fifo) argv_s.push_back("--fifo");
  if (ros2) argv_s.push_back("--e2e-ros2");
  Process client_process = Process::Spawn(argv_s);
  // Record sample ages while the client measures (it warms up for 0.5 s after discovery).
  source.SetRecording(true);
  const bool finished =
      client_process.Wait(std::chrono::milliseconds(static_cast<int64_t>((seconds + 60.0) * 1e3)));
  source.SetRecording(false);
  server.Stop();
  if (!finished) {
    client_process.Terminate(std::chrono::milliseconds(0));
    throw std::runtime_error("bench transport: the e2e client did not finish in time");
  }
  if (client_process.exit_code() != 0) {
    throw std::runtime_error("bench transport: the e2e client failed (" + client_process.Outcome() +
                             ")");
  }
  E2eClientResult client = ReadE2eClientResult(out);
  std::filesystem::remove(out);
  const std::unique_ptr<ServerReport> report = server.Report();
  result.realtime = report->realtime;
  result.samples_sent = client.samples_sent;
  result.forces_received = client.forces_received;
  result.answered = client.answered;
  result.e2e_us = Summarise(client.e2e_us);
  result.sample_age_us = Summarise(*source.ages());
  result.tick = tick;
  result.haptic = std::make_unique<LoopStatsSnapshot>(report->haptic);
  result.arrivals_ns = source.arrivals();
  return result;
}

// ---- The haptic tick: periodic against on arrival (issue 23) ------------------------------------

// The end-to-end run once per tick mode, one after the other in the same process and setting.
struct TickModeRuns {
  E2eResult periodic;  // [haptic] tick = "periodic"
  E2eResult arrival;   // [haptic] tick = "arrival" (the default)
};

TickModeRuns MeasureTickModes(const transport::DdsSettings& dds, const std::string& scene,
                              const std::string& trace, double seconds, bool fifo) {
  TickModeRuns runs;
  runs.periodic = MeasureEndToEnd(dds, scene, trace, seconds, fifo, HapticTickTrigger::kPeriodic);
  runs.arrival = MeasureEndToEnd(dds, scene, trace, seconds, fifo, HapticTickTrigger::kArrival);
  return runs;
}

// p50/p99/p99.9/max in us of a loop histogram (bin upper edges, rt/loop_stats.h).
Percentiles HistogramPercentiles(const HistogramSnapshot& h) {
  return Percentiles{static_cast<double>(h.PercentileNs(0.5)) / 1e3,
                     static_cast<double>(h.PercentileNs(0.99)) / 1e3,
                     static_cast<double>(h.PercentileNs(0.999)) / 1e3,
                     static_cast<double>(h.max_ns) / 1e3, static_cast<size_t>(h.count)};
}

// One row per mode of the same quantity, then the arrival/periodic ratio of p50 and p99.
void TickModeRows(const char* name, const Percentiles& periodic, const Percentiles& arrival) {
  Row((std::string(name) + ", periodic tick").c_str(), periodic);
  Row((std::string(name) + ", tick on arrival").c_str(), arrival);
  std::printf("| %-44s | %7.2fx | %7.2fx |          |          |         |\n",
              (std::string(name) + ": arrival / periodic").c_str(), arrival.p50 / periodic.p50,
              arrival.p99 / periodic.p99);
}

void PrintTickModes(const TickModeRuns& runs) {
  const LoopStatsSnapshot& p = *runs.periodic.haptic;
  const LoopStatsSnapshot& a = *runs.arrival.haptic;
  std::printf("\nThe haptic tick, periodic against on arrival (same run, periodic first):\n\n");
  std::printf("| %-44s | %8s | %8s | %8s | %8s | %7s |\n", "us", "p50", "p99", "p99.9", "max", "n");
  std::printf("|%s|---------:|---------:|---------:|---------:|--------:|\n",
              std::string(46, '-').c_str());
  TickModeRows("end to end", runs.periodic.e2e_us, runs.arrival.e2e_us);
  TickModeRows("sample age at the tick", runs.periodic.sample_age_us, runs.arrival.sample_age_us);
  TickModeRows("haptic lateness", HistogramPercentiles(p.lateness),
               HistogramPercentiles(a.lateness));
  TickModeRows("haptic period", HistogramPercentiles(p.period), HistogramPercentiles(a.period));
  Row("arrival -> tick wake-up, tick on arrival", HistogramPercentiles(a.arrival_wake));
  std::printf(
      "\nhaptic ticks: periodic %llu (overruns %llu, skipped %llu); on arrival %llu, of which %llu "
      "woken by a sample (overruns %llu, skipped %llu)\n",
      static_cast<unsigned long long>(p.ticks), static_cast<unsigned long long>(p.overruns),
      static_cast<unsigned long long>(p.skipped_periods), static_cast<unsigned long long>(a.ticks),
      static_cast<unsigned long long>(a.arrival_ticks), static_cast<unsigned long long>(a.overruns),
      static_cast<unsigned long long>(a.skipped_periods));
  std::printf("samples sent/answered: periodic %llu/%llu, on arrival %llu/%llu\n",
              static_cast<unsigned long long>(runs.periodic.samples_sent),
              static_cast<unsigned long long>(runs.periodic.answered),
              static_cast<unsigned long long>(runs.arrival.samples_sent),
              static_cast<unsigned long long>(runs.arrival.answered));
}

Json TickModeJson(const E2eResult& r) {
  const LoopStatsSnapshot& h = *r.haptic;
  return Json{{"e2e_us", ToJson(r.e2e_us)},
              {"sample_age_us", ToJson(r.sample_age_us)},
              {"haptic_lateness_us", ToJson(HistogramPercentiles(h.lateness))},
              {"haptic_period_us", ToJson(HistogramPercentiles(h.period))},
              {"arrival_wake_us", ToJson(HistogramPercentiles(h.arrival_wake))},
              {"haptic_ticks", h.ticks},
              {"arrival_ticks", h.arrival_ticks},
              {"overruns", h.overruns},
              {"skipped_periods", h.skipped_periods},
              {"samples_sent", r.samples_sent},
              {"samples_answered", r.answered},
              {"server_realtime", r.realtime}};
}

Json TickModesJson(const TickModeRuns& runs) {
  return Json{{"periodic", TickModeJson(runs.periodic)},
              {"arrival", TickModeJson(runs.arrival)},
              {"e2e_p50_ratio", runs.arrival.e2e_us.p50 / runs.periodic.e2e_us.p50},
              {"e2e_p99_ratio", runs.arrival.e2e_us.p99 / runs.periodic.e2e_us.p99}};
}

// ---- The phase-locked tick, simulated on the same arrivals (issue 23) ---------------------------

// Each rule's tick times over the slots of a 1 ms grid starting at `start_ns`, applied to the
// recorded `arrivals_ns`: per sample a tick read (the newest before the tick), its age at that
// tick, us. Ticks fall exactly at their planned times (no wake-up cost: the rules, not the
// machine). `tick_of(open, next)` gives slot (open, open + 1 ms]'s tick from the first arrival
// not yet read, index `next`.
template <typename TickOf>
std::vector<double> SimulatedAges(const std::vector<int64_t>& arrivals_ns, int64_t start_ns,
                                  TickOf&& tick_of) {
  constexpr int64_t kPeriodNs = 1'000'000;
  std::vector<double> ages;
  size_t next = 0;
  for (int64_t open = start_ns; next < arrivals_ns.size(); open += kPeriodNs) {
    const int64_t tick = tick_of(open, next);
    size_t read = next;
    while (read < arrivals_ns.size() && arrivals_ns[read] <= tick) ++read;
    if (read > next) ages.push_back(static_cast<double>(tick - arrivals_ns[read - 1]) / 1e3);
    next = read;
  }
  return ages;
}

struct SimulatedRule {
  std::string name;
  Percentiles age_us;
};

// The tick on arrival (ArrivalTickNs) and the phase-locked tick (PhaseLock, three margins, 20 us
// slew) on the arrivals of the tick-on-arrival run: the sample's age at the tick that reads it.
std::vector<SimulatedRule> SimulateTickRules(const std::vector<int64_t>& arrivals_ns) {
  std::vector<SimulatedRule> rules;
  if (arrivals_ns.size() < 2) return rules;
  constexpr int64_t kPeriodNs = 1'000'000;
  const int64_t start = arrivals_ns.front() - kPeriodNs / 2;
  rules.push_back({"tick on arrival (rule, no wake-up cost)",
                   Summarise(SimulatedAges(arrivals_ns, start, [&](int64_t open, size_t next) {
                     size_t in_slot = next;
                     while (in_slot < arrivals_ns.size() && arrivals_ns[in_slot] <= open) {
                       ++in_slot;
                     }
                     const int64_t pending = in_slot > next ? arrivals_ns[in_slot - 1] : INT64_MIN;
                     const int64_t first =
                         in_slot < arrivals_ns.size() ? arrivals_ns[in_slot] : INT64_MAX;
                     return ArrivalTickNs(open, open + kPeriodNs, kPeriodNs / 10, pending, first);
                   }))});
  for (const int64_t margin_us : {50, 100, 200}) {
    PhaseLockSpec spec;
    spec.margin_ns = margin_us * 1000;
    PhaseLock lock(spec, start);
    size_t observed = 0;
    const std::vector<double> ages =
        SimulatedAges(arrivals_ns, start, [&](int64_t open, size_t /*next*/) {
          const int64_t tick = lock.TickNs(open);
          // The tick reads (and the lock observes) what arrived before it.
          while (observed < arrivals_ns.size() && arrivals_ns[observed] <= tick) {
            lock.Observe(arrivals_ns[observed++]);
          }
          return tick;
        });
    rules.push_back(
        {"phase-locked, margin " + std::to_string(margin_us) + " us, slew 20 us", Summarise(ages)});
  }
  return rules;
}

void PrintSimulatedRules(const std::vector<SimulatedRule>& rules) {
  std::printf(
      "\nSample age at the tick, each rule simulated on the arrivals of the tick-on-arrival run "
      "(ticks exactly on time):\n\n");
  std::printf("| %-44s | %8s | %8s | %8s | %8s | %7s |\n", "us", "p50", "p99", "p99.9", "max", "n");
  std::printf("|%s|---------:|---------:|---------:|---------:|--------:|\n",
              std::string(46, '-').c_str());
  for (const SimulatedRule& r : rules) Row(r.name.c_str(), r.age_us);
}

Json SimulatedRulesJson(const std::vector<SimulatedRule>& rules) {
  Json out = Json::object();
  for (const SimulatedRule& r : rules) out[r.name] = ToJson(r.age_us);
  return out;
}

// ---- The ROS 2 profile against Felt's (issue 24) ------------------------------------------------

// The end-to-end rows of both profiles (tick on arrival in both) and the difference of p50 and p99.
void PrintProfiles(const E2eResult& felt, const E2eResult& ros2) {
  std::printf(
      "\nEnd to end by transport profile, tick on arrival in both (same run; the ROS 2 device "
      "publishes PoseStamped, reads WrenchStamped, ROS 2 default QoS):\n\n");
  std::printf("| %-44s | %8s | %8s | %8s | %8s | %7s |\n", "us", "p50", "p99", "p99.9", "max", "n");
  std::printf("|%s|---------:|---------:|---------:|---------:|--------:|\n",
              std::string(46, '-').c_str());
  Row("end to end, Felt profile (felt/pointer)", felt.e2e_us);
  Row("end to end, ROS 2 profile (PoseStamped)", ros2.e2e_us);
  std::printf("| %-44s | %+8.1f | %+8.1f |          |          |         |\n", "ROS 2 - Felt",
              ros2.e2e_us.p50 - felt.e2e_us.p50, ros2.e2e_us.p99 - felt.e2e_us.p99);
  Row("sample age at the tick, Felt profile", felt.sample_age_us);
  Row("sample age at the tick, ROS 2 profile", ros2.sample_age_us);
  std::printf("samples sent/answered: Felt %llu/%llu, ROS 2 %llu/%llu\n",
              static_cast<unsigned long long>(felt.samples_sent),
              static_cast<unsigned long long>(felt.answered),
              static_cast<unsigned long long>(ros2.samples_sent),
              static_cast<unsigned long long>(ros2.answered));
}

Json ProfilesJson(const E2eResult& felt, const E2eResult& ros2) {
  return Json{{"felt", TickModeJson(felt)},
              {"ros2", TickModeJson(ros2)},
              {"e2e_p50_difference_us", ros2.e2e_us.p50 - felt.e2e_us.p50},
              {"e2e_p99_difference_us", ros2.e2e_us.p99 - felt.e2e_us.p99}};
}

struct Options {
  bool raw_only = false;
  std::string scene = "scenes/curtain.toml";
  std::string trace = "recordings/poke_hold.trace";
  E2eClientArgs client;  // --e2e-client: run as the e2e device process
  double seconds = 10.0;
  std::string json;
  transport::DdsSettings dds;
  bool dma_latency = false;
  bool fifo = false;
  bool security_cost = false;  // only the DDS Security on/off comparison (its own file)
  std::string security_out = "bench/results/transport_security";
};

int Run(const Options& options) {
  if (options.security_cost) {
    SecurityCostOptions cost{options.dds, options.seconds, 4, options.security_out,
                             "felt bench transport --security-cost --seconds " +
                                 report::Sig(options.seconds) + " --domain " +
                                 std::to_string(options.dds.domain_id)};
    return RunSecurityCost(cost);
  }
  if (!options.client.out.empty()) {
    if (options.fifo) {
      const sched_param param{10};
      sched_setscheduler(0, SCHED_FIFO, &param);  // as the parent; refused: normal scheduling
    }
    if (options.client.ros2) return RunRos2E2eClient(options.dds, options.client, options.seconds);
    return RunE2eClient(options.dds, options.client, options.seconds);
  }
  // Check the inputs of the e2e half before spending time on the raw half.
  if (!options.raw_only) {
    if (!std::filesystem::exists(options.scene)) {
      throw std::invalid_argument("--scene " + options.scene + ": no such file");
    }
    ReadTrace(options.trace);  // throws naming the file and line
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
    raw[m] = Summarise(r.roundtrip_us);
    sent[m] = r.pings_sent;
    received[m] = r.pongs_received;
  }
  // The transport's own hops, in this process, for both receive modes.
  HopResult hops[2];
  for (int m = 0; m < 2; ++m) hops[m] = MeasureHops(options.dds, modes[m], options.seconds);
  // End to end through the server.
  // End to end, once per tick mode; the main rows are the default's (on arrival).
  TickModeRuns tick_runs;
  E2eResult ros2_run;  // the ROS 2 profile, tick on arrival, after the Felt profile's runs
  if (!options.raw_only) {
    tick_runs =
        MeasureTickModes(options.dds, options.scene, options.trace, options.seconds, options.fifo);
    ros2_run =
        MeasureEndToEnd(options.dds, options.scene, options.trace, options.seconds, options.fifo,
                        HapticTickTrigger::kArrival, transport::TransportProfile::kRos2);
  }
  const E2eResult& e2e = tick_runs.arrival;
  const std::vector<SimulatedRule> simulated = SimulateTickRules(e2e.arrivals_ns);
  if (dma_fd >= 0) close(dma_fd);

  // The table.
  std::printf("felt bench transport%s: %.0f s at 1 kHz, loopback, domain %u%s%s\n\n",
              options.raw_only ? " --raw-only" : "", options.seconds, options.dds.domain_id,
              options.dma_latency ? ", /dev/cpu_dma_latency held at 0" : "",
              options.fifo ? ", SCHED_FIFO 10" : "");
  std::printf("| %-44s | %8s | %8s | %8s | %8s | %7s |\n", "us", "p50", "p99", "p99.9", "max", "n");
  std::printf("|%s|---------:|---------:|---------:|---------:|--------:|\n",
              std::string(46, '-').c_str());
  if (!options.raw_only) {
    Row("end to end: publish -> force received", e2e.e2e_us);
    Row("sample age at the haptic tick (server)", e2e.sample_age_us);
    // (both with the default tick, on arrival; the periodic tick's are in the table below)
  }
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
  if (!options.raw_only) {
    std::printf(
        "end to end: scene %s (%d x %d cloth), trace %s, server SCHED_FIFO %s; samples sent %llu, "
        "answered %llu, forces received %llu\n",
        e2e.scene_name.c_str(), e2e.cloth_w, e2e.cloth_h, options.trace.c_str(),
        e2e.realtime ? "granted" : "refused", static_cast<unsigned long long>(e2e.samples_sent),
        static_cast<unsigned long long>(e2e.answered),
        static_cast<unsigned long long>(e2e.forces_received));
    PrintTickModes(tick_runs);
    PrintProfiles(tick_runs.arrival, ros2_run);
    PrintSimulatedRules(simulated);
  }

  if (!options.json.empty()) {
    std::ofstream out(options.json);
    if (!out) throw std::runtime_error("--json " + options.json + ": cannot write the file");
    const Json absent;  // null: the end-to-end half did not run (--raw-only)
    const bool e2e_ran = !options.raw_only;
    out << JsonText(
        Json{{"raw_roundtrip_us", ToJson(raw[0])},
             {"raw_roundtrip_waitset_us", ToJson(raw[1])},
             {"raw_pings_sent", sent[0]},
             {"raw_pongs_received", received[0]},
             {"hops_us", Json{{"receive_to_slot", ToJson(hops[0].stats.receive_hop)},
                              {"receive_to_slot_waitset", ToJson(hops[1].stats.receive_hop)},
                              {"slot_read", ToJson(hops[0].slot_read_us)},
                              {"push_force", ToJson(hops[0].push_us)},
                              {"queue_to_dds_write", ToJson(hops[0].stats.write_hop)}}},
             {"transport_sample_age_us", ToJson(hops[0].sample_age_us)},
             {"e2e_us", e2e_ran ? ToJson(e2e.e2e_us) : absent},
             {"sample_age_us", e2e_ran ? ToJson(e2e.sample_age_us) : absent},
             {"samples_sent", e2e_ran ? Json(e2e.samples_sent) : absent},
             {"samples_answered", e2e_ran ? Json(e2e.answered) : absent},
             {"forces_received", e2e_ran ? Json(e2e.forces_received) : absent},
             {"server_realtime", e2e_ran ? Json(e2e.realtime) : absent},
             {"tick_modes", e2e_ran ? TickModesJson(tick_runs) : absent},
             {"profiles", e2e_ran ? ProfilesJson(tick_runs.arrival, ros2_run) : absent},
             {"simulated_tick_rules_age_us", e2e_ran ? SimulatedRulesJson(simulated) : absent},
             {"seconds", options.seconds},
             {"cpu_dma_latency_zero", options.dma_latency},
             {"sched_fifo", options.fifo}});
  }
  return 0;
}

const bool kRegistered = app::RegisterCommand({
    "bench",
    "transport",
    "DDS transport latency on loopback: end to end through the server, raw round trip, hops",
    [](CLI::App& cmd) -> app::CommandRun {
      auto options = std::make_shared<Options>();
      cmd.add_flag("--raw-only", options->raw_only,
                   "only the raw round trip and the hops, not the end-to-end run");
      cmd.add_option("--scene", options->scene,
                     "scene of the end-to-end server (default scenes/curtain.toml)");
      cmd.add_option("--trace", options->trace,
                     "trace the e2e client publishes (default recordings/poke_hold.trace)");
      // The e2e client process's role (internal: MeasureEndToEnd starts it).
      cmd.add_option("--e2e-client", options->client.out)->group("");
      cmd.add_option("--e2e-suffix", options->client.topic_suffix)->group("");
      cmd.add_option("--e2e-device", options->client.device_id)->group("");
      cmd.add_flag("--e2e-ros2", options->client.ros2)->group("");
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
      cmd.add_flag("--security-cost", options->security_cost,
                   "only the raw round trip without and with DDS Security (--seconds each); "
                   "writes --security-out PREFIX.md and .json");
      cmd.add_option("--security-out", options->security_out,
                     "where --security-cost writes (default bench/results/transport_security)");
      cmd.add_flag("--fifo", options->fifo,
                   "run the bench, its echo process and Cyclone's threads under SCHED_FIFO 10");
      return [options] {
        options->client.trace = options->trace;
        return Run(*options);
      };
    },
});

}  // namespace
}  // namespace felt::bench::bench_transport
