#include "transport/mcap_recorder.h"

#include <time.h>

#include <array>
#include <cstring>
#include <stdexcept>
#include <utility>

#include "felt_types.h"
#include "recordings/mcap.h"
#include "recordings/trace.h"
#include "ros2/messages.h"
#include "transport/message_views.h"
#include "transport/dds_config.h"
#include "transport/qos.h"
#include "transport/status_diagnostics.h"

namespace felt::transport {
namespace {

// The QoS Felt's stream writers offer, in rosbag2's offered_qos_profiles YAML (rmw enums:
// history 1 = keep last, reliability 2 = best effort, durability 2 = volatile, liveliness 1 =
// automatic), so `ros2 bag play` republishes with a matching profile.
constexpr const char* kStreamQosYaml =
    "- history: 1\n  depth: 1\n  reliability: 2\n  durability: 2\n  deadline:\n    sec: 0\n"
    "    nsec: 10000000\n  lifespan:\n    sec: 9223372036\n    nsec: 854775807\n"
    "  liveliness: 1\n  liveliness_lease_duration:\n    sec: 9223372036\n    nsec: 854775807\n"
    "  avoid_ros_namespace_conventions: false\n";
// felt/status: reliable, transient local, keep last 1.
constexpr const char* kStatusQosYaml =
    "- history: 1\n  depth: 1\n  reliability: 1\n  durability: 1\n  deadline:\n"
    "    sec: 9223372036\n    nsec: 854775807\n  lifespan:\n    sec: 9223372036\n"
    "    nsec: 854775807\n  liveliness: 1\n  liveliness_lease_duration:\n    sec: 9223372036\n"
    "    nsec: 854775807\n  avoid_ros_namespace_conventions: false\n";

int64_t McapClockNs(clockid_t clock) {
  timespec ts{};
  clock_gettime(clock, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

uint64_t McapLogTime(int64_t ns) { return ns < 0 ? 0 : static_cast<uint64_t>(ns); }

template <class M>
uint16_t McapAddChannel(McapWriter& w, const std::string& topic, const char* qos) {
  const ros2::MessageType& t = ros2::TypeOf<M>();
  const uint16_t schema = w.AddSchema(t.name, "ros2msg", t.schema);
  return w.AddChannel(schema, topic, "cdr", {{"offered_qos_profiles", qos}});
}

}  // namespace

McapTopics McapTopics::ForDevice(const std::string& device_id) {
  McapTopics t;
  t.pose = "/" + device_id + "/measured_cp";
  t.twist = "/" + device_id + "/measured_cv";
  t.wrench = "/" + device_id + "/servo_cf";
  return t;
}

// ---- McapSink ----

McapSink::McapSink(const std::string& path, const std::string& device_id, size_t queue_capacity,
                   size_t chunk_size_bytes)
    : path_(path),
      device_id_(device_id),
      frame_(device_id + "/device"),
      topics_(McapTopics::ForDevice(device_id)),
      queue_(queue_capacity),
      status_queue_(64) {
  McapWriterOptions options;
  options.chunk_size_bytes = chunk_size_bytes;
  writer_ = std::make_unique<McapWriter>(path_, options);
  ch_pose_ = McapAddChannel<ros2::PoseStamped>(*writer_, topics_.pose, kStreamQosYaml);
  ch_twist_ = McapAddChannel<ros2::TwistStamped>(*writer_, topics_.twist, kStreamQosYaml);
  ch_wrench_ = McapAddChannel<ros2::WrenchStamped>(*writer_, topics_.wrench, kStreamQosYaml);
  ch_diag_ = McapAddChannel<ros2::DiagnosticArray>(*writer_, topics_.diagnostics, kStatusQosYaml);
  realtime_minus_monotonic_ns_ = McapClockNs(CLOCK_REALTIME) - McapClockNs(CLOCK_MONOTONIC);
  thread_ = std::thread([this] { Run(); });
}

McapSink::~McapSink() {
  try {
    Close();
  } catch (const std::exception&) {
    // Lost: callers that care call Close().
  }
}

bool McapSink::OfferPointer(const PointerSampleView& sample) {
  if (!queue_.TryPush(Item(sample))) {
    drops_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  offered_.fetch_add(1, std::memory_order_release);
  return true;
}

bool McapSink::OfferForce(const ForceCommandView& force) {
  if (!queue_.TryPush(Item(force))) {
    drops_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  offered_.fetch_add(1, std::memory_order_release);
  return true;
}

bool McapSink::OfferStatus(const ServerStatusView& status) {
  if (!status_queue_.TryPush({status, McapClockNs(CLOCK_REALTIME)})) {
    drops_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  return true;
}

void McapSink::WriteItem(const Item& item) {
  // Serialise into reused buffers (they stop growing after the first messages).
  thread_local std::vector<uint8_t> bytes;
  const std::string& frame = frame_;
  if (const auto* p = std::get_if<PointerSampleView>(&item)) {
    const uint64_t log = McapLogTime(p->receive_time_ns + realtime_minus_monotonic_ns_);
    const uint64_t stamp_ns = McapLogTime(p->device_time_ns);
    ros2::PoseStamped pose;
    pose.header = {ros2::TimeFromNs(p->device_time_ns), frame};
    pose.pose.position = {p->position_m_D[0], p->position_m_D[1], p->position_m_D[2]};
    ros2::Serialize(pose, &bytes);
    writer_->WriteMessage(ch_pose_, static_cast<uint32_t>(p->seq), log, stamp_ns, bytes);
    ros2::TwistStamped twist;
    twist.header = pose.header;
    twist.twist.linear = {p->velocity_m_per_s_D[0], p->velocity_m_per_s_D[1],
                          p->velocity_m_per_s_D[2]};
    ros2::Serialize(twist, &bytes);
    writer_->WriteMessage(ch_twist_, static_cast<uint32_t>(p->seq), log, stamp_ns, bytes);
    pointers_written_.fetch_add(1, std::memory_order_relaxed);
  } else {
    const auto& f = std::get<ForceCommandView>(item);
    const uint64_t log = McapLogTime(f.receive_time_ns + realtime_minus_monotonic_ns_);
    ros2::WrenchStamped w;
    // The stamp echoes the pose it answers: the round trip without clock synchronisation.
    w.header = {ros2::TimeFromNs(f.answers_device_time_ns), frame};
    w.wrench.force = {f.force_N_D[0], f.force_N_D[1], f.force_N_D[2]};
    ros2::Serialize(w, &bytes);
    writer_->WriteMessage(ch_wrench_, static_cast<uint32_t>(f.seq), log,
                          McapLogTime(f.answers_device_time_ns), bytes);
    forces_written_.fetch_add(1, std::memory_order_relaxed);
  }
}

void McapSink::WriteStatus(const ServerStatusView& status, int64_t log_ns) {
  std::vector<uint8_t> bytes;
  ros2::Serialize(StatusDiagnostics(status), &bytes);
  writer_->WriteMessage(ch_diag_, status_seq_++, McapLogTime(log_ns),
                        McapLogTime(status.wall_time_ns), bytes);
  statuses_written_.fetch_add(1, std::memory_order_relaxed);
}

void McapSink::Run() {
  // Drain both queues; sleep 1 ms when both are empty; after stop_, drain once more and end.
  try {
    Item item;
    std::pair<ServerStatusView, int64_t> status;
    while (true) {
      const bool stopping = stop_.load(std::memory_order_acquire);
      const uint64_t depth =
          offered_.load(std::memory_order_acquire) - popped_.load(std::memory_order_relaxed);
      if (depth > max_depth_.load(std::memory_order_relaxed)) {
        max_depth_.store(depth, std::memory_order_relaxed);
      }
      bool any = false;
      while (queue_.TryPop(&item)) {
        popped_.fetch_add(1, std::memory_order_relaxed);
        WriteItem(item);
        any = true;
      }
      while (status_queue_.TryPop(&status)) {
        WriteStatus(status.first, status.second);
        any = true;
      }
      bytes_.store(writer_->stats().bytes, std::memory_order_relaxed);
      chunks_.store(writer_->stats().chunks, std::memory_order_relaxed);
      if (stopping && !any) break;
      if (!any) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  } catch (const std::exception& e) {
    error_ = e.what();
  }
}

void McapSink::Close() {
  if (closed_) return;
  closed_ = true;
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
  if (!error_.empty()) throw std::runtime_error(path_ + ": " + error_);
  writer_->Close();
  bytes_.store(writer_->stats().bytes, std::memory_order_relaxed);
  chunks_.store(writer_->stats().chunks, std::memory_order_relaxed);
}

McapSinkStats McapSink::Stats() const {
  McapSinkStats s;
  s.pointers_written = pointers_written_.load(std::memory_order_relaxed);
  s.forces_written = forces_written_.load(std::memory_order_relaxed);
  s.statuses_written = statuses_written_.load(std::memory_order_relaxed);
  s.queue_drops = drops_.load(std::memory_order_relaxed);
  s.max_queue_depth = max_depth_.load(std::memory_order_relaxed);
  s.bytes = bytes_.load(std::memory_order_relaxed);
  s.chunks = chunks_.load(std::memory_order_relaxed);
  return s;
}

// ---- McapRecorder ----

// A reader of felt/status (reliable, transient local: the server's QoS) that takes every sample.
class McapRecorder::StatusReader {
 public:
  StatusReader(const DdsSettings& dds, const std::string& topic)
      : participant_(AcquireDomain(dds)) {
    topic_ = CreateTopic(participant_, &felt_msgs_ServerStatus_desc, topic);
    const Qos qos = StatusQos();
    reader_ = CreateReader(participant_, topic_, qos.get(), nullptr, topic);
  }
  /// Takes every status waiting; calls `fn` with each. Returns false when dds_take failed.
  template <class Fn>
  bool Take(const Fn& fn) {
    constexpr int kBatch = 8;
    std::array<felt_msgs_ServerStatus, kBatch> buffer{};
    std::array<void*, kBatch> ptrs{};
    std::array<dds_sample_info_t, kBatch> infos{};
    for (int i = 0; i < kBatch; ++i) ptrs[i] = &buffer[i];
    const dds_return_t n = dds_take(reader_.get(), ptrs.data(), infos.data(), kBatch, kBatch);
    if (n < 0) return false;
    for (dds_return_t i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      fn(StatusViewOf(buffer[i]));
    }
    return true;
  }

 private:
  Participant participant_;
  Entity topic_, reader_;
};

namespace {
StreamTapConfig McapTapConfigOf(const McapRecorderConfig& config) {
  if (config.out_path.empty()) throw std::invalid_argument("McapRecorderConfig.out_path: required");
  StreamTapConfig tap;
  tap.dds = config.dds;
  tap.topics = config.topics;
  tap.pointers = true;
  tap.forces = config.forces;
  tap.history_depth = config.history_depth;
  return tap;
}
}  // namespace

McapRecorder::McapRecorder(McapRecorderConfig config)
    : config_(std::move(config)), tap_(McapTapConfigOf(config_)) {
  stats_.device_id = config_.device_id;
  if (config_.status) {
    status_reader_ = std::make_unique<StatusReader>(config_.dds, config_.topics.status);
  }
}

McapRecorder::~McapRecorder() = default;

void McapRecorder::Poll(std::chrono::nanoseconds timeout) {
  tap_.Poll(
      timeout, [this](std::string_view id, const PointerSampleView& s) { OnPointer(id, s); },
      [this](std::string_view id, const ForceCommandView& f) { OnForce(id, f); });
  TakeStatuses();
}

void McapRecorder::OnPointer(std::string_view device_id, const PointerSampleView& sample) {
  if (closed_) return;
  if (stats_.device_id.empty()) stats_.device_id = std::string(device_id);
  if (device_id != stats_.device_id) {
    ++stats_.pointers_other_device;
    return;
  }
  ++stats_.pointers_received;
  if (!pointer_seq_.Accept(sample.seq, &stats_.pointer_seq_gaps, &stats_.pointers_out_of_order)) {
    return;
  }
  if (!sink_) {
    sink_ = std::make_unique<McapSink>(config_.out_path, stats_.device_id, config_.queue_capacity);
  }
  sink_->OfferPointer(sample);
}

void McapRecorder::OnForce(std::string_view device_id, const ForceCommandView& force) {
  if (closed_) return;
  if (stats_.device_id.empty() || device_id != stats_.device_id) {
    ++stats_.forces_other_device;
    return;
  }
  ++stats_.forces_received;
  force_seq_.Note(force.seq, &stats_.force_seq_gaps);
  if (!sink_) {
    ++stats_.forces_before_first_pointer;
    return;
  }
  sink_->OfferForce(force);
}

void McapRecorder::TakeStatuses() {
  if (!status_reader_ || closed_) return;
  const bool ok = status_reader_->Take([this](const ServerStatusView& v) {
    ++stats_.statuses_received;
    if (sink_) sink_->OfferStatus(v);
  });
  if (!ok) ++stats_.dds_errors;
}

void McapRecorder::Close() {
  if (closed_) return;
  closed_ = true;
  if (sink_) sink_->Close();
}

McapRecorderStats McapRecorder::Stats() const {
  McapRecorderStats s = stats_;
  s.dds_errors += tap_.dds_errors();
  if (sink_) s.sink = sink_->Stats();
  return s;
}

}  // namespace felt::transport
