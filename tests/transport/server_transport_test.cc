// ServerTransport against the real Cyclone DDS (in-process client, same domain): samples reach the
// slots, forces reach the client, every kind of bad input is rejected and counted and never
// reaches a slot. Each test uses its own topic names.

#include "transport/server_transport.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>

#include "felt_types.h"
#include "tests/transport/transport_test_util.h"
#include "transport/client_transport.h"
#include "transport/dds_config.h"
#include "transport/qos.h"

namespace felt::transport {
namespace {

using namespace ::felt::transport::testing;  // tests/transport/transport_test_util.h

// A server with devices "left" and "right", and a client publishing for "left" (index 0).
class ServerTransportTest : public ::testing::TestWithParam<ReceiveMode> {
 protected:
  void Start(double max_rate_hz = 2000.0, double burst = 50.0, size_t queue = 256,
             int64_t ownership_timeout_ns = 50'000'000) {
    ServerTransportConfig config;
    config.dds = TestDds();
    config.topics = topics_;
    config.devices = {TestDevice("left"), TestDevice("right")};
    for (DeviceLimits& d : config.devices) {
      d.max_rate_hz = max_rate_hz;
      d.burst_samples = burst;
    }
    config.force_queue_capacity = queue;
    config.receive_mode = GetParam();
    config.ownership_timeout_ns = ownership_timeout_ns;
    server_ = std::make_unique<ServerTransport>(config);
    ClientTransportConfig client_config;
    client_config.dds = TestDds();
    client_config.topics = topics_;
    client_config.device_ids = {"left"};
    client_ = std::make_unique<ClientTransport>(client_config);
    ASSERT_TRUE(WaitUntil(
        [&] {
          return server_->MatchedPointerWriters() >= 1 && client_->MatchedForceWriters() >= 1;
        },
        kWait));
  }

  // Publishes `sample` and waits until the server has counted it, accepted or rejected.
  void PublishAndWait(const PointerSampleView& sample) {
    const uint64_t before = Handled();
    ASSERT_TRUE(client_->PublishPointer(sample));
    ASSERT_TRUE(WaitUntil([&] { return Handled() > before; }, kWait));
  }

  // After one good sample (seq 1) and three bad ones: `rejected` counted all three, one was
  // accepted, and the slot still holds seq 1 (no rejected sample reaches it).
  void ExpectOnlyTheFirstAccepted(uint64_t TransportStats::*rejected) const {
    const TransportStats s = server_->Stats();
    EXPECT_EQ(s.*rejected, 3u);
    EXPECT_EQ(s.pointer_accepted, 1u);
    PointerSampleView view;
    ASSERT_TRUE(server_->LatestPointer(0, &view));
    EXPECT_EQ(view.seq, 1u) << "no rejected sample reaches the slot";
  }

  uint64_t Handled() const {
    const TransportStats s = server_->Stats();
    return s.pointer_accepted + s.rejected_nonfinite + s.rejected_workspace + s.rejected_seq +
           s.rejected_unknown_device + s.rejected_flood;
  }

  TopicNames topics_ = UniqueTopics();
  std::unique_ptr<ServerTransport> server_;
  std::unique_ptr<ClientTransport> client_;
};

TEST_P(ServerTransportTest, SamplesReachTheDeviceSlot) {
  Start();
  PointerSampleView view;
  EXPECT_FALSE(server_->LatestPointer(0, &view)) << "nothing received yet";
  // Publish a few samples; the slot ends on the last one, intact.
  for (uint64_t seq = 1; seq <= 5; ++seq) {
    PublishAndWait(Sample(seq, 0.01 * static_cast<double>(seq)));
  }
  ASSERT_TRUE(server_->LatestPointer(0, &view));
  EXPECT_EQ(view.device_index, 0u);
  EXPECT_EQ(view.seq, 5u);
  EXPECT_EQ(view.device_time_ns, 5000000);
  EXPECT_DOUBLE_EQ(view.position_m_D[0], 0.05);
  EXPECT_DOUBLE_EQ(view.velocity_m_per_s_D[1], 0.01);
  EXPECT_EQ(view.buttons, 1u);
  EXPECT_GT(view.receive_time_ns, 0);
  // The other device and an index out of range have nothing.
  EXPECT_FALSE(server_->LatestPointer(1, &view));
  EXPECT_FALSE(server_->LatestPointer(2, &view));
  EXPECT_EQ(server_->Stats().pointer_accepted, 5u);
  EXPECT_GE(server_->Stats().receive_hop.count, 1u);
}

TEST_P(ServerTransportTest, ForcesReachTheClientReader) {
  Start();
  ForceCommandView force;
  force.device_index = 0;
  force.answers_seq = 77;
  force.answers_device_time_ns = 123456;
  force.force_N_D = {1.5, -2.0, 0.25};
  force.proxy_position_m_D = {0.1, 0.2, 0.3};
  force.in_contact = true;
  force.flags = kForceClamped | kForceRamping;
  force.contact_point_m_D = {0.1, 0.2, 0.29};
  force.contact_normal_D = {0.0, 0.6, 0.8};
  force.contact_stiffness_N_per_m = 400.0;
  ASSERT_TRUE(server_->PushForce(force));
  ForceCommandView received;
  ASSERT_TRUE(client_->WaitForce(0, kWait, &received));
  EXPECT_EQ(received.seq, 1u) << "the server numbers each device's forces from 1";
  EXPECT_EQ(received.answers_seq, 77u);
  EXPECT_EQ(received.answers_device_time_ns, 123456);
  EXPECT_DOUBLE_EQ(received.force_N_D[0], 1.5);
  EXPECT_DOUBLE_EQ(received.force_N_D[1], -2.0);
  EXPECT_DOUBLE_EQ(received.force_N_D[2], 0.25);
  EXPECT_DOUBLE_EQ(received.proxy_position_m_D[2], 0.3);
  EXPECT_TRUE(received.in_contact);
  EXPECT_EQ(received.flags, kForceClamped | kForceRamping);
  EXPECT_EQ(received.contact_point_m_D, force.contact_point_m_D);
  EXPECT_EQ(received.contact_normal_D, force.contact_normal_D);
  EXPECT_EQ(received.contact_stiffness_N_per_m, 400.0);
  // A force for the other device is not this client's; a bad index is refused and counted.
  force.device_index = 1;
  ASSERT_TRUE(server_->PushForce(force));
  force.device_index = 0;
  force.answers_seq = 78;
  ASSERT_TRUE(server_->PushForce(force));
  ASSERT_TRUE(client_->WaitForce(0, kWait, &received));
  EXPECT_EQ(received.answers_seq, 78u);
  EXPECT_EQ(received.seq, 2u);
  force.device_index = 7;
  EXPECT_FALSE(server_->PushForce(force));
  EXPECT_EQ(server_->Stats().forces_bad_device, 1u);
  EXPECT_TRUE(WaitUntil([&] { return server_->Stats().forces_published == 3; }, kWait));
  EXPECT_GE(server_->Stats().write_hop.count, 3u);
}

TEST_P(ServerTransportTest, AFullForceQueueIsCountedAndNothingIsLostSilently) {
  Start(2000.0, 50.0, /*queue=*/1);
  constexpr int kPushes = 20000;
  int accepted = 0;
  ForceCommandView force;
  for (int i = 0; i < kPushes; ++i) accepted += server_->PushForce(force) ? 1 : 0;
  const TransportStats s = server_->Stats();
  EXPECT_EQ(s.forces_pushed, static_cast<uint64_t>(accepted));
  EXPECT_EQ(s.forces_pushed + s.forces_queue_full, static_cast<uint64_t>(kPushes));
  EXPECT_GT(s.forces_queue_full, 0u) << "a one-slot queue cannot keep up with a tight loop";
  // Everything queued is published.
  EXPECT_TRUE(WaitUntil(
      [&] { return server_->Stats().forces_published == static_cast<uint64_t>(accepted); }, kWait));
}

TEST_P(ServerTransportTest, NonFiniteSamplesAreRejected) {
  Start();
  PublishAndWait(Sample(1, 0.2));
  PointerSampleView bad = Sample(2);
  bad.position_m_D[1] = std::numeric_limits<double>::quiet_NaN();
  PublishAndWait(bad);
  bad = Sample(3);
  bad.velocity_m_per_s_D[2] = std::numeric_limits<double>::infinity();
  PublishAndWait(bad);
  bad = Sample(4);
  bad.position_m_D[0] = -std::numeric_limits<double>::infinity();
  PublishAndWait(bad);
  ExpectOnlyTheFirstAccepted(&TransportStats::rejected_nonfinite);
  PointerSampleView view;
  ASSERT_TRUE(server_->LatestPointer(0, &view));
  EXPECT_DOUBLE_EQ(view.position_m_D[0], 0.2);
}

TEST_P(ServerTransportTest, OutOfWorkspaceSamplesAreRejected) {
  Start();
  PublishAndWait(Sample(1, 0.5));  // on the boundary: inside
  PublishAndWait(Sample(2, 0.5000001));
  PointerSampleView bad = Sample(3);
  bad.position_m_D[2] = -0.7;
  PublishAndWait(bad);
  bad = Sample(4);
  bad.position_m_D = {1e9, 1e9, 1e9};
  PublishAndWait(bad);
  ExpectOnlyTheFirstAccepted(&TransportStats::rejected_workspace);
}

TEST_P(ServerTransportTest, SequenceNumbersGoingBackwardsOrRepeatedAreRejected) {
  Start();
  PublishAndWait(Sample(10, 0.1));
  PublishAndWait(Sample(5, 0.2));    // backwards
  PublishAndWait(Sample(10, 0.3));   // repeated
  PublishAndWait(Sample(0, 0.4));    // back to zero from the same writer
  PublishAndWait(Sample(12, 0.25));  // forward (a gap is fine)
  const TransportStats s = server_->Stats();
  EXPECT_EQ(s.rejected_seq, 3u);
  EXPECT_EQ(s.pointer_accepted, 2u);
  PointerSampleView view;
  ASSERT_TRUE(server_->LatestPointer(0, &view));
  EXPECT_EQ(view.seq, 12u);
  EXPECT_DOUBLE_EQ(view.position_m_D[0], 0.25);
}

TEST_P(ServerTransportTest, UnknownDevicesAreRejected) {
  Start();
  ClientTransportConfig config;
  config.dds = TestDds();
  config.topics = topics_;
  config.device_ids = {"intruder", "right"};
  config.subscribe_status = false;
  ClientTransport intruder(config);
  ASSERT_TRUE(WaitUntil([&] { return server_->MatchedPointerWriters() >= 2; }, kWait));
  const uint64_t before = Handled();
  PointerSampleView sample = Sample(1);
  sample.device_index = 0;  // "intruder"
  ASSERT_TRUE(intruder.PublishPointer(sample));
  ASSERT_TRUE(WaitUntil([&] { return Handled() > before; }, kWait));
  EXPECT_EQ(server_->Stats().rejected_unknown_device, 1u);
  EXPECT_EQ(server_->Stats().pointer_accepted, 0u);
  PointerSampleView view;
  EXPECT_FALSE(server_->LatestPointer(0, &view));
  EXPECT_FALSE(server_->LatestPointer(1, &view));
  // The same client's allowed device goes through to its own slot.
  sample.device_index = 1;  // "right"
  ASSERT_TRUE(intruder.PublishPointer(sample));
  ASSERT_TRUE(WaitUntil([&] { return server_->LatestPointer(1, &view); }, kWait));
  EXPECT_FALSE(server_->LatestPointer(0, &view));
}

TEST_P(ServerTransportTest, AFloodingPublisherIsRateLimited) {
  // 100 Hz sustained with a burst of 10. The client publishes each sample as soon as the server has
  // handled the previous one (far above 100 Hz; pacing it this way makes the server see every
  // sample in both receive modes, where keep-last 1 would otherwise merge a burst). At most 10 + 1
  // per elapsed 10 ms get through; the rest are counted as flood and never reach the slot.
  constexpr double kRate_hz = 100.0;
  constexpr double kBurst = 10.0;
  Start(kRate_hz, kBurst);
  constexpr uint64_t kSamples = 100;
  const int64_t start_ns = MonotonicNowNs();
  for (uint64_t seq = 1; seq <= kSamples; ++seq) PublishAndWait(Sample(seq));
  const TransportStats s = server_->Stats();
  const int64_t elapsed_ns = MonotonicNowNs() - start_ns;
  const double allowed = kBurst + kRate_hz * static_cast<double>(elapsed_ns) * 1e-9 + 1.0;
  EXPECT_LE(static_cast<double>(s.pointer_accepted), allowed);
  EXPECT_GE(s.pointer_accepted, static_cast<uint64_t>(kBurst));
  EXPECT_EQ(s.pointer_accepted + s.rejected_flood, kSamples);
  EXPECT_GT(s.rejected_flood, 0u);
  // The slot holds the newest accepted sample.
  PointerSampleView view;
  ASSERT_TRUE(server_->LatestPointer(0, &view));
  const uint64_t last_accepted_seq = view.seq;
  // A well-behaved rate afterwards is accepted again once the bucket refills (a token per 10 ms).
  ASSERT_TRUE(
      WaitUntil([&] { return MonotonicNowNs() - start_ns > elapsed_ns + 30000000; }, kWait));
  PublishAndWait(Sample(kSamples + 1, 0.3));
  ASSERT_TRUE(server_->LatestPointer(0, &view));
  EXPECT_EQ(view.seq, kSamples + 1);
  EXPECT_GT(view.seq, last_accepted_seq);
}

INSTANTIATE_TEST_SUITE_P(ReceiveModes, ServerTransportTest,
                         ::testing::Values(ReceiveMode::kListener, ReceiveMode::kWaitset),
                         [](const ::testing::TestParamInfo<ReceiveMode>& param_info) {
                           return param_info.param == ReceiveMode::kListener
                                      ? std::string("Listener")
                                      : std::string("Waitset");
                         });

// Bad configurations are refused with a message naming the field.
// A second driver for device "left" (index 0 of its own list).
std::unique_ptr<ClientTransport> SecondDriver(const TopicNames& topics) {
  ClientTransportConfig config;
  config.dds = TestDds();
  config.topics = topics;
  config.device_ids = {"left"};
  config.subscribe_status = false;
  return std::make_unique<ClientTransport>(config);
}

// One writer owns a device: a second writer's samples are refused and counted while the owner is
// heard, and it takes over once the owner has been silent for the ownership timeout.
TEST_P(ServerTransportTest, ASecondWriterIsRefusedUntilTheOwnerFallsSilent) {
  // A 1 s timeout: the interleave below must never leave the owner silent that long, or the
  // second takes the device over where the test expects a refusal. With 200 ms this test failed
  // once in six TSan runs of the suite on two loaded cores, after 10.3 s (the 10 s wait for a
  // refusal; the output was not kept, so that the owner fell silent is my reading).
  Start(2000.0, 50.0, 256, 1'000'000'000);
  PublishAndWait(Sample(1));              // the fixture's client owns "left"
  const auto second = SecondDriver(topics_);
  ASSERT_TRUE(WaitUntil([&] { return server_->MatchedPointerWriters() >= 2; }, kWait));
  // Interleaved, as two live drivers would: every one of the second's samples is refused.
  for (uint64_t k = 0; k < 20; ++k) {
    PublishAndWait(Sample(100 + k, 0.2));
    ASSERT_TRUE(second->PublishPointer(Sample(1000 + k, 0.3)));
    ASSERT_TRUE(WaitUntil([&] { return server_->Stats().rejected_not_owner >= k + 1; }, kWait));
  }
  PointerSampleView view;
  ASSERT_TRUE(server_->LatestPointer(0, &view));
  EXPECT_EQ(view.seq, 119u) << "only the owner's samples reach the slot";
  EXPECT_EQ(server_->Stats().rejected_not_owner, 20u);
  EXPECT_EQ(server_->Stats().ownership_changes, 0u);
  // The owner falls silent for longer than the timeout: the second's next sample takes over.
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  ASSERT_TRUE(second->PublishPointer(Sample(2000, 0.3)));
  ASSERT_TRUE(
      WaitUntil([&] { return server_->LatestPointer(0, &view) && view.seq == 2000u; }, kWait));
  EXPECT_EQ(server_->Stats().ownership_changes, 1u);
  // And the first, back, is now the one refused.
  const uint64_t refused = server_->Stats().rejected_not_owner;
  ASSERT_TRUE(client_->PublishPointer(Sample(3000, 0.2)));
  ASSERT_TRUE(WaitUntil([&] { return server_->Stats().rejected_not_owner == refused + 1; }, kWait));
}

// An owner that leaves (its writer deleted: the instance is unregistered) hands the device over
// at once, without waiting for the timeout (10 s here).
TEST_P(ServerTransportTest, AnOwnerThatLeavesHandsTheDeviceOverAtOnce) {
  Start(2000.0, 50.0, 256, 10'000'000'000);
  PublishAndWait(Sample(1));
  const auto second = SecondDriver(topics_);
  ASSERT_TRUE(WaitUntil([&] { return server_->MatchedPointerWriters() >= 2; }, kWait));
  ASSERT_TRUE(second->PublishPointer(Sample(10, 0.3)));
  ASSERT_TRUE(WaitUntil([&] { return server_->Stats().rejected_not_owner >= 1; }, kWait));
  client_.reset();  // the owner exits
  ASSERT_TRUE(WaitUntil([&] { return server_->MatchedPointerWriters() == 1; }, kWait));
  PointerSampleView view;
  const auto start = std::chrono::steady_clock::now();
  ASSERT_TRUE(WaitUntil(
      [&] {
        second->PublishPointer(Sample(11, 0.3));
        return server_->LatestPointer(0, &view) && view.seq == 11u;
      },
      kWait));
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
  EXPECT_EQ(server_->Stats().ownership_changes, 0u) << "released, not taken over";
}

// A writer with a QoS of its own on the server's pointer topic (`adjust` edits the stream QoS).
Entity ForeignPointerWriter(const Participant& participant, const TopicNames& topics,
                            const std::function<void(dds_qos_t*)>& adjust, Entity* topic) {
  *topic = CreateTopic(participant, &felt_msgs_PointerSample_desc, topics.pointer);
  const Qos qos = StreamQos();
  adjust(qos.get());
  return CreateWriter(participant, *topic, qos.get(), "foreign writer");
}

// A driver that offers no deadline (a ROS 2 publisher's default) matches and is heard: the
// server's reader requests none (transport/qos.h).
TEST_P(ServerTransportTest, AWriterOfferingNoDeadlineIsHeard) {
  Start();
  Participant participant(AcquireDomain(TestDds()));
  Entity topic;
  const Entity writer = ForeignPointerWriter(
      participant, topics_, [](dds_qos_t* q) { dds_qset_deadline(q, DDS_INFINITY); }, &topic);
  ASSERT_TRUE(WaitUntil([&] { return server_->MatchedPointerWriters() >= 2; }, kWait));
  felt_msgs_PointerSample sample{};
  std::snprintf(sample.device_id, sizeof(sample.device_id), "left");
  sample.seq = 1;
  sample.position_m[0] = 0.1;
  ASSERT_GE(dds_write(writer.get(), &sample), 0);
  PointerSampleView view;
  ASSERT_TRUE(WaitUntil([&] { return server_->LatestPointer(0, &view); }, kWait));
  EXPECT_EQ(view.seq, 1u);
  EXPECT_EQ(server_->Stats().incompatible_qos, 0u);
}

// Peers whose QoS cannot match are counted (and logged once with the policy's name): a writer
// asking for exclusive ownership of the pointer topic, a force reader asking for a deadline
// shorter than the 10 ms Felt's writer offers.
TEST_P(ServerTransportTest, IncompatibleQosPeersAreCounted) {
  Start();
  Participant participant(AcquireDomain(TestDds()));
  Entity pointer_topic;
  const Entity writer = ForeignPointerWriter(
      participant, topics_, [](dds_qos_t* q) { dds_qset_ownership(q, DDS_OWNERSHIP_EXCLUSIVE); },
      &pointer_topic);
  ASSERT_TRUE(WaitUntil([&] { return server_->Stats().incompatible_qos >= 1; }, kWait));
  const Entity force_topic = CreateTopic(participant, &felt_msgs_ForceCommand_desc, topics_.force);
  const Qos qos = StreamQos(std::chrono::milliseconds(5));
  const Entity reader = CreateReader(participant, force_topic, qos.get(), nullptr, "reader");
  ASSERT_TRUE(WaitUntil([&] { return server_->Stats().incompatible_qos >= 2; }, kWait));
  EXPECT_EQ(server_->MatchedPointerWriters(), 1u);  // the client's only
}

TEST(ServerTransportConfigTest, InvalidConfigurationsNameTheField) {
  const auto message_of = [](ServerTransportConfig config) -> std::string {
    config.dds = TestDds();
    config.topics = UniqueTopics();
    try {
      ServerTransport server(config);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "no error";
  };
  ServerTransportConfig config;
  EXPECT_NE(message_of(config).find("devices: at least one"), std::string::npos);
  config.devices = {TestDevice("a"), TestDevice("a")};
  EXPECT_NE(message_of(config).find("devices[1].device_id \"a\": listed twice"), std::string::npos);
  config.devices = {TestDevice("")};
  EXPECT_NE(message_of(config).find("devices[0].device_id"), std::string::npos);
  config.devices = {TestDevice(std::string(65, 'x'))};
  EXPECT_NE(message_of(config).find("1 to 64 characters"), std::string::npos);
  config.devices = {TestDevice("a")};
  config.devices[0].workspace_min_m_D[1] = 0.6;
  EXPECT_NE(message_of(config).find("axis 1 must be finite with min < max"), std::string::npos);
  config.devices = {TestDevice("a")};
  config.devices[0].max_rate_hz = 0;
  EXPECT_NE(message_of(config).find("devices[0].max_rate_hz"), std::string::npos);
  config.devices = {TestDevice("a")};
  config.force_queue_capacity = 0;
  EXPECT_NE(message_of(config).find("force_queue_capacity"), std::string::npos);
}

}  // namespace
}  // namespace felt::transport
