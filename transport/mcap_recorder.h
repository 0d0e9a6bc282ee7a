#pragma once
// Recording Felt's DDS streams into ROS 2-profile MCAP (issue 24, docs/mcap.md). The thread that
// takes samples from DDS only copies each one into a bounded single-producer single-consumer
// queue (no allocation, no I/O; a full queue is counted as a drop, never waited on); a writer
// thread turns them into ROS 2 messages (ros2/messages.h) and MCAP records (recordings/mcap.h).
//
// Topics for device D (CRTK names; frames "D/device", SI units):
//   /D/measured_cp  geometry_msgs/PoseStamped    tip position [m], identity orientation;
//                                                stamp = the driver's device_time_ns
//   /D/measured_cv  geometry_msgs/TwistStamped   tip velocity [m/s]; same stamp
//   /D/servo_cf     geometry_msgs/WrenchStamped  the force Felt sent [N]; stamp = the stamp of the
//                                                pose it answers (answers_device_time_ns)
//   /diagnostics    diagnostic_msgs/DiagnosticArray  felt/status, once a second; stamp = the
//                                                server's wall_time_ns
// MCAP log_time is the receiving clock (CLOCK_REALTIME at the take, ns), publish_time the stamp.
// Buttons have no place in these messages and are not recorded.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <variant>

#include "base/non_copyable.h"
#include "rt/spsc_queue.h"
#include "transport/recorder.h"
#include "transport/sequence_tracker.h"
#include "transport/settings.h"
#include "transport/views.h"

namespace felt {
class McapWriter;
}

namespace felt::transport {

/// The ROS 2 topic names of one device: "/<device_id>/measured_cp" etc.
struct McapTopics {
  std::string pose, twist, wrench, diagnostics = "/diagnostics";
  /// The CRTK names under `device_id` as namespace.
  static McapTopics ForDevice(const std::string& device_id);
};

/// Counters of an McapSink (any thread may read them).
struct McapSinkStats {
  uint64_t pointers_written = 0;  ///< PoseStamped (+ TwistStamped) pairs written
  uint64_t forces_written = 0;    ///< WrenchStamped written
  uint64_t statuses_written = 0;  ///< DiagnosticArray written
  uint64_t queue_drops = 0;       ///< samples refused because the queue was full
  uint64_t max_queue_depth = 0;   ///< most samples waiting at once (seen by the writer)
  uint64_t bytes = 0;             ///< file size so far
  uint64_t chunks = 0;            ///< MCAP chunks written
};

/// The queue and the writer thread: producers Offer samples, the thread writes the MCAP file.
/// One producer thread for pointers and forces (they share a queue), one for statuses (any
/// thread, including the same one).
class McapSink : NonCopyable {
 public:
  /// Creates `path` and starts the writer thread. `queue_capacity` samples may wait (pointers
  /// and forces together). Throws std::runtime_error when the file cannot be created.
  McapSink(const std::string& path, const std::string& device_id, size_t queue_capacity = 16384,
           size_t chunk_size_bytes = 1 << 20);
  /// Close() if not called (an error there is lost).
  ~McapSink();

  /// Queues a pointer sample (its receive_time_ns, CLOCK_MONOTONIC, gives the log time). False
  /// when the queue is full (counted in queue_drops). Real-time safe: no allocation, lock or I/O.
  bool OfferPointer(const PointerSampleView& sample);
  /// Queues a force (as OfferPointer).
  bool OfferForce(const ForceCommandView& force);
  /// Queues a server status (copies the id string: not real-time; 1 Hz).
  bool OfferStatus(const ServerStatusView& status);
  /// Writes what is queued, stops the thread and closes the file. Throws std::runtime_error
  /// when a write failed (here or on the thread). A second call does nothing.
  void Close();
  /// The counters so far.
  McapSinkStats Stats() const;
  /// The topic names written.
  const McapTopics& topics() const { return topics_; }

 private:
  using Item = std::variant<PointerSampleView, ForceCommandView>;
  void Run();
  void WriteItem(const Item& item);
  void WriteStatus(const ServerStatusView& status, int64_t log_ns);

  std::string path_;
  std::string device_id_;
  std::string frame_;  // "<device_id>/device"
  McapTopics topics_;
  std::unique_ptr<McapWriter> writer_;
  uint16_t ch_pose_ = 0, ch_twist_ = 0, ch_wrench_ = 0, ch_diag_ = 0;
  int64_t realtime_minus_monotonic_ns_ = 0;
  SpscQueue<Item> queue_;
  SpscQueue<std::pair<ServerStatusView, int64_t>> status_queue_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> pointers_written_{0}, forces_written_{0}, statuses_written_{0};
  std::atomic<uint64_t> drops_{0}, max_depth_{0}, bytes_{0}, chunks_{0};
  std::atomic<uint64_t> offered_{0}, popped_{0};
  std::string error_;  // the writer thread's failure, read after join
  uint32_t status_seq_ = 0;
  bool closed_ = false;
  std::thread thread_;
};

/// What an McapRecorder records.
struct McapRecorderConfig {
  DdsSettings dds;                ///< domain and Cyclone configuration
  TopicNames topics;              ///< Felt's topics, as the server's
  std::string out_path;           ///< the .mcap file (required)
  std::string device_id;          ///< "" = the first device heard from
  bool forces = true;             ///< record felt/force
  bool status = true;             ///< record felt/status
  size_t queue_capacity = 16384;  ///< McapSink queue
  uint32_t history_depth = 4096;  ///< StreamTapConfig::history_depth
};

/// Counters of an McapRecorder.
struct McapRecorderStats {
  std::string device_id;                     ///< the device recorded ("" until the first sample)
  uint64_t pointers_received = 0;            ///< pointer samples of the device taken
  uint64_t pointer_seq_gaps = 0;             ///< samples missing between received ones (seq jumps)
  uint64_t pointers_out_of_order = 0;        ///< seq not above the last: not written
  uint64_t pointers_other_device = 0;        ///< samples of other devices (ignored)
  uint64_t forces_received = 0;              ///< forces for the device taken
  uint64_t force_seq_gaps = 0;               ///< forces missing between received ones
  uint64_t forces_before_first_pointer = 0;  ///< forces before the file existed (not written)
  uint64_t forces_other_device = 0;          ///< forces for other devices (ignored)
  uint64_t statuses_received = 0;            ///< felt/status samples taken
  uint64_t dds_errors = 0;                   ///< failed DDS calls
  McapSinkStats sink;                        ///< the writer's counters (drops among them)
};

/// Records one device's pointer samples and forces, and the server status, from DDS into MCAP.
/// The file is created at the device's first pointer sample. One thread calls Poll.
class McapRecorder : NonCopyable {
 public:
  /// Joins the domain. Throws std::invalid_argument for an empty out_path; std::runtime_error
  /// when Cyclone refuses a step.
  explicit McapRecorder(McapRecorderConfig config);
  ~McapRecorder();
  /// Waits up to `timeout` for samples and queues what arrived (never waits on the file).
  void Poll(std::chrono::nanoseconds timeout);
  /// Writes what is queued and closes the file; throws std::runtime_error when a write failed.
  void Close();
  /// The counters so far.
  McapRecorderStats Stats() const;
  /// Pointer writers matched by discovery.
  uint32_t MatchedPointerWriters() const { return tap_.MatchedPointerWriters(); }

 private:
  void OnPointer(std::string_view device_id, const PointerSampleView& sample);
  void OnForce(std::string_view device_id, const ForceCommandView& force);
  void TakeStatuses();

  class StatusReader;
  McapRecorderConfig config_;
  StreamTap tap_;
  std::unique_ptr<StatusReader> status_reader_;
  std::unique_ptr<McapSink> sink_;
  McapRecorderStats stats_;
  SequenceTracker pointer_seq_, force_seq_;
  bool closed_ = false;
};

}  // namespace felt::transport
