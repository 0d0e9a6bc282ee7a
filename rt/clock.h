#pragma once
// The clocks every loop and the transport read (both through the vDSO: no system call).

#include <time.h>

#include <cstdint>

namespace felt {

/// CLOCK_MONOTONIC now, ns (loop deadlines, every receive_time_ns). Real-time safe (vDSO).
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

}  // namespace felt
