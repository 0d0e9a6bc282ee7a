// The allocation-counting guard (tests/alloc_counter.h).
#include "tests/alloc_counter.h"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cstdint>
#include <cstdlib>
#include <new>
#include <string>
#include <thread>
#include <vector>

namespace felt {
namespace {

// Escapes a pointer so the compiler cannot remove the allocation that produced it.
void* volatile g_sink = nullptr;

TEST(AllocationGuardTest, CatchesAnAllocation) {
  AllocationGuard guard;
  auto* value = new int(42);
  g_sink = value;
  EXPECT_EQ(guard.allocations(), 1u);
  delete value;

  // Through the standard library too (a string too long for the small-string buffer).
  guard.Reset();
  std::string text(100, 'x');
  g_sink = text.data();
  EXPECT_GE(guard.allocations(), 1u);
}

TEST(AllocationGuardTest, PassesOnNoAllocation) {
  std::vector<double> values(1000, 1.0);  // set-up may allocate
  AllocationGuard guard;
  double sum = 0.0;
  for (double v : values) sum += v * 0.5;
  values[0] = sum;  // in-place work: no allocation
  EXPECT_EQ(guard.allocations(), 0u);
  EXPECT_EQ(values[0], 500.0);
}

TEST(AllocationGuardTest, CountsEveryForm) {
  AllocationGuard guard;
  auto* array = new int[10];
  g_sink = array;
  delete[] array;
  auto* nothrow = new (std::nothrow) int(1);
  g_sink = nothrow;
  delete nothrow;
  struct alignas(128) Aligned {
    char bytes[128];
  };
  auto* aligned = new Aligned;
  g_sink = aligned;
  EXPECT_EQ(reinterpret_cast<uintptr_t>(aligned) % 128, 0u);
  delete aligned;
  EXPECT_EQ(guard.allocations(), 3u);
}

TEST(AllocationGuardTest, CountsOnlyTheCallingThread) {
  AllocationGuard guard;
  std::thread other([] {
    AllocationGuard inner;
    for (int i = 0; i < 10; ++i) {
      auto* p = new char[64];
      g_sink = p;
      delete[] p;
    }
    EXPECT_EQ(inner.allocations(), 10u);
  });
  other.join();
  // Only std::thread's own start-up state (one allocation) was made on this thread.
  EXPECT_LT(guard.allocations(), 10u);
}

TEST(AllocationGuardTest, CountsMallocAndEigenWithoutSanitizer) {
  if (!alloc_counter_detail::kCountsMalloc) {
    GTEST_SKIP() << "under a sanitizer only operator new is counted (it owns malloc)";
  }
  AllocationGuard guard;
  void* p = std::malloc(32);
  g_sink = p;
  std::free(p);
  EXPECT_EQ(guard.allocations(), 1u);
  void* aligned = nullptr;
  ASSERT_EQ(posix_memalign(&aligned, 64, 100), 0);
  g_sink = aligned;
  std::free(aligned);
  EXPECT_EQ(guard.allocations(), 2u);

  // Eigen's dynamic-size storage goes through std::malloc, not operator new.
  guard.Reset();
  Eigen::VectorXd v(static_cast<Eigen::Index>(100 + guard.allocations()));
  v.setOnes();
  g_sink = v.data();
  EXPECT_EQ(guard.allocations(), 1u);
  EXPECT_EQ(v.sum(), 100.0);

  // A new counts once, not once for operator new and again for the malloc beneath it.
  guard.Reset();
  auto* value = new double(1.0);
  g_sink = value;
  delete value;
  EXPECT_EQ(guard.allocations(), 1u);
}

}  // namespace
}  // namespace felt
