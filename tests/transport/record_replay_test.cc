// Record and replay over the real Cyclone DDS on loopback (issue 7): a Replayer publishes a trace
// to a real ServerTransport whose responder thread answers each new sample with a force; a
// Recorder listening on the same topics writes what it saw. Recording the replay gives back the
// same samples, bit for bit; the forces file links each force to its sample; replay timing stays
// within loose bounds; the recorder counts sequence gaps; bad input is named.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "recordings/trace.h"
#include "tests/transport/transport_test_util.h"
#include "transport/recorder.h"
#include "transport/replayer.h"

namespace felt::transport {
namespace {

using namespace ::felt::transport::testing;  // tests/transport/transport_test_util.h

constexpr double kResponderGain_N_per_m = -100.0;  // the responder's force: gain * position

std::string TempPath(const std::string& name) {
  return (std::filesystem::path(::testing::TempDir()) / name).string();
}

// A 1 kHz trace of `n` samples: times k/1000 s (exact in 9 decimals), a wavy path inside the
// test workspace, velocities from its derivative, a button pressed in the middle third.
Trace MakeTrace(int n) {
  Trace trace;
  trace.header = MakeTraceHeader(1000.0, "test-device", "record_replay_test");
  for (int k = 0; k < n; ++k) {
    TraceSample s;
    s.t_s = k / 1000.0;
    s.p_D = Vec3(0.05 * std::sin(3.0 * s.t_s), 0.01 * k / n - 0.02, 0.03 * std::cos(5.0 * s.t_s));
    s.v_D = Vec3(0.15 * std::cos(3.0 * s.t_s), 0.01 / n * 1000.0, -0.15 * std::sin(5.0 * s.t_s));
    s.buttons = (k > n / 3 && k < 2 * n / 3) ? 1u : 0u;
    trace.samples.push_back(s);
  }
  return trace;
}

// A real server transport with a thread that answers every new pointer sample with the force
// kResponderGain_N_per_m * position (the haptic loop's role, without the cloth).
class Responder {
 public:
  Responder(const TopicNames& topics, const std::string& device_id) {
    ServerTransportConfig config;
    config.dds = TestDds();
    config.topics = topics;
    config.devices = {TestDevice(device_id)};
    server_ = std::make_unique<ServerTransport>(std::move(config));
    thread_ = std::thread([this] { Loop(); });
  }
  ~Responder() {
    stop_.store(true);
    thread_.join();
  }
  ServerTransport& server() { return *server_; }

 private:
  void Loop() {
    uint64_t last_seq = 0;
    while (!stop_.load()) {
      PointerSampleView p;
      if (server_->LatestPointer(0, &p) && p.seq != last_seq) {
        last_seq = p.seq;
        ForceCommandView f;
        f.answers_seq = p.seq;
        f.answers_device_time_ns = p.device_time_ns;
        for (int k = 0; k < 3; ++k) {
          f.force_N_D[k] = kResponderGain_N_per_m * p.position_m_D[k];
          f.proxy_position_m_D[k] = p.position_m_D[k];
        }
        f.in_contact = p.buttons != 0;
        server_->PushForce(f);
      }
      std::this_thread::sleep_for(std::chrono::microseconds(100));  // the responder's poll period
    }
  }

  std::unique_ptr<ServerTransport> server_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

ReplayConfig TestReplay(const TopicNames& topics, const std::string& device_id) {
  ReplayConfig config;
  config.dds = TestDds();
  config.topics = topics;
  config.device_id = device_id;
  config.discovery_timeout = kWait;
  config.status_timeout = std::chrono::nanoseconds(0);  // the responder publishes no status
  return config;
}

RecorderConfig TestRecorder(const TopicNames& topics, const std::string& out,
                            const std::string& forces) {
  RecorderConfig config;
  config.dds = TestDds();
  config.topics = topics;
  config.out_path = out;
  config.forces_path = forces;
  return config;
}

// Polls the recorder until `done` holds or kWait passes.
template <typename Done>
bool PollUntil(Recorder& recorder, Done done) {
  const auto deadline = std::chrono::steady_clock::now() + kWait;
  while (!done(recorder.Stats())) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    recorder.Poll(std::chrono::milliseconds(20));
  }
  return true;
}

TEST(RecordReplay, RecordingAReplayGivesTheSameSamplesAndLinkedForces) {
  const TopicNames topics = UniqueTopics();
  const Trace trace = MakeTrace(400);
  const std::string out = TempPath("record_replay_same.trace");
  const std::string forces = TempPath("record_replay_same.forces.csv");
  const std::string replay_forces = TempPath("record_replay_same.replay_forces.csv");

  Responder responder(topics, "hand");
  Recorder recorder(TestRecorder(topics, out, forces));
  ReplayConfig config = TestReplay(topics, "hand");
  config.forces_out = replay_forces;
  Replayer replayer(trace, config);
  ASSERT_TRUE(replayer.WaitForServer());
  ASSERT_TRUE(WaitUntil(
      [&] {
        return recorder.tap().MatchedPointerWriters() > 0 &&
               recorder.tap().MatchedForceWriters() > 0 &&
               responder.server().MatchedPointerWriters() > 0;
      },
      kWait));

  // Replay on a thread while the recorder records here.
  ReplayReport report;
  std::thread replay([&] { report = replayer.Run(); });
  ASSERT_TRUE(PollUntil(recorder, [](const RecorderStats& s) { return s.pointers_written >= 400; }))
      << "recorded " << recorder.Stats().pointers_written;
  replay.join();
  recorder.Poll(std::chrono::milliseconds(50));  // the last forces
  recorder.Close();

  // The recorded trace: every sample, the same bits, the device id in the header.
  const RecorderStats stats = recorder.Stats();
  EXPECT_EQ(stats.device_id, "hand");
  EXPECT_EQ(stats.pointer_seq_gaps, 0u);
  EXPECT_EQ(stats.pointers_out_of_order, 0u);
  const Trace recorded = ReadTrace(out);
  ASSERT_EQ(recorded.samples.size(), trace.samples.size());
  for (size_t i = 0; i < trace.samples.size(); ++i) {
    ASSERT_EQ(recorded.samples[i], trace.samples[i]) << "sample " << i;
  }
  EXPECT_EQ(recorded.header.Get("device"), "hand");

  // The replay's report: everything published and answered by the responder.
  EXPECT_EQ(report.published, 400u);
  EXPECT_EQ(report.scheduled, 400u);
  EXPECT_EQ(report.loops_started, 1u);
  EXPECT_EQ(report.publish_failures, 0u);
  EXPECT_GT(report.forces_received, 0u);
  EXPECT_EQ(report.answered, report.latency.count);
  EXPECT_GT(report.answered, 0u);
  EXPECT_GT(report.latency.p50_us, 0.0);
  EXPECT_LE(report.latency.p50_us, report.latency.max_us);
  EXPECT_FALSE(report.server_counts);  // status_timeout 0: the server's counts are not asked for
  EXPECT_EQ(report.pointer_lost, -1);
  // Peak force: the responder's gain times the largest |position| (0.05 m sway at most).
  EXPECT_GT(report.peak_force_N, 0.0);
  EXPECT_LE(report.peak_force_N, 100.0 * std::sqrt(0.05 * 0.05 + 0.02 * 0.02 + 0.03 * 0.03));

  // The recorder's forces file: each line's answers_t_s is a trace time and its force is the
  // responder's gain times that sample's position.
  std::ifstream in(forces);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, kForcesMagic);
  while (std::getline(in, line) && line != kForcesColumns) {
  }
  ASSERT_EQ(line, kForcesColumns);
  int checked = 0;
  while (std::getline(in, line)) {
    std::stringstream fields(line);
    std::vector<double> v;
    std::string field;
    while (std::getline(fields, field, ',')) v.push_back(std::stod(field));
    ASSERT_EQ(v.size(), 12u) << line;
    const auto k = static_cast<size_t>(std::llround(v[3] * 1000.0));
    ASSERT_LT(k, trace.samples.size()) << line;
    EXPECT_EQ(v[3], trace.samples[k].t_s) << line;
    EXPECT_EQ(v[4], kResponderGain_N_per_m * trace.samples[k].p_D.x()) << line;
    EXPECT_EQ(v[9], trace.samples[k].p_D.z()) << line;
    ++checked;
  }
  EXPECT_EQ(static_cast<uint64_t>(checked), stats.forces_written);
  EXPECT_GT(checked, 0);
  std::filesystem::remove(out);
  std::filesystem::remove(forces);
  std::filesystem::remove(replay_forces);
}

TEST(RecordReplay, ReplayKeepsTheScheduleWithinLooseBoundsAtRateAndLoops) {
  const TopicNames topics = UniqueTopics();
  const Trace trace = MakeTrace(200);  // 0.199 s long; a pass lasts 0.2 s
  Responder responder(topics, "hand");
  ReplayConfig config = TestReplay(topics, "hand");
  config.rate = 2.0;
  config.loops = 3;
  Replayer replayer(trace, config);
  ASSERT_TRUE(replayer.WaitForServer());
  std::atomic<int> started{0};
  const auto begin = std::chrono::steady_clock::now();
  const ReplayReport report = replayer.Run(nullptr, [&] { started.fetch_add(1); });
  const double elapsed_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();

  // Three passes at twice the speed: the last sample is due at (2 * 0.2 + 0.199) / 2 s.
  EXPECT_EQ(started.load(), 1);
  EXPECT_EQ(report.scheduled, 600u);
  EXPECT_EQ(report.published, 600u);
  EXPECT_EQ(report.loops_started, 3u);
  const double last_due_s = (2 * 0.2 + 0.199) / 2.0;
  EXPECT_GE(report.wall_s, last_due_s - 1e-6);  // never early (absolute deadlines)
  EXPECT_LT(report.wall_s, last_due_s + 1.0);   // loose: a loaded CI machine, sanitizers
  EXPECT_LT(elapsed_s, last_due_s + 3.0);
  EXPECT_GE(report.lateness.p50_us, 0.0);
  EXPECT_EQ(report.lateness.count, 600u);
  EXPECT_LE(report.late, report.published);
}

TEST(RecordReplay, ReplayForADurationLoopsAndStopsAtIt) {
  const TopicNames topics = UniqueTopics();
  Responder responder(topics, "hand");
  ReplayConfig config = TestReplay(topics, "hand");
  config.duration_s = 0.25;  // 100-sample passes of 0.1 s: 2.5 passes
  Replayer replayer(MakeTrace(100), config);
  ASSERT_TRUE(replayer.WaitForServer());
  const ReplayReport report = replayer.Run();
  EXPECT_EQ(report.scheduled, 250u);
  EXPECT_EQ(report.published, 250u);
  EXPECT_EQ(report.loops_started, 3u);
  EXPECT_GE(report.wall_s, 0.249 - 1e-6);
}

TEST(RecordReplay, AStopFlagEndsTheReplayEarly) {
  const TopicNames topics = UniqueTopics();
  Responder responder(topics, "hand");
  ReplayConfig config = TestReplay(topics, "hand");
  config.loops = 1000;  // 100 s if nothing stops it
  Replayer replayer(MakeTrace(100), config);
  ASSERT_TRUE(replayer.WaitForServer());
  std::atomic<bool> stop{false};
  std::thread stopper([&] {
    WaitUntil([&] { return responder.server().Stats().pointer_accepted >= 50; }, kWait);
    stop.store(true);
  });
  const ReplayReport report = replayer.Run(&stop);
  stopper.join();
  EXPECT_TRUE(report.stopped_early);
  EXPECT_GE(report.published, 50u);
  EXPECT_LT(report.published, report.scheduled);
}

TEST(RecordReplay, RecorderCountsSequenceGapsAndOutOfOrderSamples) {
  const TopicNames topics = UniqueTopics();
  const std::string out = TempPath("record_gaps.trace");
  Recorder recorder(TestRecorder(topics, out, ""));
  ClientTransportConfig client_config;
  client_config.dds = TestDds();
  client_config.topics = topics;
  client_config.device_ids = {"pen"};
  client_config.subscribe_status = false;
  ClientTransport client(client_config);
  ASSERT_TRUE(WaitUntil(
      [&] {
        return client.MatchedPointerReaders() > 0 && recorder.tap().MatchedPointerWriters() > 0;
      },
      kWait));

  // seq 1, 2, 5, 6 (two missing), then 4 (out of order: not written), then 7.
  for (const uint64_t seq : {1, 2, 5, 6, 4, 7}) {
    ASSERT_TRUE(client.PublishPointer(testing::Sample(seq, 0.01 * static_cast<double>(seq))));
  }
  ASSERT_TRUE(PollUntil(recorder, [](const RecorderStats& s) { return s.pointers_received >= 6; }));
  recorder.Close();
  const RecorderStats stats = recorder.Stats();
  EXPECT_EQ(stats.device_id, "pen");
  EXPECT_EQ(stats.pointer_seq_gaps, 2u);
  EXPECT_EQ(stats.pointers_out_of_order, 1u);
  EXPECT_EQ(stats.pointers_written, 5u);
  const Trace recorded = ReadTrace(out);
  ASSERT_EQ(recorded.samples.size(), 5u);
  // device_time_ns = seq ms: the trace keeps the driver's timing from the first sample.
  const double expected_t[] = {0.0, 0.001, 0.004, 0.005, 0.006};
  for (size_t i = 0; i < 5; ++i) EXPECT_EQ(recorded.samples[i].t_s, expected_t[i]) << i;
  std::filesystem::remove(out);
}

TEST(RecordReplay, ClientTakeForcesReturnsEveryForceInOrderNotOnlyTheNewest) {
  const TopicNames topics = UniqueTopics();
  ServerTransportConfig server_config;
  server_config.dds = TestDds();
  server_config.topics = topics;
  server_config.devices = {TestDevice("hand")};
  ServerTransport server(server_config);
  ClientTransportConfig client_config;
  client_config.dds = TestDds();
  client_config.topics = topics;
  client_config.device_ids = {"hand"};
  client_config.subscribe_status = false;
  client_config.force_history = 64;
  ClientTransport client(client_config);
  ASSERT_TRUE(WaitUntil(
      [&] { return client.MatchedForceWriters() > 0 && server.MatchedForceReaders() > 0; }, kWait));

  // Ten forces pushed at once; the client takes them all, oldest first, in batches of four.
  for (uint64_t i = 1; i <= 10; ++i) {
    ForceCommandView f;
    f.answers_seq = 100 + i;
    ASSERT_TRUE(server.PushForce(f));
  }
  std::vector<ForceCommandView> taken;
  ForceCommandView batch[4];
  ASSERT_TRUE(WaitUntil(
      [&] {
        const size_t n = client.TakeForces(batch, 4);
        taken.insert(taken.end(), batch, batch + n);
        return taken.size() >= 10;
      },
      kWait));
  ASSERT_EQ(taken.size(), 10u);
  for (uint64_t i = 1; i <= 10; ++i) {
    EXPECT_EQ(taken[i - 1].seq, i);
    EXPECT_EQ(taken[i - 1].answers_seq, 100 + i);
    EXPECT_GT(taken[i - 1].receive_time_ns, 0);
  }
  EXPECT_EQ(client.Stats().forces_received, 10u);
  EXPECT_EQ(client.Stats().forces_seq_gaps, 0u);
  EXPECT_EQ(client.TakeForces(batch, 4), 0u);
}

TEST(RecordReplay, BadConfigurationsAreNamed) {
  const Trace trace = MakeTrace(10);
  const auto message = [&](ReplayConfig config, Trace t) {
    try {
      Replayer replayer(std::move(t), config);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  ReplayConfig config = TestReplay(UniqueTopics(), "hand");
  config.rate = 0.0;
  EXPECT_EQ(message(config, trace), "ReplayConfig.rate: must be finite and > 0");
  config.rate = 1.0;
  config.loops = 0;
  EXPECT_EQ(message(config, trace), "ReplayConfig.loops: must be at least 1");
  config.loops = 1;
  config.late_threshold_us = -1.0;
  EXPECT_EQ(message(config, trace), "ReplayConfig.late_threshold_us: must be finite and > 0");
  config.late_threshold_us = 1000.0;
  EXPECT_EQ(message(config, Trace{}), "replay: the trace has no samples");
  RecorderConfig recorder = TestRecorder(UniqueTopics(), "", "");
  EXPECT_THROW(Recorder{recorder}, std::invalid_argument);
}

}  // namespace
}  // namespace felt::transport
