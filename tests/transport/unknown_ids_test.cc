// A peer sending ever new device ids cannot grow the server's memory (issue 23): the pointer
// topic's filter drops a sample of a device the scene does not have before the reader stores it,
// so no such id becomes an instance. The peer is a child process (this test binary, running the
// disabled helper test below), so that this process's resident memory is the server's alone (a
// writer of 100,000 ids grows its own process by tens of MB). Measured (release build, 2-core AMD
// EPYC VM): without the filter the server grew by 58.6 MB for 100,000 ids; with it, by 12-668 kB
// over four runs.

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

#include "base/process.h"
#include "felt_types.h"
#include "tests/test_env.h"
#include "tests/transport/transport_test_util.h"
#include "transport/client_transport.h"
#include "transport/dds_config.h"
#include "transport/qos.h"
#include "transport/server_transport.h"

namespace felt::transport {
namespace {

using namespace ::felt::transport::testing;  // tests/transport/transport_test_util.h

constexpr char kChildFilter[] = "--gtest_filter=TransportChildProcess.DISABLED_PublishUnknownIds";

// The child: publishes FELT_CHILD_IDS distinct ids "intruder-<n>" from FELT_CHILD_FIRST on the
// pointer topic of FELT_CHILD_SUFFIX, one sample each, never unregistering them (the hostile
// case: each id stays registered while the writer lives).
TEST(TransportChildProcess, DISABLED_PublishUnknownIds) {
  const char* suffix = std::getenv("FELT_CHILD_SUFFIX");
  const char* ids = std::getenv("FELT_CHILD_IDS");
  const char* first = std::getenv("FELT_CHILD_FIRST");
  ASSERT_TRUE(suffix != nullptr && ids != nullptr && first != nullptr) << "run by UnknownIds";
  Participant participant(AcquireDomain(TestDds()));
  const TopicNames topics = TopicNames::WithAffixes("", suffix);
  const Entity topic = CreateTopic(participant, &felt_msgs_PointerSample_desc, topics.pointer);
  // The stream's QoS without its deadline: a writer offering a deadline keeps a timer per
  // instance, and 100,000 instances written once each missed theirs over and over, so the
  // child's own writes slowed as they went (2 s alone; 60 s and over 120 s in CI on a busy
  // machine). The server's reader requests no deadline, so the writer need not offer one.
  const Qos qos = StreamQos(std::chrono::nanoseconds::max());
  const Entity writer = CreateWriter(participant, topic, qos.get(), "intruder");
  // Wait for the server's reader before writing (best-effort: unmatched samples are lost).
  ASSERT_TRUE(WaitUntil(
      [&] {
        dds_publication_matched_status_t m{};
        return dds_get_publication_matched_status(writer.get(), &m) >= 0 && m.current_count > 0;
      },
      kWait));
  felt_msgs_PointerSample sample{};
  const long n0 = std::atol(first), n = std::atol(ids);
  for (long k = n0; k < n0 + n; ++k) {
    std::snprintf(sample.device_id, sizeof(sample.device_id), "intruder-%08ld", k);
    sample.seq = 1;
    ASSERT_GE(dds_write(writer.get(), &sample), 0);
  }
}

// Resident memory of this process [kB] (/proc/self/statm's second field, in pages).
int64_t SelfRssKb() {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  if (f == nullptr) return -1;
  long long size = 0, resident = 0;
  const int n = std::fscanf(f, "%lld %lld", &size, &resident);
  std::fclose(f);
  return n == 2 ? resident * (sysconf(_SC_PAGESIZE) / 1024) : -1;
}

// Runs the child for `count` ids from `first` and waits until the server has counted them all.
// GCC 12 warns falsely (-Warray-bounds, in std::string's inlined copy) on the strings built here.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Warray-bounds"
void Flood(ServerTransport& server, const std::string& suffix, long first, long count) {
  SpawnOptions options;
  options.env.push_back("FELT_CHILD_SUFFIX=" + suffix);
  options.env.push_back("FELT_CHILD_IDS=" + std::to_string(count));
  options.env.push_back("FELT_CHILD_FIRST=" + std::to_string(first));
  Process child =
      Process::Spawn({"/proc/self/exe", kChildFilter, "--gtest_also_run_disabled_tests"}, options);
  ASSERT_TRUE(child.Wait(std::chrono::seconds(120)));
  ASSERT_EQ(child.exit_code(), 0);
  // Best-effort, written as fast as the child can: some samples may be lost on the way. Wait
  // until the count settles, then ask that most ids arrived.
  uint64_t seen = server.Stats().rejected_unknown_device;
  for (int quiet = 0; quiet < 5;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const uint64_t now = server.Stats().rejected_unknown_device;
    quiet = now == seen ? quiet + 1 : 0;
    seen = now;
  }
  std::printf("ids %ld-%ld: rejected_unknown_device %llu\n", first, first + count - 1,
              static_cast<unsigned long long>(seen));
  // Under a sanitizer the server takes samples far slower and best-effort drops much of a flood
  // (ThreadSanitizer: 1 of the first 5,000 arrived, all of the next 5,000): there the run checks
  // the filter's threads and memory, not how many arrive.
  if (!felt::testing::Sanitized()) {
    EXPECT_GE(seen, static_cast<uint64_t>(first + count / 2));
  }
}
#pragma GCC diagnostic pop

// Issue 23's target: 100,000 distinct unknown ids grow the server's resident memory by under
// 1 MB, and the scene's device is still heard. Under a sanitizer (shadow memory, quarantine) only
// the counts are checked, over fewer ids.
//
// Two floods of 100,000 new ids each are measured after the warm-up, and the smaller growth is
// held to the target: memory the ids keep (58.6 MB a flood without the filter) would grow the
// process in every flood. One measured flood was not enough: a clean-clone release run of f53ef13
// grew by 1144 kB in it, after a warm-up that had lost 2,725 of its samples where the measured
// flood lost none (my reading, not checked: the receive path's buffers grew in the first burst
// that needed them, which the warm-up had not been).
TEST(UnknownIdsTest, DistinctUnknownIdsDoNotGrowTheServersMemory) {
  const std::string suffix = UniqueSuffix();
  ServerTransportConfig config;
  config.dds = TestDds();
  config.topics = TopicNames::WithAffixes("", suffix);
  config.devices = {TestDevice("hand")};
  ServerTransport server(config);
  const bool sanitized = felt::testing::Sanitized();
  // The warm-up is a flood like the measured one (other ids), so that Cyclone's receive buffers
  // have grown to what such a burst needs (one run grew 3.4 MB in a 100,000-id burst after a
  // 5,000-id warm-up) and what is measured is what the ids themselves keep.
  const long count = sanitized ? 5000 : 100000, warm_up = count;
  Flood(server, suffix, 0, warm_up);
  int64_t least_kb = INT64_MAX;
  for (int k = 0; k < (sanitized ? 1 : 2); ++k) {
    const int64_t before_kb = SelfRssKb();
    Flood(server, suffix, warm_up + k * count, count);
    const int64_t after_kb = SelfRssKb();
    std::printf(
        "%ld distinct unknown ids: the server's process resident %lld -> %lld kB (%+lld kB)\n",
        count, static_cast<long long>(before_kb), static_cast<long long>(after_kb),
        static_cast<long long>(after_kb - before_kb));
    least_kb = std::min(least_kb, after_kb - before_kb);
  }
  if (!sanitized) {
    EXPECT_LT(least_kb, 1024) << "kB, the smaller growth of the two measured floods";
  }
  EXPECT_EQ(server.Stats().pointer_accepted, 0u);
  // The scene's own device is heard.
  ClientTransportConfig client_config;
  client_config.dds = TestDds();
  client_config.topics = config.topics;
  client_config.device_ids = {"hand"};
  client_config.subscribe_status = false;
  ClientTransport client(client_config);
  ASSERT_TRUE(WaitUntil([&] { return server.MatchedPointerWriters() >= 1; }, kWait));
  PointerSampleView view;
  ASSERT_TRUE(WaitUntil(
      [&] {
        client.PublishPointer(Sample(1));
        return server.LatestPointer(0, &view);
      },
      kWait));
  EXPECT_EQ(view.seq, 1u);
}

}  // namespace
}  // namespace felt::transport
