#pragma once
// Replaying a pointer trace over DDS as a stand-in device (issue 7, docs/replay.md): the samples
// of a felt-trace v1 file are published on felt/pointer at their recorded times (absolute
// deadlines on CLOCK_MONOTONIC, as rt/periodic_loop.h does), every ForceCommand that
// comes back is taken, and the end-to-end latency of each sample (its publication -> receipt of
// the first force that answers it, matched by ForceCommand.answers_seq) is measured, with lost and
// late samples counted.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "recordings/trace.h"
#include "transport/settings.h"

namespace felt::transport {

/// How a trace is replayed.
struct ReplayConfig {
  DdsSettings dds;                    ///< domain and Cyclone configuration
  TopicNames topics;                  ///< must match the server's
  std::string device_id = "default";  ///< the device id the samples are published as (1..64)
  double rate = 1.0;                  ///< time scale, > 0: 2 plays twice as fast
  uint32_t loops = 1;                 ///< times the trace is played back to back, >= 1
  double duration_s = 0.0;  ///< > 0: loop the trace until this much replay time [s] (loops unused)
  /// A sample published more than this after its deadline is counted late [us], > 0.
  double late_threshold_us = 1000.0;
  std::chrono::nanoseconds discovery_timeout = std::chrono::seconds(10);  ///< WaitForServer limit
  /// After this side has matched the server's reader and writer, WaitForServer waits this much
  /// longer: best-effort DDS has no acknowledgement that the server has matched this writer in
  /// turn, and samples sent before it has are dropped (its discovery runs at the same time).
  std::chrono::nanoseconds discovery_settle = std::chrono::milliseconds(250);
  /// After the last sample, how long to wait for the force that answers it.
  std::chrono::nanoseconds drain_timeout = std::chrono::milliseconds(300);
  /// How long to wait for a felt/status before the start and one newer than the end (the
  /// server's counts, for pointer_lost); 0 = do not subscribe to felt/status.
  std::chrono::nanoseconds status_timeout = std::chrono::milliseconds(2500);
  std::string forces_out;  ///< write every force received here (felt-forces v1); "" = no file
};

/// Percentiles of a distribution of times, us (nearest rank). All 0 when count is 0.
struct TimeSummary {
  uint64_t count = 0;  ///< values
  double p50_us = 0;   ///< median
  double p99_us = 0;   ///< 99th percentile
  double p999_us = 0;  ///< 99.9th percentile
  double max_us = 0;   ///< largest
  double mean_us = 0;  ///< mean
};

/// What a replay measured.
struct ReplayReport {
  std::string device_id;       ///< the id published as
  uint64_t trace_samples = 0;  ///< samples in the trace
  double trace_length_s = 0;   ///< last t_s - first t_s of the trace [s]
  double rate = 1;             ///< time scale used
  uint64_t loops_started = 0;  ///< passes through the trace begun
  double wall_s = 0;           ///< from the first deadline to the last publication [s]
  bool stopped_early = false;  ///< the stop flag ended the replay before the schedule did

  uint64_t scheduled = 0;         ///< samples the schedule held
  uint64_t published = 0;         ///< samples written to DDS
  uint64_t publish_failures = 0;  ///< dds_write failures (not published)
  uint64_t late = 0;              ///< published more than late_threshold_us after the deadline
  TimeSummary lateness;           ///< publication - deadline, every published sample [us]

  uint64_t forces_received = 0;  ///< ForceCommands for this device taken while replaying
  uint64_t forces_lost = 0;      ///< gaps in the server's force seq between received ones
  uint64_t answered = 0;         ///< published samples answered by at least one force
  uint64_t unanswered = 0;       ///< published - answered (superseded before a haptic tick
                                 ///< read them, or lost on the way)
  TimeSummary latency;           ///< publication -> first answering force received [us]
  uint64_t contact_forces = 0;   ///< forces received with in_contact set
  double peak_force_N = 0;       ///< largest |force| received [N]

  bool server_counts = false;    ///< felt/status seen before and after: the next three are valid
  int64_t server_received = -1;  ///< samples the server took in (accepted + rejected) meanwhile
  int64_t server_rejected = -1;  ///< of which rejected (any reason, docs/transport.md)
  int64_t pointer_lost = -1;     ///< published - server_received (exact when this replay is the
                                 ///< server's only client), -1 when unknown
};

/// Publishes a trace as device `device_id` and measures what comes back. Set-up allocates
/// everything a run needs; Run publishes from the calling thread and takes forces on a second
/// thread. One Run per instance.
class Replayer {
 public:
  /// Validates the config (std::invalid_argument naming the field: rate, loops, duration_s,
  /// late_threshold_us, device_id; an empty trace) and joins the domain (std::runtime_error when
  /// Cyclone refuses).
  Replayer(Trace trace, ReplayConfig config);
  ~Replayer();
  Replayer(const Replayer&) = delete;
  Replayer& operator=(const Replayer&) = delete;

  /// Polls until a server's pointer reader and force writer are matched (then waits
  /// discovery_settle), or the discovery timeout passes (false), or `*stop` becomes true (false).
  /// `stop` may be null.
  bool WaitForServer(const std::atomic<bool>* stop = nullptr);

  /// Plays the schedule until its end or until `*stop` (may be null) becomes true, calls
  /// `on_start` (may be empty) just before the first publication, then waits for the last forces
  /// and the server's status. Throws std::logic_error when called twice and std::runtime_error
  /// when the forces file cannot be written.
  ReplayReport Run(const std::atomic<bool>* stop = nullptr,
                   const std::function<void()>& on_start = {});

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

/// The report as a JSON document (keys as the ReplayReport fields; times in us, with units in
/// the key names; docs/replay.md lists them).
std::string ReplayReportJson(const ReplayReport& report);

/// The report as a few human-readable lines, each ending in '\n'.
std::string FormatReplayReport(const ReplayReport& report);

}  // namespace felt::transport
