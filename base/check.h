#pragma once
// Always-on checks of broken invariants (Drake's DRAKE_DEMAND habit, shared/STYLE.md): unlike
// assert, FELT_CHECK stays in every build (Release builds define NDEBUG), prints the condition and
// where it failed, and aborts. For bugs in Felt only: bad user input throws an error that names
// the file, line and field instead (scene/scene_file.h), and the real-time loops count and reject
// bad samples (haptic_loop/safety.h).

namespace felt::check_detail {

/// Prints "felt: check failed: <condition> at <file>:<line>" to stderr and aborts. Allocates
/// nothing (safe to reach from a real-time thread, which is then lost anyway).
[[noreturn]] void CheckFailed(const char* condition, const char* file, int line) noexcept;

}  // namespace felt::check_detail

/// Aborts with the condition's text and place when `condition` is false, in every build. Costs one
/// predictable branch; real-time safe while it holds.
#define FELT_CHECK(condition)                                            \
  do {                                                                   \
    if (!(condition)) [[unlikely]] {                                     \
      ::felt::check_detail::CheckFailed(#condition, __FILE__, __LINE__); \
    }                                                                    \
  } while (false)
