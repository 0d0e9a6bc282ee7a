#include "transport/server_transport.h"

#include <pthread.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstring>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "felt_types.h"
#include "ros2_types.h"
#include "rt/counters.h"
#include "rt/loop_stats.h"
#include "rt/spsc_queue.h"
#include "rt/triple_buffer.h"
#include "spdlog/spdlog.h"
#include "transport/dds_config.h"
#include "transport/message_views.h"
#include "transport/qos.h"
#include "transport/status_diagnostics.h"

namespace felt::transport {
namespace {

constexpr int kTakeBatch = 16;  // samples per dds_take; more are taken in the next round
constexpr int64_t kHopUnitNs =
    100;  // hop histograms: exact 0.1 us bins to 25.6 us, then < 0.8 % wide

// The percentiles of one hop histogram in us. Not real-time: copies the bins (~20 KB).
HopSummary SummarizeHops(const Histogram& hops) {
  HistogramSnapshot snapshot;
  hops.Snapshot(&snapshot);
  HopSummary s;
  s.count = snapshot.count;
  if (s.count == 0) return s;
  s.mean_us = snapshot.MeanNs() / 1e3;
  s.p50_us = static_cast<double>(snapshot.PercentileNs(0.5)) / 1e3;
  s.p99_us = static_cast<double>(snapshot.PercentileNs(0.99)) / 1e3;
  s.p999_us = static_cast<double>(snapshot.PercentileNs(0.999)) / 1e3;
  s.max_us = static_cast<double>(snapshot.max_ns) / 1e3;
  return s;
}

uint64_t Load(const std::atomic<uint64_t>& counter) {
  return counter.load(std::memory_order_relaxed);
}

bool AllFinite(const double (&v)[3]) {
  return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]);
}

void ValidateConfig(const ServerTransportConfig& config) {
  if (config.devices.empty()) {
    throw std::invalid_argument("ServerTransportConfig.devices: at least one device is required");
  }
  for (size_t i = 0; i < config.devices.size(); ++i) {
    const DeviceLimits& d = config.devices[i];
    const std::string field = "ServerTransportConfig.devices[" + std::to_string(i) + "]";
    char scratch[65];
    CopyId(d.device_id, scratch, field + ".device_id");
    for (size_t j = 0; j < i; ++j) {
      if (config.devices[j].device_id == d.device_id) {
        throw std::invalid_argument(field + ".device_id \"" + d.device_id + "\": listed twice");
      }
    }
    for (int k = 0; k < 3; ++k) {
      if (!(std::isfinite(d.workspace_min_m_D[k]) && std::isfinite(d.workspace_max_m_D[k]) &&
            d.workspace_min_m_D[k] < d.workspace_max_m_D[k])) {
        throw std::invalid_argument(field + ".workspace_min_m_D/workspace_max_m_D: axis " +
                                    std::to_string(k) + " must be finite with min < max");
      }
    }
    if (!(d.max_rate_hz > 0 && std::isfinite(d.max_rate_hz))) {
      throw std::invalid_argument(field + ".max_rate_hz: must be positive and finite");
    }
    if (!(d.burst_samples >= 1 && std::isfinite(d.burst_samples))) {
      throw std::invalid_argument(field + ".burst_samples: must be at least 1");
    }
    if (d.profile == TransportProfile::kRos2) {
      if (!(d.ros2.length_scale > 0 && std::isfinite(d.ros2.length_scale))) {
        throw std::invalid_argument(field + ".ros2.length_scale: must be positive and finite");
      }
      if (!(d.ros2.velocity_scale > 0 && std::isfinite(d.ros2.velocity_scale))) {
        throw std::invalid_argument(field + ".ros2.velocity_scale: must be positive and finite");
      }
      if (d.ros2.wrench_type == Ros2WrenchType::kFloat64MultiArray &&
          (d.ros2.wrench_array_length < 3 || d.ros2.wrench_array_length > 16)) {
        throw std::invalid_argument(field + ".ros2.wrench_array_length: must be 3..16");
      }
    }
  }
  const Ros2MarkerSettings& markers = config.ros2_markers;
  if (!(markers.max_rate_hz > 0 && std::isfinite(markers.max_rate_hz))) {
    throw std::invalid_argument("ServerTransportConfig.ros2_markers.max_rate_hz: must be positive");
  }
  if (!(markers.rate_hz > 0 && markers.rate_hz <= markers.max_rate_hz)) {
    throw std::invalid_argument("ServerTransportConfig.ros2_markers.rate_hz: must be in (0, " +
                                std::to_string(markers.max_rate_hz) + "] (max_rate_hz)");
  }
  if (!markers.device.empty()) {
    bool found = false;
    for (const DeviceLimits& d : config.devices) found = found || d.device_id == markers.device;
    if (!found) {
      throw std::invalid_argument("ServerTransportConfig.ros2_markers.device \"" + markers.device +
                                  "\": not a device of the configuration");
    }
  }
  if (config.force_queue_capacity == 0) {
    throw std::invalid_argument("ServerTransportConfig.force_queue_capacity: must be at least 1");
  }
  if (config.ownership_timeout_ns <= 0) {
    throw std::invalid_argument("ServerTransportConfig.ownership_timeout_ns: must be positive");
  }
}

void NameThisThread(const char* name) { pthread_setname_np(pthread_self(), name); }

}  // namespace

bool Ros2MarkersOn(const ServerTransportConfig& config) {
  if (config.ros2_markers.enabled) return *config.ros2_markers.enabled;
  for (const DeviceLimits& d : config.devices) {
    if (d.profile == TransportProfile::kRos2) return true;
  }
  return false;
}

class ServerTransport::Impl {
 public:
  explicit Impl(ServerTransportConfig config);
  ~Impl();

  // Per-device state of the receive path (receive_mutex_ held) and the haptic thread's slot.
  struct Device {
    char id[65] = {};
    DeviceLimits limits;
    // Receive path only.
    double tokens = 0;
    int64_t last_refill_ns = 0;
    bool has_last = false;  // last_seq holds the owner's last accepted seq
    uint64_t last_seq = 0;
    dds_instance_handle_t owner = 0;  // the writer that owns the device (0: none)
    int64_t owner_last_ns = 0;        // when the owner's last sample arrived
    // Haptic thread only.
    uint64_t next_force_seq = 1;
  };

  // A device on the ROS 2 profile (transport/ros2_profile.h): its topics, readers and writer, and
  // the assembler of its samples (receive path, receive_mutex_ held).
  struct Ros2Device {
    Impl* impl = nullptr;
    size_t index = 0;  // into devices_
    Ros2DeviceTopics topics;
    Entity pose_topic, twist_topic, wrench_topic;
    Entity pose_reader, twist_reader, wrench_writer;
    Ros2PointerAssembler assembler;
    // The frame_id the forces echo (the newest pose's, when topics.frame_id is empty): written
    // by the receive path, read by the writer thread, under frame_mutex.
    std::mutex frame_mutex;
    std::string echoed_frame;
    std::atomic<bool> qos_logged{false};
    // Float64MultiArray only: the data buffer, sized once (writer thread).
    std::vector<double> command;
  };

  static void OnDataAvailable(dds_entity_t reader, void* arg);
  static void OnRos2Pose(dds_entity_t reader, void* arg);
  static void OnRos2Twist(dds_entity_t reader, void* arg);
  static void OnRos2OmniState(dds_entity_t reader, void* arg);
  // A sample assembled from a ROS 2 message, through the same gate as felt/pointer (Accept);
  // notes the pose's frame for the forces to echo. Receive path, receive_mutex_ held.
  void AcceptRos2(Ros2Device* device, const Ros2Pointer& in, const char* frame_id,
                  dds_instance_handle_t writer, int64_t now_ns);
  void CreateRos2Entities(Ros2Device* device, const Qos& reader_qos);
  void WriteRos2Force(Ros2Device* device, const ForceCommandView& force,
                      geometry_msgs_msg_dds__WrenchStamped_* message, std::string* frame);
  void WriteOmniFeedback(Ros2Device* device, const ForceCommandView& force);
  void WriteFloat64MultiArray(Ros2Device* device, const ForceCommandView& force);
  void WaitsetLoop();
  void WriterLoop();
  void DrainPointers();
  void Accept(const felt_msgs_PointerSample& sample, dds_instance_handle_t writer, int64_t now_ns);
  // True while `writer` is matched to the pointer reader (or when that cannot be told: an error,
  // more than kMatchedCapacity writers). Receive thread; allocates nothing.
  bool StillMatched(const Entity& reader, dds_instance_handle_t writer);
  static constexpr size_t kMatchedCapacity = 64;
  std::array<dds_instance_handle_t, kMatchedCapacity> matched_{};  // StillMatched's buffer
  // An instance state change (invalid sample): the owner that disposed or unregistered its
  // device's instance gives the device up at once.
  void Release(const felt_msgs_PointerSample& key, const dds_sample_info_t& info);
  // Counts a sample of a device the scene does not have (any receive thread: a read-modify-write)
  // and logs the first one, with the ids the scene has.
  void CountUnknownDevice(const char* id);
  // Index of device `id` in devices_, or devices_.size() when the scene does not have it.
  size_t DeviceIndex(const char* id) const;
  // The pointer topic's filter (Cyclone's receive threads): true for a device of the scene; an
  // unknown one is counted (rejected_unknown_device) and its first sample logged.
  static bool KnownDeviceFilter(const void* sample, void* arg);
  // DDS peers whose QoS does not match: the pointer reader's requested-incompatible total plus
  // the force and status writers' offered-incompatible totals. The first mismatch of each entity
  // is logged once with the policy's name (docs/transport.md). Any thread.
  uint64_t IncompatibleQos() const;
  mutable std::array<std::atomic<bool>, 3> qos_logged_{};

  ServerTransportConfig config_;
  std::vector<Device> devices_;
  std::unique_ptr<TripleBuffer<PointerSampleView>[]> slots_;
  std::unique_ptr<ArrivalSignal[]> arrivals_;  // per device: counts what reaches its slot
  SpscQueue<ForceCommandView> forces_;

  // DDS entities, deleted in reverse order by the destructor.
  Participant participant_;
  Entity pointer_topic_, force_topic_, status_topic_;
  Entity pointer_reader_, force_writer_, status_writer_;
  Entity waitset_, stop_guard_, read_condition_;
  Entity diagnostics_topic_, diagnostics_writer_;  // ROS 2 diagnostics (absent: off)
  Entity markers_topic_, markers_writer_;          // ROS 2 markers (absent: off)
  // PublishMarkers' IDL buffers, reused between calls (markers_mutex_ held).
  std::mutex markers_mutex_;
  std::vector<visualization_msgs_msg_dds__Marker_> marker_structs_;
  std::vector<std::vector<geometry_msgs_msg_dds__Point_>> marker_points_;
  std::vector<std::vector<std_msgs_msg_dds__ColorRGBA_>> marker_colors_;
  std::atomic<uint64_t> markers_{0}, dds_errors_markers_{0};
  // Writes `status` (transport fields already filled) as a DiagnosticArray. Monitor thread.
  bool WriteDiagnostics(const ServerStatusView& status);

  // Receive path: the listener may be called on more than one Cyclone thread over time (the
  // receive thread, or a local writer's thread), and each slot is single-producer, so takes are
  // serialised here. The haptic thread never touches this mutex.
  std::mutex receive_mutex_;
  std::array<felt_msgs_PointerSample, kTakeBatch> take_buffer_{};
  std::vector<std::unique_ptr<Ros2Device>> ros2_;  // [devices]; null: Felt's profile
  std::array<void*, kTakeBatch> take_ptrs_{};
  std::array<dds_sample_info_t, kTakeBatch> take_infos_{};

  std::thread waitset_thread_, writer_thread_;
  std::atomic<bool> stop_receive_{false};
  std::atomic<bool> stop_writer_{false};
  std::atomic<uint32_t> force_epoch_{0};  // bumped per push; the writer thread waits on it

  std::atomic<uint64_t> accepted_{0}, nonfinite_{0}, workspace_{0}, seq_{0}, unknown_{0}, flood_{0};
  std::atomic<uint64_t> not_owner_{0}, ownership_changes_{0};
  std::atomic<uint64_t> pushed_{0}, queue_full_{0}, bad_device_{0}, published_{0}, statuses_{0};
  std::atomic<uint64_t> dds_errors_receive_{0}, dds_errors_write_{0}, dds_errors_status_{0};
  // Hop costs: one writer each (the receive path; the writer thread), 0.1 us resolution.
  Histogram receive_hop_{kHopUnitNs}, write_hop_{kHopUnitNs};
};

ServerTransport::Impl::Impl(ServerTransportConfig config)
    : config_((ValidateConfig(config), std::move(config))),
      devices_(config_.devices.size()),
      slots_(new TripleBuffer<PointerSampleView>[config_.devices.size()]),
      arrivals_(new ArrivalSignal[config_.devices.size()]),
      forces_(config_.force_queue_capacity),
      participant_(config_.dds, "server") {
  // Devices: ids as fixed C strings for allocation-free comparison; full token buckets.
  const int64_t now_ns = MonotonicNowNs();
  for (size_t i = 0; i < devices_.size(); ++i) {
    devices_[i].limits = config_.devices[i];
    CopyId(config_.devices[i].device_id, devices_[i].id, "device_id");
    devices_[i].tokens = devices_[i].limits.burst_samples;
    devices_[i].last_refill_ns = now_ns;
  }
  for (int i = 0; i < kTakeBatch; ++i) take_ptrs_[i] = &take_buffer_[i];

  // Topics, writers, and the pointer reader (last, so nothing arrives before the rest exists).
  pointer_topic_ = CreateTopic(participant_, &felt_msgs_PointerSample_desc, config_.topics.pointer);
  // A sample for a device the scene does not have is dropped by the topic's filter, before the
  // reader stores it: its key never becomes an instance, so a peer sending ever new ids cannot
  // grow the server's memory (issue 23). Set before the reader exists, as Cyclone requires.
  CheckDds(dds_set_topic_filter_and_arg(pointer_topic_.get(), &Impl::KnownDeviceFilter, this),
           "dds_set_topic_filter_and_arg");
  force_topic_ = CreateTopic(participant_, &felt_msgs_ForceCommand_desc, config_.topics.force);
  status_topic_ = CreateTopic(participant_, &felt_msgs_ServerStatus_desc, config_.topics.status);
  const Qos stream_qos = StreamQos();
  const Qos reader_qos = StreamReaderQos();
  const Qos status_qos = StatusQos();
  force_writer_ = CreateWriter(participant_, force_topic_, stream_qos.get(), config_.topics.force);
  status_writer_ =
      CreateWriter(participant_, status_topic_, status_qos.get(), config_.topics.status);

  // Writer thread first: PushForce may be called as soon as the constructor returns.
  writer_thread_ = std::thread([this] { WriterLoop(); });

  try {
    if (config_.receive_mode == ReceiveMode::kListener) {
      std::unique_ptr<dds_listener_t, void (*)(dds_listener_t*)> listener(dds_create_listener(this),
                                                                          &dds_delete_listener);
      if (!listener) throw std::bad_alloc();
      dds_lset_data_available(listener.get(), &Impl::OnDataAvailable);
      pointer_reader_ = CreateReader(participant_, pointer_topic_, reader_qos.get(), listener.get(),
                                     config_.topics.pointer);
    } else {
      pointer_reader_ = CreateReader(participant_, pointer_topic_, reader_qos.get(), nullptr,
                                     config_.topics.pointer);
      waitset_ = Entity(CheckDds(dds_create_waitset(participant_.get()), "dds_create_waitset"));
      stop_guard_ = Entity(
          CheckDds(dds_create_guardcondition(participant_.get()), "dds_create_guardcondition"));
      read_condition_ =
          Entity(CheckDds(dds_create_readcondition(pointer_reader_.get(), DDS_ANY_STATE),
                          "dds_create_readcondition"));
      CheckDds(dds_waitset_attach(waitset_.get(), stop_guard_.get(), 0), "dds_waitset_attach");
      CheckDds(dds_waitset_attach(waitset_.get(), read_condition_.get(), 1), "dds_waitset_attach");
      waitset_thread_ = std::thread([this] { WaitsetLoop(); });
    }
    // ROS 2 diagnostics, when asked for or when a device speaks ROS 2.
    bool diagnostics = config_.ros2_diagnostics;
    for (const DeviceLimits& d : config_.devices) {
      diagnostics = diagnostics || d.profile == TransportProfile::kRos2;
    }
    if (diagnostics) {
      const std::string topic =
          Ros2DdsTopic(config_.ros2_diagnostics_topic, "ros2_diagnostics_topic");
      diagnostics_topic_ =
          CreateTopic(participant_, &diagnostic_msgs_msg_dds__DiagnosticArray__desc, topic);
      const Qos diagnostics_qos = Ros2DiagnosticsWriterQos();
      diagnostics_writer_ =
          CreateWriter(participant_, diagnostics_topic_, diagnostics_qos.get(), topic);
    }
    // ROS 2 markers (the marker feed publishes them), when on.
    if (Ros2MarkersOn(config_)) {
      const std::string topic = Ros2DdsTopic(config_.ros2_markers.topic, "ros2_markers_topic");
      markers_topic_ =
          CreateTopic(participant_, &visualization_msgs_msg_dds__MarkerArray__desc, topic);
      const Qos markers_qos = Ros2MarkerWriterQos();
      markers_writer_ = CreateWriter(participant_, markers_topic_, markers_qos.get(), topic);
    }
    // The ROS 2 profile's devices: listeners on Cyclone's receive thread in either mode.
    ros2_.resize(devices_.size());
    for (size_t i = 0; i < devices_.size(); ++i) {
      if (config_.devices[i].profile != TransportProfile::kRos2) continue;
      ros2_[i] = std::make_unique<Ros2Device>();
      ros2_[i]->impl = this;
      ros2_[i]->index = i;
      CreateRos2Entities(ros2_[i].get(), reader_qos);
    }
  } catch (...) {
    for (auto& d : ros2_) {
      if (d == nullptr) continue;
      (void)dds_set_listener(d->pose_reader.get(), nullptr);
      (void)dds_set_listener(d->twist_reader.get(), nullptr);
    }
    stop_writer_.store(true);
    force_epoch_.fetch_add(1, std::memory_order_release);
    force_epoch_.notify_one();
    writer_thread_.join();
    throw;
  }
}

ServerTransport::Impl::~Impl() {
  // 1. Stop receiving: no callback or waitset wake-up runs after this block.
  if (config_.receive_mode == ReceiveMode::kListener) {
    (void)dds_set_listener(pointer_reader_.get(), nullptr);  // waits for a running callback
  } else {
    stop_receive_.store(true);
    (void)dds_set_guardcondition(stop_guard_.get(), true);
    if (waitset_thread_.joinable()) waitset_thread_.join();
  }
  pointer_reader_.Reset();
  for (auto& d : ros2_) {
    if (d == nullptr) continue;
    (void)dds_set_listener(d->pose_reader.get(), nullptr);
    (void)dds_set_listener(d->twist_reader.get(), nullptr);
    d->pose_reader.Reset();
    d->twist_reader.Reset();
  }
  // 2. Publish what is queued, then stop the writer thread.
  stop_writer_.store(true);
  force_epoch_.fetch_add(1, std::memory_order_release);
  force_epoch_.notify_one();
  if (writer_thread_.joinable()) writer_thread_.join();
  // 3. The remaining entities go with their members (conditions, waitset, writers, topics), and
  //    the participant last.
  read_condition_.Reset();
  stop_guard_.Reset();
  waitset_.Reset();
}

void ServerTransport::Impl::OnDataAvailable(dds_entity_t /*reader*/, void* arg) {
  static_cast<Impl*>(arg)->DrainPointers();
}

void ServerTransport::Impl::WaitsetLoop() {
  NameThisThread("felt-dds-recv");
  while (!stop_receive_.load()) {
    // Block until a sample or the stop guard; the result only says how many triggered.
    const dds_return_t n = dds_waitset_wait(waitset_.get(), nullptr, 0, DDS_INFINITY);
    if (n < 0) {
      Bump(dds_errors_receive_);
      continue;
    }
    if (stop_receive_.load()) break;
    DrainPointers();
  }
}

void ServerTransport::Impl::DrainPointers() {
  std::lock_guard<std::mutex> lock(receive_mutex_);
  const int64_t start_ns = MonotonicNowNs();
  // Take everything available, validating each sample (TakeEverySample: preallocated buffers).
  const bool ok = TakeEverySample(
      pointer_reader_, take_ptrs_, take_infos_,
      [&](size_t i, int64_t now_ns) {
        Accept(take_buffer_[i], take_infos_[i].publication_handle, now_ns);
      },
      [&](size_t i) { Release(take_buffer_[i], take_infos_[i]); });
  if (!ok) Bump(dds_errors_receive_);
  receive_hop_.Record(MonotonicNowNs() - start_ns);
}

void ServerTransport::Impl::CountUnknownDevice(const char* id) {
  if (unknown_.fetch_add(1, std::memory_order_relaxed) != 0) return;
  std::string known;
  for (const Device& d : devices_) known += std::string(known.empty() ? "'" : ", '") + d.id + "'";
  spdlog::warn(
      "felt/pointer: samples for device '{}', which this scene does not have (it has {}), are "
      "ignored and counted (rejected_unknown_device); logged once",
      std::string(id, strnlen(id, sizeof(Device::id))), known);
}

uint64_t ServerTransport::Impl::IncompatibleQos() const {
  uint64_t total = 0;
  const auto note = [&](size_t k, const char* role, const std::string& topic, uint32_t count,
                        uint32_t policy) {
    total += count;
    if (count > 0 && !qos_logged_[k].exchange(true)) {
      spdlog::warn(
          "{} of {}: a DDS peer's QoS does not match ({} policy): no data flows between them; "
          "counted in felt/status (incompatible_qos), logged once (docs/transport.md, QoS)",
          role, topic, QosPolicyName(policy));
    }
  };
  dds_requested_incompatible_qos_status_t requested{};
  if (dds_get_requested_incompatible_qos_status(pointer_reader_.get(), &requested) >= 0) {
    note(0, "reader", config_.topics.pointer, requested.total_count, requested.last_policy_id);
  }
  dds_offered_incompatible_qos_status_t offered{};
  if (dds_get_offered_incompatible_qos_status(force_writer_.get(), &offered) >= 0) {
    note(1, "writer", config_.topics.force, offered.total_count, offered.last_policy_id);
  }
  offered = {};
  if (dds_get_offered_incompatible_qos_status(status_writer_.get(), &offered) >= 0) {
    note(2, "writer", config_.topics.status, offered.total_count, offered.last_policy_id);
  }
  for (const auto& d : ros2_) {
    if (d == nullptr) continue;
    uint32_t count = 0, policy = 0;
    requested = {};
    if (dds_get_requested_incompatible_qos_status(d->pose_reader.get(), &requested) >= 0) {
      count += requested.total_count;
      policy = requested.last_policy_id;
    }
    offered = {};
    if (dds_get_offered_incompatible_qos_status(d->wrench_writer.get(), &offered) >= 0) {
      count += offered.total_count;
      if (offered.total_count > 0) policy = offered.last_policy_id;
    }
    total += count;
    if (count > 0 && !d->qos_logged.exchange(true)) {
      spdlog::warn(
          "device '{}' (ROS 2 profile, {} / {}): a DDS peer's QoS does not match ({} policy): no "
          "data flows between them; counted in felt/status (incompatible_qos), logged once",
          config_.devices[d->index].device_id, d->topics.pose, d->topics.wrench,
          QosPolicyName(policy));
    }
  }
  return total;
}

bool ServerTransport::Impl::StillMatched(const Entity& reader, dds_instance_handle_t writer) {
  const dds_return_t n =
      dds_get_matched_publications(reader.get(), matched_.data(), matched_.size());
  if (n < 0 || static_cast<size_t>(n) > matched_.size()) return true;
  return std::find(matched_.begin(), matched_.begin() + n, writer) != matched_.begin() + n;
}

void ServerTransport::Impl::Release(const felt_msgs_PointerSample& key,
                                    const dds_sample_info_t& info) {
  if (info.instance_state == DDS_IST_ALIVE) return;
  const size_t index = DeviceIndex(key.device_id);
  if (index == devices_.size()) return;
  Device& device = devices_[index];
  if (device.owner == info.publication_handle) device.owner = 0;
}

size_t ServerTransport::Impl::DeviceIndex(const char* id) const {
  size_t index = 0;
  while (index < devices_.size() &&
         std::strncmp(devices_[index].id, id, sizeof(devices_[index].id)) != 0) {
    ++index;
  }
  return index;
}

bool ServerTransport::Impl::KnownDeviceFilter(const void* sample, void* arg) {
  Impl& impl = *static_cast<Impl*>(arg);
  const char* id = static_cast<const felt_msgs_PointerSample*>(sample)->device_id;
  if (impl.DeviceIndex(id) < impl.devices_.size()) return true;
  impl.CountUnknownDevice(id);
  return false;
}

void ServerTransport::Impl::Accept(const felt_msgs_PointerSample& sample,
                                   dds_instance_handle_t writer, int64_t now_ns) {
  // Unknown device: the topic's filter drops those (KnownDeviceFilter); checked again here.
  const size_t index = DeviceIndex(sample.device_id);
  if (index == devices_.size()) {
    return CountUnknownDevice(sample.device_id);
  }
  Device& device = devices_[index];

  // Ownership: another writer's sample is refused while the owner is heard and still matched;
  // after its silence the next writer's sample takes the device over; one that has left (no
  // longer matched, or disposed: Release) leaves the device free.
  const Entity& reader =
      ros2_.empty() || ros2_[index] == nullptr ? pointer_reader_ : ros2_[index]->pose_reader;
  if (device.owner != 0 && writer != device.owner && StillMatched(reader, device.owner)) {
    if (now_ns - device.owner_last_ns < config_.ownership_timeout_ns) return Bump(not_owner_);
    Bump(ownership_changes_);
  }
  // A new owner (a restarted driver, or after a silence) numbers its samples afresh.
  if (writer != device.owner) device.has_last = false;
  device.owner = writer;
  device.owner_last_ns = now_ns;

  // Flood: a token bucket of max_rate_hz with burst_samples depth; every sample costs a token.
  const double refill =
      static_cast<double>(now_ns - device.last_refill_ns) * 1e-9 * device.limits.max_rate_hz;
  device.tokens = std::min(device.limits.burst_samples, device.tokens + refill);
  device.last_refill_ns = now_ns;
  if (device.tokens < 1.0) return Bump(flood_);
  device.tokens -= 1.0;

  // Non-finite position or velocity.
  if (!AllFinite(sample.position_m) || !AllFinite(sample.velocity_m_per_s)) {
    return Bump(nonfinite_);
  }

  // Outside the device's workspace box (device frame).
  for (int k = 0; k < 3; ++k) {
    if (sample.position_m[k] < device.limits.workspace_min_m_D[k] ||
        sample.position_m[k] > device.limits.workspace_max_m_D[k]) {
      return Bump(workspace_);
    }
  }

  // Sequence: strictly increasing for the owner.
  if (device.has_last && sample.seq <= device.last_seq) return Bump(seq_);
  device.has_last = true;
  device.last_seq = sample.seq;

  // Accepted: into the device's slot for the haptic thread.
  TripleBuffer<PointerSampleView>& slot = slots_[index];
  slot.write_slot() = PointerViewOf(sample, static_cast<uint32_t>(index), now_ns);
  slot.Publish();
  arrivals_[index].Notify(now_ns);  // after the publication: a woken haptic tick reads it
  Bump(accepted_);
}

void ServerTransport::Impl::WriterLoop() {
  NameThisThread("felt-dds-force");
  felt_msgs_ForceCommand message{};
  geometry_msgs_msg_dds__WrenchStamped_ wrench{};
  std::string frame;
  frame.reserve(256);
  ForceCommandView force;
  for (;;) {
    // Read the epoch before draining: a push after this read changes it, so wait() returns.
    const uint32_t epoch = force_epoch_.load(std::memory_order_acquire);
    while (forces_.TryPop(&force)) {
      const int64_t start_ns = MonotonicNowNs();
      Ros2Device* ros2 = ros2_.empty() ? nullptr : ros2_[force.device_index].get();
      if (ros2 != nullptr) {
        if (ros2->topics.wrench_type == Ros2WrenchType::kOmniFeedback) {
          WriteOmniFeedback(ros2, force);
        } else if (ros2->topics.wrench_type == Ros2WrenchType::kFloat64MultiArray) {
          WriteFloat64MultiArray(ros2, force);
        } else {
          WriteRos2Force(ros2, force, &wrench, &frame);
        }
        write_hop_.Record(MonotonicNowNs() - start_ns);
        continue;
      }
      FillForceMessage(force, devices_[force.device_index].id, &message);
      if (dds_write(force_writer_.get(), &message) < 0) {
        Bump(dds_errors_write_);
      } else {
        Bump(published_);
      }
      write_hop_.Record(MonotonicNowNs() - start_ns);
    }
    if (stop_writer_.load()) break;  // after the drain: nothing queued is left behind
    force_epoch_.wait(epoch, std::memory_order_acquire);
  }
}

void ServerTransport::Impl::CreateRos2Entities(Ros2Device* d, const Qos& reader_qos) {
  const DeviceLimits& limits = config_.devices[d->index];
  const Ros2DeviceTopics defaults = DefaultRos2Topics(limits.device_id);
  d->topics = limits.ros2;
  if (d->topics.pose.empty()) d->topics.pose = defaults.pose;
  if (d->topics.wrench.empty()) d->topics.wrench = defaults.wrench;
  const std::string what = "device '" + limits.device_id + "' (profile ros2): ";
  const std::string pose = Ros2DdsTopic(d->topics.pose, what + "pose topic");
  const std::string wrench = Ros2DdsTopic(d->topics.wrench, what + "wrench topic");
  const bool omni_state = d->topics.pose_type == Ros2PoseType::kOmniState;
  d->pose_topic = CreateTopic(
      participant_,
      omni_state ? &omni_msgs_msg_dds__OmniState__desc : &geometry_msgs_msg_dds__PoseStamped__desc,
      pose);
  const dds_topic_descriptor_t* wrench_desc = &geometry_msgs_msg_dds__WrenchStamped__desc;
  if (d->topics.wrench_type == Ros2WrenchType::kOmniFeedback) {
    wrench_desc = &omni_msgs_msg_dds__OmniFeedback__desc;
  } else if (d->topics.wrench_type == Ros2WrenchType::kFloat64MultiArray) {
    wrench_desc = &std_msgs_msg_dds__Float64MultiArray__desc;
    d->command.assign(d->topics.wrench_array_length, 0.0);
  }
  d->wrench_topic = CreateTopic(participant_, wrench_desc, wrench);
  const Qos writer_qos = Ros2WrenchWriterQos();
  d->wrench_writer = CreateWriter(participant_, d->wrench_topic, writer_qos.get(), wrench);
  using ListenerPtr = std::unique_ptr<dds_listener_t, void (*)(dds_listener_t*)>;
  // OmniState carries its velocity: such a device reads no twist.
  if (!d->topics.twist.empty() && !omni_state) {
    const std::string twist = Ros2DdsTopic(d->topics.twist, what + "twist topic");
    d->twist_topic = CreateTopic(participant_, &geometry_msgs_msg_dds__TwistStamped__desc, twist);
    ListenerPtr listener(dds_create_listener(d), &dds_delete_listener);
    if (!listener) throw std::bad_alloc();
    dds_lset_data_available(listener.get(), &Impl::OnRos2Twist);
    d->twist_reader =
        CreateReader(participant_, d->twist_topic, reader_qos.get(), listener.get(), twist);
  }
  ListenerPtr listener(dds_create_listener(d), &dds_delete_listener);
  if (!listener) throw std::bad_alloc();
  dds_lset_data_available(listener.get(), omni_state ? &Impl::OnRos2OmniState : &Impl::OnRos2Pose);
  d->pose_reader =
      CreateReader(participant_, d->pose_topic, reader_qos.get(), listener.get(), pose);
}

// Takes every sample of `reader` on loan (ROS 2's types hold unbounded strings, which Cyclone
// allocates), calling on_valid(sample, info, now_ns) for each that holds data.
template <class T, class OnValid>
bool TakeLoaned(dds_entity_t reader, OnValid&& on_valid) {
  constexpr int kBatch = 16;
  for (;;) {
    std::array<void*, kBatch> ptrs{};
    std::array<dds_sample_info_t, kBatch> infos{};
    const dds_return_t n = dds_take(reader, ptrs.data(), infos.data(), kBatch, kBatch);
    if (n < 0) return false;
    const int64_t now_ns = MonotonicNowNs();
    for (dds_return_t i = 0; i < n; ++i) {
      if (infos[static_cast<size_t>(i)].valid_data) {
        on_valid(*static_cast<const T*>(ptrs[static_cast<size_t>(i)]),
                 infos[static_cast<size_t>(i)], now_ns);
      }
    }
    if (n > 0) (void)dds_return_loan(reader, ptrs.data(), n);
    if (n < kBatch) return true;
  }
}

void ServerTransport::Impl::AcceptRos2(Ros2Device* d, const Ros2Pointer& in, const char* frame_id,
                                       dds_instance_handle_t writer, int64_t now_ns) {
  felt_msgs_PointerSample sample{};
  std::memcpy(sample.device_id, devices_[d->index].id, sizeof(sample.device_id));
  sample.seq = in.seq;
  sample.device_time_ns = in.device_time_ns;
  for (int k = 0; k < 3; ++k) {
    sample.position_m[k] = in.position_m[k];
    sample.velocity_m_per_s[k] = in.velocity_m_per_s[k];
  }
  Accept(sample, writer, now_ns);
  if (d->topics.frame_id.empty() && frame_id != nullptr) {
    std::lock_guard<std::mutex> frame_lock(d->frame_mutex);
    if (d->echoed_frame != frame_id) d->echoed_frame.assign(frame_id);
  }
}

void ServerTransport::Impl::OnRos2Pose(dds_entity_t reader, void* arg) {
  Ros2Device& d = *static_cast<Ros2Device*>(arg);
  Impl& impl = *d.impl;
  std::lock_guard<std::mutex> lock(impl.receive_mutex_);
  const int64_t start_ns = MonotonicNowNs();
  const double scale = d.topics.length_scale;
  const bool ok = TakeLoaned<geometry_msgs_msg_dds__PoseStamped_>(
      reader, [&](const geometry_msgs_msg_dds__PoseStamped_& m, const dds_sample_info_t& info,
                  int64_t now_ns) {
        const double p[3] = {m.pose.position.x * scale, m.pose.position.y * scale,
                             m.pose.position.z * scale};
        const Ros2Pointer in =
            d.assembler.Pose(Ros2StampNs(m.header.stamp.sec, m.header.stamp.nanosec), p);
        impl.AcceptRos2(&d, in, m.header.frame_id, info.publication_handle, now_ns);
      });
  if (!ok) Bump(impl.dds_errors_receive_);
  impl.receive_hop_.Record(MonotonicNowNs() - start_ns);
}

void ServerTransport::Impl::OnRos2OmniState(dds_entity_t reader, void* arg) {
  Ros2Device& d = *static_cast<Ros2Device*>(arg);
  Impl& impl = *d.impl;
  std::lock_guard<std::mutex> lock(impl.receive_mutex_);
  const int64_t start_ns = MonotonicNowNs();
  const double scale = d.topics.length_scale;
  const double velocity_scale = d.topics.velocity_scale;
  const bool ok = TakeLoaned<omni_msgs_msg_dds__OmniState_>(
      reader,
      [&](const omni_msgs_msg_dds__OmniState_& m, const dds_sample_info_t& info, int64_t now_ns) {
        // The driver's units to SI: position [units] * length_scale, velocity * velocity_scale.
        const double p[3] = {m.pose.position.x * scale, m.pose.position.y * scale,
                             m.pose.position.z * scale};
        const double v[3] = {m.velocity.x * velocity_scale, m.velocity.y * velocity_scale,
                             m.velocity.z * velocity_scale};
        const int64_t stamp_ns = Ros2StampNs(m.header.stamp.sec, m.header.stamp.nanosec);
        d.assembler.Twist(stamp_ns, v);  // the same stamp: the assembler uses this velocity
        const Ros2Pointer in = d.assembler.Pose(stamp_ns, p);
        impl.AcceptRos2(&d, in, m.header.frame_id, info.publication_handle, now_ns);
      });
  if (!ok) Bump(impl.dds_errors_receive_);
  impl.receive_hop_.Record(MonotonicNowNs() - start_ns);
}

void ServerTransport::Impl::OnRos2Twist(dds_entity_t reader, void* arg) {
  Ros2Device& d = *static_cast<Ros2Device*>(arg);
  Impl& impl = *d.impl;
  std::lock_guard<std::mutex> lock(impl.receive_mutex_);
  const bool ok = TakeLoaned<geometry_msgs_msg_dds__TwistStamped_>(
      reader,
      [&](const geometry_msgs_msg_dds__TwistStamped_& m, const dds_sample_info_t&, int64_t) {
        const double vs = d.topics.velocity_scale;
        const double v[3] = {m.twist.linear.x * vs, m.twist.linear.y * vs, m.twist.linear.z * vs};
        d.assembler.Twist(Ros2StampNs(m.header.stamp.sec, m.header.stamp.nanosec), v);
      });
  if (!ok) Bump(impl.dds_errors_receive_);
}

void ServerTransport::Impl::WriteRos2Force(Ros2Device* d, const ForceCommandView& force,
                                           geometry_msgs_msg_dds__WrenchStamped_* m,
                                           std::string* frame) {
  // The stamp of the pose this force answers: the driver pairs them without a common clock.
  Ros2StampOf(force.answers_device_time_ns, &m->header.stamp.sec, &m->header.stamp.nanosec);
  if (!d->topics.frame_id.empty()) {
    *frame = d->topics.frame_id;
  } else {
    std::lock_guard<std::mutex> lock(d->frame_mutex);
    *frame = d->echoed_frame;
  }
  m->header.frame_id = frame->data();
  m->wrench.force.x = force.force_N_D[0];
  m->wrench.force.y = force.force_N_D[1];
  m->wrench.force.z = force.force_N_D[2];
  m->wrench.torque = geometry_msgs_msg_dds__Vector3_{0.0, 0.0, 0.0};
  if (dds_write(d->wrench_writer.get(), m) < 0) {
    Bump(dds_errors_write_);
  } else {
    Bump(published_);
  }
}

void ServerTransport::Impl::WriteOmniFeedback(Ros2Device* d, const ForceCommandView& force) {
  // Force [N] in the driver's frame (that of its pose); the lock position, which the driver
  // reads only when locked, is the proxy's position in the driver's units.
  omni_msgs_msg_dds__OmniFeedback_ m{};
  const double per_unit = 1.0 / d->topics.length_scale;
  m.force = {force.force_N_D[0], force.force_N_D[1], force.force_N_D[2]};
  m.position = {force.proxy_position_m_D[0] * per_unit, force.proxy_position_m_D[1] * per_unit,
                force.proxy_position_m_D[2] * per_unit};
  if (dds_write(d->wrench_writer.get(), &m) < 0) {
    Bump(dds_errors_write_);
  } else {
    Bump(published_);
  }
}

void ServerTransport::Impl::WriteFloat64MultiArray(Ros2Device* d, const ForceCommandView& force) {
  // data = [fx, fy, fz, 0, ...]: the controller's joints in order (forcedimension_ros2's
  // fd_controllers.yaml: fd_x, fd_y, fd_z, then roll, pitch, yaw torques and the gripper), N;
  // layout empty, as `ros2 topic pub ... "data: [...]"` sends it.
  for (int k = 0; k < 3; ++k) d->command[static_cast<size_t>(k)] = force.force_N_D[k];
  std_msgs_msg_dds__Float64MultiArray_ m{};
  m.layout.dim = {0, 0, nullptr, false};
  m.layout.data_offset = 0;
  m.data._maximum = m.data._length = static_cast<uint32_t>(d->command.size());
  m.data._buffer = d->command.data();
  m.data._release = false;
  if (dds_write(d->wrench_writer.get(), &m) < 0) {
    Bump(dds_errors_write_);
  } else {
    Bump(published_);
  }
}

ServerTransport::ServerTransport(ServerTransportConfig config)
    : impl_(std::make_unique<Impl>(std::move(config))) {}

ServerTransport::~ServerTransport() = default;

size_t ServerTransport::device_count() const { return impl_->devices_.size(); }

int ServerTransport::DeviceIndex(const std::string& device_id) const {
  for (size_t i = 0; i < impl_->devices_.size(); ++i) {
    if (impl_->config_.devices[i].device_id == device_id) return static_cast<int>(i);
  }
  return -1;
}

bool ServerTransport::LatestPointer(uint32_t device_index, PointerSampleView* out) {
  if (device_index >= impl_->devices_.size()) return false;
  TripleBuffer<PointerSampleView>& slot = impl_->slots_[device_index];
  slot.Acquire();
  const PointerSampleView& newest = slot.read_slot();
  if (newest.receive_time_ns == 0) return false;  // nothing accepted yet
  *out = newest;
  return true;
}

const ArrivalSignal* ServerTransport::Arrivals(uint32_t device_index) const {
  return device_index < impl_->devices_.size() ? &impl_->arrivals_[device_index] : nullptr;
}

bool ServerTransport::PushForce(const ForceCommandView& force) {
  Impl& impl = *impl_;
  if (force.device_index >= impl.devices_.size()) {
    Bump(impl.bad_device_);
    return false;
  }
  ForceCommandView queued = force;
  queued.seq = impl.devices_[force.device_index].next_force_seq++;
  if (!impl.forces_.TryPush(queued)) {
    Bump(impl.queue_full_);
    return false;
  }
  Bump(impl.pushed_);
  impl.force_epoch_.fetch_add(1, std::memory_order_release);
  impl.force_epoch_.notify_one();  // a futex wake only when the writer thread sleeps
  return true;
}

bool ServerTransport::PublishStatus(const ServerStatusView& status) {
  Impl& impl = *impl_;
  const TransportStats stats = Stats();
  felt_msgs_ServerStatus message{};
  CopyId(status.server_id, message.server_id, "ServerStatusView.server_id");
  message.wall_time_ns = status.wall_time_ns != 0 ? status.wall_time_ns : WallNowNs();
  message.realtime = status.realtime;
  message.haptic_ticks = status.haptic_ticks;
  message.haptic_overruns = status.haptic_overruns;
  const auto copy = [](const PercentilesView& in, felt_msgs_Percentiles* out) {
    out->p50 = in.p50;
    out->p99 = in.p99;
    out->p999 = in.p999;
    out->max = in.max;
  };
  copy(status.haptic_lateness_us, &message.haptic_lateness_us);
  copy(status.haptic_compute_us, &message.haptic_compute_us);
  message.sim_frames = status.sim_frames;
  copy(status.sim_frame_ms, &message.sim_frame_ms);
  copy(status.snapshot_age_ms, &message.snapshot_age_ms);
  message.sim_stalled = status.sim_stalled;
  // The transport's own counters replace whatever the caller put in these fields.
  message.rejected_nonfinite = stats.rejected_nonfinite;
  message.rejected_workspace = stats.rejected_workspace;
  message.rejected_seq = stats.rejected_seq;
  message.rejected_unknown_device = stats.rejected_unknown_device;
  message.rejected_flood = stats.rejected_flood;
  message.rejected_not_owner = stats.rejected_not_owner;
  message.pointer_accepted = stats.pointer_accepted;
  message.forces_published = stats.forces_published;
  message.forces_queue_full = stats.forces_queue_full;
  message.dds_errors = stats.dds_errors;
  message.incompatible_qos = stats.incompatible_qos;
  message.nan_events = status.nan_events;
  message.devices_connected = status.devices_connected;
  message.passivity_energy_J = status.passivity_energy_J;
  if (dds_write(impl.status_writer_.get(), &message) < 0) {
    impl.dds_errors_status_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  impl.statuses_.fetch_add(1, std::memory_order_relaxed);
  if (impl.diagnostics_writer_.get() != 0) {
    // The same fields as felt/status: the caller's, with the transport's counters.
    ServerStatusView view = status;
    view.wall_time_ns = message.wall_time_ns;
    view.rejected_nonfinite = stats.rejected_nonfinite;
    view.rejected_workspace = stats.rejected_workspace;
    view.rejected_seq = stats.rejected_seq;
    view.rejected_unknown_device = stats.rejected_unknown_device;
    view.rejected_flood = stats.rejected_flood;
    view.rejected_not_owner = stats.rejected_not_owner;
    view.pointer_accepted = stats.pointer_accepted;
    view.forces_published = stats.forces_published;
    view.forces_queue_full = stats.forces_queue_full;
    view.dds_errors = stats.dds_errors;
    view.incompatible_qos = stats.incompatible_qos;
    if (!impl.WriteDiagnostics(view)) {
      impl.dds_errors_status_.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
  }
  return true;
}

bool ServerTransport::Impl::WriteDiagnostics(const ServerStatusView& status) {
  // The message as ros2/messages.h builds it, then the IDL struct pointing into its strings.
  const ros2::DiagnosticArray d = StatusDiagnostics(status);
  using StatusC = diagnostic_msgs_msg_dds__DiagnosticStatus_;
  using KeyValueC = diagnostic_msgs_msg_dds__KeyValue_;
  std::vector<StatusC> statuses(d.status.size());
  std::vector<std::vector<KeyValueC>> values(d.status.size());
  for (size_t i = 0; i < d.status.size(); ++i) {
    const ros2::DiagnosticStatus& in = d.status[i];
    for (const ros2::KeyValue& kv : in.values) {
      values[i].push_back(
          KeyValueC{const_cast<char*>(kv.key.c_str()), const_cast<char*>(kv.value.c_str())});
    }
    StatusC& out = statuses[i];
    out.level = in.level;
    out.name = const_cast<char*>(in.name.c_str());
    out.message = const_cast<char*>(in.message.c_str());
    out.hardware_id = const_cast<char*>(in.hardware_id.c_str());
    out.values._maximum = out.values._length = static_cast<uint32_t>(values[i].size());
    out.values._buffer = values[i].data();
    out.values._release = false;
  }
  diagnostic_msgs_msg_dds__DiagnosticArray_ m{};
  m.header.stamp = {d.header.stamp.sec, d.header.stamp.nanosec};
  m.header.frame_id = const_cast<char*>(d.header.frame_id.c_str());
  m.status._maximum = m.status._length = static_cast<uint32_t>(statuses.size());
  m.status._buffer = statuses.data();
  m.status._release = false;
  return dds_write(diagnostics_writer_.get(), &m) >= 0;
}

bool ServerTransport::markers_enabled() const { return impl_->markers_writer_.get() != 0; }

bool ServerTransport::PublishMarkers(const ros2::MarkerArray& markers) {
  Impl& impl = *impl_;
  if (impl.markers_writer_.get() == 0) return false;
  std::lock_guard<std::mutex> lock(impl.markers_mutex_);
  // The IDL struct pointing into `markers` (strings) and into buffers reused between calls.
  const size_t n = markers.markers.size();
  impl.marker_structs_.resize(n);
  impl.marker_points_.resize(n);
  impl.marker_colors_.resize(n);
  const auto chars = [](const std::string& s) { return const_cast<char*>(s.c_str()); };
  static char empty[] = "";
  for (size_t i = 0; i < n; ++i) {
    const ros2::Marker& in = markers.markers[i];
    visualization_msgs_msg_dds__Marker_& out = impl.marker_structs_[i];
    out = visualization_msgs_msg_dds__Marker_{};
    out.header.stamp = {in.header.stamp.sec, in.header.stamp.nanosec};
    out.header.frame_id = chars(in.header.frame_id);
    out.ns = chars(in.ns);
    out.id = in.id;
    out.type = in.type;
    out.action = in.action;
    out.pose.position = {in.pose.position.x, in.pose.position.y, in.pose.position.z};
    out.pose.orientation = {in.pose.orientation.x, in.pose.orientation.y, in.pose.orientation.z,
                            in.pose.orientation.w};
    out.scale = {in.scale.x, in.scale.y, in.scale.z};
    out.color = {in.color.r, in.color.g, in.color.b, in.color.a};
    out.lifetime = {in.lifetime.sec, in.lifetime.nanosec};
    out.frame_locked = in.frame_locked;
    std::vector<geometry_msgs_msg_dds__Point_>& points = impl.marker_points_[i];
    points.resize(in.points.size());
    for (size_t k = 0; k < in.points.size(); ++k) {
      points[k] = {in.points[k].x, in.points[k].y, in.points[k].z};
    }
    out.points = {static_cast<uint32_t>(points.size()), static_cast<uint32_t>(points.size()),
                  points.data(), false};
    std::vector<std_msgs_msg_dds__ColorRGBA_>& colors = impl.marker_colors_[i];
    colors.resize(in.colors.size());
    for (size_t k = 0; k < in.colors.size(); ++k) {
      colors[k] = {in.colors[k].r, in.colors[k].g, in.colors[k].b, in.colors[k].a};
    }
    out.colors = {static_cast<uint32_t>(colors.size()), static_cast<uint32_t>(colors.size()),
                  colors.data(), false};
    // Humble's fields Felt leaves empty: texture, uv_coordinates, mesh_file.
    out.texture_resource = empty;
    out.texture.header.frame_id = empty;
    out.texture.format = empty;
    out.texture.data = {0, 0, nullptr, false};
    out.uv_coordinates = {0, 0, nullptr, false};
    out.text = chars(in.text);
    out.mesh_resource = chars(in.mesh_resource);
    out.mesh_file.filename = empty;
    out.mesh_file.data = {0, 0, nullptr, false};
    out.mesh_use_embedded_materials = in.mesh_use_embedded_materials;
  }
  visualization_msgs_msg_dds__MarkerArray_ m{};
  m.markers = {static_cast<uint32_t>(n), static_cast<uint32_t>(n), impl.marker_structs_.data(),
               false};
  if (dds_write(impl.markers_writer_.get(), &m) < 0) {
    Bump(impl.dds_errors_markers_);
    return false;
  }
  Bump(impl.markers_);
  return true;
}

uint32_t ServerTransport::MatchedMarkerReaders() const {
  return impl_->markers_writer_.get() == 0 ? 0 : MatchedReaders(impl_->markers_writer_);
}

TransportStats ServerTransport::Stats() const {
  const Impl& impl = *impl_;
  TransportStats s;
  s.pointer_accepted = Load(impl.accepted_);
  s.rejected_nonfinite = Load(impl.nonfinite_);
  s.rejected_workspace = Load(impl.workspace_);
  s.rejected_seq = Load(impl.seq_);
  s.rejected_unknown_device = Load(impl.unknown_);
  s.rejected_flood = Load(impl.flood_);
  s.rejected_not_owner = Load(impl.not_owner_);
  s.ownership_changes = Load(impl.ownership_changes_);
  s.forces_pushed = Load(impl.pushed_);
  s.forces_queue_full = Load(impl.queue_full_);
  s.forces_bad_device = Load(impl.bad_device_);
  s.forces_published = Load(impl.published_);
  s.statuses_published = Load(impl.statuses_);
  s.markers_published = Load(impl.markers_);
  s.dds_errors = Load(impl.dds_errors_receive_) + Load(impl.dds_errors_write_) +
                 Load(impl.dds_errors_status_) + Load(impl.dds_errors_markers_);
  s.incompatible_qos = impl.IncompatibleQos();
  s.receive_hop = SummarizeHops(impl.receive_hop_);
  s.write_hop = SummarizeHops(impl.write_hop_);
  return s;
}

uint32_t ServerTransport::MatchedPointerWriters() const {
  uint32_t n = MatchedWriters(impl_->pointer_reader_);
  for (const auto& d : impl_->ros2_) {
    if (d != nullptr) n += MatchedWriters(d->pose_reader);
  }
  return n;
}

uint32_t ServerTransport::MatchedForceReaders() const {
  uint32_t n = MatchedReaders(impl_->force_writer_);
  for (const auto& d : impl_->ros2_) {
    if (d != nullptr) n += MatchedReaders(d->wrench_writer);
  }
  return n;
}

}  // namespace felt::transport
