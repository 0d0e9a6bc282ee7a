#include "transport/recorder.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <utility>

#include "felt_types.h"
#include "transport/dds_config.h"
#include "transport/message_views.h"
#include "transport/qos.h"

namespace felt::transport {
namespace {

constexpr int kTapBatch = 64;  // samples per dds_take

// The stream readers' QoS (transport/qos.h) with a deeper history, so nothing is overwritten
// before taken.
Qos TapQos(uint32_t depth) {
  Qos qos = StreamReaderQos();
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST,
                   static_cast<int32_t>(std::min<uint32_t>(depth, 1u << 20)));
  return qos;
}

std::string_view IdOf(const char (&id)[65]) { return {id, strnlen(id, sizeof(id))}; }

void CheckNoNewline(std::string_view text, const char* what) {
  if (text.find('\n') != std::string_view::npos || text.find('\r') != std::string_view::npos) {
    throw std::invalid_argument(std::string(what) + ": must not hold a line break");
  }
}

}  // namespace

// ---- StreamTap ----

class StreamTap::Impl {
 public:
  explicit Impl(StreamTapConfig config);

  StreamTapConfig config_;
  Participant participant_;
  Entity pointer_topic_, force_topic_, pointer_reader_, force_reader_;
  Entity waitset_, pointer_condition_, force_condition_;
  std::array<felt_msgs_PointerSample, kTapBatch> pointers_{};
  std::array<felt_msgs_ForceCommand, kTapBatch> forces_{};
  std::array<void*, kTapBatch> pointer_ptrs_{}, force_ptrs_{};
  std::array<dds_sample_info_t, kTapBatch> infos_{};
  std::atomic<uint64_t> errors_{0};

  /// Takes everything `reader` holds, kTapBatch samples at a time into `samples` (through
  /// `ptrs`), calling `handler` (when set) with each valid sample's device id and
  /// view_of(sample, 0, receive time: CLOCK_MONOTONIC after the take, ns). Returns the number of
  /// valid samples; a failed dds_take is counted in errors_ and ends the taking.
  template <class Message, class ViewOf, class Handler>
  size_t TakeAll(const Entity& reader, const std::array<Message, kTapBatch>& samples,
                 std::array<void*, kTapBatch>& ptrs, ViewOf view_of, const Handler& handler);
};

template <class Message, class ViewOf, class Handler>
size_t StreamTap::Impl::TakeAll(const Entity& reader, const std::array<Message, kTapBatch>& samples,
                                std::array<void*, kTapBatch>& ptrs, ViewOf view_of,
                                const Handler& handler) {
  size_t taken = 0;
  const bool ok = TakeEverySample(reader, ptrs, infos_, [&](size_t i, int64_t now_ns) {
    const Message& m = samples[i];
    const auto v = view_of(m, 0, now_ns);
    ++taken;
    if (handler) handler(IdOf(m.device_id), v);
  });
  if (!ok) errors_.fetch_add(1, std::memory_order_relaxed);
  return taken;
}

StreamTap::Impl::Impl(StreamTapConfig config)
    : config_(std::move(config)), participant_(config_.dds, "recorder") {
  if (!config_.pointers && !config_.forces) {
    throw std::invalid_argument("StreamTapConfig: read at least one of pointers and forces");
  }
  if (config_.history_depth < 1) {
    throw std::invalid_argument("StreamTapConfig.history_depth: must be at least 1");
  }
  for (int i = 0; i < kTapBatch; ++i) {
    pointer_ptrs_[i] = &pointers_[i];
    force_ptrs_[i] = &forces_[i];
  }
  const Qos qos = TapQos(config_.history_depth);
  waitset_ = Entity(CheckDds(dds_create_waitset(participant_.get()), "dds_create_waitset"));
  if (config_.pointers) {
    pointer_topic_ =
        CreateTopic(participant_, &felt_msgs_PointerSample_desc, config_.topics.pointer);
    pointer_reader_ =
        CreateReader(participant_, pointer_topic_, qos.get(), nullptr, config_.topics.pointer);
    pointer_condition_ =
        Entity(CheckDds(dds_create_readcondition(pointer_reader_.get(), DDS_ANY_STATE),
                        "dds_create_readcondition"));
    CheckDds(dds_waitset_attach(waitset_.get(), pointer_condition_.get(), 0), "dds_waitset_attach");
  }
  if (config_.forces) {
    force_topic_ = CreateTopic(participant_, &felt_msgs_ForceCommand_desc, config_.topics.force);
    force_reader_ =
        CreateReader(participant_, force_topic_, qos.get(), nullptr, config_.topics.force);
    force_condition_ = Entity(CheckDds(dds_create_readcondition(force_reader_.get(), DDS_ANY_STATE),
                                       "dds_create_readcondition"));
    CheckDds(dds_waitset_attach(waitset_.get(), force_condition_.get(), 1), "dds_waitset_attach");
  }
}

StreamTap::StreamTap(StreamTapConfig config) : impl_(std::make_unique<Impl>(std::move(config))) {}

StreamTap::~StreamTap() = default;

size_t StreamTap::Poll(std::chrono::nanoseconds timeout, const TapPointerHandler& on_pointer,
                       const TapForceHandler& on_force) {
  Impl& impl = *impl_;
  // Wait for data on either reader (relative timeout: the _until form wants wall-clock time).
  if (dds_waitset_wait(impl.waitset_.get(), nullptr, 0, timeout.count()) < 0) {
    impl.errors_.fetch_add(1, std::memory_order_relaxed);
    return 0;
  }
  size_t taken = 0;
  // Pointer samples, in batches until the reader is empty; then forces, likewise.
  if (impl.config_.pointers) {
    taken += impl.TakeAll(impl.pointer_reader_, impl.pointers_, impl.pointer_ptrs_, PointerViewOf,
                          on_pointer);
  }
  if (impl.config_.forces) {
    taken +=
        impl.TakeAll(impl.force_reader_, impl.forces_, impl.force_ptrs_, ForceViewOf, on_force);
  }
  return taken;
}

uint32_t StreamTap::MatchedPointerWriters() const {
  if (!impl_->config_.pointers) return 0;
  return MatchedWriters(impl_->pointer_reader_);
}

uint32_t StreamTap::MatchedForceWriters() const {
  if (!impl_->config_.forces) return 0;
  return MatchedWriters(impl_->force_reader_);
}

uint64_t StreamTap::dds_errors() const { return impl_->errors_.load(std::memory_order_relaxed); }

// ---- ForceLogWriter ----

ForceLogWriter::ForceLogWriter(std::string path, std::string_view device, std::string_view source)
    : path_(std::move(path)) {
  CheckNoNewline(device, "forces file device");
  CheckNoNewline(source, "forces file source");
  out_.open(path_, std::ios::out | std::ios::trunc);
  if (!out_) {
    throw std::runtime_error(path_ + ": cannot create forces file: " + std::strerror(errno));
  }
  out_ << kForcesMagic << "\n# units: N, m, s\n# device: " << device << "\n# source: " << source
       << "\n# frame: device\n"
       << kForcesColumns << "\n";
}

ForceLogWriter::~ForceLogWriter() {
  if (out_.is_open()) out_.close();
}

void ForceLogWriter::Write(double t_s, double answers_t_s, const ForceCommandView& force) {
  // Shortest round-trip numbers (TraceWriteOptions::decimals < 0), like the trace.
  line_.clear();
  AppendTraceNumber(t_s, -1, &line_);
  line_ += ',';
  line_ += std::to_string(force.seq);
  line_ += ',';
  line_ += std::to_string(force.answers_seq);
  line_ += ',';
  AppendTraceNumber(answers_t_s, -1, &line_);
  for (int k = 0; k < 3; ++k) {
    line_ += ',';
    AppendTraceNumber(force.force_N_D[k], -1, &line_);
  }
  for (int k = 0; k < 3; ++k) {
    line_ += ',';
    AppendTraceNumber(force.proxy_position_m_D[k], -1, &line_);
  }
  line_ += force.in_contact ? ",1," : ",0,";
  line_ += std::to_string(force.flags);
  line_ += '\n';
  out_ << line_;
  ++lines_;
}

void ForceLogWriter::Close() {
  if (!out_.is_open()) return;
  out_.flush();
  const bool good = static_cast<bool>(out_);
  out_.close();
  if (!good || out_.fail()) throw std::runtime_error(path_ + ": write failed");
}

// ---- Recorder ----

namespace {
StreamTapConfig TapConfigOf(const RecorderConfig& config) {
  if (config.out_path.empty()) throw std::invalid_argument("RecorderConfig.out_path: required");
  if (!(config.rate_hz > 0 && std::isfinite(config.rate_hz))) {
    throw std::invalid_argument("RecorderConfig.rate_hz: must be finite and > 0");
  }
  StreamTapConfig tap;
  tap.dds = config.dds;
  tap.topics = config.topics;
  tap.pointers = true;
  tap.forces = !config.forces_path.empty();
  tap.history_depth = config.history_depth;
  return tap;
}
}  // namespace

Recorder::Recorder(RecorderConfig config) : config_(std::move(config)), tap_(TapConfigOf(config_)) {
  stats_.device_id = config_.device_id;
}

Recorder::~Recorder() = default;

void Recorder::Poll(std::chrono::nanoseconds timeout) {
  tap_.Poll(
      timeout, [this](std::string_view id, const PointerSampleView& s) { OnPointer(id, s); },
      [this](std::string_view id, const ForceCommandView& f) { OnForce(id, f); });
}

void Recorder::OnPointer(std::string_view device_id, const PointerSampleView& sample) {
  if (closed_) return;
  // The device: the configured one, else the first heard from.
  if (stats_.device_id.empty()) stats_.device_id = std::string(device_id);
  if (device_id != stats_.device_id) {
    ++stats_.pointers_other_device;
    return;
  }
  ++stats_.pointers_received;

  // Sequence: count the missing samples of a jump; a seq not above the last is not written.
  if (!pointer_seq_.Accept(sample.seq, &stats_.pointer_seq_gaps, &stats_.pointers_out_of_order)) {
    return;
  }
  if (have_origin_ && sample.device_time_ns <= last_device_ns_) {
    ++stats_.pointers_time_not_increasing;
    return;
  }
  last_device_ns_ = sample.device_time_ns;

  // First sample: the time origin and the files.
  if (!have_origin_) {
    have_origin_ = true;
    origin_device_ns_ = sample.device_time_ns;
    origin_receive_ns_ = sample.receive_time_ns;
    const std::string source = "felt record: " + config_.topics.pointer + " on DDS domain " +
                               std::to_string(config_.dds.domain_id);
    TraceHeader header = MakeTraceHeader(config_.rate_hz, stats_.device_id, source);
    header.Set("timebase", "device_time_ns");
    header.Set("first_seq", std::to_string(sample.seq));
    trace_ = std::make_unique<TraceWriter>(config_.out_path, header);
    if (!config_.forces_path.empty()) {
      forces_ = std::make_unique<ForceLogWriter>(config_.forces_path, stats_.device_id,
                                                 "felt record: " + config_.topics.force +
                                                     ", t_s on the receiving clock, origin = "
                                                     "receipt of the trace's first sample");
    }
  }

  // The trace line: time on the driver's clock from the first sample.
  TraceSample row;
  row.t_s = static_cast<double>(sample.device_time_ns - origin_device_ns_) / 1e9;
  row.p_D = Vec3(sample.position_m_D[0], sample.position_m_D[1], sample.position_m_D[2]);
  row.v_D = Vec3(sample.velocity_m_per_s_D[0], sample.velocity_m_per_s_D[1],
                 sample.velocity_m_per_s_D[2]);
  row.buttons = sample.buttons;
  trace_->Write(row);
  ++stats_.pointers_written;
}

void Recorder::OnForce(std::string_view device_id, const ForceCommandView& force) {
  if (stats_.device_id.empty() || device_id != stats_.device_id) {
    ++stats_.forces_other_device;
    return;
  }
  if (closed_) return;
  ++stats_.forces_received;
  force_seq_.Note(force.seq, &stats_.force_seq_gaps);
  if (!forces_) return;  // before the first pointer sample: no time origin yet
  const double t_s = static_cast<double>(force.receive_time_ns - origin_receive_ns_) / 1e9;
  const double answers_t_s =
      static_cast<double>(force.answers_device_time_ns - origin_device_ns_) / 1e9;
  forces_->Write(t_s, answers_t_s, force);
  ++stats_.forces_written;
}

void Recorder::Close() {
  closed_ = true;
  // Each writer is closed once (a second Close of a TraceWriter would report a failure).
  std::unique_ptr<TraceWriter> trace = std::move(trace_);
  std::unique_ptr<ForceLogWriter> forces = std::move(forces_);
  if (trace) trace->Close();
  if (forces) forces->Close();
}

RecorderStats Recorder::Stats() const {
  RecorderStats s = stats_;
  s.dds_errors = tap_.dds_errors();
  return s;
}

}  // namespace felt::transport
