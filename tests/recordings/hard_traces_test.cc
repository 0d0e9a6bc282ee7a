// The hard pointer traces (recordings/hard/*.trace) and the real pen trace made at test time.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include "recordings/generate.h"
#include "tests/recordings/test_util.h"

namespace felt {
namespace {

constexpr double kHardPi = std::numbers::pi;

std::string HardPath(const std::string& name) {
  return std::string(FELT_SOURCE_DIR "/recordings/hard/") + name + ".trace";
}

// Samples where the position steps more than 1 cm in one sample (5 m/s for 2 ms would be needed
// to come close by hand): the documented jumps.
std::vector<size_t> JumpSamples(const Trace& trace) {
  std::vector<size_t> jumps;
  for (size_t k = 1; k < trace.samples.size(); ++k) {
    if ((trace.samples[k].p_D - trace.samples[k - 1].p_D).norm() > 0.01) jumps.push_back(k);
  }
  return jumps;
}

// Largest deviation [m] of the trapezoid integral of the velocity from the position change since
// the first sample, per axis, over every sample but those in `skip`.
double WorstIntegralDrift(const Trace& trace, const std::vector<size_t>& skip) {
  const auto& s = trace.samples;
  Vec3 integral = Vec3::Zero();
  double worst = 0.0;
  for (size_t k = 1; k < s.size(); ++k) {
    integral += 0.5 * (s[k].t_s - s[k - 1].t_s) * (s[k].v_D + s[k - 1].v_D);
    if (std::find(skip.begin(), skip.end(), k) != skip.end()) continue;
    worst = std::max(worst, (s[k].p_D - s[0].p_D - integral).cwiseAbs().maxCoeff());
  }
  return worst;
}

// The sensor-noise bound of the generated traces on the integral of their velocity: quantisation
// (half a step at each end) + 5 sigma of white noise at each end + rounding to 1 um.
constexpr double kNoiseDrift_m = kEncoderStep_m + 10.0 * kSensorNoiseSigma_m + 1e-5;

class HardTraceTest : public ::testing::TestWithParam<std::string> {};

TEST_P(HardTraceTest, StartsAndEndsAtRestInFrontAndStaysInTheWorkspace) {
  const Trace trace = ReadTrace(HardPath(GetParam()));
  EXPECT_EQ(trace.header.rate_hz(), 1000.0);
  EXPECT_EQ(*trace.header.Get("set"), "hard");
  const auto& s = trace.samples;
  const double duration = s.back().t_s - s.front().t_s;
  EXPECT_GE(duration, 4.0);
  EXPECT_LE(duration, 8.0);
  for (size_t k = 0; k < s.size(); ++k) {
    ASSERT_NEAR(s[k].t_s, static_cast<double>(k) / 1000.0, 1e-12);
    ASSERT_LE(s[k].p_D.cwiseAbs().maxCoeff(), kWorkspaceHalfExtent_m) << k;
    ASSERT_LT(std::fabs(s[k].p_D.x()), kCurtainHalfWidth_m) << k;
    ASSERT_LT(s[k].p_D.y(), kCurtainTopY_m) << k;
  }
  // In front of the cloth, 3-5 cm away, still but for tremor (|v| of the tremor stays under
  // about 5 cm/s) over the first and last 0.3 s.
  for (size_t k : {size_t{0}, size_t{299}, s.size() - 300, s.size() - 1}) {
    SCOPED_TRACE(k);
    EXPECT_GT(s[k].p_D.z(), 0.03);
    EXPECT_LT(s[k].p_D.z(), 0.05);
    EXPECT_LT(s[k].v_D.norm(), 0.06);
    EXPECT_LT((s[k].p_D - s[k < 300 ? 0 : s.size() - 1].p_D).norm(), 0.002);
  }
}

TEST_P(HardTraceTest, VelocityIntegratesToThePositionExceptAtTheJumps) {
  const Trace trace = ReadTrace(HardPath(GetParam()));
  const std::vector<size_t> jumps = JumpSamples(trace);
  EXPECT_EQ(jumps.size(), GetParam() == "jump" ? 2u : 0u);
  // The trapezoid rule integrates a sinusoid sampled every h to (w h / 2) cot(w h / 2) times its
  // true change (w = 2 pi f), so the 250 Hz vibration (4 samples a period) may drift by up to
  // (1 - pi / 4) times its peak-to-peak; every other motion is smooth at 1 kHz.
  const double x = kHardPi * kVibrateFrequency_hz / 1000.0;
  const double vibration =
      GetParam() == "vibrate" ? (1.0 - x / std::tan(x)) * 2.0 * kVibrateAmplitudeZ_m : 0.0;
  EXPECT_LT(WorstIntegralDrift(trace, jumps), kNoiseDrift_m + vibration);
}

INSTANTIATE_TEST_SUITE_P(Hard, HardTraceTest, ::testing::ValuesIn(HardTraceNames()));

TEST(HardTraces, ScrubReachesItsPeakSpeedWhilePressed) {
  const Trace trace = ReadTrace(HardPath("scrub"));
  const auto& s = trace.samples;
  const double peak = 2.0 * kHardPi * kScrubFrequency_hz * kScrubAmplitude_m;  // 0.94 m/s
  double peak_v = 0.0, peak_diff = 0.0, x_min = 1.0, x_max = -1.0;
  int fast = 0;  // samples within 5% of the peak speed
  for (size_t k = 1; k + 1 < s.size(); ++k) {
    const double speed = s[k].v_D.norm();
    // The velocity column, and the positions' central difference: both show the speed.
    const double diff = (s[k + 1].p_D - s[k - 1].p_D).norm() / 0.002;
    peak_v = std::max(peak_v, speed);
    peak_diff = std::max(peak_diff, diff);
    if (speed > 0.95 * peak) {
      ASSERT_LT(s[k].p_D.z(), -0.011) << "fast only while pressed 1.2 cm in, sample " << k;
      ++fast;
    }
    if (s[k].p_D.z() < -0.011) {
      x_min = std::min(x_min, s[k].p_D.x());
      x_max = std::max(x_max, s[k].p_D.x());
    }
  }
  EXPECT_NEAR(peak_v, peak, 0.05);
  EXPECT_NEAR(peak_diff, peak, 0.06);
  EXPECT_GT(fast, 100);  // 18 full-amplitude passes, each fast for about 10 ms
  EXPECT_NEAR(x_max, kScrubAmplitude_m, 0.002);
  EXPECT_NEAR(x_min, -kScrubAmplitude_m, 0.002);
}

TEST(HardTraces, PinDragHoldsOneCentimetreFromTheTopLeftPin) {
  const Trace trace = ReadTrace(HardPath("pin_drag"));
  int near_pin = 0;
  for (const TraceSample& s : trace.samples) {
    const double dx = s.p_D.x() + kCurtainHalfWidth_m;
    const double dy = kCurtainTopY_m - s.p_D.y();
    if (dx < 0.0105 && dy < 0.0105) {
      ++near_pin;
      ASSERT_GT(dx, 0.009);
      ASSERT_GT(dy, 0.009);
      ASSERT_NEAR(s.p_D.z(), -0.015, 0.001);  // pressed 1.5 cm in
    }
  }
  EXPECT_GT(near_pin, 1000);  // held there 1 s
}

TEST(HardTraces, VibrateHasItsFrequencyAndAmplitudeAndAnExactVelocity) {
  const Trace trace = ReadTrace(HardPath("vibrate"));
  const auto& s = trace.samples;
  // The vibration: from the first to the last sample moving faster than 0.3 m/s along z (its
  // speed amplitude is 2 pi f A = 0.63 m/s, 0.44 m/s at the samples' phase; tremor is ~1 cm/s).
  size_t first = 0, last = 0;
  for (size_t k = 0; k < s.size(); ++k) {
    if (std::fabs(s[k].v_D.z()) > 0.3) {
      if (first == 0) first = k;
      last = k;
    }
  }
  ASSERT_GT(first, 0u);
  EXPECT_NEAR((last - first) / 1000.0, 2.0, 0.05);
  // Sign changes of v_z: two per period.
  int crossings = 0;
  for (size_t k = first + 1; k <= last; ++k) {
    crossings += (s[k].v_D.z() > 0.0) != (s[k - 1].v_D.z() > 0.0);
    ASSERT_LT(s[k].p_D.z(), -0.009) << "vibrates while pressed 1 cm in, sample " << k;
  }
  EXPECT_NEAR(crossings / (2.0 * (last - first) / 1000.0), kVibrateFrequency_hz, 2.0);
  // One DFT bin at f over a whole number of periods: amplitude 2 |X| / N; the velocity's bin is
  // i w times the position's if the velocity is the exact derivative (a central difference
  // would give sin(w h) / h = 0.64 w at 4 samples a period).
  const double w = 2.0 * kHardPi * kVibrateFrequency_hz;
  const size_t n = (last - first) / 4 * 4;
  Vec3 mean = Vec3::Zero();
  for (size_t k = first; k < first + n; ++k) mean += s[k].p_D / static_cast<double>(n);
  std::complex<double> pz, vz, px;
  for (size_t k = first; k < first + n; ++k) {
    const std::complex<double> e = std::polar(1.0, -w * s[k].t_s);
    pz += (s[k].p_D.z() - mean.z()) * e;
    vz += s[k].v_D.z() * e;
    px += (s[k].p_D.x() - mean.x()) * e;
  }
  EXPECT_NEAR(2.0 * std::abs(pz) / n, kVibrateAmplitudeZ_m, 0.05 * kVibrateAmplitudeZ_m);
  EXPECT_NEAR(2.0 * std::abs(px) / n, kVibrateAmplitudeX_m, 0.05 * kVibrateAmplitudeX_m);
  const std::complex<double> ratio = vz / (std::complex<double>(0.0, w) * pz);
  EXPECT_NEAR(ratio.real(), 1.0, 0.02);
  EXPECT_NEAR(ratio.imag(), 0.0, 0.02);
  // The 250 Hz bin stands far above its neighbours at 200 and 300 Hz.
  for (double f : {200.0, 300.0}) {
    std::complex<double> other;
    for (size_t k = first; k < first + n; ++k) {
      other += (s[k].p_D.z() - mean.z()) * std::polar(1.0, -2.0 * kHardPi * f * s[k].t_s);
    }
    EXPECT_LT(std::abs(other), 0.02 * std::abs(pz)) << f;
  }
}

TEST(HardTraces, JumpStepsWithinOneSampleAndReportsTheBackwardDifference) {
  const Trace trace = ReadTrace(HardPath("jump"));
  const auto& s = trace.samples;
  const std::vector<size_t> jumps = JumpSamples(trace);
  ASSERT_EQ(jumps.size(), 2u);
  // 4.5 cm sideways while pressed 1 cm in.
  const Vec3 sideways = s[jumps[0]].p_D - s[jumps[0] - 1].p_D;
  EXPECT_NEAR(sideways.x(), 0.045, 0.001);
  EXPECT_NEAR(s[jumps[0]].p_D.z(), -0.01, 0.001);
  EXPECT_NEAR(s[jumps[0] - 1].p_D.z(), -0.01, 0.001);
  // From 2 cm in front of the cloth to 1 cm behind it.
  EXPECT_NEAR(s[jumps[1] - 1].p_D.z(), 0.02, 0.001);
  EXPECT_NEAR(s[jumps[1]].p_D.z(), -0.01, 0.001);
  for (size_t k : jumps) {
    SCOPED_TRACE(k);
    // The first sample after the step reports step / 1 ms (plus tremor), its neighbours not.
    const Vec3 backward = (s[k].p_D - s[k - 1].p_D) / 0.001;
    EXPECT_LT((s[k].v_D - backward).norm(), 0.1);
    EXPECT_LT(s[k - 1].v_D.norm(), 0.1);
    EXPECT_LT(s[k + 1].v_D.norm(), 0.1);
    // The position holds still around the step.
    EXPECT_LT((s[k + 50].p_D - s[k].p_D).norm(), 0.002);
    EXPECT_LT((s[k - 50].p_D - s[k - 1].p_D).norm(), 0.002);
  }
}

TEST(HardTraces, BurstWalkWandersPressedInWithFastBursts) {
  const Trace trace = ReadTrace(HardPath("burst_walk"));
  int pressed = 0, bursts = 0;
  bool in_burst = false;
  double z_sum = 0.0, peak = 0.0;
  Eigen::Vector2d lo(1.0, 1.0), hi(-1.0, -1.0);
  for (const TraceSample& s : trace.samples) {
    if (s.p_D.z() < -0.0005) {
      ++pressed;
      z_sum += s.p_D.z();
      lo = lo.cwiseMin(s.p_D.head<2>());
      hi = hi.cwiseMax(s.p_D.head<2>());
    }
    const double speed = s.v_D.norm();
    peak = std::max(peak, speed);
    // A burst starts above 0.5 m/s and ends below 0.3 m/s.
    if (!in_burst && speed > 0.5) {
      ++bursts;
      in_burst = true;
    } else if (speed < 0.3) {
      in_burst = false;
    }
  }
  EXPECT_GT(pressed, 5000);                      // the 5.3 s walk, pressed in all along
  EXPECT_NEAR(z_sum / pressed, -0.005, 0.0015);  // about 5 mm in
  EXPECT_GE(bursts, 3);
  EXPECT_GT(peak, 0.8);
  EXPECT_LT(peak, 1.3);
  EXPECT_GT((hi - lo).minCoeff(), 0.02);  // wanders over centimetres in x and y
}

TEST(HardTraces, RealPenWritesIntoTheClothInsideTheWorkspace) {
  const std::string dir = test::RealMotionDir();
  if (!std::filesystem::exists(dir + "/" + kRealPenFile)) {
    GTEST_SKIP() << "no real-motion data at " << dir << "/" << kRealPenFile;
  }
  const Trace trace = RealPenTrace(dir);
  EXPECT_NE(trace.header.Get("license")->find("never commit"), std::string::npos);
  const auto& s = trace.samples;
  const double duration = s.back().t_s;
  EXPECT_GT(duration, 4.0);
  EXPECT_LT(duration, 8.0);
  int writing = 0;
  double peak = 0.0;
  Eigen::Vector2d lo(1.0, 1.0), hi(-1.0, -1.0);
  for (size_t k = 0; k < s.size(); ++k) {
    ASSERT_EQ(s[k].t_s, static_cast<double>(k) / 1000.0);
    ASSERT_LE(s[k].p_D.cwiseAbs().maxCoeff(), kWorkspaceHalfExtent_m) << k;
    ASSERT_GE(s[k].p_D.z(), -0.008 - 1e-12) << k;  // never deeper than the press depth
    if (s[k].p_D.z() < -0.008 + 1e-9) {
      ++writing;
      lo = lo.cwiseMin(s[k].p_D.head<2>());
      hi = hi.cwiseMax(s[k].p_D.head<2>());
    }
    peak = std::max(peak, s[k].v_D.norm());
  }
  EXPECT_GT(writing, 2300);  // the 2.3 s trial, pressed 8 mm in
  // Scaled to fit +-5 cm: the larger extent spans it exactly.
  EXPECT_NEAR(std::max(hi.x() - lo.x(), hi.y() - lo.y()), 2.0 * kRealPenHalfExtent_m, 1e-4);
  EXPECT_LE(hi.cwiseAbs().maxCoeff(), kRealPenHalfExtent_m + 1e-4);
  EXPECT_LE(lo.cwiseAbs().maxCoeff(), kRealPenHalfExtent_m + 1e-4);
  EXPECT_GT(peak, 0.4);  // the pen's 0.6 m/s peak, scaled up about 1.4x
  EXPECT_LT(peak, 1.5);
  // At rest in front of the cloth at both ends.
  for (const TraceSample* e : {&s.front(), &s.back()}) {
    EXPECT_GT(e->p_D.z(), 0.03);
    EXPECT_EQ(e->v_D.norm(), 0.0);
  }
  // The velocity is the derivative: the trapezoid integral follows the position to the bound the
  // import tests use on smooth recordings (the handwriting is rough: up to 25 um per step).
  EXPECT_LT(WorstIntegralDrift(trace, {}), 1e-3);
}

TEST(HardTraces, EveryRealPenTrialIsItsOwnWritingAndNoOtherExists) {
  const std::string dir = test::RealMotionDir();
  if (!std::filesystem::exists(dir + "/" + kRealPenFile)) {
    GTEST_SKIP() << "no real-motion data at " << dir << "/" << kRealPenFile;
  }
  const Trace first = RealPenTrace(dir, 1);
  for (int64_t trial = 2; trial <= kRealPenTrials; ++trial) {
    const Trace t = RealPenTrace(dir, trial);
    ASSERT_GT(t.samples.size(), 4000u) << trial;
    double differ = 0.0;
    for (size_t k = 0; k < std::min(t.samples.size(), first.samples.size()); ++k) {
      differ = std::max(differ, (t.samples[k].p_D - first.samples[k].p_D).norm());
    }
    EXPECT_GT(differ, 1e-3) << "trial " << trial << " repeats trial 1";
  }
  EXPECT_ANY_THROW(RealPenTrace(dir, kRealPenTrials + 1));
}

}  // namespace
}  // namespace felt
