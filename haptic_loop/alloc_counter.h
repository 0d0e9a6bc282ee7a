#pragma once
// An allocation-counting guard for tests: proves that a real-time tick does not allocate
// (shared/STYLE.md, "Threads and the real-time tick"; Drake's LimitMalloc habit).
//
// Usage, in any test executable (tests/haptic_loop, tests/proxy, ...):
//
//   // In exactly ONE .cc file of the executable, at namespace scope:
//   #include "haptic_loop/alloc_counter.h"
//   FELT_DEFINE_ALLOC_COUNTER();
//
//   // In any test of that executable:
//   felt::AllocationGuard guard;
//   tick();                                    // the code that must not allocate
//   EXPECT_EQ(guard.allocations(), 0u);
//
// The macro defines the replaceable global operator new/delete (every form) over malloc/free,
// counting each new on a thread_local counter. Forgetting the macro is a link error (undefined
// felt::alloc_counter_detail::Installed), expanding it twice is a link error (multiple
// definition), so a guard can never silently count nothing. An executable whose tests already
// replace operator new themselves must not expand it (the linker reports the clash).
//
// Where Eigen is used, add EIGEN_RUNTIME_NO_MALLOC as a second check: compile the test target
// with -DEIGEN_RUNTIME_NO_MALLOC (every TU, so inline Eigen code agrees) and wrap the tick in
// Eigen::internal::set_is_malloc_allowed(false) / (true); Eigen then asserts on any heap use,
// including through its own aligned allocator.

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <new>

namespace felt {

namespace alloc_counter_detail {
/// operator new calls made by this thread so far (written by the replacement operator new).
inline thread_local uint64_t thread_allocations = 0;
/// Defined only by FELT_DEFINE_ALLOC_COUNTER(): links the guard to the counting operator new.
bool Installed() noexcept;
}  // namespace alloc_counter_detail

/// operator new calls (every form, including nothrow, array and aligned) made by the calling
/// thread since it started. Needs FELT_DEFINE_ALLOC_COUNTER() in the executable.
inline uint64_t ThreadAllocationCount() noexcept {
  return alloc_counter_detail::thread_allocations;
}

/// Counts the calling thread's operator new calls from construction on. Allocations on other
/// threads are not counted. Needs FELT_DEFINE_ALLOC_COUNTER() in the executable.
class AllocationGuard {
 public:
  /// Starts counting at the current count.
  AllocationGuard() noexcept : start_(Start()) {}

  /// operator new calls on this thread since construction (or the last Reset()).
  uint64_t allocations() const noexcept { return ThreadAllocationCount() - start_; }

  /// Starts counting again from now.
  void Reset() noexcept { start_ = ThreadAllocationCount(); }

 private:
  static uint64_t Start() noexcept {
    static_cast<void>(alloc_counter_detail::Installed());
    return ThreadAllocationCount();
  }
  uint64_t start_;
};

}  // namespace felt

// Replacement global allocation functions: expand once per executable, at namespace scope.
// malloc-based; aligned forms use aligned_alloc with the size rounded up to the alignment.
#define FELT_DEFINE_ALLOC_COUNTER()                                                                \
  namespace felt::alloc_counter_detail {                                                           \
  bool Installed() noexcept { return true; }                                                       \
  static void* Allocate(std::size_t size) {                                                        \
    ++thread_allocations;                                                                          \
    void* p = std::malloc(size == 0 ? 1 : size);                                                   \
    if (p == nullptr) throw std::bad_alloc();                                                      \
    return p;                                                                                      \
  }                                                                                                \
  static void* AllocateAligned(std::size_t size, std::align_val_t align) {                         \
    ++thread_allocations;                                                                          \
    const std::size_t a = static_cast<std::size_t>(align);                                         \
    const std::size_t rounded = ((size == 0 ? 1 : size) + a - 1) / a * a;                          \
    void* p = std::aligned_alloc(a < sizeof(void*) ? sizeof(void*) : a, rounded);                  \
    if (p == nullptr) throw std::bad_alloc();                                                      \
    return p;                                                                                      \
  }                                                                                                \
  }                                                                                                \
  void* operator new(std::size_t size) { return felt::alloc_counter_detail::Allocate(size); }      \
  void* operator new[](std::size_t size) { return felt::alloc_counter_detail::Allocate(size); }    \
  void* operator new(std::size_t size, const std::nothrow_t&) noexcept {                           \
    try {                                                                                          \
      return felt::alloc_counter_detail::Allocate(size);                                           \
    } catch (...) {                                                                                \
      return nullptr;                                                                              \
    }                                                                                              \
  }                                                                                                \
  void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {                         \
    try {                                                                                          \
      return felt::alloc_counter_detail::Allocate(size);                                           \
    } catch (...) {                                                                                \
      return nullptr;                                                                              \
    }                                                                                              \
  }                                                                                                \
  void* operator new(std::size_t size, std::align_val_t align) {                                   \
    return felt::alloc_counter_detail::AllocateAligned(size, align);                               \
  }                                                                                                \
  void* operator new[](std::size_t size, std::align_val_t align) {                                 \
    return felt::alloc_counter_detail::AllocateAligned(size, align);                               \
  }                                                                                                \
  void* operator new(std::size_t size, std::align_val_t align, const std::nothrow_t&) noexcept {   \
    try {                                                                                          \
      return felt::alloc_counter_detail::AllocateAligned(size, align);                             \
    } catch (...) {                                                                                \
      return nullptr;                                                                              \
    }                                                                                              \
  }                                                                                                \
  void* operator new[](std::size_t size, std::align_val_t align, const std::nothrow_t&) noexcept { \
    try {                                                                                          \
      return felt::alloc_counter_detail::AllocateAligned(size, align);                             \
    } catch (...) {                                                                                \
      return nullptr;                                                                              \
    }                                                                                              \
  }                                                                                                \
  void operator delete(void* p) noexcept { std::free(p); }                                         \
  void operator delete[](void* p) noexcept { std::free(p); }                                       \
  void operator delete(void* p, std::size_t) noexcept { std::free(p); }                            \
  void operator delete[](void* p, std::size_t) noexcept { std::free(p); }                          \
  void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }                  \
  void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }                \
  void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }                       \
  void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }                     \
  void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }          \
  void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }        \
  void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept {                \
    std::free(p);                                                                                  \
  }                                                                                                \
  void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept {              \
    std::free(p);                                                                                  \
  }                                                                                                \
  static_assert(true, "FELT_DEFINE_ALLOC_COUNTER() ends here")
