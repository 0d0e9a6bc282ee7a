// SpscQueue: FIFO semantics, full/empty, bad capacity, and a two-thread stress test (TSan too).
#include "rt/spsc_queue.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <thread>

#include "tests/stress_scale.h"

namespace felt {
namespace {

constexpr uint64_t kItems = test::StressIterations(3'000'000);

TEST(SpscQueueTest, FifoFullAndEmpty) {
  SpscQueue<int> queue(3);
  EXPECT_EQ(queue.capacity(), 3u);
  int out = -1;
  EXPECT_FALSE(queue.TryPop(&out));
  EXPECT_TRUE(queue.TryPush(1));
  EXPECT_TRUE(queue.TryPush(2));
  EXPECT_TRUE(queue.TryPush(3));
  EXPECT_FALSE(queue.TryPush(4));  // full: refused, not overwritten
  ASSERT_TRUE(queue.TryPop(&out));
  EXPECT_EQ(out, 1);
  EXPECT_TRUE(queue.TryPush(4));  // wraps around
  for (int expected : {2, 3, 4}) {
    ASSERT_TRUE(queue.TryPop(&out));
    EXPECT_EQ(out, expected);
  }
  EXPECT_FALSE(queue.TryPop(&out));
}

TEST(SpscQueueTest, CapacityOfOneAlternates) {
  SpscQueue<int> queue(1);
  int out = 0;
  for (int i = 0; i < 10; ++i) {
    EXPECT_TRUE(queue.TryPush(i));
    EXPECT_FALSE(queue.TryPush(i));
    ASSERT_TRUE(queue.TryPop(&out));
    EXPECT_EQ(out, i);
  }
}

TEST(SpscQueueTest, BadCapacityThrowsNamingIt) {
  try {
    SpscQueue<int> queue(0);
    FAIL() << "no exception for capacity 0";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("capacity"), std::string::npos) << e.what();
  }
  EXPECT_THROW(SpscQueue<int>(static_cast<size_t>(-1)), std::invalid_argument);
}

TEST(SpscQueueTest, StressTwoThreadsLosesNothingKeepsOrder) {
  struct Item {
    uint64_t seq = 0;
    uint64_t check = 0;  // ~seq: a torn item shows as a mismatch
  };
  SpscQueue<Item> queue(64);  // small: exercises full, empty and wrap-around constantly
  std::atomic<uint64_t> full_count{0};

  std::thread producer([&] {
    uint64_t full = 0;
    for (uint64_t seq = 0; seq < kItems; ++seq) {
      while (!queue.TryPush(Item{seq, ~seq})) {
        ++full;  // full: the producer retries (a real caller counts it)
        std::this_thread::yield();
      }
    }
    full_count.store(full, std::memory_order_relaxed);
  });

  uint64_t expected = 0;
  uint64_t failures = 0;
  Item item;
  while (expected < kItems && failures == 0) {
    if (!queue.TryPop(&item)) {
      std::this_thread::yield();
      continue;
    }
    if (item.seq != expected || item.check != ~expected) ++failures;
    ++expected;
  }
  producer.join();
  EXPECT_EQ(failures, 0u) << "item " << item.seq << " where " << expected - 1 << " was due";
  EXPECT_EQ(expected, kItems);
  EXPECT_FALSE(queue.TryPop(&item));  // nothing extra
}

}  // namespace
}  // namespace felt
