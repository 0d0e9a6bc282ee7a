// `felt serve` as a child process: SIGTERM stops it cleanly (exit 0, the final statistics
// printed, the stats JSON written); a trace run touches the cloth; the example driver
// (examples/device_client.cpp) feels the default scene. Needs the `felt` binary of the
// same build (built with the `felt` target); skipped where it was not built (the TSan CI build
// compiles only the test executables).
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

#include "base/json.h"
#include "base/process.h"
#include "ros2_types.h"
#include "tests/test_domain.h"
#include "transport/dds_config.h"

namespace {

using felt::Json;
using felt::ParseJson;
using felt::Process;
using felt::SpawnOptions;

const std::string kFelt = std::string(FELT_BINARY_DIR) + "/felt";
const std::string kDeviceClient = std::string(FELT_BINARY_DIR) + "/felt_device_client";
const std::string kScene = std::string(FELT_SOURCE_DIR "/scenes/curtain.toml");
const std::string kTrace = std::string(FELT_SOURCE_DIR "/recordings/poke_hold.trace");

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

struct Child {
  Process process;
  std::string log;  // stdout and stderr of the child
};

// Starts `felt serve <args>` with its output in a file of its own.
Child StartServe(const std::string& args, const std::string& name) {
  Child child;
  child.log = (std::filesystem::path(testing::TempDir()) / (name + ".log")).string();
  SpawnOptions options;
  options.output = SpawnOptions::Output::kFile;
  options.output_file = child.log;
  child.process = Process::Spawn({"/bin/sh", "-c", "exec " + kFelt + " serve " + args}, options);
  return child;
}

// Waits up to `timeout` for the child to exit; returns its exit code (-1: still running, then
// killed, or ended by a signal).
int WaitExit(Process& process, std::chrono::milliseconds timeout) {
  if (!process.Wait(timeout)) process.Terminate(std::chrono::milliseconds(0));
  return process.exit_code();
}

class ServeTest : public testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(kFelt)) GTEST_SKIP() << kFelt << " not built";
  }
};

TEST_F(ServeTest, SigtermStopsCleanlyWithTheFinalStats) {
  const std::string json = (std::filesystem::path(testing::TempDir()) / "serve_sigterm.json");
  std::filesystem::remove(json);
  Child child = StartServe("--scene " + kScene + " --trace " + kTrace +
                               " --duration 60 --no-realtime --stats-json " + json,
                           "serve_sigterm");
  ASSERT_GT(child.process.pid(), 0);
  // Wait (deadline) until the loops have run: the monitor's first once-a-second line, then SIGTERM.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (ReadFile(child.log).find("[info] haptic: ") == std::string::npos &&
         std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  child.process.Signal(SIGTERM);
  const int code = WaitExit(child.process, std::chrono::seconds(10));
  const std::string log = ReadFile(child.log);
  EXPECT_EQ(code, 0) << log;
  EXPECT_NE(log.find("stopped by signal"), std::string::npos) << log;
  EXPECT_NE(log.find("final: haptic:"), std::string::npos) << log;
  EXPECT_NE(log.find("final: realtime false"), std::string::npos) << log;
  const std::string stats = ReadFile(json);
  for (const char* key : {"\"lateness_us\"", "\"frame_ms\"", "\"p999\"", "\"overruns\"",
                          "\"ticks\"", "\"frames\"", "\"realtime\": false"}) {
    EXPECT_NE(stats.find(key), std::string::npos) << key << "\n" << stats;
  }
}

TEST_F(ServeTest, TraceRunTouchesTheCloth) {
  const std::string json = (std::filesystem::path(testing::TempDir()) / "serve_trace.json");
  Child child = StartServe("--scene " + kScene + " --trace " + kTrace +
                               " --duration 3 --no-realtime --stats-json " + json,
                           "serve_trace");
  const int code = WaitExit(child.process, std::chrono::seconds(30));
  const std::string log = ReadFile(child.log);
  ASSERT_EQ(code, 0) << log;
  EXPECT_NE(log.find("stopped after the duration"), std::string::npos) << log;
  const Json stats = ParseJson(ReadFile(json), json);
  EXPECT_GT(stats.value("contacts", 0), 0) << stats;
  EXPECT_GT(stats.value("peak_force_N", 0.0), 0.0) << stats;
}

// The README's two lines, as a driver author runs them: `felt serve` with the default scene and
// the example driver with its defaults (only the domain is the test's own). Forces arrive and the
// simulated tip is pushed back by the cloth; a driver with a device id the scene lacks gets none,
// and the server says so once, naming the ids it has.
TEST_F(ServeTest, TheExampleDriverFeelsTheDefaultScene) {
  if (!std::filesystem::exists(kDeviceClient)) GTEST_SKIP() << kDeviceClient << " not built";
  const std::string domain = std::to_string(felt::testing::ExclusiveDdsDomain());
  Child server = StartServe("--scene " + kScene + " --duration 30 --no-realtime --domain " + domain,
                            "serve_example");
  const auto run_client = [&](const std::string& args, const std::string& name) {
    const std::string log = (std::filesystem::path(testing::TempDir()) / (name + ".log")).string();
    SpawnOptions options;
    options.output = SpawnOptions::Output::kFile;
    options.output_file = log;
    Process client = Process::Spawn(
        {"/bin/sh", "-c", "exec " + kDeviceClient + " --domain " + domain + " " + args}, options);
    EXPECT_EQ(WaitExit(client, std::chrono::seconds(30)), 0) << ReadFile(log);
    return ReadFile(log);
  };
  // One press of the example's 4 s cycle (in, stroke, out), and a little more.
  const std::string out = run_client("--seconds 5", "example_default");
  unsigned long long samples = 0, forces = 0;
  double impulse = 0, peak = 0;
  const size_t at = out.find("stopped: ");
  ASSERT_NE(at, std::string::npos) << out;
  ASSERT_EQ(std::sscanf(out.c_str() + at,
                        "stopped: samples %llu, forces %llu, motor impulse %lf N s, peak force "
                        "%lf N",
                        &samples, &forces, &impulse, &peak),
            4)
      << out;
  EXPECT_GT(forces, samples / 4) << out;  // loose: a loaded machine may miss periods
  EXPECT_GT(peak, 0.05) << out;           // the cloth pushes back (0.28 N measured)
  const std::string other = run_client("--seconds 1 --device right-hand", "example_unknown");
  EXPECT_NE(other.find("forces 0,"), std::string::npos) << other;
  server.process.Signal(SIGTERM);
  EXPECT_EQ(WaitExit(server.process, std::chrono::seconds(10)), 0);
  const std::string log = ReadFile(server.log);
  EXPECT_NE(log.find("device 'right-hand', which this scene does not have (it has 'default')"),
            std::string::npos)
      << log;
}

// Issue 24: a driver that knows only ROS 2 (a PoseStamped publisher and a WrenchStamped
// subscriber with ROS 2's default QoS, the CRTK names under the device's id) drives `felt serve`
// with the default scene on the ROS 2 profile, and every force it reads carries the stamp of a
// pose it sent.
TEST_F(ServeTest, ARos2OnlyDriverDrivesTheServer) {
  const int domain = static_cast<int>(felt::testing::ExclusiveDdsDomain());
  const std::string scene = (std::filesystem::path(testing::TempDir()) / "ros2_profile.toml");
  std::ofstream(scene) << ReadFile(kScene) << "\n[transport]\nprofile = \"ros2\"\n";
  Child server = StartServe(
      "--scene " + scene + " --duration 30 --no-realtime --domain " + std::to_string(domain),
      "serve_ros2");
  using namespace felt::transport;
  DdsSettings dds;
  dds.domain_id = static_cast<uint32_t>(domain);
  Participant driver(AcquireDomain(dds));
  const Entity pose_topic =
      CreateTopic(driver, &geometry_msgs_msg_dds__PoseStamped__desc, "rt/default/measured_cp");
  const Entity wrench_topic =
      CreateTopic(driver, &geometry_msgs_msg_dds__WrenchStamped__desc, "rt/default/servo_cf");
  dds_qos_t* qos = dds_create_qos();  // rclcpp's default: reliable, keep-last 10, volatile
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 10);
  const Entity writer = CreateWriter(driver, pose_topic, qos, "pose");
  const Entity reader = CreateReader(driver, wrench_topic, qos, nullptr, "wrench");
  // The markers felt serve publishes with a ROS 2 device, read with RViz's default QoS.
  const Entity marker_topic =
      CreateTopic(driver, &visualization_msgs_msg_dds__MarkerArray__desc, "rt/felt/markers");
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 5);
  const Entity marker_reader = CreateReader(driver, marker_topic, qos, nullptr, "markers");
  dds_delete_qos(qos);
  int marker_arrays = 0;
  uint32_t marker_points = 0, marker_count = 0;

  // 1 kHz for up to 20 s: poses stamped 1 ms apart (sec 100 on), until 500 forces came back.
  geometry_msgs_msg_dds__PoseStamped_ pose{};
  char frame[] = "touch_base";
  pose.header.frame_id = frame;
  pose.pose.orientation.w = 1.0;
  int64_t first_stamp = 100'000'000'000, last_stamp = 0;
  int forces = 0, stamps_echoed = 0, frames_echoed = 0;
  void* ptrs[16] = {};
  dds_sample_info_t infos[16];
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  for (int k = 0; forces < 500 && std::chrono::steady_clock::now() < deadline; ++k) {
    last_stamp = first_stamp + int64_t{k} * 1'000'000;
    Ros2StampOf(last_stamp, &pose.header.stamp.sec, &pose.header.stamp.nanosec);
    pose.pose.position.x = 0.01 * std::sin(k * 0.002);
    (void)dds_write(writer.get(), &pose);
    const dds_return_t n = dds_take(reader.get(), ptrs, infos, 16, 16);
    for (dds_return_t i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      const auto* w = static_cast<const geometry_msgs_msg_dds__WrenchStamped_*>(ptrs[i]);
      ++forces;
      const int64_t stamp = Ros2StampNs(w->header.stamp.sec, w->header.stamp.nanosec);
      if (stamp >= first_stamp && stamp <= last_stamp && (stamp - first_stamp) % 1'000'000 == 0) {
        ++stamps_echoed;
      }
      if (w->header.frame_id != nullptr && std::string(w->header.frame_id) == "touch_base") {
        ++frames_echoed;
      }
    }
    if (n > 0) (void)dds_return_loan(reader.get(), ptrs, n);
    void* mptr[1] = {nullptr};
    dds_sample_info_t minfo{};
    if (dds_take(marker_reader.get(), mptr, &minfo, 1, 1) == 1) {
      if (minfo.valid_data) {
        const auto* m = static_cast<const visualization_msgs_msg_dds__MarkerArray_*>(mptr[0]);
        ++marker_arrays;
        marker_count = m->markers._length;
        marker_points = m->markers._length > 0 ? m->markers._buffer[0].points._length : 0;
      }
      (void)dds_return_loan(marker_reader.get(), mptr, 1);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  server.process.Signal(SIGTERM);
  EXPECT_EQ(WaitExit(server.process, std::chrono::seconds(10)), 0) << ReadFile(server.log);
  EXPECT_GE(forces, 500) << ReadFile(server.log);
  // The cloth (32 x 32: 2 x 31 x 31 triangles) and the one proxy, as markers.
  EXPECT_GE(marker_arrays, 1) << ReadFile(server.log);
  EXPECT_EQ(marker_count, 2u);
  EXPECT_EQ(marker_points, 3u * 2u * 31u * 31u);
  EXPECT_NE(ReadFile(server.log).find("ROS 2 markers on /felt/markers at 30 Hz"),
            std::string::npos);
  EXPECT_EQ(stamps_echoed, forces) << "every force answers a pose that was sent";
  // The first forces may precede the first pose's frame (ramp-in from no input): nearly all echo.
  EXPECT_GE(frames_echoed, forces - 5);
}

// The Geomagic Touch driver's messages (ros2_preset = "omni"): a participant with omni_msgs'
// and diagnostic_msgs' IDL types only publishes OmniState on /phantom/state in millimetres at
// 1 kHz with the driver's QoS (reliable, keep-last 1) and reads OmniFeedback on
// /phantom/force_feedback, whose lock position is the proxy in millimetres; `felt serve` also
// publishes its status on /diagnostics, where the same participant reads the accepted count.
TEST_F(ServeTest, ATouchDriverSpeakingOmniMsgsDrivesTheServer) {
  const int domain = static_cast<int>(felt::testing::ExclusiveDdsDomain());
  const std::string scene = (std::filesystem::path(testing::TempDir()) / "omni_preset.toml");
  std::ofstream(scene) << ReadFile(kScene)
                       << "\n[transport]\n[[transport.devices]]\nid = \"default\"\n"
                          "ros2_preset = \"omni\"\n";
  Child server = StartServe(
      "--scene " + scene + " --duration 30 --no-realtime --domain " + std::to_string(domain),
      "serve_omni");
  // `felt serve`'s server id ("felt-" + its pid: sh execs it) names its diagnostics.
  const std::string server_id = "felt-" + std::to_string(server.process.pid());
  using namespace felt::transport;
  DdsSettings dds;
  dds.domain_id = static_cast<uint32_t>(domain);
  Participant driver(AcquireDomain(dds));
  const Entity state_topic =
      CreateTopic(driver, &omni_msgs_msg_dds__OmniState__desc, "rt/phantom/state");
  const Entity feedback_topic =
      CreateTopic(driver, &omni_msgs_msg_dds__OmniFeedback__desc, "rt/phantom/force_feedback");
  const Entity diagnostics_topic =
      CreateTopic(driver, &diagnostic_msgs_msg_dds__DiagnosticArray__desc, "rt/diagnostics");
  dds_qos_t* qos = dds_create_qos();  // omni_state.cpp: depth 1, rclcpp's default otherwise
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 1);
  const Entity writer = CreateWriter(driver, state_topic, qos, "state");
  const Entity reader = CreateReader(driver, feedback_topic, qos, nullptr, "feedback");
  const Entity diagnostics = CreateReader(driver, diagnostics_topic, qos, nullptr, "diagnostics");
  dds_delete_qos(qos);

  // 1 kHz for up to 20 s, x = 10 sin(...) mm, until 500 feedbacks and a diagnostics message
  // reporting accepted samples came back.
  omni_msgs_msg_dds__OmniState_ state{};
  char empty[] = "";
  state.header.frame_id = empty;
  state.pose.orientation.w = 1.0;
  int feedbacks = 0, finite = 0;
  double max_proxy_x = 0;  // mm
  std::string at_max;      // the feedback that set max_proxy_x
  std::string accepted;
  void* ptrs[16] = {};
  dds_sample_info_t infos[16];
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  for (int k = 0; (k < 800 || feedbacks < 500 || accepted.empty() || accepted == "0") &&
                  std::chrono::steady_clock::now() < deadline;
       ++k) {
    Ros2StampOf(100'000'000'000 + int64_t{k} * 1'000'000, &state.header.stamp.sec,
                &state.header.stamp.nanosec);
    state.pose.position.x = 10.0 * std::sin(k * 0.002);  // mm
    (void)dds_write(writer.get(), &state);
    dds_return_t n = dds_take(reader.get(), ptrs, infos, 16, 16);
    for (dds_return_t i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      const auto* f = static_cast<const omni_msgs_msg_dds__OmniFeedback_*>(ptrs[i]);
      ++feedbacks;
      if (std::isfinite(f->force.x) && std::isfinite(f->force.y) && std::isfinite(f->force.z)) {
        ++finite;
      }
      if (std::abs(f->position.x) > max_proxy_x) {  // kept for the failure message below
        max_proxy_x = std::abs(f->position.x);
        at_max = "feedback " + std::to_string(feedbacks) + " at state " + std::to_string(k) +
                 ": position (" + std::to_string(f->position.x) + ", " +
                 std::to_string(f->position.y) + ", " + std::to_string(f->position.z) +
                 ") mm, force (" + std::to_string(f->force.x) + ", " + std::to_string(f->force.y) +
                 ", " + std::to_string(f->force.z) + ") N";
      }
    }
    if (n > 0) (void)dds_return_loan(reader.get(), ptrs, n);
    n = dds_take(diagnostics.get(), ptrs, infos, 16, 16);
    for (dds_return_t i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      const auto* d = static_cast<const diagnostic_msgs_msg_dds__DiagnosticArray_*>(ptrs[i]);
      for (uint32_t s = 0; s < d->status._length; ++s) {
        const auto& st = d->status._buffer[s];
        if (std::string(st.hardware_id) != server_id) continue;  // another test's server
        for (uint32_t v = 0; v < st.values._length; ++v) {
          if (std::string(st.values._buffer[v].key) == "pointer_accepted") {
            accepted = st.values._buffer[v].value;
          }
        }
      }
    }
    if (n > 0) (void)dds_return_loan(diagnostics.get(), ptrs, n);
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  server.process.Signal(SIGTERM);
  EXPECT_EQ(WaitExit(server.process, std::chrono::seconds(10)), 0) << ReadFile(server.log);
  EXPECT_GE(feedbacks, 500) << ReadFile(server.log);
  EXPECT_EQ(finite, feedbacks);
  // The proxy follows the tip, which swings to 10 mm in x (the cloth may push it further, tens
  // of mm): in millimetres its |x| exceeds 5, in metres it would stay below 0.1.
  EXPECT_GT(max_proxy_x, 5.0) << "the lock position is the proxy in millimetres";
  // Failed once (TSan, 1 of about 12 runs of the suite on two loaded cores, session 32):
  // max_proxy_x 21920 mm, not understood; not reproduced in 95 TSan runs since (alone, beside two
  // busy loops, beside SecurityTest). The message names the feedback and prints the server's log,
  // for whoever meets it next. Until session 33 the DDS domains of tests running side by side
  // could coincide (by pid modulo 30; now tests/test_domain.h); whether that had to do with it
  // is not known.
  EXPECT_LT(max_proxy_x, 500.0) << at_max << "\n" << ReadFile(server.log);
  EXPECT_FALSE(accepted.empty()) << "no DiagnosticArray with pointer_accepted on /diagnostics";
  EXPECT_NE(accepted, "0");
}

TEST_F(ServeTest, BadSceneExitsTwoAndStartsNothing) {
  const std::string scene = (std::filesystem::path(testing::TempDir()) / "bad_haptic.toml");
  std::ofstream(scene) << ReadFile(kScene) << "\n[haptic]\nstale_input_ms = -1\n";
  Child child = StartServe("--scene " + scene + " --trace " + kTrace, "serve_bad");
  EXPECT_EQ(WaitExit(child.process, std::chrono::seconds(20)), 2);
  const std::string log = ReadFile(child.log);
  EXPECT_NE(log.find("haptic.stale_input_ms"), std::string::npos) << log;
  EXPECT_EQ(log.find("serve: scene"), std::string::npos) << log;
}

}  // namespace
