// `felt security init` as a user runs it: the files it makes, and a clear one-line error (exit 2)
// when openssl is missing, DIR cannot be made or written, a key exists without --force, or the
// participants list is wrong.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "base/process.h"
#include "tests/app/felt_process.h"

namespace {

using felt::test::ExpectFeltError;
using felt::test::kFelt;
using felt::test::Outcome;
using felt::test::RunFelt;
using felt::test::TempPath;

TEST(SecurityCommand, InitMakesTheDirectoryAndKeepsKeysWithoutForce) {
  const std::string dir = TempPath("security_cmd_" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  const Outcome made = RunFelt("security init " + dir + " --participants server,device:left");
  ASSERT_EQ(made.exit_code, 0) << made.output;
  EXPECT_NE(made.output.find("identities: server device-left"), std::string::npos) << made.output;
  for (const char* file : {"ca_cert.pem", "governance.p7s", "server/permissions.p7s",
                           "device-left/cert.pem", "device-left/key.pem"}) {
    EXPECT_TRUE(std::filesystem::exists(std::filesystem::path(dir) / file)) << file;
  }
  ExpectFeltError("security init " + dir + " --participants device:left",
                  dir + "/device-left/key.pem exists: use --force to replace the identity's key");
  // Adding an identity reuses the CA; --force replaces.
  const Outcome added = RunFelt("security init " + dir + " --participants recorder");
  EXPECT_EQ(added.exit_code, 0) << added.output;
  EXPECT_EQ(added.output.find("ca_key.pem"), std::string::npos) << "the CA was remade";
  const Outcome forced = RunFelt("security init " + dir + " --participants device:left --force");
  EXPECT_EQ(forced.exit_code, 0) << forced.output;
  ExpectFeltError("security init " + dir + " --participants server,admin",
                  "--participants: \"admin\" is not server, recorder or device:ID");
  std::filesystem::remove_all(dir);
}

TEST(SecurityCommand, MissingOpensslAndUnusableDirectoriesAreNamed) {
  const std::string dir = TempPath("security_cmd_bad_" + std::to_string(getpid()));
  const felt::CapturedRun no_openssl =
      felt::RunCaptured({"/usr/bin/env", "PATH=/nonexistent", kFelt, "security", "init", dir});
  EXPECT_EQ(no_openssl.exit_code, 2) << no_openssl.output;
  EXPECT_EQ(no_openssl.output,
            "felt: error: the openssl command was not found in PATH: install Debian's openssl "
            "package (apt-get install openssl)\n");
  EXPECT_FALSE(std::filesystem::exists(dir)) << "nothing is made without openssl";
  // A directory below a regular file cannot be made.
  const std::string file = TempPath("security_cmd_file_" + std::to_string(getpid()));
  std::ofstream(file) << "x";
  ExpectFeltError("security init " + file + "/sec",
                  file + "/sec: cannot create the directory (Not a directory)");
  std::filesystem::remove(file);
  // A directory without write permission (root may write anywhere: then this part is skipped).
  if (geteuid() != 0) {
    std::filesystem::create_directories(dir);
    chmod(dir.c_str(), 0500);
    ExpectFeltError("security init " + dir, dir + ": the directory is not writable");
    chmod(dir.c_str(), 0700);
    std::filesystem::remove_all(dir);
  }
}

}  // namespace
