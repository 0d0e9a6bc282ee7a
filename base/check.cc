#include "base/check.h"

#include <unistd.h>

#include <cstdlib>
#include <cstring>

namespace felt::check_detail {
namespace {

// Writes `text` to stderr with write(2): no stdio buffer, no allocation.
void WriteError(const char* text) {
  const size_t length = std::strlen(text);
  size_t written = 0;
  while (written < length) {
    const ssize_t n = ::write(STDERR_FILENO, text + written, length - written);
    if (n <= 0) return;
    written += static_cast<size_t>(n);
  }
}

}  // namespace

void CheckFailed(const char* condition, const char* file, int line) noexcept {
  // The line number in decimal, without snprintf's locale machinery.
  char number[16];
  char* end = number + sizeof number;
  char* p = end;
  *--p = '\0';
  unsigned value = line > 0 ? static_cast<unsigned>(line) : 0u;
  do {
    *--p = static_cast<char>('0' + value % 10);
    value /= 10;
  } while (value != 0 && p > number);
  WriteError("felt: check failed: ");
  WriteError(condition);
  WriteError(" at ");
  WriteError(file);
  WriteError(":");
  WriteError(p);
  WriteError("\n");
  std::abort();
}

}  // namespace felt::check_detail
