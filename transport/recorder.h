#pragma once
// Recording what travels on Felt's DDS topics (issue 7, docs/replay.md): a StreamTap reads every
// PointerSample and ForceCommand on felt/pointer and felt/force (any device, not only the newest),
// and a Recorder writes one device's pointer samples as a felt-trace v1 file
// (recordings/trace.h) and its forces into a companion felt-forces v1 CSV file, counting gaps by
// sequence number. Cyclone types stay out of this header.

#include <chrono>
#include <cstdint>
#include <fstream>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "base/non_copyable.h"
#include "recordings/trace.h"
#include "transport/sequence_tracker.h"
#include "transport/settings.h"
#include "transport/views.h"

namespace felt::transport {

/// What a StreamTap reads.
struct StreamTapConfig {
  DdsSettings dds;                ///< domain and Cyclone configuration
  TopicNames topics;              ///< must match the server's and the drivers'
  bool pointers = true;           ///< read felt/pointer
  bool forces = true;             ///< read felt/force
  uint32_t history_depth = 4096;  ///< samples kept per device until taken (KEEP_LAST depth), >= 1
};

/// Called for each pointer sample taken: the sender's device id and the sample
/// (`device_index` 0, `receive_time_ns` CLOCK_MONOTONIC at the take, ns).
using TapPointerHandler = std::function<void(std::string_view device_id, const PointerSampleView&)>;
/// Called for each force taken: the device id it is for and the force
/// (`device_index` 0, `receive_time_ns` CLOCK_MONOTONIC at the take, ns).
using TapForceHandler = std::function<void(std::string_view device_id, const ForceCommandView&)>;

/// A passive reader of felt/pointer and felt/force with a deep history, so that every sample
/// that reaches it is seen (best-effort, volatile, the streams' deadline: it matches the server
/// and any driver). One thread calls Poll; the Matched* queries are for any thread.
class StreamTap : NonCopyable {
 public:
  /// Joins the domain and creates the readers. Throws std::invalid_argument when neither topic is
  /// chosen or history_depth is 0; std::runtime_error when Cyclone refuses a step.
  explicit StreamTap(StreamTapConfig config);
  ~StreamTap();

  /// Waits up to `timeout` for data, then takes everything available, calling `on_pointer` and
  /// `on_force` (either may be empty) once per sample, oldest first per device. Returns the number
  /// of samples taken. Not real-time: the handlers may allocate and write files.
  size_t Poll(std::chrono::nanoseconds timeout, const TapPointerHandler& on_pointer,
              const TapForceHandler& on_force);

  /// Pointer writers (device drivers, replays) matched by discovery.
  uint32_t MatchedPointerWriters() const;
  /// Force writers (servers) matched by discovery.
  uint32_t MatchedForceWriters() const;
  /// Failed dds_take/dds_waitset_wait calls so far.
  uint64_t dds_errors() const;

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

/// The first line of a forces file.
inline constexpr std::string_view kForcesMagic = "# felt-forces v1";
/// The column line that ends a forces file's header.
inline constexpr std::string_view kForcesColumns =
    "t_s,seq,answers_seq,answers_t_s,fx,fy,fz,px,py,pz,in_contact,flags";

/// Writes a felt-forces v1 file: the ForceCommands one device received, one per line:
///   # felt-forces v1
///   # units: N, m, s
///   # device: <id>
///   # source: <text>
///   # frame: device
///   t_s,seq,answers_seq,answers_t_s,fx,fy,fz,px,py,pz,in_contact,flags
/// t_s: receipt time [s] on the same origin as the companion trace; answers_t_s: the t_s of the
/// pointer sample the force answers (-1 when unknown); f [N] and p (proxy) [m] in the device
/// frame; in_contact 0/1; flags the ForceCommand bit mask (docs/transport.md).
class ForceLogWriter {
 public:
  /// Creates (truncates) `path` and writes the header. Throws std::runtime_error naming the file
  /// when it cannot be opened; std::invalid_argument when device or source holds a newline.
  ForceLogWriter(std::string path, std::string_view device, std::string_view source);
  /// Closes the file (a write error here is lost: call Close()).
  ~ForceLogWriter();
  ForceLogWriter(const ForceLogWriter&) = delete;
  ForceLogWriter& operator=(const ForceLogWriter&) = delete;

  /// Appends one force received at `t_s` [s] answering the sample of time `answers_t_s` [s].
  void Write(double t_s, double answers_t_s, const ForceCommandView& force);
  /// Lines written so far.
  uint64_t lines() const { return lines_; }
  /// Flushes and closes; throws std::runtime_error naming the file when any write failed.
  void Close();

 private:
  std::string path_;
  std::ofstream out_;
  std::string line_;  // reused
  uint64_t lines_ = 0;
};

/// What a Recorder records.
struct RecorderConfig {
  DdsSettings dds;                ///< domain and Cyclone configuration
  TopicNames topics;              ///< must match the server's and the drivers'
  std::string out_path;           ///< the felt-trace v1 file written (required)
  std::string forces_path;        ///< the companion felt-forces v1 file; "" = no force file
  std::string device_id;          ///< the device recorded; "" = the first device heard from
  double rate_hz = 1000.0;        ///< the nominal rate written into the trace header [Hz], > 0
  uint32_t history_depth = 4096;  ///< StreamTapConfig::history_depth
};

/// Counters of a Recorder. Pointer gaps are by the driver's seq, force gaps by the server's.
struct RecorderStats {
  std::string device_id;                      ///< the device recorded ("" until the first sample)
  uint64_t pointers_received = 0;             ///< pointer samples of the recorded device taken
  uint64_t pointers_written = 0;              ///< trace lines written
  uint64_t pointer_seq_gaps = 0;              ///< samples missing between received ones (seq jumps)
  uint64_t pointers_out_of_order = 0;         ///< seq not above the last one: not written
  uint64_t pointers_time_not_increasing = 0;  ///< device_time_ns not above the last: not written
  uint64_t pointers_other_device = 0;         ///< samples of other devices (ignored)
  uint64_t forces_received = 0;               ///< forces for the recorded device taken
  uint64_t forces_written = 0;                ///< force lines written
  uint64_t force_seq_gaps = 0;                ///< forces missing between received ones (seq jumps)
  uint64_t forces_other_device = 0;           ///< forces for other devices (ignored)
  uint64_t dds_errors = 0;                    ///< failed DDS calls of the tap
};

/// Records one device's pointer samples into a trace and its forces into a forces file.
/// Trace time: t_s = (device_time_ns - device_time_ns of the first sample) / 1e9, the driver's
/// own clock, so a recording keeps the timing the driver measured (a replay at rate 1 stamps
/// device_time_ns with the trace's own times, so recording it gives back the same t_s). Forces
/// received before the first pointer sample are not written (there is no time origin yet).
/// Files are created at the first sample of the recorded device. One thread uses an instance.
class Recorder : NonCopyable {
 public:
  /// Joins the domain (see StreamTap). Throws std::invalid_argument for an empty out_path or a
  /// bad rate_hz; std::runtime_error when Cyclone refuses a step.
  explicit Recorder(RecorderConfig config);
  ~Recorder();

  /// Waits up to `timeout` for samples and writes what arrived. Throws std::runtime_error when a
  /// file cannot be created or written.
  void Poll(std::chrono::nanoseconds timeout);
  /// Flushes and closes the files (later samples are ignored); throws std::runtime_error when a
  /// write failed. A second call does nothing.
  void Close();
  /// The counters so far.
  RecorderStats Stats() const;
  /// The tap (for discovery queries).
  const StreamTap& tap() const { return tap_; }

 private:
  void OnPointer(std::string_view device_id, const PointerSampleView& sample);
  void OnForce(std::string_view device_id, const ForceCommandView& force);

  RecorderConfig config_;
  StreamTap tap_;
  RecorderStats stats_;
  std::unique_ptr<TraceWriter> trace_;
  std::unique_ptr<ForceLogWriter> forces_;
  bool closed_ = false;  // after Close(): samples are no longer written
  bool have_origin_ = false;
  int64_t origin_device_ns_ = 0;   // device_time_ns of the first sample
  int64_t origin_receive_ns_ = 0;  // CLOCK_MONOTONIC when it was taken
  SequenceTracker pointer_seq_, force_seq_;
  int64_t last_device_ns_ = 0;
};

}  // namespace felt::transport
