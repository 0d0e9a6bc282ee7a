// The MCAP recorder (transport/mcap_recorder.h): over the real Cyclone DDS on loopback, a replay
// answered by a real ServerTransport is recorded into ROS 2 MCAP and read back sample for sample;
// the writer queue keeps up with 1 kHz pointer + 1 kHz force + 1 Hz status with zero drops and
// the file replays with every sample in order; @mcap/core reads what the recorder wrote
// (tools/npm/check_mcap.mjs; skipped with the reason when it is not installed).
#include "transport/mcap_recorder.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "recordings/mcap.h"
#include "recordings/mcap_trace.h"
#include "ros2/messages.h"
#include "tests/npm_check.h"
#include "tests/test_env.h"
#include "tests/transport/transport_test_util.h"
#include "transport/replayer.h"
#include "transport/server_transport.h"

namespace felt::transport {
namespace {

using namespace ::felt::transport::testing;  // tests/transport/transport_test_util.h

constexpr double kMcapGain_N_per_m = -100.0;  // the responder's force: gain * position

std::string McapTempPath(const std::string& name) {
  return (std::filesystem::path(::testing::TempDir()) / name).string();
}

// A 1 kHz trace of `n` samples inside the test workspace, velocities from its derivative.
Trace McapTestTrace(int n) {
  Trace trace;
  trace.header = MakeTraceHeader(1000.0, "test-device", "mcap_recorder_test");
  for (int k = 0; k < n; ++k) {
    TraceSample s;
    s.t_s = k / 1000.0;
    s.p_D = Vec3(0.05 * std::sin(3.0 * s.t_s), 0.01 * k / n - 0.02, 0.03 * std::cos(5.0 * s.t_s));
    s.v_D = Vec3(0.15 * std::cos(3.0 * s.t_s), 0.01 / n * 1000.0, -0.15 * std::sin(5.0 * s.t_s));
    trace.samples.push_back(s);
  }
  return trace;
}

// A real server transport whose thread answers every new pointer sample with the force
// kMcapGain_N_per_m * position, and publishes a status every 100 ms.
class McapTestResponder {
 public:
  McapTestResponder(const TopicNames& topics, const std::string& device_id) {
    ServerTransportConfig config;
    config.dds = TestDds();
    config.topics = topics;
    config.devices = {TestDevice(device_id)};
    server_ = std::make_unique<ServerTransport>(std::move(config));
    thread_ = std::thread([this] { Loop(); });
  }
  ~McapTestResponder() {
    stop_.store(true);
    thread_.join();
  }
  ServerTransport& server() { return *server_; }

 private:
  void Loop() {
    uint64_t last_seq = 0;
    auto next_status = std::chrono::steady_clock::now();
    while (!stop_.load()) {
      PointerSampleView p;
      if (server_->LatestPointer(0, &p) && p.seq != last_seq) {
        last_seq = p.seq;
        ForceCommandView f;
        f.answers_seq = p.seq;
        f.answers_device_time_ns = p.device_time_ns;
        for (int k = 0; k < 3; ++k) f.force_N_D[k] = kMcapGain_N_per_m * p.position_m_D[k];
        server_->PushForce(f);
      }
      if (std::chrono::steady_clock::now() >= next_status) {
        ServerStatusView status;
        status.server_id = "mcap-test";
        status.haptic_ticks = last_seq;
        server_->PublishStatus(status);
        next_status += std::chrono::milliseconds(100);
      }
      std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
  }

  std::unique_ptr<ServerTransport> server_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

TEST(McapRecorder, RecordingAReplayGivesTheSamplesForcesAndStatusAsRos2Messages) {
  const TopicNames topics = UniqueTopics();
  const Trace trace = McapTestTrace(400);
  const std::string out = McapTempPath("mcap_recorder_replay.mcap");

  McapTestResponder responder(topics, "hand");
  McapRecorderConfig rc;
  rc.dds = TestDds();
  rc.topics = topics;
  rc.out_path = out;
  McapRecorder recorder(rc);
  ReplayConfig config;
  config.dds = TestDds();
  config.topics = topics;
  config.device_id = "hand";
  config.discovery_timeout = kWait;
  config.status_timeout = std::chrono::nanoseconds(0);
  Replayer replayer(trace, config);
  ASSERT_TRUE(replayer.WaitForServer());
  ASSERT_TRUE(WaitUntil(
      [&] {
        return recorder.MatchedPointerWriters() > 0 &&
               responder.server().MatchedPointerWriters() > 0;
      },
      kWait));

  std::thread replay([&] { (void)replayer.Run(); });
  const auto deadline = std::chrono::steady_clock::now() + kWait;
  while (recorder.Stats().pointers_received < 400 && std::chrono::steady_clock::now() < deadline) {
    recorder.Poll(std::chrono::milliseconds(20));
  }
  replay.join();
  // The last forces, and a status after the first sample.
  for (int i = 0; i < 15; ++i) recorder.Poll(std::chrono::milliseconds(20));
  recorder.Close();
  const McapRecorderStats stats = recorder.Stats();
  EXPECT_EQ(stats.device_id, "hand");
  EXPECT_EQ(stats.pointers_received, 400u);
  EXPECT_EQ(stats.sink.pointers_written, 400u);
  EXPECT_EQ(stats.sink.queue_drops, 0u);
  EXPECT_GT(stats.sink.forces_written, 0u);
  EXPECT_GT(stats.sink.statuses_written, 0u);

  // Read back as a trace: the same times, positions and velocities, bit for bit.
  McapTraceInfo info;
  const Trace recorded = ReadMcapTrace(out, {}, &info);
  EXPECT_EQ(info.topic, "/hand/measured_cp");
  EXPECT_EQ(info.velocity_topic, "/hand/measured_cv");
  EXPECT_EQ(info.frame_id, "hand/device");
  ASSERT_EQ(recorded.samples.size(), trace.samples.size());
  for (size_t i = 0; i < trace.samples.size(); ++i) {
    ASSERT_EQ(recorded.samples[i].t_s, trace.samples[i].t_s) << i;
    ASSERT_EQ(recorded.samples[i].p_D, trace.samples[i].p_D) << i;
    ASSERT_EQ(recorded.samples[i].v_D, trace.samples[i].v_D) << i;
  }

  // The forces: each WrenchStamped's stamp is the stamp of the pose it answers, its force the
  // responder's gain times that pose's position. The status: a DiagnosticArray.
  McapReader reader(out);
  std::map<std::string, uint16_t> ids;
  for (const auto& [id, c] : reader.channels()) ids[c.topic] = id;
  ASSERT_TRUE(ids.count("/hand/servo_cf"));
  ASSERT_TRUE(ids.count("/diagnostics"));
  uint64_t forces = 0, statuses = 0;
  reader.ReadMessages(
      [&](const McapMessage& m) {
        if (m.channel_id == ids["/hand/servo_cf"]) {
          const ros2::WrenchStamped w = ros2::ParseWrenchStamped(m.data);
          const int64_t k = ros2::NsFromTime(w.header.stamp) / 1'000'000;
          ASSERT_GE(k, 0);
          ASSERT_LT(k, 400);
          EXPECT_EQ(w.wrench.force.x, kMcapGain_N_per_m * trace.samples[k].p_D.x());
          EXPECT_EQ(w.header.frame_id, "hand/device");
          ++forces;
        } else {
          const ros2::DiagnosticArray d = ros2::ParseDiagnosticArray(m.data);
          ASSERT_EQ(d.status.size(), 1u);
          EXPECT_EQ(d.status[0].name, "felt: server mcap-test");
          ++statuses;
        }
      },
      {ids["/hand/servo_cf"], ids["/diagnostics"]});
  EXPECT_EQ(forces, stats.sink.forces_written);
  EXPECT_EQ(statuses, stats.sink.statuses_written);
  std::filesystem::remove(out);
}

// Feeds an McapSink at 1 kHz pointer + 1 kHz force + 1 Hz status for `seconds` on absolute
// deadlines, as the DDS thread would. Returns the positions offered.
std::vector<double> McapFeedAtOneKilohertz(McapSink& sink, double seconds) {
  std::vector<double> xs;
  const int n = static_cast<int>(seconds * 1000);
  auto next = std::chrono::steady_clock::now();
  for (int i = 0; i < n; ++i) {
    std::this_thread::sleep_until(next);
    next += std::chrono::milliseconds(1);
    const int64_t now_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                               std::chrono::steady_clock::now().time_since_epoch())
                               .count();
    PointerSampleView p;
    p.seq = i + 1;
    p.device_time_ns = 1'000'000'000 + int64_t{i} * 1'000'000;
    p.position_m_D = {0.001 * i, std::sin(i * 1e-3), 0};
    p.velocity_m_per_s_D = {1.0, std::cos(i * 1e-3), 0};
    p.receive_time_ns = now_ns;
    sink.OfferPointer(p);
    xs.push_back(p.position_m_D[0]);
    ForceCommandView f;
    f.seq = i + 1;
    f.answers_device_time_ns = p.device_time_ns;
    f.force_N_D = {0.1, 0.2, 0.3};
    f.receive_time_ns = now_ns;
    sink.OfferForce(f);
    if (i % 1000 == 0) {
      ServerStatusView s;
      s.server_id = "endurance";
      s.wall_time_ns = 1'700'000'000'000'000'000 + int64_t{i} * 1'000'000;
      sink.OfferStatus(s);
    }
  }
  return xs;
}

TEST(McapRecorder, SinkKeepsUpWithOneKilohertzPointerAndForceAndReplaysEverySampleInOrder) {
  // 3 s here (the 10-minute run is `felt bench mcap`, bench/results/mcap.md).
  const std::string out = McapTempPath("mcap_sink_endurance.mcap");
  McapSink sink(out, "touch");
  const std::vector<double> xs = McapFeedAtOneKilohertz(sink, 3.0);
  sink.Close();
  const McapSinkStats s = sink.Stats();
  EXPECT_EQ(s.queue_drops, 0u);
  EXPECT_EQ(s.pointers_written, 3000u);
  EXPECT_EQ(s.forces_written, 3000u);
  EXPECT_EQ(s.statuses_written, 3u);
  // The queue never came near full (16384): the writer keeps up.
  EXPECT_LT(s.max_queue_depth, felt::testing::Sanitized() ? 8000u : 2000u);
  const Trace t = ReadMcapTrace(out);
  ASSERT_EQ(t.samples.size(), xs.size());
  for (size_t i = 0; i < xs.size(); ++i) {
    ASSERT_EQ(t.samples[i].p_D.x(), xs[i]) << i;
    ASSERT_EQ(t.samples[i].t_s, static_cast<double>(int64_t(i) * 1'000'000) / 1e9) << i;
  }
  std::filesystem::remove(out);
}

TEST(McapRecorder, AFullQueueIsCountedNotWaitedOn) {
  const std::string out = McapTempPath("mcap_sink_full.mcap");
  McapSink sink(out, "d", /*queue_capacity=*/4);
  // Offer far more than 4 at once: some are refused and counted, none blocks.
  int accepted = 0;
  for (int i = 0; i < 10000; ++i) {
    PointerSampleView p;
    p.seq = i + 1;
    p.device_time_ns = int64_t{i + 1} * 1000;
    accepted += sink.OfferPointer(p) ? 1 : 0;
  }
  sink.Close();
  const McapSinkStats s = sink.Stats();
  EXPECT_EQ(s.queue_drops + s.pointers_written, 10000u);
  EXPECT_GT(s.queue_drops, 0u);  // 10000 offers in a tight loop overfill a queue of 4
  EXPECT_EQ(s.pointers_written, static_cast<uint64_t>(accepted));
  std::filesystem::remove(out);
}

TEST(McapRecorderIndependent, McapCoreReadsTheRecordersFile) {
  FELT_SKIP_WITHOUT_NPM();
  const std::string out = McapTempPath("mcap_sink_npm.mcap");
  McapSink sink(out, "touch", 16384, /*chunk_size_bytes=*/64 * 1024);
  (void)McapFeedAtOneKilohertz(sink, 1.0);
  sink.Close();
  std::string output;
  ASSERT_EQ(felt::testing::RunNpmCheck("check_mcap.mjs", "'" + out + "'", &output), 0) << output;
  const nlohmann::json j = nlohmann::json::parse(output);
  EXPECT_TRUE(j["ok"].get<bool>()) << output;
  EXPECT_EQ(j["messages"], 1000 * 3 + 1);
  EXPECT_EQ(j["topics"]["/touch/measured_cp"]["schema"], "geometry_msgs/msg/PoseStamped");
  EXPECT_EQ(j["topics"]["/touch/measured_cv"]["count"], 1000);
  EXPECT_EQ(j["topics"]["/touch/servo_cf"]["schema"], "geometry_msgs/msg/WrenchStamped");
  EXPECT_EQ(j["topics"]["/diagnostics"]["schema"], "diagnostic_msgs/msg/DiagnosticArray");
  EXPECT_GT(j["chunks"].get<int>(), 1);
  std::filesystem::remove(out);
}

}  // namespace
}  // namespace felt::transport
