#include "transport/client_transport.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cstring>
#include <stdexcept>
#include <thread>
#include <utility>

#include "felt_types.h"
#include "transport/dds_config.h"
#include "transport/message_views.h"
#include "transport/qos.h"

namespace felt::transport {
namespace {

constexpr int kForceBatch = 16;  // forces per dds_take
constexpr int kStatusBatch = 8;  // status instances (servers) read at once

// Counters the client bumps may have more than one writer thread: a real read-modify-write.
void AtomicBump(std::atomic<uint64_t>& counter) { counter.fetch_add(1, std::memory_order_relaxed); }

}  // namespace

class ClientTransport::Impl {
 public:
  explicit Impl(ClientTransportConfig config);
  void PollForces();

  struct Device {
    char id[65] = {};
    ForceCommandView latest;
    bool fresh = false;
    bool has_seq = false;
    uint64_t last_seq = 0;
  };
  // Index of device id `id` in devices_, or devices_.size() when it is not this client's.
  size_t FindDevice(const char* id) const;
  // Bumps the gap counter for `seq` on device `d` and makes it the last seen.
  void NoteSeq(Device& d, uint64_t seq);

  ClientTransportConfig config_;
  std::vector<Device> devices_;
  Participant participant_;
  Entity pointer_topic_, force_topic_, status_topic_;
  Entity pointer_writer_, force_reader_, status_reader_;
  Entity waitset_, force_condition_;

  felt_msgs_PointerSample pointer_message_{};  // PublishPointer's thread only
  std::array<felt_msgs_ForceCommand, kForceBatch> force_buffer_{};
  std::array<void*, kForceBatch> force_ptrs_{};
  std::array<dds_sample_info_t, kForceBatch> force_infos_{};

  std::atomic<uint64_t> published_{0}, received_{0}, gaps_{0}, other_{0}, errors_{0};
};

ClientTransport::Impl::Impl(ClientTransportConfig config)
    : config_(std::move(config)),
      devices_(config_.device_ids.size()),
      participant_(config_.dds, "device-" + (config_.device_ids.empty() ? std::string()
                                                                        : config_.device_ids[0])) {
  // Device ids: non-empty, at most 64 characters, unique.
  if (devices_.empty()) {
    throw std::invalid_argument(
        "ClientTransportConfig.device_ids: at least one device is required");
  }
  for (size_t i = 0; i < devices_.size(); ++i) {
    const std::string field = "ClientTransportConfig.device_ids[" + std::to_string(i) + "]";
    CopyId(config_.device_ids[i], devices_[i].id, field);
    for (size_t j = 0; j < i; ++j) {
      if (config_.device_ids[j] == config_.device_ids[i]) {
        throw std::invalid_argument(field + " \"" + config_.device_ids[i] + "\": listed twice");
      }
    }
  }
  for (int i = 0; i < kForceBatch; ++i) force_ptrs_[i] = &force_buffer_[i];

  // Entities: the same QoS as the server's (transport/qos.h), so they match.
  pointer_topic_ = CreateTopic(participant_, &felt_msgs_PointerSample_desc, config_.topics.pointer);
  force_topic_ = CreateTopic(participant_, &felt_msgs_ForceCommand_desc, config_.topics.force);
  const Qos stream_qos = StreamQos();
  pointer_writer_ =
      CreateWriter(participant_, pointer_topic_, stream_qos.get(), config_.topics.pointer);
  if (config_.force_history < 1) {
    throw std::invalid_argument("ClientTransportConfig.force_history: must be at least 1");
  }
  const Qos force_qos = StreamReaderQos();
  dds_qset_history(force_qos.get(), DDS_HISTORY_KEEP_LAST,
                   static_cast<int32_t>(std::min<uint32_t>(config_.force_history, 1u << 20)));
  force_reader_ =
      CreateReader(participant_, force_topic_, force_qos.get(), nullptr, config_.topics.force);
  if (config_.subscribe_status) {
    status_topic_ = CreateTopic(participant_, &felt_msgs_ServerStatus_desc, config_.topics.status);
    const Qos status_qos = StatusQos();
    status_reader_ =
        CreateReader(participant_, status_topic_, status_qos.get(), nullptr, config_.topics.status);
  }
  waitset_ = Entity(CheckDds(dds_create_waitset(participant_.get()), "dds_create_waitset"));
  force_condition_ = Entity(CheckDds(dds_create_readcondition(force_reader_.get(), DDS_ANY_STATE),
                                     "dds_create_readcondition"));
  CheckDds(dds_waitset_attach(waitset_.get(), force_condition_.get(), 0), "dds_waitset_attach");
}

size_t ClientTransport::Impl::FindDevice(const char* id) const {
  size_t index = 0;
  while (index < devices_.size() &&
         std::strncmp(devices_[index].id, id, sizeof(devices_[index].id)) != 0) {
    ++index;
  }
  return index;
}

void ClientTransport::Impl::NoteSeq(Device& d, uint64_t seq) {
  if (d.has_seq && seq > d.last_seq + 1) {
    gaps_.fetch_add(seq - d.last_seq - 1, std::memory_order_relaxed);
  }
  d.has_seq = true;
  d.last_seq = seq;
}

void ClientTransport::Impl::PollForces() {
  // Take every force available; keep the newest per device and count gaps in its seq.
  const bool ok =
      TakeEverySample(force_reader_, force_ptrs_, force_infos_, [&](size_t i, int64_t now_ns) {
        const felt_msgs_ForceCommand& m = force_buffer_[i];
        const size_t index = FindDevice(m.device_id);
        if (index == devices_.size()) {
          AtomicBump(other_);
          return;
        }
        Device& d = devices_[index];
        NoteSeq(d, m.seq);
        d.latest = ForceViewOf(m, static_cast<uint32_t>(index), now_ns);
        d.fresh = true;
        AtomicBump(received_);
      });
  if (!ok) AtomicBump(errors_);
}

ClientTransport::ClientTransport(ClientTransportConfig config)
    : impl_(std::make_unique<Impl>(std::move(config))) {}

ClientTransport::~ClientTransport() = default;

bool ClientTransport::PublishPointer(const PointerSampleView& sample) {
  Impl& impl = *impl_;
  if (sample.device_index >= impl.devices_.size()) return false;
  felt_msgs_PointerSample& m = impl.pointer_message_;
  FillPointerMessage(sample, impl.devices_[sample.device_index].id, &m);
  if (dds_write(impl.pointer_writer_.get(), &m) < 0) {
    AtomicBump(impl.errors_);
    return false;
  }
  AtomicBump(impl.published_);
  return true;
}

bool ClientTransport::TakeForce(uint32_t device_index, ForceCommandView* out) {
  Impl& impl = *impl_;
  if (device_index >= impl.devices_.size()) return false;
  impl.PollForces();
  Impl::Device& d = impl.devices_[device_index];
  if (!d.fresh) return false;
  d.fresh = false;
  *out = d.latest;
  return true;
}

bool ClientTransport::WaitForce(uint32_t device_index, std::chrono::nanoseconds timeout,
                                ForceCommandView* out) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    if (TakeForce(device_index, out)) return true;
    const auto left = deadline - std::chrono::steady_clock::now();
    if (left <= std::chrono::nanoseconds::zero()) return false;
    // Relative timeout: dds_waitset_wait_until would want a wall-clock deadline.
    const dds_return_t n =
        dds_waitset_wait(impl_->waitset_.get(), nullptr, 0,
                         std::chrono::duration_cast<std::chrono::nanoseconds>(left).count());
    if (n < 0) {
      AtomicBump(impl_->errors_);
      return false;
    }
  }
}

size_t ClientTransport::TakeForces(ForceCommandView* out, size_t capacity) {
  Impl& impl = *impl_;
  size_t count = 0;
  while (count < capacity) {
    // Take at most what still fits in `out`, so nothing taken is dropped.
    const auto batch = static_cast<uint32_t>(std::min<size_t>(kForceBatch, capacity - count));
    const dds_return_t n = dds_take(impl.force_reader_.get(), impl.force_ptrs_.data(),
                                    impl.force_infos_.data(), batch, batch);
    if (n < 0) {
      AtomicBump(impl.errors_);
      break;
    }
    const int64_t now_ns = MonotonicNowNs();
    for (dds_return_t i = 0; i < n; ++i) {
      if (!impl.force_infos_[i].valid_data) continue;
      const felt_msgs_ForceCommand& m = impl.force_buffer_[i];
      const size_t index = impl.FindDevice(m.device_id);
      if (index == impl.devices_.size()) {
        AtomicBump(impl.other_);
        continue;
      }
      impl.NoteSeq(impl.devices_[index], m.seq);
      out[count++] = ForceViewOf(m, static_cast<uint32_t>(index), now_ns);
      AtomicBump(impl.received_);
    }
    if (n < static_cast<dds_return_t>(batch)) break;
  }
  return count;
}

bool ClientTransport::WaitForForces(std::chrono::nanoseconds timeout) {
  // Relative timeout: dds_waitset_wait_until would want a wall-clock deadline.
  const dds_return_t n = dds_waitset_wait(impl_->waitset_.get(), nullptr, 0, timeout.count());
  if (n < 0) {
    AtomicBump(impl_->errors_);
    return false;
  }
  return n > 0;
}

bool ClientTransport::LatestStatus(ServerStatusView* out) {
  Impl& impl = *impl_;
  if (!impl.config_.subscribe_status) return false;
  std::array<felt_msgs_ServerStatus, kStatusBatch> buffer{};
  std::array<void*, kStatusBatch> ptrs{};
  std::array<dds_sample_info_t, kStatusBatch> infos{};
  for (int i = 0; i < kStatusBatch; ++i) ptrs[i] = &buffer[i];
  // Read (not take): the newest status stays for the next caller.
  const dds_return_t n =
      dds_read(impl.status_reader_.get(), ptrs.data(), infos.data(), kStatusBatch, kStatusBatch);
  if (n < 0) {
    AtomicBump(impl.errors_);
    return false;
  }
  const felt_msgs_ServerStatus* newest = nullptr;
  for (dds_return_t i = 0; i < n; ++i) {
    if (infos[i].valid_data &&
        (newest == nullptr || buffer[i].wall_time_ns > newest->wall_time_ns)) {
      newest = &buffer[i];
    }
  }
  if (newest == nullptr) return false;
  const felt_msgs_ServerStatus& m = *newest;
  const auto copy = [](const felt_msgs_Percentiles& in) {
    return PercentilesView{in.p50, in.p99, in.p999, in.max};
  };
  out->server_id.assign(m.server_id, strnlen(m.server_id, sizeof(m.server_id)));
  out->wall_time_ns = m.wall_time_ns;
  out->realtime = m.realtime;
  out->haptic_ticks = m.haptic_ticks;
  out->haptic_overruns = m.haptic_overruns;
  out->haptic_lateness_us = copy(m.haptic_lateness_us);
  out->haptic_compute_us = copy(m.haptic_compute_us);
  out->sim_frames = m.sim_frames;
  out->sim_frame_ms = copy(m.sim_frame_ms);
  out->snapshot_age_ms = copy(m.snapshot_age_ms);
  out->sim_stalled = m.sim_stalled;
  out->rejected_nonfinite = m.rejected_nonfinite;
  out->rejected_workspace = m.rejected_workspace;
  out->rejected_seq = m.rejected_seq;
  out->rejected_unknown_device = m.rejected_unknown_device;
  out->rejected_flood = m.rejected_flood;
  out->rejected_not_owner = m.rejected_not_owner;
  out->pointer_accepted = m.pointer_accepted;
  out->forces_published = m.forces_published;
  out->forces_queue_full = m.forces_queue_full;
  out->dds_errors = m.dds_errors;
  out->incompatible_qos = m.incompatible_qos;
  out->nan_events = m.nan_events;
  out->devices_connected = m.devices_connected;
  out->passivity_energy_J = m.passivity_energy_J;
  return true;
}

ClientStats ClientTransport::Stats() const {
  const Impl& impl = *impl_;
  ClientStats s;
  s.pointers_published = impl.published_.load(std::memory_order_relaxed);
  s.forces_received = impl.received_.load(std::memory_order_relaxed);
  s.forces_seq_gaps = impl.gaps_.load(std::memory_order_relaxed);
  s.forces_other = impl.other_.load(std::memory_order_relaxed);
  s.dds_errors = impl.errors_.load(std::memory_order_relaxed);
  return s;
}

uint32_t ClientTransport::MatchedPointerReaders() const {
  return MatchedReaders(impl_->pointer_writer_);
}

uint32_t ClientTransport::MatchedForceWriters() const {
  return MatchedWriters(impl_->force_reader_);
}

uint32_t ClientTransport::MatchedStatusWriters() const {
  if (!impl_->config_.subscribe_status) return 0;
  return MatchedWriters(impl_->status_reader_);
}

bool WaitUntil(const std::function<bool()>& done, std::chrono::nanoseconds timeout,
               std::chrono::nanoseconds poll) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    if (done()) return true;
    if (std::chrono::steady_clock::now() >= deadline) return done();
    std::this_thread::sleep_for(poll);
  }
}

}  // namespace felt::transport
