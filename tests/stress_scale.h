#pragma once
// The size of the two-thread stress tests, one rule for all of them: ThreadSanitizer runs them
// about ten times slower, so under it a test does a tenth of its iterations (staying under 10 s).

#include <cstdint>

namespace felt::test {

/// How many times slower the stress loops run under ThreadSanitizer (a factor, no unit).
inline constexpr uint64_t kTsanSlowdown = 10;

/// `iterations` (a count) in a plain build; a kTsanSlowdown-th of them under ThreadSanitizer.
constexpr uint64_t StressIterations(uint64_t iterations) {
#if defined(__SANITIZE_THREAD__)
  return iterations / kTsanSlowdown;
#else
  return iterations;
#endif
}

}  // namespace felt::test
