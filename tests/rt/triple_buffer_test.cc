// TripleBuffer: single-thread semantics, and a two-thread stress test (also run under TSan).
#include "rt/triple_buffer.h"

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <thread>

#include "tests/stress_scale.h"

namespace felt {
namespace {

constexpr uint64_t kPublishes = test::StressIterations(2'000'000);

// A slot large enough to span cache lines: a torn read shows as a payload that disagrees with seq.
struct Slot {
  uint64_t seq = 0;
  std::array<uint64_t, 31> payload{};
};

void Fill(Slot* slot, uint64_t seq) {
  slot->seq = seq;
  for (size_t i = 0; i < slot->payload.size(); ++i) slot->payload[i] = seq * 31 + i;
}

bool Complete(const Slot& slot) {
  for (size_t i = 0; i < slot.payload.size(); ++i) {
    if (slot.payload[i] != slot.seq * 31 + i) return false;
  }
  return true;
}

TEST(TripleBufferTest, ReaderGetsNewestPublishedSlot) {
  TripleBuffer<int> buffer(7);
  EXPECT_EQ(buffer.read_slot(), 7);
  EXPECT_FALSE(buffer.Acquire());  // nothing published yet
  EXPECT_EQ(buffer.read_slot(), 7);

  buffer.write_slot() = 1;
  buffer.Publish();
  EXPECT_TRUE(buffer.Acquire());
  EXPECT_EQ(buffer.read_slot(), 1);
  EXPECT_FALSE(buffer.Acquire());  // nothing new: keeps the slot
  EXPECT_EQ(buffer.read_slot(), 1);

  // Two publishes before an acquire: the reader gets the newest, the older one is dropped.
  buffer.write_slot() = 2;
  buffer.Publish();
  buffer.write_slot() = 3;
  buffer.Publish();
  EXPECT_TRUE(buffer.Acquire());
  EXPECT_EQ(buffer.read_slot(), 3);
  EXPECT_FALSE(buffer.Acquire());
}

TEST(TripleBufferTest, WriterNeverGetsTheReadersSlot) {
  TripleBuffer<int> buffer(0);
  // Every interleaving of publish/acquire over a few steps: the writer's slot is never the
  // reader's (writing into it would change what the reader holds).
  for (int pattern = 0; pattern < 1 << 10; ++pattern) {
    for (int step = 0; step < 10; ++step) {
      if ((pattern >> step) & 1) {
        buffer.write_slot() = 1000 + step;
        EXPECT_NE(&buffer.write_slot(), &buffer.read_slot());
        buffer.Publish();
      } else {
        buffer.Acquire();
      }
      EXPECT_NE(&buffer.write_slot(), &buffer.read_slot());
    }
  }
}

TEST(TripleBufferTest, StressTwoThreadsCompleteAndNeverOlder) {
  Slot initial;
  Fill(&initial, 0);
  TripleBuffer<Slot> buffer(initial);
  std::atomic<uint64_t> published{0};  // the last seq whose Publish() has returned

  std::thread writer([&] {
    for (uint64_t seq = 1; seq <= kPublishes; ++seq) {
      Fill(&buffer.write_slot(), seq);
      buffer.Publish();
      published.store(seq, std::memory_order_release);
    }
  });

  // Reader: every slot complete; seq never goes backwards, strictly newer when Acquire() says so,
  // and at least the newest publish that happened before the Acquire().
  uint64_t last_seq = 0;
  uint64_t acquisitions = 0;
  uint64_t failures = 0;
  while (last_seq < kPublishes && failures == 0) {
    const uint64_t published_before = published.load(std::memory_order_acquire);
    const bool fresh = buffer.Acquire();
    const Slot& slot = buffer.read_slot();
    if (!Complete(slot)) ++failures;
    if (slot.seq < last_seq || (fresh && slot.seq == last_seq)) ++failures;
    if (slot.seq < published_before) ++failures;
    acquisitions += fresh ? 1 : 0;
    last_seq = slot.seq;
  }
  writer.join();
  EXPECT_EQ(failures, 0u) << "at seq " << last_seq;
  EXPECT_EQ(last_seq, kPublishes);
  EXPECT_GT(acquisitions, 1u);
}

}  // namespace
}  // namespace felt
