#pragma once
// The device side of Felt's DDS transport (docs/transport.md): publish PointerSamples, receive the
// ForceCommands for one's own devices, read the server's status. Used by
// examples/device_client.cpp, the record/replay tools and the tests. Cyclone types stay out of this
// header.

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "base/non_copyable.h"
#include "rt/clock.h"
#include "transport/settings.h"
#include "transport/views.h"

namespace felt::transport {

/// What a client publishes for and listens to.
struct ClientTransportConfig {
  DdsSettings dds;                      ///< domain and Cyclone configuration
  TopicNames topics;                    ///< must match the server's
  std::vector<std::string> device_ids;  ///< this client's devices; device_index = position here
  bool subscribe_status = true;         ///< create a felt/status reader (LatestStatus)
  /// ForceCommands the force reader keeps per device until taken (KEEP_LAST depth). 1 (the
  /// default) keeps only the newest, as a driver wants; a tool that must see every force
  /// (replay, record) asks for more, e.g. 1024, and takes them with TakeForces. History depth is
  /// not a request-offered QoS, so any depth matches the server's keep-last-1 writer.
  uint32_t force_history = 1;
};

/// Counters of a client since construction.
struct ClientStats {
  uint64_t pointers_published = 0;  ///< successful PublishPointer calls
  uint64_t forces_received = 0;     ///< ForceCommands for this client's devices
  uint64_t forces_seq_gaps = 0;     ///< forces missing between received ones (by seq)
  uint64_t forces_other = 0;        ///< ForceCommands for devices not in device_ids (ignored)
  uint64_t dds_errors = 0;          ///< failed dds_write/dds_take/dds_read/dds_waitset_wait
};

/// Client side of the transport. Construction allocates and creates the DDS entities; the calls
/// after it do not allocate (LatestStatus excepted: it fills a std::string).
/// Threads: PublishPointer from one thread; TakeForce/WaitForce from one thread (may be another);
/// LatestStatus, Stats and the Matched* queries from any thread.
class ClientTransport : NonCopyable {
 public:
  /// Joins the domain and creates the pointer writer, force reader and (optionally) status reader.
  /// Throws std::invalid_argument naming the field for an empty, too long (> 64) or repeated
  /// device id, or no device; std::runtime_error when Cyclone refuses a step.
  explicit ClientTransport(ClientTransportConfig config);
  ~ClientTransport();

  /// Publishes `sample` on felt/pointer for device `sample.device_index` (receive_time_ns is
  /// ignored). False when the index is out of range or dds_write fails (counted).
  bool PublishPointer(const PointerSampleView& sample);

  /// The newest ForceCommand received for device `device_index` since the last call that returned
  /// it; false when there is none new. Never blocks. `out->receive_time_ns` is CLOCK_MONOTONIC at
  /// the take.
  bool TakeForce(uint32_t device_index, ForceCommandView* out);

  /// As TakeForce, but waits up to `timeout` for a force to arrive.
  bool WaitForce(uint32_t device_index, std::chrono::nanoseconds timeout, ForceCommandView* out);

  /// Every ForceCommand for this client's devices received since the last call, oldest first,
  /// up to `capacity` of them, into `out[0..n)`; returns n (0 when none). Counts received forces
  /// and seq gaps as TakeForce does. Does not allocate. Use it or TakeForce/WaitForce, not both:
  /// each consumes what the other would return. `out[i].receive_time_ns` is CLOCK_MONOTONIC at
  /// the take.
  size_t TakeForces(ForceCommandView* out, size_t capacity);

  /// Waits up to `timeout` until the force reader holds data (for TakeForces); true when it does,
  /// false on timeout or error (counted). Does not take anything.
  bool WaitForForces(std::chrono::nanoseconds timeout);

  /// The newest ServerStatus seen (the latest of any server, by wall_time_ns); false when none
  /// has arrived or subscribe_status is false.
  bool LatestStatus(ServerStatusView* out);

  /// A copy of the counters. Any thread.
  ClientStats Stats() const;

  /// Server-side pointer readers matched by discovery. Any thread.
  uint32_t MatchedPointerReaders() const;
  /// Server-side force writers matched by discovery. Any thread.
  uint32_t MatchedForceWriters() const;
  /// Status writers matched (0 when subscribe_status is false). Any thread.
  uint32_t MatchedStatusWriters() const;

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

/// Polls `done` every `poll` until it returns true or `timeout` passes; returns its last value.
/// For discovery waits in tools and tests (no fixed sleeps).
bool WaitUntil(const std::function<bool()>& done, std::chrono::nanoseconds timeout,
               std::chrono::nanoseconds poll = std::chrono::milliseconds(2));

}  // namespace felt::transport
