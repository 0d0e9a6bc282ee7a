// The QoS of transport/qos.h, observed on the real Cyclone DDS: keep-last 1 hands a slow reader
// only the newest sample (and keep-all, the control, hands it every one); the stream deadline is
// detected; a volatile stream gives a late joiner nothing old; the transient-local status gives a
// late subscriber the latest status.

#include "transport/qos.h"

#include <gtest/gtest.h>

#include <array>
#include <vector>

#include "felt_types.h"
#include "tests/transport/transport_test_util.h"
#include "transport/client_transport.h"
#include "transport/dds_config.h"
#include "transport/server_transport.h"

namespace felt::transport {
namespace {

using namespace ::felt::transport::testing;  // tests/transport/transport_test_util.h

// A participant with a pointer topic of its own.
struct PointerTopic {
  Participant participant{AcquireDomain(TestDds())};
  Entity topic = CreateTopic(participant, &felt_msgs_PointerSample_desc, UniqueTopics().pointer);

  // A reader of the topic with `qos`, named `what` in errors.
  Entity Reader(const Qos& qos, const char* what = "reader") const {
    return CreateReader(participant, topic, qos.get(), nullptr, what);
  }
  // A writer of the topic with `qos`.
  Entity Writer(const Qos& qos) const {
    return CreateWriter(participant, topic, qos.get(), "writer");
  }
  // A reader made first, then a writer, both with `qos`.
  struct Pair {
    Entity reader;
    Entity writer;
  };
  Pair ReaderThenWriter(const Qos& qos) const { return Pair{Reader(qos), Writer(qos)}; }
};

// Reads (without taking) and returns the seq of every sample the reader holds.
std::vector<uint64_t> Peek(const Entity& reader) {
  std::array<felt_msgs_PointerSample, 32> buffer{};
  std::array<void*, 32> ptrs{};
  std::array<dds_sample_info_t, 32> infos{};
  for (size_t i = 0; i < buffer.size(); ++i) ptrs[i] = &buffer[i];
  const dds_return_t n = dds_read(reader.get(), ptrs.data(), infos.data(), 32, 32);
  EXPECT_GE(n, 0) << dds_strretcode(n);
  std::vector<uint64_t> seqs;
  for (dds_return_t i = 0; i < n; ++i) {
    if (infos[i].valid_data) seqs.push_back(buffer[i].seq);
  }
  return seqs;
}

// Peeks at `reader` until done(seqs) holds or kWait passes: true if it held, the last peek in
// *seqs.
template <class Done>
bool PeekUntil(const Entity& reader, Done done, std::vector<uint64_t>* seqs) {
  return WaitUntil(
      [&] {
        *seqs = Peek(reader);
        return done(*seqs);
      },
      kWait);
}

// Waits until `done(status)` holds for the DDS status that `get` reads from `entity` (each read
// checked), or kWait passes: true if it held.
template <class Status, class Done>
bool WaitForStatus(const Entity& entity, dds_return_t (*get)(dds_entity_t, Status*), Done done) {
  return WaitUntil(
      [&] {
        Status status{};
        EXPECT_GE(get(entity.get(), &status), 0);
        return done(status);
      },
      kWait);
}

// Writes samples 1..count of device "d" as fast as possible, before the reader looks.
void WriteBurst(const Entity& writer, uint64_t count) {
  felt_msgs_PointerSample sample{};
  sample.device_id[0] = 'd';
  for (uint64_t seq = 1; seq <= count; ++seq) {
    sample.seq = seq;
    ASSERT_GE(dds_write(writer.get(), &sample), 0);
  }
}

TEST(QosTest, KeepLastOneGivesASlowReaderOnlyTheNewestSample) {
  PointerTopic t;
  const auto [reader, writer] = t.ReaderThenWriter(StreamQos());
  WriteBurst(writer, 10);
  // The reader never took anything while the burst went by: it holds the newest only.
  std::vector<uint64_t> seqs;
  ASSERT_TRUE(PeekUntil(
      reader, [](const std::vector<uint64_t>& s) { return !s.empty() && s.back() == 10; }, &seqs));
  EXPECT_EQ(seqs, std::vector<uint64_t>{10});
}

TEST(QosTest, KeepAllControlHandsTheSameSlowReaderEverySample) {
  // The control for the test above: with keep-all (and reliable, so nothing is dropped) the same
  // burst leaves all ten samples, so the keep-last test can fail.
  PointerTopic t;
  Qos qos = StreamQos();
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_ALL, 0);
  dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  const auto [reader, writer] = t.ReaderThenWriter(qos);
  WriteBurst(writer, 10);
  std::vector<uint64_t> seqs;
  ASSERT_TRUE(PeekUntil(
      reader, [](const std::vector<uint64_t>& s) { return s.size() == 10; }, &seqs));
  EXPECT_EQ(seqs.front(), 1u);
  EXPECT_EQ(seqs.back(), 10u);
}

TEST(QosTest, TheStreamDeadlineIsDetectedWhenAWriterGoesSilent) {
  PointerTopic t;
  const auto [reader, writer] = t.ReaderThenWriter(StreamQos());
  WriteBurst(writer, 1);
  // One sample, then silence: more than kStreamDeadline later the reader reports a miss.
  ASSERT_TRUE(WaitForStatus(reader, dds_get_requested_deadline_missed_status,
                            [](const auto& status) { return status.total_count >= 1; }));
}

TEST(QosTest, AVolatileStreamGivesALateReaderNothingOld) {
  PointerTopic t;
  const Qos qos = StreamQos();
  const Entity writer = t.Writer(qos);
  const Entity early = t.Reader(qos, "early reader");
  WriteBurst(writer, 3);
  ASSERT_TRUE(WaitUntil([&] { return !Peek(early).empty(); }, kWait));
  // A reader created after the samples were written must not act on an old position.
  const Entity late = t.Reader(qos, "late reader");
  ASSERT_TRUE(WaitForStatus(late, dds_get_subscription_matched_status,
                            [](const auto& status) { return status.current_count >= 1; }));
  EXPECT_TRUE(Peek(late).empty());
}

TEST(QosTest, ALateStatusSubscriberSeesTheLatestStatus) {
  // A server publishes two statuses before any subscriber exists.
  ServerTransportConfig config;
  config.dds = TestDds();
  config.topics = UniqueTopics();
  config.devices = {TestDevice("left")};
  ServerTransport server(config);
  ServerStatusView status;
  status.server_id = "felt-test";
  status.haptic_ticks = 1000;
  status.haptic_lateness_us = {40, 90, 300, 900};
  status.realtime = true;
  ASSERT_TRUE(server.PublishStatus(status));
  status.haptic_ticks = 2000;
  status.nan_events = 3;
  status.rejected_flood = 99;  // replaced by the transport's own count (0)
  ASSERT_TRUE(server.PublishStatus(status));
  // A subscriber that starts afterwards receives the second one.
  ClientTransportConfig client_config;
  client_config.dds = TestDds();
  client_config.topics = config.topics;
  client_config.device_ids = {"left"};
  ClientTransport client(client_config);
  ServerStatusView seen;
  ASSERT_TRUE(WaitUntil([&] { return client.LatestStatus(&seen); }, kWait));
  EXPECT_EQ(seen.server_id, "felt-test");
  EXPECT_EQ(seen.haptic_ticks, 2000u);
  EXPECT_EQ(seen.nan_events, 3u);
  EXPECT_TRUE(seen.realtime);
  EXPECT_DOUBLE_EQ(seen.haptic_lateness_us.p999, 300.0);
  EXPECT_EQ(seen.rejected_flood, 0u);
  EXPECT_GT(seen.wall_time_ns, 0);
  EXPECT_EQ(server.Stats().statuses_published, 2u);
}

}  // namespace
}  // namespace felt::transport
