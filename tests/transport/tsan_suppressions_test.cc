// The ThreadSanitizer suppressions of tests/transport/tsan.supp, built into this test binary so
// that `make test-tsan` needs no TSAN_OPTIONS change, and a test that keeps the two copies equal.

#include <gtest/gtest.h>

#include <fstream>
#include <string>

namespace {

// The non-comment lines of tests/transport/tsan.supp, one per line.
constexpr char kSuppressions[] = "race:libddsc.so\nrace:libcivetweb.so\n";

}  // namespace

#if defined(__SANITIZE_THREAD__)
/// Read by the TSan runtime at start-up, in addition to any TSAN_OPTIONS suppressions file.
extern "C" const char* __tsan_default_suppressions() { return kSuppressions; }
#endif

TEST(TsanSuppressionsTest, TheEmbeddedCopyMatchesTheFile) {
  std::ifstream in(std::string(FELT_SOURCE_DIR "/tests/transport/tsan.supp"));
  ASSERT_TRUE(in) << "tests/transport/tsan.supp is missing";
  std::string rules, line;
  while (std::getline(in, line)) {
    if (!line.empty() && line[0] != '#') rules += line + "\n";
  }
  EXPECT_EQ(rules, kSuppressions);
}
