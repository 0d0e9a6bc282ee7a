// The haptic thread's side of the server transport is real-time safe: LatestPointer and PushForce
// never allocate (the allocation-counting guard of tests/alloc_counter.h), while samples and
// forces really flow through real Cyclone DDS.

#include <gtest/gtest.h>

#include <thread>

#include "tests/alloc_counter.h"
#include "tests/transport/transport_test_util.h"
#include "transport/client_transport.h"
#include "transport/server_transport.h"

namespace felt::transport {
namespace {

TEST(RealtimeTest, LatestPointerAndPushForceNeverAllocate) {
  ServerTransportConfig config;
  config.dds = testing::TestDds();
  config.topics = testing::UniqueTopics();
  config.devices = {testing::TestDevice("hand")};
  ServerTransport server(config);
  ClientTransportConfig client_config;
  client_config.dds = config.dds;
  client_config.topics = config.topics;
  client_config.device_ids = {"hand"};
  client_config.subscribe_status = false;
  ClientTransport client(client_config);
  ASSERT_TRUE(WaitUntil([&] { return server.MatchedPointerWriters() >= 1; }, testing::kWait));
  ASSERT_TRUE(client.PublishPointer(testing::Sample(1)));
  PointerSampleView sample;
  ASSERT_TRUE(WaitUntil([&] { return server.LatestPointer(0, &sample); }, testing::kWait));

  // A stand-in haptic thread: read the slot and push a force, 2000 times, under the guard, while
  // this thread keeps publishing samples.
  uint64_t allocations = 1;
  int pushed = 0;
  std::thread haptic([&] {
    AllocationGuard guard;
    for (int i = 0; i < 2000; ++i) {
      PointerSampleView newest;
      if (server.LatestPointer(0, &newest)) {
        ForceCommandView force;
        force.answers_seq = newest.seq;
        pushed += server.PushForce(force) ? 1 : 0;
      }
      std::this_thread::yield();
    }
    allocations = guard.allocations();
  });
  for (uint64_t seq = 2; seq < 200; ++seq) client.PublishPointer(testing::Sample(seq));
  haptic.join();
  EXPECT_EQ(allocations, 0u);
  EXPECT_GT(pushed, 0);
  EXPECT_TRUE(WaitUntil(
      [&] {
        const TransportStats s = server.Stats();
        return s.forces_published + s.forces_queue_full == 2000;
      },
      testing::kWait));
}

}  // namespace
}  // namespace felt::transport
