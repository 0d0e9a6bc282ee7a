// DDS Security end to end, as a driver author turns it on (docs/transport.md, "Security"):
// `felt security init`, `felt serve` with `[transport] security` in its scene, and the example
// driver with `--security`: the driver feels the cloth; the same driver without `--security` gets
// no force. Needs the `felt` and `felt_device_client` binaries of the same build; skipped where
// they were not built (the TSan CI build compiles only the test executables).
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "base/process.h"
#include "tests/test_domain.h"
#include "tests/test_env.h"
#include "transport/security.h"

namespace {

using felt::Process;
using felt::SpawnOptions;

const std::string kSecFelt = std::string(FELT_BINARY_DIR) + "/felt";
const std::string kSecClient = std::string(FELT_BINARY_DIR) + "/felt_device_client";
const std::string kSecScene = std::string(FELT_SOURCE_DIR "/scenes/curtain.toml");

std::string ReadWhole(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string InTemp(const std::string& name) {
  return (std::filesystem::path(testing::TempDir()) / name).string();
}

// Runs `command` through the shell with its output in the file `log`.
Process StartLogged(const std::string& command, const std::string& log) {
  SpawnOptions options;
  options.output = SpawnOptions::Output::kFile;
  options.output_file = log;
  options.die_with_parent = true;
  return Process::Spawn({"/bin/sh", "-c", "exec " + command}, options);
}

TEST(ServeSecurity, TheExampleDriverFeelsTheCurtainOnlyWithItsIdentity) {
  if (!std::filesystem::exists(kSecFelt) || !std::filesystem::exists(kSecClient)) {
    GTEST_SKIP() << "felt or felt_device_client not built";
  }
  if (felt::transport::SecurityPluginDir().empty()) {
    GTEST_SKIP() << "Cyclone's security plugins (libdds_security_auth.so) were not found";
  }
  const std::string dir = InTemp("serve_security_" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  const felt::CapturedRun init = felt::RunCaptured(
      {kSecFelt, "security", "init", dir, "--participants", "server,device:default"});
  ASSERT_EQ(init.exit_code, 0) << init.output;
  // The default scene with security turned on in its [transport] section.
  const std::string scene = InTemp("serve_security.toml");
  std::ofstream(scene) << ReadWhole(kSecScene) << "\n[transport]\nsecurity = \"" << dir << "\"\n";
  const std::string domain = std::to_string(felt::testing::ExclusiveDdsDomain());
  const std::string server_log = InTemp("serve_security.log");
  Process server = StartLogged(
      kSecFelt + " serve --no-realtime --duration 60 --domain " + domain + " --scene " + scene,
      server_log);
  const auto run_client = [&](const std::string& args, const std::string& name) {
    const std::string log = InTemp(name + ".log");
    Process client = StartLogged(kSecClient + " --domain " + domain + " " + args, log);
    if (!client.Wait(std::chrono::seconds(60))) client.Terminate(std::chrono::milliseconds(0));
    EXPECT_EQ(client.exit_code(), 0) << ReadWhole(log);
    return ReadWhole(log);
  };
  // One press of the example's 4 s cycle, and secure discovery (about 0.4 s; under TSan on two
  // loaded cores it took 4.2 s once, so that 8 s left forces in under a quarter of the samples'
  // ticks: a sanitizer's run keeps 12 s).
  const double seconds = felt::testing::Sanitized() ? 12 : 6;
  const std::string secure =
      run_client("--seconds " + std::to_string(seconds) + " --security " + dir, "secure_client");
  unsigned long long samples = 0, forces = 0;
  double impulse = 0, peak = 0;
  const size_t at = secure.find("stopped: ");
  ASSERT_NE(at, std::string::npos) << secure;
  ASSERT_EQ(std::sscanf(secure.c_str() + at,
                        "stopped: samples %llu, forces %llu, motor impulse %lf N s, peak force "
                        "%lf N",
                        &samples, &forces, &impulse, &peak),
            4)
      << secure;
  EXPECT_GT(forces, samples / 4) << secure;  // loose: a loaded machine may miss periods
  EXPECT_GT(peak, 0.05) << secure;           // the cloth pushes back
  const std::string plain = run_client("--seconds 2", "plain_client");
  EXPECT_NE(plain.find("stopped: samples"), std::string::npos) << plain;
  EXPECT_NE(plain.find("forces 0,"), std::string::npos) << plain;
  server.Signal(SIGTERM);
  if (!server.Wait(std::chrono::seconds(20))) server.Terminate(std::chrono::milliseconds(0));
  const std::string log = ReadWhole(server_log);
  EXPECT_EQ(server.exit_code(), 0) << log;
  EXPECT_NE(log.find("DDS Security " + dir), std::string::npos) << log;
  std::filesystem::remove_all(dir);
}

}  // namespace
