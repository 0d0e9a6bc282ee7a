// SequenceTracker (transport/sequence_tracker.h): gaps, repeats and reversals of a recorded stream.
#include "transport/sequence_tracker.h"

#include <gtest/gtest.h>

namespace felt::transport {
namespace {

TEST(SequenceTrackerTest, PointerNumbersCountGapsAndRefuseRepeatsAndReversals) {
  SequenceTracker t;
  uint64_t gaps = 0, out_of_order = 0;
  EXPECT_TRUE(t.Accept(7, &gaps, &out_of_order));  // the first number starts the stream
  EXPECT_TRUE(t.Accept(8, &gaps, &out_of_order));
  EXPECT_TRUE(t.Accept(11, &gaps, &out_of_order));  // 9 and 10 missing
  EXPECT_FALSE(t.Accept(11, &gaps, &out_of_order));
  EXPECT_FALSE(t.Accept(5, &gaps, &out_of_order));
  EXPECT_TRUE(t.Accept(12, &gaps, &out_of_order));
  EXPECT_EQ(gaps, 2u);
  EXPECT_EQ(out_of_order, 2u);
  EXPECT_EQ(t.last, 12u);
}

TEST(SequenceTrackerTest, ForceNumbersCountGapsAndKeepTheHighest) {
  SequenceTracker t;
  uint64_t gaps = 0;
  t.Note(1, &gaps);
  t.Note(4, &gaps);  // 2, 3 missing
  t.Note(3, &gaps);  // late: no gap, the last stays 4
  t.Note(5, &gaps);
  EXPECT_EQ(gaps, 2u);
  EXPECT_EQ(t.last, 5u);
}

}  // namespace
}  // namespace felt::transport
