// FELT_CHECK stays on in every build (these tests run in the Release build, where NDEBUG is
// defined and assert is compiled out) and names the broken condition and its place.
#include "base/check.h"

#include <gtest/gtest.h>

namespace felt {
namespace {

TEST(Check, PassingConditionDoesNothing) {
  int evaluated = 0;
  FELT_CHECK(++evaluated == 1);
  EXPECT_EQ(evaluated, 1);  // evaluated exactly once
}

TEST(CheckDeathTest, FailingConditionAbortsNamingItAndItsPlace) {
  const int width = 1;
  EXPECT_DEATH(FELT_CHECK(width >= 2), "felt: check failed: width >= 2 at .*check_test.cc:[0-9]+");
}

}  // namespace
}  // namespace felt
