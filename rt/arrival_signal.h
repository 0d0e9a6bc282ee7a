#pragma once
// An event count one or more producer threads bump when an input arrives, and one consumer (the
// haptic thread) waits on with an absolute CLOCK_MONOTONIC deadline: the wake-up behind the haptic
// tick on arrival (docs/server.md, "The tick: periodic or on arrival"). A Linux futex
// (futex(2), FUTEX_WAIT_BITSET takes an absolute CLOCK_MONOTONIC timeout), the same mechanism the
// transport's force writer sleeps on (std::atomic::wait).
//
// Ordering: Notify() bumps the count after the producer published the input (a triple buffer's
// release exchange), so a consumer that sees the count move and then reads the input sees it.
// The futex only puts the consumer to sleep; every datum crosses threads through atomics
// (TSan-clean).

#include <atomic>
#include <cstdint>

namespace felt {

/// A count of arrivals with a timed wait. Producers: any threads. Consumer: one thread.
class ArrivalSignal {
 public:
  ArrivalSignal() = default;
  ArrivalSignal(const ArrivalSignal&) = delete;
  ArrivalSignal& operator=(const ArrivalSignal&) = delete;

  /// Records an arrival at CLOCK_MONOTONIC `now_ns` and wakes the consumer if it sleeps. Any
  /// thread. Real-time safe: two atomic operations, plus one futex wake system call only while
  /// the consumer sleeps.
  void Notify(int64_t now_ns);

  /// The arrivals so far (wraps at 2^32; compare for inequality only). Any thread.
  uint32_t count() const { return count_.load(std::memory_order_acquire); }

  /// CLOCK_MONOTONIC of the latest Notify() [ns] (0: none). Any thread; read after count(), it
  /// is at least the time of the newest arrival that count included (it may be newer).
  int64_t last_ns() const { return last_ns_.load(std::memory_order_acquire); }

  /// Sleeps until count() differs from `seen` or CLOCK_MONOTONIC reaches `deadline_ns`, whichever
  /// is first (spurious early returns are possible: re-check). Returns count() != seen. The one
  /// consumer thread only. Real-time safe: no allocation, lock or log; one futex system call.
  bool WaitUntil(uint32_t seen, int64_t deadline_ns) const;

 private:
  std::atomic<uint32_t> count_{0};            // the futex word
  mutable std::atomic<bool> waiting_{false};  // the consumer is (about to be) in futex wait
  std::atomic<int64_t> last_ns_{0};
};

}  // namespace felt
