#include "recordings/trace.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <new>
#include <random>
#include <string>
#include <vector>

#include "tests/alloc_counter.h"
#include "tests/recordings/test_util.h"

namespace felt {
namespace {

const char kGoodHeader[] =
    "# felt-trace v1\n"
    "# units: m, s, m/s\n"
    "# rate_hz: 1000\n"
    "# device: test\n"
    "# source: unit test\n"
    "# frame: device\n"
    "t_s,x,y,z,vx,vy,vz,buttons\n";  // the column line is line 7

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

TEST(TraceTest, RoundTripIsBitwise) {
  const std::string dir = test::ScratchDir("round_trip");
  Trace trace;
  trace.header = MakeTraceHeader(1000.0, "touch", "unit test, with: colons");
  trace.header.Set("extra_key", "  leading spaces kept after the first");
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double awkward[] = {
      1.0 / 3.0, -2.0 / 7.0,   1e-300, -4.9e-324, 0.1, 123456.789e-9, std::nextafter(0.05, 1.0),
      0.0,       6.02214076e23};
  double t = -0.5;  // times may start anywhere
  for (int k = 0; k < 2000; ++k) {
    TraceSample s;
    t = std::nextafter(t + 0.001 * (1.0 + u(rng) * 0.5), 1e9);
    s.t_s = t;
    for (int a = 0; a < 3; ++a) {
      s.p_D[a] = k < 9 ? awkward[(k + a) % 9] : 0.08 * u(rng);
      s.v_D[a] = k < 9 ? -awkward[(k + 2 * a) % 9] : u(rng) * std::pow(10.0, 3.0 * u(rng));
    }
    s.buttons = k == 5 ? std::numeric_limits<uint32_t>::max() : static_cast<uint32_t>(k % 4);
    trace.samples.push_back(s);
  }
  const std::string path = dir + "/rt.trace";
  WriteTrace(path, trace);
  const Trace back = ReadTrace(path);
  EXPECT_EQ(back.header.entries, trace.header.entries);
  ASSERT_EQ(back.samples.size(), trace.samples.size());
  for (size_t k = 0; k < trace.samples.size(); ++k) {
    const TraceSample& a = trace.samples[k];
    const TraceSample& b = back.samples[k];
    ASSERT_TRUE(SameBits(a.t_s, b.t_s)) << k;
    for (int i = 0; i < 3; ++i) {
      ASSERT_TRUE(SameBits(a.p_D[i], b.p_D[i])) << k << " " << i;
      ASSERT_TRUE(SameBits(a.v_D[i], b.v_D[i])) << k << " " << i;
    }
    ASSERT_EQ(a.buttons, b.buttons);
  }
  // Writing what was read gives the same bytes.
  WriteTrace(dir + "/rt2.trace", back);
  EXPECT_EQ(test::ReadFile(path), test::ReadFile(dir + "/rt2.trace"));
}

TEST(TraceTest, FixedDecimalsTrimZerosAndNeverPrintMinusZero) {
  std::string out;
  AppendTraceNumber(0.001, 6, &out);
  out += ' ';
  AppendTraceNumber(-0.0000001, 6, &out);
  out += ' ';
  AppendTraceNumber(2.0, 6, &out);
  out += ' ';
  AppendTraceNumber(-0.0123456789, 6, &out);
  out += ' ';
  AppendTraceNumber(0.1, -1, &out);
  EXPECT_EQ(out, "0.001 0 2 -0.012346 0.1");
}

TEST(TraceTest, WriterRejectsTimesThatPrintEqualOrGoBack) {
  const std::string dir = test::ScratchDir("writer_times");
  TraceWriter writer(dir + "/w.trace", MakeTraceHeader(1000, "d", "s"), TraceWriteOptions{3});
  writer.Write({0.001, Vec3::Zero(), Vec3::Zero(), 0});
  EXPECT_THROW(writer.Write({0.0012, Vec3::Zero(), Vec3::Zero(), 0}), std::invalid_argument);
  EXPECT_THROW(writer.Write({0.0005, Vec3::Zero(), Vec3::Zero(), 0}), std::invalid_argument);
  EXPECT_THROW(writer.Write({0.002, Vec3(NAN, 0, 0), Vec3::Zero(), 0}), std::invalid_argument);
  writer.Write({0.002, Vec3::Zero(), Vec3::Zero(), 0});
  writer.Close();
  EXPECT_EQ(ReadTrace(dir + "/w.trace").samples.size(), 2u);
}

TEST(TraceTest, AcceptsCrLfLineEnds) {
  const std::string dir = test::ScratchDir("crlf");
  std::string text = kGoodHeader;
  text += "0,0,0,0,0,0,0,0\n0.001,1,2,3,4,5,6,7\n";
  std::string crlf;
  for (char c : text) {
    if (c == '\n') crlf += '\r';
    crlf += c;
  }
  const Trace trace = ReadTrace(test::WriteFile(dir + "/crlf.trace", crlf));
  ASSERT_EQ(trace.samples.size(), 2u);
  EXPECT_EQ(trace.samples[1].p_D, Vec3(1, 2, 3));
  EXPECT_EQ(trace.samples[1].buttons, 7u);
  EXPECT_EQ(*trace.header.Get("source"), "unit test");
}

struct BadCase {
  const char* name;
  std::string text;
  int64_t line;         // expected TraceError::line()
  const char* message;  // expected to appear after "PATH:LINE: "
};

TEST(TraceTest, EveryMalformedFileErrorNamesFileLineAndField) {
  const std::string dir = test::ScratchDir("malformed");
  const std::string h = kGoodHeader;
  const std::string ok = "0,0,0,0,0,0,0,0\n";
  const std::vector<BadCase> cases = {
      {"empty", "", 0, "empty file"},
      {"bad_magic", "# felt-trace v2\n" + h.substr(16), 1, "bad header: first line must be"},
      {"no_magic", "t_s,x,y,z,vx,vy,vz,buttons\n" + ok, 1, "bad header: first line must be"},
      {"header_no_space", "# felt-trace v1\n#units: m, s, m/s\n", 2, "expected '# key: value'"},
      {"header_no_colon", "# felt-trace v1\n# units m\n", 2, "(no ':')"},
      {"header_empty_key", "# felt-trace v1\n# : m\n", 2, "key must be non-empty"},
      {"duplicate_key", h.substr(0, 35) + "# units: m, s, m/s\n" + h.substr(35), 3,
       "duplicate key 'units'"},
      {"missing_rate",
       "# felt-trace v1\n# units: m, s, m/s\n# device: d\n# source: s\n"
       "# frame: device\nt_s,x,y,z,vx,vy,vz,buttons\n" +
           ok,
       6, "missing required key 'rate_hz'"},
      {"bad_units",
       "# felt-trace v1\n# units: mm, s, mm/s\n# rate_hz: 1000\n# device: d\n"
       "# source: s\n# frame: device\nt_s,x,y,z,vx,vy,vz,buttons\n" +
           ok,
       7, "units must be 'm, s, m/s'"},
      {"bad_frame",
       "# felt-trace v1\n# units: m, s, m/s\n# rate_hz: 1000\n# device: d\n"
       "# source: s\n# frame: world\nt_s,x,y,z,vx,vy,vz,buttons\n" +
           ok,
       7, "frame must be 'device'"},
      {"bad_rate",
       "# felt-trace v1\n# units: m, s, m/s\n# rate_hz: fast\n# device: d\n"
       "# source: s\n# frame: device\nt_s,x,y,z,vx,vy,vz,buttons\n" +
           ok,
       7, "rate_hz must be a finite number > 0"},
      {"no_column_line", h.substr(0, h.size() - 27), 6, "missing the column line"},
      {"wrong_column_line", h.substr(0, h.size() - 27) + "t,x,y,z\n" + ok, 7,
       "expected a '# key: value' line or the column line"},
      {"too_few_columns", h + ok + "0.001,0,0,0,0,0,0\n", 9,
       "wrong column count: expected 8 fields (t_s,x,y,z,vx,vy,vz,buttons), got 7"},
      {"too_many_columns", h + "0,0,0,0,0,0,0,0,0\n", 8, "wrong column count: expected 8 fields"},
      {"non_numeric", h + ok + "0.001,0,abc,0,0,0,0,0\n", 9,
       "field 3 (y): non-numeric value 'abc'"},
      {"trailing_junk", h + "0,0,0,0,0.5m,0,0,0\n", 8, "field 5 (vx): non-numeric value '0.5m'"},
      {"space_in_field", h + "0, 0,0,0,0,0,0,0\n", 8, "field 2 (x): non-numeric value ' 0'"},
      {"nan", h + ok + "0.001,0,0,nan,0,0,0,0\n", 9, "field 4 (z): non-finite value 'nan'"},
      {"inf", h + "0,0,0,0,0,-inf,0,0\n", 8, "field 6 (vy): non-finite value '-inf'"},
      {"overflow", h + "0,0,0,0,0,0,1e999,0\n", 8, "field 7 (vz): non-finite value '1e999'"},
      {"empty_field", h + "0,0,,0,0,0,0,0\n", 8, "field 3 (y): empty value"},
      {"backwards", h + ok + "0.002,0,0,0,0,0,0,0\n0.001,0,0,0,0,0,0,0\n", 10,
       "field 1 (t_s): time goes backwards: t_s 0.001 after 0.002"},
      {"duplicate_time", h + ok + "0.001,0,0,0,0,0,0,0\n0.001,0,0,0,0,0,0,0\n", 10,
       "field 1 (t_s): duplicate time"},
      {"negative_buttons", h + ok + "0.001,0,0,0,0,0,0,-1\n", 9,
       "field 8 (buttons): negative buttons '-1'"},
      {"fractional_buttons", h + "0,0,0,0,0,0,0,1.5\n", 8,
       "field 8 (buttons): buttons must be an unsigned integer bit mask, got '1.5'"},
      {"huge_buttons", h + "0,0,0,0,0,0,0,4294967296\n", 8,
       "field 8 (buttons): buttons '4294967296' do not fit in 32 bits"},
      {"empty_line", h + ok + "\n0.001,0,0,0,0,0,0,0\n", 9, "empty line"},
      {"no_samples", h, 7, "no samples after the header"},
  };
  for (const BadCase& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string path = test::WriteFile(dir + "/" + c.name + ".trace", c.text);
    try {
      const Trace trace = ReadTrace(path);
      ADD_FAILURE() << "no error; read " << trace.samples.size() << " samples";
    } catch (const TraceError& e) {
      EXPECT_EQ(e.file(), path);
      EXPECT_EQ(e.line(), c.line);
      const std::string prefix = path + (c.line > 0 ? ":" + std::to_string(c.line) : "") + ": ";
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(prefix, 0), 0u) << what;
      EXPECT_NE(what.find(c.message), std::string::npos) << what;
    }
  }
  // A file that does not exist.
  try {
    ReadTrace(dir + "/missing.trace");
    ADD_FAILURE() << "no error";
  } catch (const TraceError& e) {
    EXPECT_EQ(e.line(), 0);
    EXPECT_NE(std::string(e.what()).find("missing.trace: cannot open"), std::string::npos);
  }
}

TEST(TraceTest, ReaderStreamsGoodLinesButReadTraceUsesNothingPartial) {
  const std::string dir = test::ScratchDir("partial");
  const std::string path =
      test::WriteFile(dir + "/p.trace", std::string(kGoodHeader) +
                                            "0,0,0,0,0,0,0,0\n0.001,0,0,0,0,0,0,0\n"
                                            "0.002,0,0,0,0,0,0,0\n0.003,0,0,0,0,0,0\n");
  TraceReader reader(path);
  TraceSample s;
  for (int k = 0; k < 3; ++k) ASSERT_TRUE(reader.Next(&s));
  EXPECT_EQ(s.t_s, 0.002);
  EXPECT_THROW(reader.Next(&s), TraceError);
  EXPECT_THROW(ReadTrace(path), TraceError);
}

TEST(TraceTest, StreamingReaderUsesBoundedMemoryOnALargeFile) {
  // 400 000 samples (400 s at 1 kHz, about 40 MB written with full precision).
  const std::string dir = test::ScratchDir("large");
  const std::string path = dir + "/large.trace";
  constexpr int64_t kSamples = 400000;
  {
    TraceWriter writer(path, MakeTraceHeader(1000.0, "synthetic", "large file test"));
    for (int64_t k = 0; k < kSamples; ++k) {
      const double t = static_cast<double>(k) / 1000.0;
      writer.Write({t, Vec3(0.05 * std::sin(t), 0.05 * std::cos(1.3 * t), -0.01 / 3.0 * t),
                    Vec3(0.05 * std::cos(t), -0.065 * std::sin(1.3 * t), -0.01 / 3.0),
                    static_cast<uint32_t>(k & 3)});
    }
    writer.Close();
  }
  TraceReader reader(path);
  TraceSample s;
  // Warm up: the line buffer grows to the longest line seen.
  for (int k = 0; k < 1000; ++k) ASSERT_TRUE(reader.Next(&s));
  const AllocationGuard guard;  // tests/alloc_counter.h
  int64_t count = 1000;
  double checksum = 0.0;
  while (reader.Next(&s)) {
    ++count;
    checksum += s.p_D.x();
  }
  const int64_t allocations = static_cast<int64_t>(guard.allocations());
  EXPECT_EQ(count, kSamples);
  EXPECT_EQ(reader.samples_read(), kSamples);
  EXPECT_EQ(s.t_s, static_cast<double>(kSamples - 1) / 1000.0);
  EXPECT_TRUE(std::isfinite(checksum));
  // Lines are at most a few bytes longer than the warm-up ones; a handful of buffer regrowths at
  // most, never one per sample.
  EXPECT_LE(allocations, 8) << "the reader allocates while streaming";
}

TEST(TraceTest, HeaderSetRejectsKeysThatWouldCorruptTheFile) {
  TraceHeader h;
  EXPECT_THROW(h.Set("", "v"), std::invalid_argument);
  EXPECT_THROW(h.Set("a b", "v"), std::invalid_argument);
  EXPECT_THROW(h.Set("a:b", "v"), std::invalid_argument);
  EXPECT_THROW(h.Set("k", "two\nlines"), std::invalid_argument);
  h.Set("k", "1");
  h.Set("k", "2");
  ASSERT_EQ(h.entries.size(), 1u);
  EXPECT_EQ(*h.Get("k"), "2");
  EXPECT_FALSE(h.Get("other").has_value());
  EXPECT_THROW(h.rate_hz(), std::invalid_argument);
  h.Set("rate_hz", "-5");
  EXPECT_THROW(h.rate_hz(), std::invalid_argument);
  h.Set("rate_hz", "600");
  EXPECT_EQ(h.rate_hz(), 600.0);
}

}  // namespace
}  // namespace felt
