#include "recordings/import.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "tests/recordings/test_util.h"

namespace felt {
namespace {

// The velocity column agrees with the positions: over every output step the trapezoid integral of
// the velocity matches the position change, and the central difference of the positions matches
// the velocity. Returns the largest deviations.
struct Consistency {
  double step_integral_m = 0.0;       // max |p_{k+1} - p_k - h (v_k + v_{k+1}) / 2|
  double total_integral_m = 0.0;      // |p_end - p_0 - sum of trapezoids|
  double central_diff_m_per_s = 0.0;  // max |(p_{k+1} - p_{k-1}) / 2h - v_k|
  double max_speed_m_per_s = 0.0;
};

Consistency CheckConsistency(const Trace& trace) {
  Consistency c;
  const auto& s = trace.samples;
  Vec3 integral = Vec3::Zero();
  for (size_t k = 0; k + 1 < s.size(); ++k) {
    const double h = s[k + 1].t_s - s[k].t_s;
    const Vec3 step = 0.5 * h * (s[k].v_D + s[k + 1].v_D);
    integral += step;
    c.step_integral_m = std::max(c.step_integral_m, (s[k + 1].p_D - s[k].p_D - step).norm());
    if (k > 0) {
      const Vec3 central = (s[k + 1].p_D - s[k - 1].p_D) / (s[k + 1].t_s - s[k - 1].t_s);
      c.central_diff_m_per_s = std::max(c.central_diff_m_per_s, (central - s[k].v_D).norm());
    }
    c.max_speed_m_per_s = std::max(c.max_speed_m_per_s, s[k].v_D.norm());
  }
  c.total_integral_m = (s.back().p_D - s.front().p_D - integral).norm();
  return c;
}

// The velocity column is the derivative of the positions. A trapezoid step of the velocity errs
// from the position change by h^3 j / 12 (j the interpolant's third derivative) plus O(h^2) at
// steps that straddle a source sample, and a central difference of the positions errs by
// h^2 j / 6 plus up to h |jump of p''| / 4 at source samples (a C1 interpolant's second
// derivative jumps there). So resampling the same source 10x faster must shrink the largest step
// error about 100x and the largest central-difference error at least about 10x, which a velocity
// taken from anything but the interpolant's derivative (finite differences of other samples, a
// wrong time scale) would not do. For smooth motion (`smooth`) the 1 kHz errors must also be
// small against the motion itself; rough sources (a noisy force profile) have a large j, so there
// only the convergence is checked. Returns the 1 kHz trace.
Trace ExpectVelocityIsTheDerivative(const std::string& path, ImportOptions options, bool smooth) {
  options.rate_hz = 1000.0;
  const Trace trace = ImportTrace(path, options);
  const Consistency c = CheckConsistency(trace);
  if (smooth) {
    EXPECT_LT(c.step_integral_m, 1e-4 * c.max_speed_m_per_s);  // 10% of the largest 1 ms step
    EXPECT_LT(c.total_integral_m, 1e-3);
    EXPECT_LT(c.central_diff_m_per_s, 0.2 * c.max_speed_m_per_s);
  }
  options.rate_hz = 10000.0;
  const Consistency fine = CheckConsistency(ImportTrace(path, options));
  EXPECT_LT(fine.step_integral_m, c.step_integral_m / 50.0);
  EXPECT_LT(fine.total_integral_m, c.total_integral_m / 20.0 + 1e-12);
  EXPECT_LT(fine.central_diff_m_per_s, c.central_diff_m_per_s / 3.0);
  // 1 kHz sampling may miss a sharp speed peak by a few per cent, no more.
  EXPECT_NEAR(fine.max_speed_m_per_s, c.max_speed_m_per_s, 0.06 * c.max_speed_m_per_s);
  return trace;
}

void ExpectUniform(const Trace& trace, double rate_hz) {
  for (size_t k = 0; k < trace.samples.size(); ++k) {
    ASSERT_EQ(trace.samples[k].t_s, static_cast<double>(k) / rate_hz) << k;
  }
}

class RealMotionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::RealMotionDir();
    if (!std::filesystem::is_directory(dir_)) {
      GTEST_SKIP() << "no real-motion data at " << dir_;
    }
  }
  std::string dir_;
};

TEST_F(RealMotionTest, H3dDeviceLogImportsAt1kHz) {
  ImportOptions options;
  options.format = ImportFormat::kDeviceLog;
  const std::string path = dir_ + "/h3dapi_device_log_raw.txt";
  const Trace trace = ImportTrace(path, options);
  // 265 rows over 0 .. 10.6643 s -> 10665 samples at 1 kHz; the log runs at about 24.8 Hz.
  EXPECT_EQ(trace.samples.size(), 10665u);
  ExpectUniform(trace, 1000.0);
  EXPECT_EQ(*trace.header.Get("source_samples"), "265");
  EXPECT_EQ(*trace.header.Get("source"), path);
  const double source_rate = std::stod(*trace.header.Get("source_rate_hz"));
  EXPECT_GT(source_rate, 24.0);
  EXPECT_LT(source_rate, 26.0);
  EXPECT_EQ(trace.header.rate_hz(), 1000.0);
  // Starts at the first logged RAW_POSITION exactly (the interpolant passes through the knots).
  EXPECT_EQ(trace.samples.front().p_D, Vec3(-0.00397507, -0.0248125, -0.0173377));
  // The last output (10.664 s) is 0.3 ms before the last row, where the device is almost still.
  EXPECT_LT((trace.samples.back().p_D - Vec3(0.00149191, -0.0557388, -0.0474162)).norm(), 1e-5);
  ExpectVelocityIsTheDerivative(path, options, true);
  const Consistency c = CheckConsistency(trace);
  // The README's numbers: workspace about +-8 cm, peak speed about 0.27 m/s.
  EXPECT_GT(c.max_speed_m_per_s, 0.15);
  EXPECT_LT(c.max_speed_m_per_s, 0.5);
  for (const TraceSample& s : trace.samples) ASSERT_LT(s.p_D.cwiseAbs().maxCoeff(), 0.1);
}

TEST_F(RealMotionTest, H3dCsvCopyGivesTheSameTraceAsTheRawLog) {
  ImportOptions log_options;
  log_options.format = ImportFormat::kDeviceLog;
  const Trace from_log = ImportTrace(dir_ + "/h3dapi_device_log_raw.txt", log_options);
  ImportOptions csv_options;
  csv_options.format = ImportFormat::kCsv;
  csv_options.SetColumns("t=t_s,x=x_m,y=y_m,z=z_m");
  const Trace from_csv = ImportTrace(dir_ + "/h3dapi_device_log_25Hz.csv", csv_options);
  ASSERT_EQ(from_log.samples.size(), from_csv.samples.size());
  for (size_t k = 0; k < from_log.samples.size(); ++k) {
    ASSERT_EQ(from_log.samples[k], from_csv.samples[k]) << k;
  }
}

TEST_F(RealMotionTest, HandwritOptotrakTrialsSelectedAndConcatenated) {
  ImportOptions options;
  options.format = ImportFormat::kCsv;  // automatic columns: t_ms (x 0.001), x_m, y_m, rep
  options.select_trial = 1;
  const Trace one = ImportTrace(dir_ + "/fda_handwrit_optotrak_600Hz.csv", options);
  // 1401 samples over 2300 ms -> 2301 samples at 1 kHz; the source runs at 1401 / 2.3 s ~ 609 Hz.
  EXPECT_EQ(one.samples.size(), 2301u);
  ExpectUniform(one, 1000.0);
  EXPECT_EQ(*one.header.Get("source_samples_used"), "1401");
  EXPECT_NEAR(std::stod(*one.header.Get("source_rate_hz")), 608.7, 0.2);
  EXPECT_EQ(*one.header.Get("selected_trial"), "1");
  EXPECT_EQ(one.samples.front().p_D, Vec3(-0.0316, -0.0076, 0.0));
  ExpectVelocityIsTheDerivative(dir_ + "/fda_handwrit_optotrak_600Hz.csv", options, true);
  Consistency c = CheckConsistency(one);
  EXPECT_GT(c.max_speed_m_per_s, 0.3);  // README: peak pen speed ~0.6 m/s
  EXPECT_LT(c.max_speed_m_per_s, 1.0);

  // All 20 repetitions, 0.5 s apart: 20 x 2.3 s + 19 x 0.5 s = 55.5 s.
  options.select_trial.reset();
  const Trace all = ImportTrace(dir_ + "/fda_handwrit_optotrak_600Hz.csv", options);
  EXPECT_EQ(all.samples.size(), 55501u);
  EXPECT_EQ(*all.header.Get("trials"), "20");
  EXPECT_EQ(*all.header.Get("source_samples"), "28020");
  c = CheckConsistency(all);
  EXPECT_LT(c.step_integral_m, 1e-4 * c.max_speed_m_per_s);  // bridges between trials too
  EXPECT_LT(c.central_diff_m_per_s, 0.2 * c.max_speed_m_per_s);
  // Trial 1 inside the concatenation is the same as trial 1 alone.
  for (size_t k = 0; k < one.samples.size(); ++k) {
    ASSERT_EQ(all.samples[k].p_D, one.samples[k].p_D) << k;
  }
}

TEST_F(RealMotionTest, StatSciChinesePen3dWithAxisMapping) {
  // x, y on the paper, z the height above it: stand the paper up in the device frame so pen
  // height becomes -z? Here "x,z,-y" maps device (x, y, z) = (x, z, -y)_source, scaled by 0.5.
  ImportOptions options;
  options.format = ImportFormat::kCsv;
  options.select_trial = 7;
  options.axes = ParseAxisMap("x,z,-y");
  options.scale = 0.5;
  options.offset_D_m = Vec3(0.0, 0.01, 0.0);
  const std::string path = dir_ + "/fda_StatSciChinese_pen3d_100Hz.csv";
  const Trace trace = ImportTrace(path, options);
  // 601 samples over 6 s -> 6001 at 1 kHz; source 100 Hz.
  EXPECT_EQ(trace.samples.size(), 6001u);
  ExpectUniform(trace, 1000.0);
  EXPECT_NEAR(std::stod(*trace.header.Get("source_rate_hz")), 100.0, 1e-3);
  EXPECT_EQ(*trace.header.Get("source_samples_used"), "601");
  ExpectVelocityIsTheDerivative(path, options, true);
  // The mapping against the unmapped import at the knots (every 10th output sample is a knot).
  ImportOptions plain;
  plain.format = ImportFormat::kCsv;
  plain.select_trial = 7;
  const Trace raw = ImportTrace(path, plain);
  ASSERT_EQ(raw.samples.size(), trace.samples.size());
  for (size_t k = 0; k < raw.samples.size(); k += 10) {
    const Vec3& q = raw.samples[k].p_D;
    const Vec3 expected = 0.5 * Vec3(q.x(), q.z(), -q.y()) + Vec3(0.0, 0.01, 0.0);
    ASSERT_LT((trace.samples[k].p_D - expected).norm(), 1e-15) << k;
    const Vec3& w = raw.samples[k].v_D;
    ASSERT_LT((trace.samples[k].v_D - 0.5 * Vec3(w.x(), w.z(), -w.y())).norm(), 1e-12) << k;
  }
}

TEST_F(RealMotionTest, PinchForceAsAOneAxisPress) {
  // The pinch force profile (500 Hz) as a press depth: z = -0.002 m/N * force.
  ImportOptions options;
  options.format = ImportFormat::kCsv;
  options.SetColumns("t=t_s,z=force_N");
  options.scale = -0.002;
  options.select_trial = 3;
  const Trace trace = ImportTrace(dir_ + "/fda_pinchraw_force_500Hz.csv", options);
  // 151 samples over 0.3 s -> 301 samples at 1 kHz.
  EXPECT_EQ(trace.samples.size(), 301u);
  EXPECT_NEAR(std::stod(*trace.header.Get("source_rate_hz")), 500.0, 1e-3);
  for (const TraceSample& s : trace.samples) {
    ASSERT_EQ(s.p_D.x(), 0.0);
    ASSERT_EQ(s.p_D.y(), 0.0);
    ASSERT_LT(s.p_D.z(), 0.0);
  }
  ExpectVelocityIsTheDerivative(dir_ + "/fda_pinchraw_force_500Hz.csv", options, false);
}

TEST(ImportTest, NonUniformTimesOfAQuadraticAreReproducedExactly) {
  // Samples of a quadratic at irregular times (milliseconds): the Bessel interpolant reproduces it
  // and its velocity exactly, whatever the spacing.
  const std::string dir = test::ScratchDir("import_quadratic");
  std::string csv = "time_ms,px,py,pz\n";
  const auto f = [](double t) {
    return Vec3(0.01 + 0.02 * t - 0.03 * t * t, -0.02 * t * t, 0.005);
  };
  const double times_ms[] = {0, 3, 4, 11, 30, 31, 45, 70, 72, 100};
  for (double t_ms : times_ms) {
    const Vec3 p = f(t_ms * 1e-3);
    char line[160];
    std::snprintf(line, sizeof line, "%.17g,%.17g,%.17g,%.17g\n", t_ms, p.x(), p.y(), p.z());
    csv += line;
  }
  ImportOptions options;
  options.SetColumns("t=time_ms,x=px,y=py,z=pz");
  options.time_scale = 1e-3;
  options.rate_hz = 2000.0;
  const Trace trace = ImportTrace(test::WriteFile(dir + "/q.csv", csv), options);
  ASSERT_EQ(trace.samples.size(), 201u);
  EXPECT_EQ(*trace.header.Get("gaps"), "0 (steps > 0.07 s)");  // 10 x the 7 ms median
  for (const TraceSample& s : trace.samples) {
    ASSERT_LT((s.p_D - f(s.t_s)).norm(), 1e-15);
    const Vec3 v(0.02 - 0.06 * s.t_s, -0.04 * s.t_s, 0.0);
    ASSERT_LT((s.v_D - v).norm(), 1e-13);
  }
}

TEST(ImportTest, GapsAreBridgedWithoutDifferencingAcrossThem) {
  // A still hand, a 2 s dropout, then a moving hand: the tangent before the gap must stay zero
  // (a difference across the gap would invent motion before it).
  const std::string dir = test::ScratchDir("import_gap");
  std::string csv = "t,x,y\n";
  for (int k = 0; k <= 10; ++k) csv += std::to_string(0.01 * k) + ",0.0,0.0\n";
  for (int k = 0; k <= 10; ++k) {
    csv += std::to_string(2.1 + 0.01 * k) + "," + std::to_string(0.001 * k) + ",0.0\n";
  }
  const Trace trace = ImportTrace(test::WriteFile(dir + "/gap.csv", csv), ImportOptions{});
  EXPECT_EQ(*trace.header.Get("gaps"), "1 (steps > 0.1 s)");
  EXPECT_EQ(trace.samples.size(), 2201u);
  for (size_t k = 0; k <= 100; ++k) {
    ASSERT_EQ(trace.samples[k].p_D, Vec3::Zero()) << k;
    ASSERT_EQ(trace.samples[k].v_D, Vec3::Zero()) << k;
  }
  // Across the bridge the curve stays C1 (no jump in the velocity column at the knots).
  const Consistency c = CheckConsistency(trace);
  EXPECT_LT(c.central_diff_m_per_s, 1e-4);
  EXPECT_NEAR(trace.samples.back().p_D.x(), 0.01, 1e-15);
}

TEST(ImportTest, DuplicateTimesAreDroppedAndCounted) {
  const std::string dir = test::ScratchDir("import_dup");
  const Trace trace = ImportTrace(
      test::WriteFile(dir + "/d.csv", "t_s,x,y\n0,0,0\n0.01,1,0\n0.01,1,0\n0.02,2,0\n"), {});
  EXPECT_EQ(*trace.header.Get("dropped_duplicate_times"), "1");
  EXPECT_EQ(*trace.header.Get("source_samples_used"), "3");
  EXPECT_EQ(trace.samples.size(), 21u);
}

TEST(ImportTest, AxisMapParsing) {
  AxisMap m = ParseAxisMap("xzy");
  EXPECT_EQ(m.source_axis, (std::array<int, 3>{0, 2, 1}));
  m = ParseAxisMap("x,-z,y");
  EXPECT_EQ(m.source_axis, (std::array<int, 3>{0, 2, 1}));
  EXPECT_EQ(m.sign, (std::array<double, 3>{1.0, -1.0, 1.0}));
  m = ParseAxisMap("-y+x-z");
  EXPECT_EQ(m.source_axis, (std::array<int, 3>{1, 0, 2}));
  EXPECT_EQ(m.sign, (std::array<double, 3>{-1.0, 1.0, -1.0}));
  for (const char* bad : {"xy", "xxy", "xyzx", "x,-,y,z", "abc", "--xyz", "xyz-"}) {
    EXPECT_THROW(ParseAxisMap(bad), std::invalid_argument) << bad;
  }
  EXPECT_EQ(ParseImportFormat("devicelog"), ImportFormat::kDeviceLog);
  EXPECT_THROW(ParseImportFormat("bvh"), std::invalid_argument);
  ImportOptions o;
  EXPECT_THROW(o.SetColumns("t=a,w=b"), std::invalid_argument);
  EXPECT_THROW(o.SetColumns("t"), std::invalid_argument);
}

struct BadSource {
  const char* name;
  ImportFormat format;
  std::string text;
  int64_t line;
  const char* message;
};

TEST(ImportTest, MalformedSourcesNameFileLineAndField) {
  const std::string dir = test::ScratchDir("import_bad");
  const std::vector<BadSource> cases = {
      {"csv_backwards", ImportFormat::kCsv, "t_s,x,y\n0,0,0\n0.02,0,0\n0.01,0,0\n", 4,
       "time goes backwards: 0.01 after 0.02"},
      {"csv_non_numeric", ImportFormat::kCsv, "t_s,x,y\n0,0,0\n0.01,0,oops\n", 3,
       "field 3 (y): non-numeric value 'oops'"},
      {"csv_nan", ImportFormat::kCsv, "t_s,x,y\n0,0,0\n0.01,NaN,0\n", 3,
       "field 2 (x): non-finite value 'NaN'"},
      {"csv_columns", ImportFormat::kCsv, "t_s,x,y\n0,0,0\n0.01,0\n", 3,
       "wrong column count: expected 3, got 2"},
      {"csv_no_x", ImportFormat::kCsv, "t_s,a,b\n0,0,0\n", 1, "no column x or x_m"},
      {"csv_no_time", ImportFormat::kCsv, "x,y\n0,0\n", 1, "no time column"},
      {"csv_one_sample", ImportFormat::kCsv, "t_s,x,y\n0,0,0\n", 0, "at least two samples"},
      {"csv_trial_id", ImportFormat::kCsv, "rep,t_s,x,y\n1.5,0,0,0\n", 2,
       "field 1 (rep): trial id must be an integer"},
      {"log_unknown_field", ImportFormat::kDeviceLog, "TIME RAW_POSITION WOBBLE\n0 0 0 0 1\n", 1,
       "unknown field 'WOBBLE'"},
      {"log_no_position", ImportFormat::kDeviceLog, "TIME BUTTONS\n0 0\n", 1,
       "no RAW_POSITION or POSITION"},
      {"log_short_row", ImportFormat::kDeviceLog,
       "TIME RAW_POSITION RAW_ORIENTATION\n0 0 0 0 1 0 0 0\n0.04 0 0 0 1 0 0\n", 3,
       "wrong column count: expected 8, got 7"},
      {"log_bad_value", ImportFormat::kDeviceLog,
       "TIME RAW_POSITION RAW_ORIENTATION\n0 0 0 0 1 0 0 0\n0.04 0 0 0 1 0 0 x\n", 3,
       "field 8 (RAW_ORIENTATION.angle): non-numeric value 'x'"},
      {"log_backwards", ImportFormat::kDeviceLog,
       "TIME RAW_POSITION\n0 0 0 0\n0.04 0 0 0\n0.03 0 0 0\n", 4, "time goes backwards"},
      {"log_negative_buttons", ImportFormat::kDeviceLog,
       "TIME RAW_POSITION BUTTONS\n0 0 0 0 0\n0.04 0 0 0 -1\n", 3,
       "field 5 (BUTTONS): must be an unsigned 32-bit integer"},
      // Finite but absurd (found by tests/recordings/bad_input_test.cc's mutants): a position
      // whose Hermite tangents overflow, a span of 1e15 output samples, a trial whose time
      // cancels its placement offset.
      {"csv_huge_position", ImportFormat::kCsv, "t_s,x,y,z\n0,0,0,0\n0.01,0,0,1e308\n", 3,
       "position (0, 0, 1e+308) m after --scale and --offset is beyond 1000 m"},
      {"csv_huge_span", ImportFormat::kCsv, "t_s,x,y\n0,0,0\n1e12,0,0\n", 0,
       "the source spans 1e+12 s: at 1000 Hz that is more than the 16777216 samples"},
  };
  for (const BadSource& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string path = test::WriteFile(dir + "/" + c.name + ".txt", c.text);
    ImportOptions options;
    options.format = c.format;
    try {
      ImportTrace(path, options);
      ADD_FAILURE() << "no error";
    } catch (const TraceError& e) {
      EXPECT_EQ(e.line(), c.line);
      const std::string prefix = path + (c.line > 0 ? ":" + std::to_string(c.line) : "") + ": ";
      EXPECT_EQ(std::string(e.what()).rfind(prefix, 0), 0u) << e.what();
      EXPECT_NE(std::string(e.what()).find(c.message), std::string::npos) << e.what();
    }
  }
  // A trial starting at a huge source time is still placed --trial-gap after the previous one
  // ends (before, its offset cancelled to 0 and the interpolant refused the times unnamed).
  const Trace placed = ImportTrace(
      test::WriteFile(dir + "/far.csv", "trial,t_s,x,y\n0,0,0,0\n0,0.01,0,0\n1,1e20,0.001,0\n"),
      ImportOptions{});
  EXPECT_EQ(placed.samples.size(), 511u);
  EXPECT_EQ(placed.samples.back().p_D.x(), 0.001);
  // A trial that is not there, and --select without a trial column.
  ImportOptions options;
  options.select_trial = 9;
  EXPECT_THROW(
      ImportTrace(test::WriteFile(dir + "/t.csv", "rep,t_s,x,y\n1,0,0,0\n1,1,0,0\n"), options),
      TraceError);
  EXPECT_THROW(ImportTrace(test::WriteFile(dir + "/n.csv", "t_s,x,y\n0,0,0\n1,0,0\n"), options),
               TraceError);
  options.select_trial.reset();
  options.rate_hz = 0.0;
  EXPECT_THROW(ImportTrace(dir + "/n.csv", options), std::invalid_argument);
}

TEST(ImportTest, DeviceLogButtonsAreSampleAndHold) {
  const std::string dir = test::ScratchDir("import_buttons");
  const std::string path =
      test::WriteFile(dir + "/b.txt",
                      "TIME POSITION VELOCITY BUTTONS\n0 0 0 0 9 9 9 0\n0.0025 0 0 0.001 9 9 9 1\n"
                      "0.005 0 0 0.002 9 9 9 3\n");
  ImportOptions options;
  options.format = ImportFormat::kDeviceLog;
  const Trace trace = ImportTrace(path, options);
  ASSERT_EQ(trace.samples.size(), 6u);
  const uint32_t expected[] = {0, 0, 0, 1, 1, 3};
  for (size_t k = 0; k < 6; ++k) EXPECT_EQ(trace.samples[k].buttons, expected[k]) << k;
  // POSITION (no RAW_POSITION logged) is used; the logged VELOCITY is not (it is recomputed).
  EXPECT_NEAR(trace.samples[5].p_D.z(), 0.002, 1e-15);
  EXPECT_NEAR(trace.samples[2].v_D.z(), 0.4, 1e-12);
}

}  // namespace
}  // namespace felt
