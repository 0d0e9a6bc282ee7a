#pragma once
// A DDS domain that no other running test process holds. ctest runs every test in a process of its
// own, two at a time in CI; tests that start `felt serve`, `felt soak` or secure participants used
// to take 140-229 by `getpid() % N`, where two processes whose pids agree modulo N (or ranges that
// overlapped: soak's 160-199 and the secure server's 170-189) met on one domain and could discover
// each other's servers.

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cstdint>
#include <stdexcept>
#include <string>

namespace felt::testing {

/// The first domain of the range ExclusiveDdsDomain hands out (the transport tests' fixed 42 and
/// 43 are below it).
inline constexpr uint32_t kFirstExclusiveDomain = 100;
/// The last: Felt refuses domain ids above 230 (the ports of higher ids overflow 16 bits).
inline constexpr uint32_t kLastExclusiveDomain = 230;

/// A DDS domain id in [100, 230] held by this process alone among the processes that call this:
/// an exclusive flock on /tmp/felt-test-dds-domain-<id>.lock, kept until the process exits (the
/// kernel drops it then, also on a crash). The search starts at a pid-dependent id to keep tries
/// few. Thread-safe; every call in one process returns the same id. Throws std::runtime_error when
/// every id is held.
inline uint32_t ExclusiveDdsDomain() {
  static const uint32_t domain = [] {
    constexpr uint32_t kCount = kLastExclusiveDomain - kFirstExclusiveDomain + 1;
    const uint32_t start = static_cast<uint32_t>(getpid()) % kCount;
    for (uint32_t k = 0; k < kCount; ++k) {
      const uint32_t id = kFirstExclusiveDomain + (start + k) % kCount;
      const std::string path = "/tmp/felt-test-dds-domain-" + std::to_string(id) + ".lock";
      const int fd = open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
      if (fd < 0) continue;
      if (flock(fd, LOCK_EX | LOCK_NB) == 0) return id;  // fd stays open: the lock lives on
      close(fd);
    }
    throw std::runtime_error("ExclusiveDdsDomain: every DDS domain 100-230 is held by a test");
  }();
  return domain;
}

}  // namespace felt::testing
