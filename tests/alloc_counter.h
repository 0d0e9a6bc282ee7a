#pragma once
// An allocation-counting guard for tests: proves that a real-time tick does not allocate
// (shared/STYLE.md, "Threads and the real-time tick"; Drake's LimitMalloc habit).
//
// Usage, in any test executable (tests/alloc_counter.cc, which CMake compiles into every one, is
// the executable's one expansion of the macro):
//
//   #include "tests/alloc_counter.h"
//   FELT_DEFINE_ALLOC_COUNTER();               // once per executable: tests/alloc_counter.cc
//
//   // In any test of that executable:
//   felt::AllocationGuard guard;
//   tick();                                    // the code that must not allocate
//   EXPECT_EQ(guard.allocations(), 0u);
//
// The macro defines the replaceable global operator new/delete (every form) and, in builds
// without a sanitizer, glibc's malloc family (malloc, calloc, realloc, free, memalign,
// aligned_alloc, posix_memalign, valloc, pvalloc: glibc supports replacing them, and the
// replacements forward to glibc's own __libc_* allocator). Each allocation call increments a
// thread_local counter. Counting malloc matters: Eigen allocates dynamic-size storage with
// std::malloc (Eigen::internal::aligned_malloc), never operator new, and so does C code. Under
// ASan/TSan the sanitizer owns malloc, so only operator new is counted there: a stray
// Eigen/malloc allocation is caught by the release build's run of the same test.
//
// Forgetting the macro is a link error (undefined felt::alloc_counter_detail::Installed),
// expanding it twice is a link error (multiple definition), so a guard can never silently count
// nothing. An executable whose tests already replace operator new or malloc themselves must not
// expand it (the linker reports the clash).
//
// EIGEN_RUNTIME_NO_MALLOC is a second check where Eigen is used: compile every TU of the target
// (library code included, so the tick's inline Eigen code carries the check) with
// -DEIGEN_RUNTIME_NO_MALLOC and wrap the tick in Eigen::internal::set_is_malloc_allowed(false) /
// (true). Note that Eigen reports through eigen_assert, which NDEBUG compiles out (Release and
// RelWithDebInfo both define NDEBUG), so that check only fires in a build without NDEBUG or
// with eigen_assert defined to abort.

#include <unistd.h>

#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <new>

// Whether the malloc family is replaced too (not under a sanitizer, which owns malloc).
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define FELT_ALLOC_COUNTER_COUNTS_MALLOC 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(memory_sanitizer)
#define FELT_ALLOC_COUNTER_COUNTS_MALLOC 0
#endif
#endif
#ifndef FELT_ALLOC_COUNTER_COUNTS_MALLOC
#define FELT_ALLOC_COUNTER_COUNTS_MALLOC 1
#endif

namespace felt {

namespace alloc_counter_detail {
/// Allocation calls made by this thread so far (written by the replacement functions).
inline thread_local uint64_t thread_allocations = 0;
/// True when the malloc family is counted (builds without a sanitizer).
inline constexpr bool kCountsMalloc = FELT_ALLOC_COUNTER_COUNTS_MALLOC != 0;
/// Defined only by FELT_DEFINE_ALLOC_COUNTER(): links the guard to the counting operator new.
bool Installed() noexcept;

/// Runs `allocate` (one of the counted allocations below) for a nothrow operator new: the block
/// it returns, or nullptr where it throws (std::bad_alloc).
template <class Allocate>
void* NoThrow(Allocate allocate) noexcept {
  try {
    return allocate();
  } catch (...) {
    return nullptr;
  }
}

}  // namespace alloc_counter_detail

/// Allocation calls made by the calling thread since it started: operator new in every form
/// (nothrow, array, aligned) and, without a sanitizer, the malloc family (one operator new counts
/// once). Needs FELT_DEFINE_ALLOC_COUNTER() in the executable.
inline uint64_t ThreadAllocationCount() noexcept {
  // A volatile read: GCC assumes a call to the builtin malloc changes no other memory, so a plain
  // read after `std::malloc` could reuse the value read before it (it did: the count of a
  // malloc/free pair came out 0 once the surrounding code changed).
  return *static_cast<volatile uint64_t*>(&alloc_counter_detail::thread_allocations);
}

/// Counts the calling thread's allocation calls (see ThreadAllocationCount) from construction on.
/// Allocations on other threads are not counted. Needs FELT_DEFINE_ALLOC_COUNTER() in the
/// executable.
class AllocationGuard {
 public:
  /// Starts counting at the current count.
  AllocationGuard() noexcept : start_(Start()) {}

  /// Allocation calls on this thread since construction (or the last Reset()).
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
    if constexpr (!kCountsMalloc) ++thread_allocations;                                            \
    void* p = std::malloc(size == 0 ? 1 : size);                                                   \
    if (p == nullptr) throw std::bad_alloc();                                                      \
    return p;                                                                                      \
  }                                                                                                \
  static void* AllocateAligned(std::size_t size, std::align_val_t align) {                         \
    if constexpr (!kCountsMalloc) ++thread_allocations;                                            \
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
    return felt::alloc_counter_detail::NoThrow(                                                    \
        [=] { return felt::alloc_counter_detail::Allocate(size); });                               \
  }                                                                                                \
  void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {                         \
    return felt::alloc_counter_detail::NoThrow(                                                    \
        [=] { return felt::alloc_counter_detail::Allocate(size); });                               \
  }                                                                                                \
  void* operator new(std::size_t size, std::align_val_t align) {                                   \
    return felt::alloc_counter_detail::AllocateAligned(size, align);                               \
  }                                                                                                \
  void* operator new[](std::size_t size, std::align_val_t align) {                                 \
    return felt::alloc_counter_detail::AllocateAligned(size, align);                               \
  }                                                                                                \
  void* operator new(std::size_t size, std::align_val_t align, const std::nothrow_t&) noexcept {   \
    return felt::alloc_counter_detail::NoThrow(                                                    \
        [=] { return felt::alloc_counter_detail::AllocateAligned(size, align); });                 \
  }                                                                                                \
  void* operator new[](std::size_t size, std::align_val_t align, const std::nothrow_t&) noexcept { \
    return felt::alloc_counter_detail::NoThrow(                                                    \
        [=] { return felt::alloc_counter_detail::AllocateAligned(size, align); });                 \
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
  FELT_ALLOC_COUNTER_MALLOC_FAMILY_                                                                \
  static_assert(true, "FELT_DEFINE_ALLOC_COUNTER() ends here")

// The malloc family over glibc's __libc_* allocator, counted (not under a sanitizer).
#if FELT_ALLOC_COUNTER_COUNTS_MALLOC
#define FELT_ALLOC_COUNTER_MALLOC_FAMILY_                                        \
  extern "C" {                                                                   \
  void* __libc_malloc(std::size_t) noexcept;                                     \
  void* __libc_calloc(std::size_t, std::size_t) noexcept;                        \
  void* __libc_realloc(void*, std::size_t) noexcept;                             \
  void __libc_free(void*) noexcept;                                              \
  void* __libc_memalign(std::size_t, std::size_t) noexcept;                      \
  void* __libc_valloc(std::size_t) noexcept;                                     \
  void* __libc_pvalloc(std::size_t) noexcept;                                    \
  void* malloc(std::size_t size) noexcept {                                      \
    ++felt::alloc_counter_detail::thread_allocations;                            \
    return __libc_malloc(size);                                                  \
  }                                                                              \
  void* calloc(std::size_t count, std::size_t size) noexcept {                   \
    ++felt::alloc_counter_detail::thread_allocations;                            \
    return __libc_calloc(count, size);                                           \
  }                                                                              \
  void* realloc(void* p, std::size_t size) noexcept {                            \
    if (size != 0) ++felt::alloc_counter_detail::thread_allocations;             \
    return __libc_realloc(p, size);                                              \
  }                                                                              \
  void free(void* p) noexcept { __libc_free(p); }                                \
  void* memalign(std::size_t align, std::size_t size) noexcept {                 \
    ++felt::alloc_counter_detail::thread_allocations;                            \
    return __libc_memalign(align, size);                                         \
  }                                                                              \
  void* aligned_alloc(std::size_t align, std::size_t size) noexcept {            \
    ++felt::alloc_counter_detail::thread_allocations;                            \
    return __libc_memalign(align, size);                                         \
  }                                                                              \
  int posix_memalign(void** out, std::size_t align, std::size_t size) noexcept { \
    if (align < sizeof(void*) || (align & (align - 1)) != 0) return EINVAL;      \
    ++felt::alloc_counter_detail::thread_allocations;                            \
    void* p = __libc_memalign(align, size);                                      \
    if (p == nullptr) return ENOMEM;                                             \
    *out = p;                                                                    \
    return 0;                                                                    \
  }                                                                              \
  void* valloc(std::size_t size) noexcept {                                      \
    ++felt::alloc_counter_detail::thread_allocations;                            \
    return __libc_valloc(size);                                                  \
  }                                                                              \
  void* pvalloc(std::size_t size) noexcept {                                     \
    ++felt::alloc_counter_detail::thread_allocations;                            \
    return __libc_pvalloc(size);                                                 \
  }                                                                              \
  }
#else
#define FELT_ALLOC_COUNTER_MALLOC_FAMILY_
#endif
