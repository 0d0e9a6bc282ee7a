#pragma once
// Runs the built `felt` binary as a child process, for the tests of its commands.

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "base/json.h"
#include "base/process.h"

namespace felt::test {

/// The felt binary of this build.
inline const std::string kFelt = std::string(FELT_BINARY_DIR) + "/felt";

/// The repository root (scenes/, recordings/ are under it).
inline const std::string kSource = FELT_SOURCE_DIR;

/// The bundled poke-and-hold trace, the one most command tests replay.
inline const std::string kPokeHoldTrace = FELT_SOURCE_DIR "/recordings/poke_hold.trace";

/// The whole text of the file at `path` ("" if it cannot be read).
inline std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

/// `name` in GoogleTest's temporary directory.
inline std::string TempPath(const std::string& name) {
  return (std::filesystem::path(::testing::TempDir()) / name).string();
}

/// What a `felt` run returned.
struct Outcome {
  int exit_code = -1;
  std::string output;  ///< stdout and stderr together
};

/// Runs `felt <args>` through the shell (`args` may quote) and collects its exit code and output.
inline Outcome RunFelt(const std::string& args) {
  const CapturedRun run = RunCaptured({"/bin/sh", "-c", "exec " + kFelt + " " + args});
  return Outcome{run.exit_code, run.output};
}

/// Runs `felt <args>` and expects a refused input: exit code 2 and exactly the one line
/// "felt: error: <message>\n" (no unit).
inline void ExpectFeltError(const std::string& args, const std::string& message) {
  SCOPED_TRACE("felt " + args);
  const Outcome outcome = RunFelt(args);
  EXPECT_EQ(outcome.exit_code, 2) << outcome.output;
  EXPECT_EQ(outcome.output, "felt: error: " + message + "\n");
}

}  // namespace felt::test
