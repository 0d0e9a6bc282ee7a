#pragma once
// Shared helpers of the transport tests: unique topic names per test, the test domain, and
// condition polling with a deadline (never fixed sleeps).

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <string>

#include "transport/client_transport.h"
#include "transport/server_transport.h"
#include "transport/settings.h"

namespace felt::transport::testing {

/// The domain the transport tests use: away from domain 0, where a developer's server may run.
inline constexpr uint32_t kTestDomain = 42;

/// Settings for the test domain with the default configuration precedence.
inline DdsSettings TestDds() {
  DdsSettings settings;
  settings.domain_id = kTestDomain;
  return settings;
}

/// "/test_<pid>_<n>": a suffix no other test (or process) uses.
inline std::string UniqueSuffix() {
  static std::atomic<int> counter{0};
  return "/test_" + std::to_string(getpid()) + "_" + std::to_string(counter.fetch_add(1));
}

/// Topic names no other test (or process) uses.
inline TopicNames UniqueTopics() { return TopicNames::WithAffixes("", UniqueSuffix()); }

/// How long discovery and delivery may take before a test fails (generous: TSan, loaded CI).
inline constexpr std::chrono::seconds kWait{10};

/// A device with a +-0.5 m workspace box and the default rate limit.
inline DeviceLimits TestDevice(const std::string& id) {
  DeviceLimits device;
  device.device_id = id;
  device.workspace_min_m_D = {-0.5, -0.5, -0.5};
  device.workspace_max_m_D = {0.5, 0.5, 0.5};
  return device;
}

/// A valid pointer sample for device 0 with sequence number `seq` and position (x, 0, 0).
inline PointerSampleView Sample(uint64_t seq, double x = 0.1) {
  PointerSampleView s;
  s.seq = seq;
  s.device_time_ns = static_cast<int64_t>(seq) * 1000000;
  s.position_m_D = {x, 0.0, 0.0};
  s.velocity_m_per_s_D = {0.0, 0.01, 0.0};
  s.buttons = 1;
  return s;
}

}  // namespace felt::transport::testing
