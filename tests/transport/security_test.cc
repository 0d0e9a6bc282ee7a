// DDS Security (transport/security.h, docs/transport.md "Security") with the real Cyclone DDS and
// its plugins on loopback: `felt security init`'s files, the clear errors for missing or bad
// files, and the three promises: an authenticated device with permission drives the server and
// gets forces; an unauthenticated participant can neither inject samples nor read forces; an
// authenticated participant without permission to publish pointer samples cannot publish them.
// The peers run in forked processes (forked before this process creates any DDS entity): inside
// one process Cyclone matches readers and writers locally, without the security plugins.
#include "transport/security.h"

#include <gtest/gtest.h>
#include <poll.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "base/process.h"
#include "tests/test_domain.h"
#include "tests/test_env.h"
#include "tests/transport/transport_test_util.h"
#include "transport/dds_config.h"

namespace felt::transport {
namespace {

namespace fs = std::filesystem;
using testing::UniqueTopics;

// The security directory of this test process, made once: server, device "sec", recorder.
const std::string& SecurityTestDir() {
  static const std::string dir = [] {
    const std::string path =
        (fs::path(::testing::TempDir()) / ("felt_security_" + std::to_string(getpid()))).string();
    fs::remove_all(path);
    SecurityInitOptions options;
    options.dir = path;
    options.identities = ParseSecurityParticipants("server,device:sec,recorder");
    InitSecurityDir(options);
    return path;
  }();
  return dir;
}

// A domain of this test process's own (secure participants stay away from other tests' domain).
uint32_t SecurityTestDomain() { return felt::testing::ExclusiveDdsDomain(); }

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

// How long a peer waits for secure discovery (about 0.3 s on loopback; far slower under TSan).
std::chrono::seconds DiscoveryWait() {
  return felt::testing::Sanitized() ? std::chrono::seconds(60) : std::chrono::seconds(20);
}

// What a forked peer does: join with `dds`, publish for `devices[0]` at 1 kHz, count forces for
// all of `devices`. It prints "matched R forces F published P" and exits 0, or prints the error and
// exits 3 when its transport cannot be created. It publishes until `stop_fd` closes, or for
// `publish_s` seconds after it matched the server when `stop_fd` is -1.
struct PeerPlan {
  DdsSettings dds;
  TopicNames topics;
  std::vector<std::string> devices;
  int stop_fd = -1;
  double publish_s = 1.5;
};

int RunSecurityPeer(const PeerPlan& plan) {
  try {
    ClientTransportConfig config;
    config.dds = plan.dds;
    config.topics = plan.topics;
    config.device_ids = plan.devices;
    config.subscribe_status = false;
    ClientTransport client(config);
    const auto matched = [&] {
      return client.MatchedPointerReaders() > 0 && client.MatchedForceWriters() > 0;
    };
    int64_t end_ns = INT64_MAX;
    if (plan.stop_fd < 0) {
      WaitUntil(matched, DiscoveryWait());
      end_ns = MonotonicNowNs() + static_cast<int64_t>(plan.publish_s * 1e9);
    }
    uint64_t seq = 0, forces = 0;
    uint32_t most_matched = 0;
    while (MonotonicNowNs() < end_ns) {
      pollfd stop{plan.stop_fd, POLLIN, 0};
      if (plan.stop_fd >= 0 && poll(&stop, 1, 0) != 0) break;  // the parent closed the pipe
      client.PublishPointer(testing::Sample(++seq));
      most_matched = std::max(most_matched, client.MatchedPointerReaders());
      ForceCommandView force;
      for (uint32_t d = 0; d < plan.devices.size(); ++d) {
        while (client.TakeForce(d, &force)) ++forces;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    std::printf("matched %u forces %llu published %llu\n", most_matched,
                static_cast<unsigned long long>(forces), static_cast<unsigned long long>(seq));
    return 0;
  } catch (const std::exception& e) {
    std::printf("peer error: %s\n", e.what());
    return 3;
  }
}

// Forks a peer with its output on a pipe; the child first closes `close_fd` (when >= 0), the
// parent's end of a stop pipe.
Process ForkSecurityPeer(const PeerPlan& plan, int close_fd = -1) {
  SpawnOptions options;
  options.output = SpawnOptions::Output::kPipe;
  options.die_with_parent = true;
  return Process::Fork(
      [plan, close_fd] {
        if (close_fd >= 0) close(close_fd);
        return RunSecurityPeer(plan);
      },
      options);
}

// "matched R forces F published P" of a peer's output; false when it is not there.
bool ParsePeer(const std::string& out, unsigned* matched, unsigned long long* forces,
               unsigned long long* published) {
  const size_t at = out.find("matched ");
  return at != std::string::npos &&
         std::sscanf(out.c_str() + at, "matched %u forces %llu published %llu", matched, forces,
                     published) == 3;
}

class SecurityTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (SecurityPluginDir().empty()) {
      GTEST_SKIP() << "Cyclone's security plugins (libdds_security_auth.so) were not found";
    }
    dir_ = SecurityTestDir();
  }
  DdsSettings Secure(const std::string& identity) const {
    DdsSettings dds;
    dds.domain_id = SecurityTestDomain();
    dds.security_dir = dir_;
    dds.identity = identity;
    return dds;
  }
  std::string dir_;
};

TEST(SecurityFilesTest, ParticipantsListIsCheckedAndNamed) {
  const auto ids = ParseSecurityParticipants("server,device:left-1,recorder");
  ASSERT_EQ(ids.size(), 3u);
  EXPECT_EQ(ids[1].Name(), "device-left-1");
  EXPECT_EQ(SecurityIdentityName("device:left-1"), "device-left-1");
  EXPECT_NE(ErrorOf([] { ParseSecurityParticipants("server,admin"); }).find("\"admin\""),
            std::string::npos);
  EXPECT_NE(ErrorOf([] { ParseSecurityParticipants("device:a/b"); }).find("device:a/b"),
            std::string::npos);
  EXPECT_NE(ErrorOf([] { ParseSecurityParticipants("server,server"); }).find("listed twice"),
            std::string::npos);
}

TEST(SecurityFilesTest, DocumentsSayWhatEachIdentityMayDo) {
  const std::string governance = GovernanceXml();
  for (const char* text :
       {"<allow_unauthenticated_participants>false", "<enable_join_access_control>true",
        "<topic_expression>felt/*</topic_expression>", "<data_protection_kind>ENCRYPT",
        "<enable_write_access_control>true", "<enable_read_access_control>true"}) {
    EXPECT_NE(governance.find(text), std::string::npos) << text;
  }
  SecurityIdentity recorder;
  recorder.role = SecurityRole::kRecorder;
  const std::string permissions = PermissionsXml(recorder, "CN=recorder,O=Felt", "a", "b");
  EXPECT_EQ(permissions.find("<publish>"), std::string::npos);
  EXPECT_NE(permissions.find("<subject_name>CN=recorder,O=Felt</subject_name>"), std::string::npos);
  EXPECT_NE(permissions.find("<default>DENY</default>"), std::string::npos);
}

TEST_F(SecurityTest, InitMakesEveryFileAndKeepsKeysWithoutForce) {
  for (const char* file :
       {"ca_cert.pem", "governance.p7s", "server/key.pem", "server/cert.pem",
        "server/permissions.p7s", "device-sec/permissions.p7s", "recorder/key.pem"}) {
    EXPECT_TRUE(fs::exists(fs::path(dir_) / file)) << file;
  }
  struct stat info {};
  ASSERT_EQ(stat((fs::path(dir_) / "server/key.pem").c_str(), &info), 0);
  EXPECT_EQ(info.st_mode & 077, 0u) << "a private key readable by others";
  SecurityInitOptions again;
  again.dir = dir_;
  again.identities = ParseSecurityParticipants("server");
  EXPECT_NE(ErrorOf([&] { InitSecurityDir(again); }).find("server/key.pem exists: use --force"),
            std::string::npos);
}

TEST_F(SecurityTest, MissingOrBadFilesAreNamed) {
  DdsSettings plain;
  plain.identity = "server";
  EXPECT_NE(ErrorOf([&] { Participant p(plain, "server"); }).find("needs --security"),
            std::string::npos);
  DdsSettings dds = Secure("nobody");
  EXPECT_NE(ErrorOf([&] { Participant p(dds, "server"); }).find("no identity 'nobody'"),
            std::string::npos);
  // A copy of the directory with one file broken, then one removed.
  const fs::path copy =
      fs::path(::testing::TempDir()) / ("felt_security_bad_" + std::to_string(getpid()));
  fs::remove_all(copy);
  fs::copy(dir_, copy, fs::copy_options::recursive);
  std::ofstream(copy / "server" / "cert.pem") << "not a certificate\n";
  dds.security_dir = copy.string();
  dds.identity = "";
  std::string error = ErrorOf([&] { Participant p(dds, "server"); });
  EXPECT_NE(error.find((copy / "server" / "cert.pem").string() + ": not a PEM certificate"),
            std::string::npos)
      << error;
  // A certificate of another CA: the files look right, Cyclone refuses it, the error names them.
  SecurityInitOptions other;
  other.dir = copy.string() + "_other";
  other.identities = ParseSecurityParticipants("server");
  InitSecurityDir(other);
  fs::copy_file(fs::path(other.dir) / "server" / "cert.pem", copy / "server" / "cert.pem",
                fs::copy_options::overwrite_existing);
  fs::remove_all(other.dir);
  error = ErrorOf([&] { Participant p(dds, "server"); });
  EXPECT_NE(error.find("Cyclone refused the identity"), std::string::npos) << error;
  EXPECT_NE(error.find((copy / "server" / "cert.pem").string()), std::string::npos) << error;
  fs::remove(copy / "governance.p7s");
  error = ErrorOf([&] { Participant p(dds, "device:sec"); });
  EXPECT_NE(error.find((copy / "governance.p7s").string() + ": cannot read the file"),
            std::string::npos)
      << error;
  fs::remove_all(copy);
}

// An authenticated device drives the server and gets forces, while an unauthenticated
// participant on the same domain and topics, publishing for another device and listening to both
// devices' forces, is never matched: the server accepts nothing from it and it reads no force.
TEST_F(SecurityTest, OnlyTheAuthenticatedDeviceDrivesTheServer) {
  const TopicNames topics = UniqueTopics();
  PeerPlan device{Secure("device:sec"), topics, {"sec"}};
  int stop_pipe[2];
  ASSERT_EQ(pipe(stop_pipe), 0);
  PeerPlan intruder{DdsSettings{}, topics, {"intruder", "sec"}, stop_pipe[0]};
  intruder.dds.domain_id = SecurityTestDomain();  // no security
  Process intruder_process = ForkSecurityPeer(intruder, stop_pipe[1]);
  close(stop_pipe[0]);
  Process device_process = ForkSecurityPeer(device, stop_pipe[1]);

  // The server, after the forks; it pushes a force to both devices every millisecond.
  ServerTransportConfig config;
  config.dds = Secure("");  // default identity "server"
  config.topics = topics;
  config.devices = {testing::TestDevice("sec"), testing::TestDevice("intruder")};
  ServerTransport server(config);
  const auto deadline = std::chrono::steady_clock::now() + DiscoveryWait() * 2;
  while (device_process.running() && std::chrono::steady_clock::now() < deadline) {
    for (uint32_t d = 0; d < 2; ++d) {
      ForceCommandView force;
      force.device_index = d;
      force.force_N_D = {0.0, 0.0, 0.1};
      server.PushForce(force);
    }
    device_process.Poll();
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  close(stop_pipe[1]);  // the intruder stops once the device is done
  ASSERT_TRUE(device_process.Wait(std::chrono::seconds(10)));
  ASSERT_TRUE(intruder_process.Wait(std::chrono::seconds(10)));
  const std::string device_out = device_process.ReadAllOutput();
  const std::string intruder_out = intruder_process.ReadAllOutput();
  const TransportStats stats = server.Stats();

  unsigned matched = 0;
  unsigned long long forces = 0, published = 0;
  ASSERT_TRUE(ParsePeer(device_out, &matched, &forces, &published)) << device_out;
  EXPECT_EQ(matched, 1u) << device_out;
  EXPECT_GT(forces, 0u) << device_out;
  EXPECT_GT(stats.pointer_accepted, 0u);
  EXPECT_LE(stats.pointer_accepted, published);
  PointerSampleView latest;
  EXPECT_TRUE(server.LatestPointer(0, &latest));

  ASSERT_TRUE(ParsePeer(intruder_out, &matched, &forces, &published)) << intruder_out;
  EXPECT_GT(published, 100u) << intruder_out;  // it tried for as long as the device ran
  EXPECT_EQ(matched, 0u) << intruder_out;
  EXPECT_EQ(forces, 0u) << intruder_out;
  EXPECT_FALSE(server.LatestPointer(1, &latest)) << "a sample of the intruder was accepted";
  EXPECT_EQ(stats.rejected_unknown_device + stats.rejected_not_owner + stats.rejected_seq +
                stats.rejected_workspace + stats.rejected_nonfinite + stats.rejected_flood,
            0u);
  EXPECT_EQ(server.MatchedPointerWriters(), 0u);  // the device has left; the intruder never came
}

// The recorder identity is authenticated but may only subscribe: Cyclone refuses it a pointer
// writer, so it cannot publish, and the server accepts nothing.
TEST_F(SecurityTest, AnIdentityWithoutPublishPermissionCannotPublishPointers) {
  const TopicNames topics = UniqueTopics();
  PeerPlan recorder{Secure("recorder"), topics, {"sec"}};
  recorder.publish_s = 1.0;
  Process recorder_process = ForkSecurityPeer(recorder);
  ServerTransportConfig config;
  config.dds = Secure("server");
  config.topics = topics;
  config.devices = {testing::TestDevice("sec")};
  ServerTransport server(config);
  ASSERT_TRUE(recorder_process.Wait(DiscoveryWait() * 2));
  const std::string out = recorder_process.ReadAllOutput();
  EXPECT_EQ(recorder_process.exit_code(), 3) << out;
  EXPECT_NE(out.find("dds_create_writer for " + topics.pointer), std::string::npos) << out;
  EXPECT_NE(out.find("Not Allowed By Security"), std::string::npos) << out;
  EXPECT_EQ(server.Stats().pointer_accepted, 0u);
  EXPECT_EQ(server.MatchedPointerWriters(), 0u);
}

}  // namespace
}  // namespace felt::transport
