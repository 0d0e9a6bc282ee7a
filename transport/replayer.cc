#include "transport/replayer.h"

#include <spdlog/fmt/fmt.h>
#include <sys/prctl.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <numeric>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "base/json.h"
#include "base/report.h"
#include "rt/clock.h"
#include "transport/client_transport.h"
#include "transport/recorder.h"

namespace felt::transport {
namespace {

constexpr size_t kReplayTakeBatch = 256;   // forces per TakeForces call
constexpr uint32_t kForceHistory = 4096;   // forces the reader holds before overwriting
constexpr int64_t kStartLeadNs = 5000000;  // first deadline: 5 ms after Run begins
constexpr int64_t kMaxSleepNs = 50000000;  // sleep at most 50 ms at a time (to see the stop flag)

TimeSummary Summarise(const std::vector<int64_t>& values_ns) {
  TimeSummary s;
  s.count = values_ns.size();
  if (values_ns.empty()) return s;
  std::vector<double> us(values_ns.size());
  std::transform(values_ns.begin(), values_ns.end(), us.begin(),
                 [](int64_t ns) { return static_cast<double>(ns) / 1e3; });
  s.p50_us = report::Percentile(us, 50.0);
  s.p99_us = report::Percentile(us, 99.0);
  s.p999_us = report::Percentile(us, 99.9);
  s.max_us = *std::max_element(us.begin(), us.end());
  const long double sum = std::accumulate(values_ns.begin(), values_ns.end(), 0.0L);
  s.mean_us = static_cast<double>(sum / static_cast<long double>(values_ns.size()) / 1e3L);
  return s;
}

// Sleeps until CLOCK_MONOTONIC `deadline_ns` or until *stop; false when stopped.
bool SleepUntil(int64_t deadline_ns, const std::atomic<bool>* stop) {
  for (;;) {
    if (stop != nullptr && stop->load(std::memory_order_relaxed)) return false;
    const int64_t now_ns = MonotonicNowNs();
    if (now_ns >= deadline_ns) return true;
    const int64_t wake_ns = std::min(deadline_ns, now_ns + kMaxSleepNs);
    timespec ts{};
    ts.tv_sec = static_cast<time_t>(wake_ns / 1000000000);
    ts.tv_nsec = static_cast<long>(wake_ns % 1000000000);
    // Absolute deadline; EINTR (a signal) just loops and re-checks.
    (void)clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
  }
}

// Pointer samples a server rejected, every reason (docs/transport.md).
uint64_t StatusRejected(const ServerStatusView& s) {
  return s.rejected_nonfinite + s.rejected_workspace + s.rejected_seq + s.rejected_unknown_device +
         s.rejected_flood;
}

// Pointer samples a server took in: accepted or rejected.
uint64_t StatusReceived(const ServerStatusView& s) {
  return s.pointer_accepted + StatusRejected(s);
}

}  // namespace

class Replayer::Impl {
 public:
  Impl(Trace trace, ReplayConfig config);
  void ReceiveLoop();
  void OnForce(const ForceCommandView& force);
  bool FreshStatus(int64_t after_wall_ns, ServerStatusView* out);

  Trace trace_;
  ReplayConfig config_;
  std::vector<int64_t> offsets_ns_;  // schedule: replay time of each sample from the start, ns
  std::vector<uint32_t> sample_of_;  // schedule: trace sample index of each scheduled sample
  std::unique_ptr<ClientTransport> client_;
  bool ran_ = false;

  // Shared between the publishing and the receiving thread.
  std::unique_ptr<std::atomic<int64_t>[]> publish_ns_;  // by seq - 1; 0 = not published
  std::atomic<bool> stop_receiving_{false};
  std::atomic<uint64_t> last_published_seq_{0};
  std::atomic<bool> last_answered_{false};

  // Receiving thread only (read by Run after the join).
  int64_t start_ns_ = 0;
  std::vector<uint8_t> answered_;
  std::vector<int64_t> latencies_ns_;
  uint64_t forces_received_ = 0, contact_forces_ = 0;
  double peak_force_N_ = 0;
  std::unique_ptr<ForceLogWriter> forces_file_;
  std::string receive_error_;
};

Replayer::Impl::Impl(Trace trace, ReplayConfig config)
    : trace_(std::move(trace)), config_(std::move(config)) {
  // Validation, each error naming the field.
  if (trace_.samples.empty()) throw std::invalid_argument("replay: the trace has no samples");
  if (!(config_.rate > 0 && std::isfinite(config_.rate))) {
    throw std::invalid_argument("ReplayConfig.rate: must be finite and > 0");
  }
  if (config_.loops < 1) throw std::invalid_argument("ReplayConfig.loops: must be at least 1");
  if (!(config_.duration_s >= 0 && std::isfinite(config_.duration_s))) {
    throw std::invalid_argument("ReplayConfig.duration_s: must be finite and >= 0");
  }
  if (!(config_.late_threshold_us > 0 && std::isfinite(config_.late_threshold_us))) {
    throw std::invalid_argument("ReplayConfig.late_threshold_us: must be finite and > 0");
  }

  // The schedule: loop L, sample i at (L * loop_length + t_i - t_0) / rate, where a loop lasts
  // the trace plus one nominal period (so the first sample of the next pass is not a duplicate
  // time). At rate 1, loop 0 keeps the trace's own times to the nanosecond.
  const std::vector<TraceSample>& s = trace_.samples;
  const double t0_s = s.front().t_s;
  const double loop_length_s = (s.back().t_s - t0_s) + 1.0 / trace_.header.rate_hz();
  // Every offset computed must fit the schedule's int64 nanoseconds (292 years): the loops asked
  // for, or up to the duration plus the pass it stops in. A corrupt time does not.
  const double pass_s = loop_length_s / config_.rate;
  const double last_s =
      (config_.duration_s > 0 ? config_.duration_s : static_cast<double>(config_.loops) * pass_s) +
      pass_s;
  if (!(last_s < 9.0e9)) {
    char span[32];
    std::snprintf(span, sizeof span, "%.6g", loop_length_s);
    throw std::invalid_argument(std::string("replay: the trace spans ") + span +
                                " s per pass: its schedule does not fit in nanoseconds (a corrupt "
                                "time in the trace?)");
  }
  const auto offset_ns = [&](uint64_t loop, size_t i) {
    const double t_s = static_cast<double>(loop) * loop_length_s + (s[i].t_s - t0_s);
    return static_cast<int64_t>(std::llround(t_s / config_.rate * 1e9));
  };
  const int64_t end_ns = static_cast<int64_t>(std::llround(config_.duration_s * 1e9));
  for (uint64_t loop = 0;; ++loop) {
    if (config_.duration_s <= 0 && loop >= config_.loops) break;
    if (config_.duration_s > 0 && offset_ns(loop, 0) >= end_ns) break;
    for (size_t i = 0; i < s.size(); ++i) {
      const int64_t t_ns = offset_ns(loop, i);
      if (config_.duration_s > 0 && t_ns >= end_ns) break;
      offsets_ns_.push_back(t_ns);
      sample_of_.push_back(static_cast<uint32_t>(i));
    }
  }
  publish_ns_ = std::make_unique<std::atomic<int64_t>[]>(offsets_ns_.size());
  for (size_t i = 0; i < offsets_ns_.size(); ++i) publish_ns_[i].store(0);
  answered_.assign(offsets_ns_.size(), 0);
  latencies_ns_.reserve(offsets_ns_.size());

  // The client: a deep force history, so every force reaches TakeForces.
  ClientTransportConfig client;
  client.dds = config_.dds;
  client.topics = config_.topics;
  client.device_ids = {config_.device_id};
  client.subscribe_status = config_.status_timeout.count() > 0;
  client.force_history = kForceHistory;
  client_ = std::make_unique<ClientTransport>(std::move(client));
}

void Replayer::Impl::OnForce(const ForceCommandView& force) {
  // Every force: counts, contact, peak, the file.
  ++forces_received_;
  if (force.in_contact) ++contact_forces_;
  const double magnitude_N =
      std::sqrt(force.force_N_D[0] * force.force_N_D[0] + force.force_N_D[1] * force.force_N_D[1] +
                force.force_N_D[2] * force.force_N_D[2]);
  if (std::isfinite(magnitude_N)) peak_force_N_ = std::max(peak_force_N_, magnitude_N);

  // The sample it answers: one of ours (seq 1..N, published before this receipt)?
  const uint64_t seq = force.answers_seq;
  int64_t published_ns = 0;
  if (seq >= 1 && seq <= offsets_ns_.size()) {
    published_ns = publish_ns_[seq - 1].load(std::memory_order_acquire);
  }
  const bool ours = published_ns != 0 && force.receive_time_ns >= published_ns;
  if (ours && answered_[seq - 1] == 0) {
    // The first force answering a sample gives its end-to-end latency.
    answered_[seq - 1] = 1;
    latencies_ns_.push_back(force.receive_time_ns - published_ns);
    if (seq == last_published_seq_.load(std::memory_order_acquire)) {
      last_answered_.store(true, std::memory_order_release);
    }
  }
  if (forces_file_) {
    const double answers_t_s = ours ? static_cast<double>(offsets_ns_[seq - 1]) / 1e9 : -1.0;
    forces_file_->Write(static_cast<double>(force.receive_time_ns - start_ns_) / 1e9, answers_t_s,
                        force);
  }
}

void Replayer::Impl::ReceiveLoop() {
  std::vector<ForceCommandView> batch(kReplayTakeBatch);
  try {
    for (;;) {
      const bool stopping = stop_receiving_.load(std::memory_order_acquire);
      // Take everything there is; after the stop request, one last full drain.
      size_t n = 0;
      while ((n = client_->TakeForces(batch.data(), batch.size())) > 0) {
        for (size_t i = 0; i < n; ++i) OnForce(batch[i]);
      }
      if (stopping) break;
      (void)client_->WaitForForces(std::chrono::milliseconds(20));
    }
  } catch (const std::exception& e) {
    receive_error_ = e.what();
  }
}

bool Replayer::Impl::FreshStatus(int64_t after_wall_ns, ServerStatusView* out) {
  const bool found =
      WaitUntil([&] { return client_->LatestStatus(out) && out->wall_time_ns > after_wall_ns; },
                config_.status_timeout, std::chrono::milliseconds(10));
  return found;
}

Replayer::Replayer(Trace trace, ReplayConfig config)
    : impl_(std::make_unique<Impl>(std::move(trace), std::move(config))) {}

Replayer::~Replayer() = default;

bool Replayer::WaitForServer(const std::atomic<bool>* stop) {
  ClientTransport& client = *impl_->client_;
  WaitUntil(
      [&] {
        return (stop != nullptr && stop->load()) ||
               (client.MatchedPointerReaders() > 0 && client.MatchedForceWriters() > 0);
      },
      impl_->config_.discovery_timeout);
  if (!(client.MatchedPointerReaders() > 0 && client.MatchedForceWriters() > 0)) return false;
  // The settle margin, still watching the stop flag.
  const auto settle_end = std::chrono::steady_clock::now() + impl_->config_.discovery_settle;
  WaitUntil([&] { return stop != nullptr && stop->load(); },
            settle_end - std::chrono::steady_clock::now());
  return !(stop != nullptr && stop->load());
}

ReplayReport Replayer::Run(const std::atomic<bool>* stop, const std::function<void()>& on_start) {
  Impl& impl = *impl_;
  if (impl.ran_) throw std::logic_error("Replayer::Run: called twice");
  impl.ran_ = true;
  const ReplayConfig& config = impl.config_;
  const std::vector<TraceSample>& samples = impl.trace_.samples;
  ReplayReport r;
  r.device_id = config.device_id;
  r.trace_samples = samples.size();
  r.trace_length_s = samples.back().t_s - samples.front().t_s;
  r.rate = config.rate;
  r.scheduled = impl.offsets_ns_.size();

  // The server's counters before (a status newer than now, or the newest one it has).
  ServerStatusView before, after;
  bool have_before = false;
  if (config.status_timeout.count() > 0) {
    have_before = WaitUntil([&] { return impl.client_->LatestStatus(&before); },
                            config.status_timeout, std::chrono::milliseconds(10));
  }

  // Forces file and the receiving thread.
  impl.start_ns_ = MonotonicNowNs() + kStartLeadNs;
  if (!config.forces_out.empty()) {
    impl.forces_file_ = std::make_unique<ForceLogWriter>(
        config.forces_out, config.device_id,
        "felt replay: t_s on the replay's clock from its first deadline");
  }
  std::thread receiver([&impl] { impl.ReceiveLoop(); });

  // Publish on absolute deadlines, with minimal timer slack for this thread while it does.
  const int previous_slack = prctl(PR_GET_TIMERSLACK, 0, 0, 0, 0);
  (void)prctl(PR_SET_TIMERSLACK, 1, 0, 0, 0);
  std::vector<int64_t> lateness_ns;
  lateness_ns.reserve(impl.offsets_ns_.size());
  const auto late_ns = static_cast<int64_t>(config.late_threshold_us * 1e3);
  if (on_start) on_start();
  PointerSampleView view;
  int64_t last_publish_ns = impl.start_ns_;
  uint32_t previous_sample = UINT32_MAX;
  for (size_t k = 0; k < impl.offsets_ns_.size(); ++k) {
    const int64_t deadline_ns = impl.start_ns_ + impl.offsets_ns_[k];
    if (!SleepUntil(deadline_ns, stop)) {
      r.stopped_early = true;
      break;
    }
    const uint32_t i = impl.sample_of_[k];
    if (i <= previous_sample) ++r.loops_started;  // index 0 of a new pass
    previous_sample = i;
    const TraceSample& s = samples[i];
    view.seq = k + 1;
    view.device_time_ns = impl.offsets_ns_[k];
    view.position_m_D = {s.p_D.x(), s.p_D.y(), s.p_D.z()};
    view.velocity_m_per_s_D = {s.v_D.x(), s.v_D.y(), s.v_D.z()};
    view.buttons = s.buttons;
    // Stamp before the write: a force may come back before dds_write returns.
    const int64_t publish_ns = MonotonicNowNs();
    impl.publish_ns_[k].store(publish_ns, std::memory_order_release);
    impl.last_published_seq_.store(view.seq, std::memory_order_release);
    if (!impl.client_->PublishPointer(view)) {
      impl.publish_ns_[k].store(0, std::memory_order_release);
      ++r.publish_failures;
      continue;
    }
    ++r.published;
    last_publish_ns = publish_ns;
    lateness_ns.push_back(publish_ns - deadline_ns);
    if (publish_ns - deadline_ns > late_ns) ++r.late;
  }
  (void)prctl(PR_SET_TIMERSLACK, previous_slack > 0 ? previous_slack : 50000, 0, 0, 0);
  r.wall_s = static_cast<double>(last_publish_ns - impl.start_ns_) / 1e9;
  const int64_t end_wall_ns = WallNowNs();

  // The last forces: until the last sample is answered or the drain time passes.
  if (r.published > 0) {
    WaitUntil([&impl] { return impl.last_answered_.load(std::memory_order_acquire); },
              config.drain_timeout, std::chrono::milliseconds(1));
  }
  impl.stop_receiving_.store(true, std::memory_order_release);
  receiver.join();
  if (!impl.receive_error_.empty()) throw std::runtime_error(impl.receive_error_);
  if (impl.forces_file_) impl.forces_file_->Close();

  // What came back.
  const ClientStats stats = impl.client_->Stats();
  r.forces_received = impl.forces_received_;
  r.forces_lost = stats.forces_seq_gaps;
  r.answered = impl.latencies_ns_.size();
  r.unanswered = r.published - r.answered;
  r.latency = Summarise(impl.latencies_ns_);
  r.lateness = Summarise(lateness_ns);
  r.contact_forces = impl.contact_forces_;
  r.peak_force_N = impl.peak_force_N_;

  // The server's counters after: a status published after the last sample.
  if (have_before && impl.FreshStatus(end_wall_ns + 20000000, &after) &&
      after.server_id == before.server_id) {
    r.server_counts = true;
    r.server_received = static_cast<int64_t>(StatusReceived(after) - StatusReceived(before));
    r.server_rejected = static_cast<int64_t>(StatusRejected(after) - StatusRejected(before));
    r.pointer_lost = static_cast<int64_t>(r.published) - r.server_received;
  }
  return r;
}

std::string ReplayReportJson(const ReplayReport& r) {
  const auto times = [](const TimeSummary& t) {
    return Json{{"count", t.count},  {"p50", t.p50_us}, {"p99", t.p99_us},
                {"p999", t.p999_us}, {"max", t.max_us}, {"mean", t.mean_us}};
  };
  return JsonText(Json{{"device_id", r.device_id},
                       {"trace_samples", r.trace_samples},
                       {"trace_length_s", r.trace_length_s},
                       {"rate", r.rate},
                       {"loops_started", r.loops_started},
                       {"wall_s", r.wall_s},
                       {"stopped_early", r.stopped_early},
                       {"scheduled", r.scheduled},
                       {"published", r.published},
                       {"publish_failures", r.publish_failures},
                       {"late", r.late},
                       {"lateness_us", times(r.lateness)},
                       {"forces_received", r.forces_received},
                       {"forces_lost", r.forces_lost},
                       {"answered", r.answered},
                       {"unanswered", r.unanswered},
                       {"latency_us", times(r.latency)},
                       {"contact_forces", r.contact_forces},
                       {"peak_force_N", r.peak_force_N},
                       {"server_counts", r.server_counts},
                       {"server_received", r.server_received},
                       {"server_rejected", r.server_rejected},
                       {"pointer_lost", r.pointer_lost}});
}

namespace {

// "p50 12 p99 40 p99.9 90 max 300": one line's percentiles, whole microseconds.
std::string TimesText(const TimeSummary& t) {
  return fmt::format("p50 {:.0f} p99 {:.0f} p99.9 {:.0f} max {:.0f}", t.p50_us, t.p99_us, t.p999_us,
                     t.max_us);
}

}  // namespace

std::string FormatReplayReport(const ReplayReport& r) {
  std::string out = fmt::format(
      "replay: device {}, {} of {} samples published ({} pass(es), rate {:g}, {:.2f} s){}\n",
      r.device_id, r.published, r.scheduled, r.loops_started, r.rate, r.wall_s,
      r.stopped_early ? ", stopped early" : "");
  out += fmt::format("publish lateness us  {}; late {}; failed {}\n", TimesText(r.lateness), r.late,
                     r.publish_failures);
  out += fmt::format("latency us           {} ({} answered, {} unanswered)\n", TimesText(r.latency),
                     r.answered, r.unanswered);
  out += fmt::format("forces               {} received, {} lost, {} in contact, peak {:.2f} N\n",
                     r.forces_received, r.forces_lost, r.contact_forces, r.peak_force_N);
  out += r.server_counts ? fmt::format("server               {} received, {} rejected, {} lost\n",
                                       r.server_received, r.server_rejected, r.pointer_lost)
                         : std::string("server               no felt/status: lost unknown\n");
  return out;
}

}  // namespace felt::transport
