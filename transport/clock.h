#pragma once
// The clocks the transport stamps samples with.

#include <time.h>

#include <cstdint>

namespace felt::transport {

/// CLOCK_MONOTONIC now, ns (the clock of every receive_time_ns). Real-time safe (vDSO).
inline int64_t MonotonicNowNs() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}

/// CLOCK_REALTIME now, ns since 1970 (ServerStatus.wall_time_ns). Real-time safe (vDSO).
inline int64_t WallNowNs() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}

}  // namespace felt::transport
