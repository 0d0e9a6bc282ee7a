#pragma once
// Counters one loop thread writes and any thread reads: plain relaxed load + store instead of a
// read-modify-write (a lock-prefixed instruction the writer does not need, being the only one).
#include <atomic>
#include <cstdint>

namespace felt {

/// Adds 1 to a counter only the calling thread writes. Real-time safe.
inline void Bump(std::atomic<uint64_t>& counter) {
  counter.store(counter.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
}

/// Adds `delta` to a value only the calling thread writes. Real-time safe.
inline void AddTo(std::atomic<double>& value, double delta) {
  value.store(value.load(std::memory_order_relaxed) + delta, std::memory_order_relaxed);
}

/// Raises `value` to `candidate` if larger; only the calling thread writes it. Real-time safe.
inline void RaiseTo(std::atomic<double>& value, double candidate) {
  if (candidate > value.load(std::memory_order_relaxed)) {
    value.store(candidate, std::memory_order_relaxed);
  }
}

}  // namespace felt
