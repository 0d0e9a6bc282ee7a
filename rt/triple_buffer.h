#pragma once
// A single-producer single-consumer triple buffer: the writer always has a slot to fill, the reader
// always gets the newest complete slot, and neither ever waits. One atomic exchange per publish
// and per acquire, no copy (shared/STYLE.md, "Threads and the real-time tick").

#include <atomic>
#include <cstdint>
#include <utility>

namespace felt {

/// Three slots of T handed between one writer thread and one reader thread.
/// Writer: fill write_slot(), then Publish(). Reader: Acquire() returns the newest published slot
/// (or the one it already held when nothing new arrived); that slot stays valid until the next
/// Acquire(). Lock-free and wait-free; real-time safe on both sides.
template <typename T>
class TripleBuffer {
 public:
  /// Constructs the three slots from copies of `initial` (set-up time: may allocate).
  explicit TripleBuffer(const T& initial = T()) : slots_{initial, initial, initial} {}

  TripleBuffer(const TripleBuffer&) = delete;
  TripleBuffer& operator=(const TripleBuffer&) = delete;

  /// The slot the writer fills next. Writer thread only.
  T& write_slot() { return slots_[write_]; }

  /// Makes the write slot the newest; the writer gets the old "middle" slot to fill next.
  /// Writer thread only. Real-time safe.
  void Publish() {
    const uint32_t previous = middle_.exchange(write_ | kFreshBit, std::memory_order_acq_rel);
    write_ = previous & kIndexMask;
  }

  /// Takes the newest published slot if there is one; returns true when it is new since the last
  /// call. Reader thread only. Real-time safe.
  bool Acquire() {
    if ((middle_.load(std::memory_order_relaxed) & kFreshBit) == 0) return false;
    const uint32_t previous = middle_.exchange(read_, std::memory_order_acq_rel);
    read_ = previous & kIndexMask;
    return true;
  }

  /// The slot the reader holds (the newest at its last Acquire()). Reader thread only.
  const T& read_slot() const { return slots_[read_]; }

  /// The reader's slot, mutable. Reader thread only. The next Acquire() that returns true hands
  /// this slot back to the writer, so a reader that must keep the previous snapshot copies it or
  /// swaps its contents into storage of its own (e.g. std::swap of equally sized vectors, which
  /// does not allocate) before that call.
  T& read_slot_mutable() { return slots_[read_]; }

 private:
  static constexpr uint32_t kFreshBit = 4;
  static constexpr uint32_t kIndexMask = 3;

  // Each index on its own cache line: the writer's, the shared one and the reader's are written
  // by different threads on every publish and acquire (no false sharing between them).
  T slots_[3];
  alignas(64) uint32_t write_ = 0;               // owned by the writer
  alignas(64) std::atomic<uint32_t> middle_{2};  // the slot in between, plus "fresh" bit
  alignas(64) uint32_t read_ = 1;                // owned by the reader
};

}  // namespace felt
