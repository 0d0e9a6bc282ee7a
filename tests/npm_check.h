#pragma once
// Running the independent checkers of tools/npm/ (@mcap/core, @foxglove/rosmsg2-serialization)
// from a test. `make test` installs them (`npm ci` in tools/npm, Makefile step `npm-deps`); when
// they are absent (no node, or the registry was unreachable) the tests that need them skip and
// say why.

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

namespace felt::testing {

/// The folder of the npm checkers.
inline std::string NpmDir() {
  return (std::filesystem::path(FELT_SOURCE_DIR) / "tools" / "npm").string();
}

/// Why the npm checkers cannot run here ("" when they can).
inline std::string NpmUnavailableReason() {
  if (std::system("node --version > /dev/null 2>&1") != 0) {
    return "node is not installed (Debian package nodejs; `make deps` installs it)";
  }
  for (const char* pkg : {"@mcap/core", "@foxglove/rosmsg2-serialization", "@foxglove/rosmsg"}) {
    if (!std::filesystem::exists(NpmDir() + "/node_modules/" + pkg + "/package.json")) {
      return std::string("tools/npm/node_modules/") + pkg +
             " is missing: run `make npm-deps` (npm ci in tools/npm; it needs the npm registry, "
             "which was unreachable or not tried)";
    }
  }
  return "";
}

/// Runs `node tools/npm/SCRIPT ARGS` (args already shell-quoted), returns its exit code and puts
/// its stdout and stderr in *output.
inline int RunNpmCheck(const std::string& script, const std::string& args, std::string* output) {
  const std::string cmd = "node '" + NpmDir() + "/" + script + "' " + args + " 2>&1";
  FILE* pipe = popen(cmd.c_str(), "r");
  if (pipe == nullptr) {
    *output = "popen failed: " + cmd;
    return -1;
  }
  std::array<char, 4096> buf{};
  output->clear();
  size_t n;
  while ((n = std::fread(buf.data(), 1, buf.size(), pipe)) > 0) output->append(buf.data(), n);
  const int status = pclose(pipe);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace felt::testing

/// Skips the current test, saying why, when the npm checkers are unavailable.
#define FELT_SKIP_WITHOUT_NPM()                                                  \
  do {                                                                           \
    const std::string felt_npm_reason = ::felt::testing::NpmUnavailableReason(); \
    if (!felt_npm_reason.empty())                                                \
      GTEST_SKIP() << "independent check skipped: " << felt_npm_reason;          \
  } while (0)
