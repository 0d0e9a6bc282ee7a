#pragma once
// The raw Cyclone DDS round trip on this machine, with Felt's configuration, types and QoS but none
// of Felt's code in the path: a pinger publishes a PointerSample at a fixed rate, an echo process
// answers each with a ForceCommand, the pinger measures publication -> reception of the answer.
// The floor that `felt bench transport` puts next to the end-to-end latency.

#include <cstdint>
#include <string>
#include <vector>

#include "transport/server_transport.h"
#include "transport/settings.h"

namespace felt::transport {

/// What RunRawRoundTrip measures.
struct RawRoundTripOptions {
  DdsSettings dds;                                 ///< domain and configuration (as the server's)
  double seconds = 10.0;                           ///< measured duration, s (after 0.5 s warm-up)
  double rate_hz = 1000.0;                         ///< pings per second
  ReceiveMode echo_mode = ReceiveMode::kListener;  ///< how the echo process takes pings
  std::string topic_suffix;                        ///< appended to felt/pointer and felt/force
  // With dds.security_dir set, the echo authenticates as identity "server" and the pinger as
  // dds.identity, by default "device-bench" (`felt security init DIR --participants
  // server,device:bench`).
};

/// Round-trip times and counts of one run.
struct RawRoundTripResult {
  std::vector<double> roundtrip_us;  ///< one per answered ping, in order, us
  uint64_t pings_sent = 0;           ///< pings written (after warm-up)
  uint64_t pongs_received = 0;       ///< answers received for those pings
};

/// Forks an echo process (its own Cyclone domain instance, so the samples cross the loopback
/// interface as between two programs), measures, stops the echo and returns. Call it before this
/// process has created any DDS entity (fork after Cyclone's threads exist is unsafe).
/// Throws std::runtime_error when discovery does not complete within 10 s, fork fails or the echo
/// process fails.
RawRoundTripResult RunRawRoundTrip(const RawRoundTripOptions& options);

}  // namespace felt::transport
