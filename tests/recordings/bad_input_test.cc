// Mutated recordings: every reader either returns a valid trace or throws an error that names the
// file, never crashes, hangs or asks for unbounded memory (README: "Bad input always gets a clear
// error that names what was wrong"). Seeded mutants (tests/mutate.h) of a felt trace, a CSV and a
// DeviceLog source and an MCAP file; under ASan+UBSan these also check every byte the readers
// touch.
#include <gtest/gtest.h>

#include <cmath>
#include <exception>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "recordings/import.h"
#include "recordings/mcap.h"
#include "recordings/mcap_trace.h"
#include "recordings/trace.h"
#include "ros2/messages.h"
#include "tests/mutate.h"
#include "tests/recordings/test_util.h"
#include "tests/test_env.h"

namespace felt {
namespace {

// Mutants per source (tests/mutate.h, MutantCount).
int Mutants() { return test::MutantCount(600, 150); }

// A returned trace must be one every consumer can use: samples, strictly increasing finite
// times, finite positions and velocities, and a bounded count.
void ExpectUsableTrace(const Trace& t, const std::string& what) {
  ASSERT_FALSE(t.samples.empty()) << what;
  ASSERT_LE(t.samples.size(), static_cast<size_t>(kMaxImportSamples)) << what;
  double last = -INFINITY;
  for (const TraceSample& s : t.samples) {
    ASSERT_TRUE(std::isfinite(s.t_s) && s.t_s > last) << what << ": t_s " << s.t_s;
    ASSERT_TRUE(s.p_D.allFinite() && s.v_D.allFinite()) << what << " at t " << s.t_s;
    last = s.t_s;
  }
}

// Runs `read` on `mutants` of `good` written to `path`: each must return a usable trace or throw
// a std::exception whose message names the file. Returns how many were refused.
int ExpectEveryMutantReadOrRefused(const std::string& good, const std::string& path, bool binary,
                                   uint64_t seed, const std::function<Trace()>& read) {
  test::Mutator mutate(seed);
  int refused = 0;
  for (int i = 0; i < Mutants(); ++i) {
    test::WriteFile(path, binary ? mutate.Bytes(good) : mutate.Text(good));
    const std::string what =
        path + " (seed " + std::to_string(seed) + ", mutant " + std::to_string(i) + ")";
    try {
      ExpectUsableTrace(read(), what);
    } catch (const std::exception& e) {
      ++refused;
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos)
          << what << ": the error does not name the file: " << e.what();
    }
    if (::testing::Test::HasFailure()) return refused;
  }
  return refused;
}

// The file descriptors this process holds (Linux: /proc/self/fd).
int OpenFds() {
  int n = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator("/proc/self/fd")) ++n;
  return n;
}

// The first `lines` lines of a file.
std::string Head(const std::string& text, int lines) {
  size_t end = 0;
  for (int i = 0; i < lines && end != std::string::npos; ++i) end = text.find('\n', end + 1);
  return end == std::string::npos ? text : text.substr(0, end + 1);
}

TEST(BadRecordings, MutatedTracesAreReadOrRefusedNamingTheFile) {
  const std::string dir = test::ScratchDir("bad_traces");
  const std::string path = dir + "/mutant.trace";
  for (const char* name : {"circle.trace", "hard/scrub.trace"}) {
    const std::string good =
        Head(test::ReadFile(FELT_SOURCE_DIR "/recordings/" + std::string(name)), 120);
    ASSERT_GT(good.size(), 1000u) << name;
    const int refused =
        ExpectEveryMutantReadOrRefused(good, path, false, 1, [&] { return ReadTrace(path); });
    EXPECT_GT(refused, 0) << name;
  }
}

TEST(BadRecordings, MutatedCsvAndDeviceLogSourcesAreImportedOrRefusedNamingTheFile) {
  const std::string dir = test::ScratchDir("bad_imports");
  std::string csv = "trial,t_s,x,y,z\n";
  std::string log = "TIME RAW_POSITION RAW_ORIENTATION BUTTONS\n";
  for (int k = 0; k < 60; ++k) {
    const double t = 0.01 * k;
    csv += std::to_string(k / 30) + "," + std::to_string(t) + "," +
           std::to_string(0.01 * std::sin(t)) + "," + std::to_string(0.02 * t) + ",0.001\n";
    log += std::to_string(0.04 * k) + " " + std::to_string(0.01 * std::cos(t)) + " 0.002 " +
           std::to_string(-0.03 * t) + " 0 1 0 0 " + std::to_string(k % 3) + "\n";
  }
  struct Source {
    const std::string& good;
    ImportFormat format;
    std::string path;
    uint64_t seed;
  };
  for (const Source& source : {Source{csv, ImportFormat::kCsv, dir + "/mutant.csv", 2},
                               Source{log, ImportFormat::kDeviceLog, dir + "/mutant.log", 3}}) {
    ImportOptions options;
    options.format = source.format;
    EXPECT_GT(ExpectEveryMutantReadOrRefused(source.good, source.path, false, source.seed,
                                             [&] { return ImportTrace(source.path, options); }),
              0)
        << source.path;
  }
}

TEST(BadRecordings, MutatedMcapFilesAreReadOrRefusedNamingTheFile) {
  const std::string dir = test::ScratchDir("bad_mcap");
  const std::string good_path = dir + "/good.mcap";
  {
    McapWriterOptions options;
    options.chunk_size_bytes = 1024;
    McapWriter w(good_path, options);
    const uint16_t s_pose = w.AddSchema(ros2::TypeOf<ros2::PoseStamped>().name, "ros2msg",
                                        ros2::TypeOf<ros2::PoseStamped>().schema);
    const uint16_t s_twist = w.AddSchema(ros2::TypeOf<ros2::TwistStamped>().name, "ros2msg",
                                         ros2::TypeOf<ros2::TwistStamped>().schema);
    const uint16_t c_pose = w.AddChannel(s_pose, "/dev/measured_cp", "cdr");
    const uint16_t c_twist = w.AddChannel(s_twist, "/dev/measured_cv", "cdr");
    std::vector<uint8_t> b;
    for (int i = 0; i < 40; ++i) {
      const int64_t t_ns = 1'000'000'000 + int64_t{i} * 1'000'000;
      ros2::PoseStamped p;
      p.header = {ros2::TimeFromNs(t_ns), "dev/device"};
      p.pose.position = {0.01 * std::sin(i * 0.1), 0.002 * i, -0.03};
      ros2::Serialize(p, &b);
      w.WriteMessage(c_pose, static_cast<uint32_t>(i), static_cast<uint64_t>(t_ns),
                     static_cast<uint64_t>(t_ns), b);
      ros2::TwistStamped tw;
      tw.header = p.header;
      tw.twist.linear = {0.1 * std::cos(i * 0.1), 2.0, 0};
      ros2::Serialize(tw, &b);
      w.WriteMessage(c_twist, static_cast<uint32_t>(i), static_cast<uint64_t>(t_ns),
                     static_cast<uint64_t>(t_ns), b);
    }
    w.Close();
  }
  const std::string good = test::ReadFile(good_path);
  ASSERT_EQ(ReadMcapTrace(good_path).samples.size(), 40u);
  // A refused file is closed too (the reader's constructor once left it open when it threw:
  // 20000 mutants ran out of file descriptors).
  const int fds_before = OpenFds();
  const std::string path = dir + "/mutant.mcap";
  EXPECT_GT(
      ExpectEveryMutantReadOrRefused(good, path, true, 4, [&] { return ReadMcapTrace(path); }), 0);
  ImportOptions options;
  options.format = ImportFormat::kMcap;
  EXPECT_GT(ExpectEveryMutantReadOrRefused(good, path, true, 5,
                                           [&] { return ImportTrace(path, options); }),
            0);

  // A Touch driver's OmniState topic (millimetres, its own velocity and buttons), read by log time.
  const std::string omni_path = dir + "/omni.mcap";
  {
    McapWriter w(omni_path);
    const uint16_t s = w.AddSchema(ros2::TypeOf<ros2::OmniState>().name, "ros2msg",
                                   ros2::TypeOf<ros2::OmniState>().schema);
    const uint16_t c = w.AddChannel(s, "/phantom/state", "cdr");
    std::vector<uint8_t> b;
    for (int i = 0; i < 40; ++i) {
      ros2::OmniState m;
      m.header = {ros2::TimeFromNs(5'000'000'000 + int64_t{i} * 1'000'000), "phantom"};
      m.pose.position = {10.0 * std::sin(i * 0.1), -20.0, 30.0};  // mm
      m.velocity = {0.01, 0, 0};                                  // m/s
      m.close_gripper = i % 2 == 1;
      ros2::Serialize(m, &b);
      w.WriteMessage(c, static_cast<uint32_t>(i),
                     7'000'000'000 + static_cast<uint64_t>(i) * 1'000'000, 0, b);
    }
    w.Close();
  }
  ASSERT_EQ(ReadMcapTrace(omni_path).samples.size(), 40u);
  McapTraceOptions by_log;
  by_log.time = McapTraceTime::kLogTime;
  EXPECT_GT(ExpectEveryMutantReadOrRefused(test::ReadFile(omni_path), path, true, 6,
                                           [&] { return ReadMcapTrace(path, by_log); }),
            0);
  EXPECT_EQ(OpenFds(), fds_before);
}

}  // namespace
}  // namespace felt
