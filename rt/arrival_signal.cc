#include "rt/arrival_signal.h"

#include <linux/futex.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include <climits>

namespace felt {
namespace {

// std::atomic<uint32_t> is a plain 32-bit word here (the futex word; libstdc++'s atomic::wait
// relies on the same).
static_assert(sizeof(std::atomic<uint32_t>) == sizeof(uint32_t));
static_assert(std::atomic<uint32_t>::is_always_lock_free);

uint32_t* FutexWord(const std::atomic<uint32_t>& word) {
  return reinterpret_cast<uint32_t*>(const_cast<std::atomic<uint32_t>*>(&word));
}

}  // namespace

void ArrivalSignal::Notify(int64_t now_ns) {
  last_ns_.store(now_ns, std::memory_order_relaxed);  // published by the count's increment
  count_.fetch_add(1, std::memory_order_seq_cst);
  // Dekker with WaitUntil: either the consumer sees the new count before sleeping, or this load
  // sees its flag and wakes it (futex(2) re-checks the word in the kernel as well).
  if (waiting_.load(std::memory_order_seq_cst)) {
    syscall(SYS_futex, FutexWord(count_), FUTEX_WAKE_PRIVATE, INT_MAX, nullptr, nullptr, 0);
  }
}

bool ArrivalSignal::WaitUntil(uint32_t seen, int64_t deadline_ns) const {
  waiting_.store(true, std::memory_order_seq_cst);
  if (count_.load(std::memory_order_seq_cst) == seen) {
    // FUTEX_WAIT_BITSET: the timeout is absolute, on CLOCK_MONOTONIC (futex(2)). Returns at once
    // (EAGAIN) when the word no longer holds `seen`; EINTR and ETIMEDOUT need nothing more.
    const timespec deadline{static_cast<time_t>(deadline_ns / 1000000000),
                            static_cast<long>(deadline_ns % 1000000000)};
    syscall(SYS_futex, FutexWord(count_), FUTEX_WAIT_BITSET_PRIVATE, seen, &deadline, nullptr,
            FUTEX_BITSET_MATCH_ANY);
  }
  waiting_.store(false, std::memory_order_relaxed);
  return count_.load(std::memory_order_acquire) != seen;
}

}  // namespace felt
