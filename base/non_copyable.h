#pragma once
// A base for classes that own what must not be duplicated or moved (threads, DDS entities whose
// addresses other threads hold): deriving from it deletes the copy and move operations.

namespace felt {

/// Deletes copy construction and assignment (and with them the implicit moves) of a derived class.
class NonCopyable {
 public:
  NonCopyable(const NonCopyable&) = delete;
  NonCopyable& operator=(const NonCopyable&) = delete;

 protected:
  NonCopyable() = default;
  ~NonCopyable() = default;
};

}  // namespace felt
