#pragma once
// A bounded single-producer single-consumer ring (Lamport's queue with cached indices).
// Nothing is silently lost: TryPush fails when full and the caller counts it.

#include <atomic>
#include <cstddef>
#include <limits>
#include <new>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace felt {

/// Bounded lock-free FIFO between one producer thread and one consumer thread.
/// Capacity is fixed at construction (set-up time); TryPush/TryPop never allocate, lock or wait.
template <typename T>
class SpscQueue {
 public:
  /// A queue holding up to `capacity` items (>= 1). Allocates once, here. Throws
  /// std::invalid_argument for a capacity of 0 or one so large that capacity + 1 overflows (which
  /// would leave an empty buffer that TryPush writes past).
  explicit SpscQueue(size_t capacity) : buffer_(CheckedSize(capacity)) {}

  SpscQueue(const SpscQueue&) = delete;
  SpscQueue& operator=(const SpscQueue&) = delete;

  /// Appends a copy of `item`; false when the queue is full. Producer only. Real-time safe.
  bool TryPush(const T& item) {
    const size_t tail = tail_.load(std::memory_order_relaxed);
    const size_t next = Next(tail);
    if (next == head_cache_) {
      head_cache_ = head_.load(std::memory_order_acquire);
      if (next == head_cache_) return false;
    }
    buffer_[tail] = item;
    tail_.store(next, std::memory_order_release);
    return true;
  }

  /// Moves the oldest item into `*out`; false when empty. Consumer only. Real-time safe.
  bool TryPop(T* out) {
    const size_t head = head_.load(std::memory_order_relaxed);
    if (head == tail_cache_) {
      tail_cache_ = tail_.load(std::memory_order_acquire);
      if (head == tail_cache_) return false;
    }
    *out = std::move(buffer_[head]);
    head_.store(Next(head), std::memory_order_release);
    return true;
  }

  /// Maximum number of items held at once.
  size_t capacity() const { return buffer_.size() - 1; }

 private:
  static size_t CheckedSize(size_t capacity) {
    if (capacity == 0 || capacity >= std::numeric_limits<size_t>::max() / sizeof(T)) {
      throw std::invalid_argument("SpscQueue: capacity must be in [1, max / sizeof(T)), got " +
                                  std::to_string(capacity));
    }
    return capacity + 1;
  }
  size_t Next(size_t i) const { return i + 1 == buffer_.size() ? 0 : i + 1; }

  std::vector<T> buffer_;
  alignas(64) std::atomic<size_t> head_{0};  // consumer's index
  size_t tail_cache_ = 0;                    // consumer's cached copy of tail_
  alignas(64) std::atomic<size_t> tail_{0};  // producer's index
  size_t head_cache_ = 0;                    // producer's cached copy of head_
};

}  // namespace felt
