#pragma once
// What the test run is: the release run checks the physics on full-length runs; the sanitizer runs
// (make test-asan and test-tsan set FELT_SANITIZER) check memory, undefined behaviour and threads
// on the same code paths over shorter runs, so that CI stays within its time budget.

#include <cstdlib>

namespace felt::testing {

/// True under a sanitizer (FELT_SANITIZER set, not empty, by the Makefile's test-asan and
/// test-tsan).
inline bool Sanitized() {
  const char* v = std::getenv("FELT_SANITIZER");
  return v != nullptr && *v != '\0';
}

}  // namespace felt::testing
