#include "recordings/generate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>

#include "tests/recordings/test_util.h"

namespace felt {
namespace {

std::string BundledPath(const std::string& name) {
  return std::string(FELT_SOURCE_DIR "/recordings/") + name + ".trace";
}

TEST(GenerateTest, SameSeedSameBytesOtherSeedOtherNoise) {
  const std::string dir = test::ScratchDir("generate_determinism");
  std::vector<std::string> names = BundledTraceNames();
  names.insert(names.end(), HardTraceNames().begin(), HardTraceNames().end());
  for (const std::string& name : names) {
    SCOPED_TRACE(name);
    const Trace a = GenerateTrace(name, 42);
    const Trace b = GenerateTrace(name, 42);
    const Trace c = GenerateTrace(name, 43);
    ASSERT_EQ(a.samples.size(), b.samples.size());
    EXPECT_EQ(a.samples, b.samples);
    EXPECT_NE(a.samples, c.samples);
    WriteTrace(dir + "/a.trace", a, TraceWriteOptions{kBundledDecimals});
    WriteTrace(dir + "/b.trace", b, TraceWriteOptions{kBundledDecimals});
    EXPECT_EQ(test::ReadFile(dir + "/a.trace"), test::ReadFile(dir + "/b.trace"));
  }
  EXPECT_THROW(GenerateTrace("wave", 1), std::invalid_argument);
}

// The committed files are exactly what `felt trace generate --seed 1` writes: the bundled ones in
// recordings/, the hard ones in recordings/hard/.
void ExpectCommittedEqualsFresh(const std::vector<std::string>& names,
                                const std::vector<std::string>& fresh_paths,
                                const std::string& committed_dir) {
  ASSERT_EQ(fresh_paths.size(), names.size());
  for (size_t i = 0; i < fresh_paths.size(); ++i) {
    const std::string path = committed_dir + "/" + names[i] + ".trace";
    SCOPED_TRACE(path);
    const std::string committed = test::ReadFile(path);
    ASSERT_FALSE(committed.empty()) << path << " is missing; run felt trace generate";
    EXPECT_TRUE(committed == test::ReadFile(fresh_paths[i]))
        << path << " differs from a fresh `felt trace generate --seed " << kDefaultTraceSeed << "`";
    EXPECT_LT(committed.size(), 1000000u);
  }
}

TEST(GenerateTest, BundledFilesEqualAFreshGeneration) {
  const std::string dir = test::ScratchDir("generate_fresh");
  ExpectCommittedEqualsFresh(BundledTraceNames(), WriteBundledTraces(dir, kDefaultTraceSeed),
                             FELT_SOURCE_DIR "/recordings");
}

TEST(GenerateTest, HardFilesEqualAFreshGeneration) {
  const std::string dir = test::ScratchDir("generate_fresh_hard");
  ExpectCommittedEqualsFresh(HardTraceNames(), WriteHardTraces(dir, kDefaultTraceSeed),
                             FELT_SOURCE_DIR "/recordings/hard");
}

// Properties every bundled trace must have, read back from the committed files.
class BundledTraceTest : public ::testing::TestWithParam<std::string> {};

TEST_P(BundledTraceTest, IsA1kHzTraceInsideTheWorkspaceWithConsistentVelocity) {
  const Trace trace = ReadTrace(BundledPath(GetParam()));
  EXPECT_EQ(trace.header.rate_hz(), 1000.0);
  const auto& s = trace.samples;
  const double duration = s.back().t_s - s.front().t_s;
  EXPECT_GE(duration, 5.0);
  EXPECT_LE(duration, 10.0);
  Vec3 integral = Vec3::Zero();
  double worst_drift = 0.0;
  for (size_t k = 0; k < s.size(); ++k) {
    ASSERT_NEAR(s[k].t_s, static_cast<double>(k) / 1000.0, 1e-12);
    ASSERT_LE(s[k].p_D.cwiseAbs().maxCoeff(), kWorkspaceHalfExtent_m) << k;
    // Inside the curtain's x extent (0.248 m / 3) and below its top edge (0.25 m / 3).
    ASSERT_LT(std::fabs(s[k].p_D.x()), 0.248 / kDefaultDeviceScale);
    ASSERT_LT(s[k].p_D.y(), 0.25 / kDefaultDeviceScale);
    if (k > 0) {
      // Integrated velocity follows the position up to the sensor noise (which is not in v).
      integral += 0.5 * (s[k].t_s - s[k - 1].t_s) * (s[k].v_D + s[k - 1].v_D);
      worst_drift = std::max(worst_drift, (s[k].p_D - s[0].p_D - integral).cwiseAbs().maxCoeff());
    }
  }
  // Quantisation (half a step at each end) + 5 sigma of white noise at each end + rounding.
  EXPECT_LT(worst_drift, kEncoderStep_m + 10.0 * kSensorNoiseSigma_m + 1e-5);
  // Starts and ends in front of the cloth (+z), away from it.
  EXPECT_GT(s.front().p_D.z(), 0.03);
  EXPECT_GT(s.back().p_D.z(), 0.03);
}

TEST_P(BundledTraceTest, HasRealisticTremorWhileTheHandIsStill) {
  // Over the first 0.3 s every trace holds still: what moves is tremor plus sensor noise.
  const Trace trace = ReadTrace(BundledPath(GetParam()));
  Vec3 mean = Vec3::Zero();
  const int n = 300;
  for (int k = 0; k < n; ++k) mean += trace.samples[k].p_D / n;
  double rms = 0.0;
  double peak = 0.0;
  for (int k = 0; k < n; ++k) {
    const Vec3 d = trace.samples[k].p_D - mean;
    rms += d.squaredNorm() / (3.0 * n);
    peak = std::max(peak, d.cwiseAbs().maxCoeff());
  }
  rms = std::sqrt(rms);
  EXPECT_GT(rms, 0.05e-3);
  EXPECT_LT(rms, 0.3e-3);
  EXPECT_GT(peak, 0.1e-3);
  EXPECT_LT(peak, 0.7e-3);
  // The tremor's velocity has 8-12 Hz content: |v| ~ 2 pi f x_rms, about 6-11 mm/s RMS.
  double v_rms = 0.0;
  for (int k = 0; k < n; ++k) v_rms += trace.samples[k].v_D.squaredNorm() / (3.0 * n);
  v_rms = std::sqrt(v_rms);
  EXPECT_GT(v_rms, 2.0 * std::numbers::pi * 8.0 * 0.5 * kTremorRms_m);
  EXPECT_LT(v_rms, 2.0 * std::numbers::pi * 12.0 * 1.5 * kTremorRms_m);
}

INSTANTIATE_TEST_SUITE_P(Bundled, BundledTraceTest, ::testing::ValuesIn(BundledTraceNames()));

TEST(GenerateTest, PokeGoesThroughTheClothPlaneAndHolds) {
  const Trace trace = ReadTrace(BundledPath("poke_hold"));
  double min_z = 1.0;
  int below = 0;  // samples more than 1 cm behind the cloth plane z_D = 0
  for (const TraceSample& s : trace.samples) {
    min_z = std::min(min_z, s.p_D.z());
    below += s.p_D.z() < -0.01;
    // Near the cloth's centre while pressing.
    if (s.p_D.z() < 0.0) {
      ASSERT_LT(s.p_D.head<2>().norm(), 0.02);
    }
  }
  EXPECT_GT(trace.samples.front().p_D.z(), 0.045);  // approach from z_D = +0.05
  EXPECT_LT(min_z, -0.01);                          // 1-2 cm into the cloth
  EXPECT_GT(min_z, -0.02);
  EXPECT_GE(below, 2000);  // held for about 2 s
}

TEST(GenerateTest, SwipeReaches2MetresPerSecondInTheWorldAndCrossesTheCloth) {
  const Trace trace = ReadTrace(BundledPath("fast_swipe"));
  double peak = 0.0;
  double min_z = 1.0;
  for (const TraceSample& s : trace.samples) {
    peak = std::max(peak, s.v_D.norm());
    min_z = std::min(min_z, s.p_D.z());
  }
  EXPECT_NEAR(peak * kDefaultDeviceScale, 2.0, 0.1);
  EXPECT_LT(min_z, -0.005);
}

TEST(GenerateTest, SlowStrokeDragsInContactAtAboutFiveCentimetresPerSecond) {
  const Trace trace = ReadTrace(BundledPath("slow_stroke"));
  // Path length and time spent behind the cloth plane.
  double length = 0.0, time = 0.0, peak = 0.0;
  for (size_t k = 1; k < trace.samples.size(); ++k) {
    const TraceSample& s = trace.samples[k];
    if (s.p_D.z() < -0.005) {
      length += s.v_D.head<2>().norm() * 0.001;
      time += 0.001;
      peak = std::max(peak, s.v_D.head<2>().norm());
    }
  }
  EXPECT_GT(time, 4.0);
  EXPECT_NEAR(length / time, 0.05, 0.015);
  EXPECT_LT(peak, 0.13);  // minimum-jerk peak 9.4 cm/s plus tremor
}

TEST(GenerateTest, PinchDragHoldsButtonZeroWhilePressedIn) {
  const Trace trace = ReadTrace(BundledPath("pinch_drag"));
  double x_min = 1.0, x_max = -1.0;
  for (const TraceSample& s : trace.samples) {
    if (s.buttons & 1u) {
      ASSERT_LT(s.p_D.z(), -0.015);
      x_min = std::min(x_min, s.p_D.x());
      x_max = std::max(x_max, s.p_D.x());
    }
  }
  EXPECT_EQ(trace.samples.front().buttons, 0u);
  EXPECT_EQ(trace.samples.back().buttons, 0u);
  EXPECT_GT(x_max, 0.045);  // dragged sideways and back
  EXPECT_LT(x_min, -0.025);
}

TEST(GenerateTest, CircleStaysOnTheSurface) {
  const Trace trace = ReadTrace(BundledPath("circle"));
  int on_circle = 0;
  for (const TraceSample& s : trace.samples) {
    if (s.p_D.z() < -0.005) {
      ++on_circle;
      ASSERT_NEAR((s.p_D.head<2>() - Eigen::Vector2d(0.0, -0.01)).norm(), 0.03, 0.002);
    }
  }
  EXPECT_GT(on_circle, 5000);
}

}  // namespace
}  // namespace felt
