#include "recordings/import.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <stdexcept>
#include <vector>

#include "recordings/hermite.h"

namespace felt {
namespace {

// One source sample after parsing, before mapping.
struct RawSample {
  double t = 0.0;         // source time units
  Vec3 p = Vec3::Zero();  // source position units and axes
  uint32_t buttons = 0;
  int64_t trial = 0;  // trial id (0 when the source has none)
  int64_t line = 0;   // 1-based source line, for messages
};

std::string_view Trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r'))
    s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> Split(std::string_view line, char sep) {
  std::vector<std::string_view> out;
  size_t start = 0;
  while (true) {
    const size_t pos = line.find(sep, start);
    out.push_back(Trim(line.substr(start, pos == std::string_view::npos ? pos : pos - start)));
    if (pos == std::string_view::npos) break;
    start = pos + 1;
  }
  return out;
}

std::vector<std::string_view> SplitWhitespace(std::string_view line) {
  std::vector<std::string_view> out;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    const size_t start = i;
    while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
  return out;
}

// A finite number, or a TraceError naming file, line, field and column name.
double ParseNumber(std::string_view text, const std::string& path, int64_t line, size_t field,
                   std::string_view name) {
  const auto where = [&] {
    return "field " + std::to_string(field + 1) + " (" + std::string(name) + "): ";
  };
  if (text.empty()) throw TraceError(path, line, where() + "empty value");
  double value = 0.0;
  const char* begin = text.data();
  if (*begin == '+') ++begin;  // CSV writers may print a leading '+'
  const auto [ptr, ec] = std::from_chars(begin, text.data() + text.size(), value);
  if (ptr != text.data() + text.size() ||
      (ec != std::errc() && ec != std::errc::result_out_of_range)) {
    throw TraceError(path, line, where() + "non-numeric value '" + std::string(text) + "'");
  }
  if (ec == std::errc::result_out_of_range || !std::isfinite(value)) {
    throw TraceError(path, line, where() + "non-finite value '" + std::string(text) + "'");
  }
  return value;
}

std::string Num(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", value);
  return text;
}

// ---------------------------------------------------------------------------------------------
// CSV

struct ParsedSource {
  std::vector<RawSample> samples;
  double default_time_scale = 1.0;
  bool has_trials = false;
  std::string columns;  // a description of the columns used, for the header
};

int FindColumn(const std::vector<std::string>& names, std::string_view name) {
  for (size_t i = 0; i < names.size(); ++i) {
    if (names[i] == name) return static_cast<int>(i);
  }
  return -1;
}

/// Opens `path` (a text source) and reads its first line, the header, into *header. Throws
/// TraceError naming the file when it cannot be opened (line 0) or is empty (line 1, "empty file:
/// expected " + `expected`).
std::ifstream OpenWithHeader(const std::string& path, const char* expected, std::string* header) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw TraceError(path, 0, "cannot open for reading: " + std::string(strerror(errno)));
  if (!std::getline(in, *header)) {
    throw TraceError(path, 1, std::string("empty file: expected ") + expected);
  }
  return in;
}

ParsedSource ReadCsv(const std::string& path, const ImportOptions& options) {
  std::string line;
  // Header row: column names.
  std::ifstream in = OpenWithHeader(path, "a header row", &line);
  int64_t line_no = 1;
  std::vector<std::string> names;
  for (std::string_view name : Split(line, ',')) names.emplace_back(name);
  for (size_t i = 0; i < names.size(); ++i) {
    if (names[i].empty()) {
      throw TraceError(path, 1, "header row: column " + std::to_string(i + 1) + " has no name");
    }
  }

  // Resolve the columns: explicit names, or the automatic choices.
  ParsedSource out;
  const bool explicit_columns = !options.column_t.empty() || !options.column_x.empty() ||
                                !options.column_y.empty() || !options.column_z.empty();
  const auto require = [&](const std::string& name, const char* what) {
    const int index = FindColumn(names, name);
    if (index < 0) {
      throw TraceError(path, 1,
                       std::string("header row: no column '") + name + "' (for " + what +
                           ") among '" + line + "'");
    }
    return index;
  };
  const auto automatic = [&](std::initializer_list<const char*> candidates) {
    for (const char* name : candidates) {
      const int index = FindColumn(names, name);
      if (index >= 0) return index;
    }
    return -1;
  };
  int col_t = -1;
  std::array<int, 3> col_p = {-1, -1, -1};
  if (!options.column_t.empty()) {
    col_t = require(options.column_t, "t");
  } else {
    col_t = automatic({"t_s", "t", "time", "time_s"});
    if (col_t < 0) {
      col_t = automatic({"t_ms", "time_ms"});
      if (col_t >= 0) out.default_time_scale = 1e-3;
    }
    if (col_t < 0) {
      throw TraceError(path, 1, "header row: no time column (t_s, t, time, t_ms; or --columns t=)");
    }
  }
  const std::array<const std::string*, 3> given = {&options.column_x, &options.column_y,
                                                   &options.column_z};
  const char* const axis_names[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) {
    if (!given[a]->empty()) {
      col_p[a] = require(*given[a], axis_names[a]);
    } else if (!explicit_columns) {
      const std::string plain = axis_names[a];
      col_p[a] = automatic({plain.c_str(), (plain + "_m").c_str()});
      if (col_p[a] < 0 && a < 2) {
        throw TraceError(path, 1,
                         "header row: no column " + plain + " or " + plain +
                             "_m (name it with --columns " + plain + "=NAME)");
      }
    }
  }
  int col_trial = -1;
  if (!options.trial_column.empty()) {
    col_trial = require(options.trial_column, "the trial id");
  } else {
    col_trial = automatic({"rep", "trial", "stroke"});
  }
  out.has_trials = col_trial >= 0;
  out.columns = "t=" + names[static_cast<size_t>(col_t)];
  for (int a = 0; a < 3; ++a) {
    out.columns += std::string(",") + axis_names[a] + "=" +
                   (col_p[a] >= 0 ? names[static_cast<size_t>(col_p[a])] : std::string("(0)"));
  }
  if (col_trial >= 0) out.columns += ",trial=" + names[static_cast<size_t>(col_trial)];

  // Rows.
  while (std::getline(in, line)) {
    ++line_no;
    if (Trim(line).empty()) continue;  // blank lines (often one at the end) carry nothing
    const std::vector<std::string_view> fields = Split(line, ',');
    if (fields.size() != names.size()) {
      throw TraceError(path, line_no,
                       "wrong column count: expected " + std::to_string(names.size()) + ", got " +
                           std::to_string(fields.size()));
    }
    RawSample s;
    s.line = line_no;
    const auto number = [&](int col) {
      const size_t c = static_cast<size_t>(col);
      return ParseNumber(fields[c], path, line_no, c, names[c]);
    };
    s.t = number(col_t);
    for (int a = 0; a < 3; ++a) s.p[a] = col_p[a] >= 0 ? number(col_p[a]) : 0.0;
    if (col_trial >= 0) {
      const double id = number(col_trial);
      if (id != std::floor(id) || std::fabs(id) > 9.0e15) {
        throw TraceError(path, line_no,
                         "field " + std::to_string(col_trial + 1) + " (" +
                             names[static_cast<size_t>(col_trial)] +
                             "): trial id must be an integer");
      }
      s.trial = static_cast<int64_t>(id);
    }
    out.samples.push_back(s);
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// H3D/HAPI DeviceLog text

// Values per field name in a HAPI DeviceLog text row (HAPI's DeviceLog writes the names of the
// logged fields on the first line, then one row per haptic frame: a Vec3 as 3 numbers, a
// Rotation as axis x y z and angle, BUTTONS as one integer).
const std::map<std::string, int, std::less<>>& DeviceLogArity() {
  static const std::map<std::string, int, std::less<>> arity = {
      {"TIME", 1},         {"POSITION", 3},     {"ORIENTATION", 4},
      {"VELOCITY", 3},     {"FORCE", 3},        {"TORQUE", 3},
      {"BUTTONS", 1},      {"RAW_POSITION", 3}, {"RAW_ORIENTATION", 4},
      {"RAW_VELOCITY", 3}, {"RAW_FORCE", 3},    {"RAW_TORQUE", 3}};
  return arity;
}

ParsedSource ReadDeviceLog(const std::string& path) {
  std::string line;
  // The first line names the logged fields.
  std::ifstream in = OpenWithHeader(path, "a DeviceLog header", &line);
  int64_t line_no = 1;
  const std::vector<std::string_view> tokens = SplitWhitespace(line);
  if (tokens.empty()) throw TraceError(path, 1, "DeviceLog header: no field names");
  std::vector<std::string> column_names;  // one per number, e.g. RAW_POSITION.x
  int col_t = -1, col_pos = -1, col_raw_pos = -1, col_buttons = -1;
  for (std::string_view token : tokens) {
    const auto it = DeviceLogArity().find(token);
    if (it == DeviceLogArity().end()) {
      throw TraceError(path, 1,
                       "DeviceLog header: unknown field '" + std::string(token) +
                           "' (a binary DeviceLog cannot be imported; log as text)");
    }
    const int first = static_cast<int>(column_names.size());
    if (token == "TIME") col_t = first;
    if (token == "POSITION") col_pos = first;
    if (token == "RAW_POSITION") col_raw_pos = first;
    if (token == "BUTTONS") col_buttons = first;
    static const char* const kSuffix[4] = {".x", ".y", ".z", ".angle"};
    for (int i = 0; i < it->second; ++i) {
      column_names.push_back(std::string(token) + (it->second == 1 ? "" : kSuffix[i]));
    }
  }
  if (col_t < 0) throw TraceError(path, 1, "DeviceLog header: no TIME field");
  // RAW_POSITION is in the device's own coordinates; POSITION has H3D's calibration applied.
  const int col_p = col_raw_pos >= 0 ? col_raw_pos : col_pos;
  if (col_p < 0) throw TraceError(path, 1, "DeviceLog header: no RAW_POSITION or POSITION field");

  ParsedSource out;
  out.columns = std::string("TIME,") + (col_raw_pos >= 0 ? "RAW_POSITION" : "POSITION") +
                (col_buttons >= 0 ? ",BUTTONS" : "");
  while (std::getline(in, line)) {
    ++line_no;
    const std::vector<std::string_view> fields = SplitWhitespace(line);
    if (fields.empty()) continue;
    if (fields.size() != column_names.size()) {
      throw TraceError(path, line_no,
                       "wrong column count: expected " + std::to_string(column_names.size()) +
                           ", got " + std::to_string(fields.size()));
    }
    RawSample s;
    s.line = line_no;
    for (size_t c = 0; c < fields.size(); ++c) {
      ParseNumber(fields[c], path, line_no, c, column_names[c]);  // every value is checked
    }
    const auto number = [&](int col) {
      const size_t c = static_cast<size_t>(col);
      return ParseNumber(fields[c], path, line_no, c, column_names[c]);
    };
    s.t = number(col_t);
    for (int a = 0; a < 3; ++a) s.p[a] = number(col_p + a);
    if (col_buttons >= 0) {
      const double b = number(col_buttons);
      if (b < 0.0 || b != std::floor(b) || b > 4294967295.0) {
        throw TraceError(path, line_no,
                         "field " + std::to_string(col_buttons + 1) +
                             " (BUTTONS): must be an unsigned 32-bit integer");
      }
      s.buttons = static_cast<uint32_t>(b);
    }
    out.samples.push_back(s);
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// MCAP: one pose topic (recordings/mcap_trace.h), times in s and positions in m already.

ParsedSource ReadMcapSource(const std::string& path, const ImportOptions& options) {
  McapTraceOptions mcap;
  mcap.topic = options.mcap_topic;
  mcap.time = options.mcap_time;
  McapTraceInfo info;
  const Trace trace = ReadMcapTrace(path, mcap, &info);
  ParsedSource source;
  source.columns = info.topic + " (" + info.type + ")";
  int64_t index = 0;
  for (const TraceSample& s : trace.samples) {
    source.samples.push_back({s.t_s, s.p_D, s.buttons, 0, ++index});
  }
  return source;
}

}  // namespace

ImportFormat ParseImportFormat(std::string_view text) {
  if (text == "devicelog") return ImportFormat::kDeviceLog;
  if (text == "csv") return ImportFormat::kCsv;
  if (text == "mcap") return ImportFormat::kMcap;
  throw std::invalid_argument("--format must be 'devicelog', 'csv' or 'mcap', not '" +
                              std::string(text) + "'");
}

AxisMap ParseAxisMap(std::string_view text) {
  AxisMap map;
  const auto fail = [&](const std::string& why) {
    throw std::invalid_argument("--axes '" + std::string(text) + "': " + why +
                                " (expected a signed permutation of x, y, z, e.g. \"x,-z,y\")");
  };
  int count = 0;
  bool used[3] = {false, false, false};
  double sign = 1.0;
  bool have_sign = false;
  for (char c : text) {
    if (c == ',' || c == ' ') {
      if (have_sign) fail("a sign without an axis");
      continue;
    }
    if (c == '-' || c == '+') {
      if (have_sign) fail("two signs in a row");
      sign = c == '-' ? -1.0 : 1.0;
      have_sign = true;
      continue;
    }
    const int axis = c == 'x' ? 0 : c == 'y' ? 1 : c == 'z' ? 2 : -1;
    if (axis < 0) fail(std::string("unknown character '") + c + "'");
    if (count >= 3) fail("more than three axes");
    if (used[axis]) fail(std::string("axis ") + c + " used twice");
    used[axis] = true;
    map.source_axis[static_cast<size_t>(count)] = axis;
    map.sign[static_cast<size_t>(count)] = sign;
    ++count;
    sign = 1.0;
    have_sign = false;
  }
  if (have_sign) fail("a sign without an axis");
  if (count != 3) fail("needs all three axes");
  return map;
}

void ImportOptions::SetColumns(std::string_view text) {
  for (std::string_view item : Split(text, ',')) {
    const size_t eq = item.find('=');
    if (eq == std::string_view::npos) {
      throw std::invalid_argument("--columns item '" + std::string(item) + "' is not KEY=NAME");
    }
    const std::string_view key = Trim(item.substr(0, eq));
    const std::string name(Trim(item.substr(eq + 1)));
    if (name.empty()) throw std::invalid_argument("--columns item '" + std::string(item) + "'");
    if (key == "t") {
      column_t = name;
    } else if (key == "x") {
      column_x = name;
    } else if (key == "y") {
      column_y = name;
    } else if (key == "z") {
      column_z = name;
    } else {
      throw std::invalid_argument("--columns key '" + std::string(key) +
                                  "' must be one of t, x, y, z");
    }
  }
}

Trace ImportTrace(const std::string& path, const ImportOptions& options) {
  if (!(options.rate_hz > 0.0) || !std::isfinite(options.rate_hz)) {
    throw std::invalid_argument("--rate must be a finite number > 0");
  }
  if (!std::isfinite(options.scale) || options.scale == 0.0 || !options.offset_D_m.allFinite()) {
    throw std::invalid_argument("--scale must be finite and non-zero, --offset finite");
  }
  if (options.time_scale && (!std::isfinite(*options.time_scale) || *options.time_scale <= 0.0)) {
    throw std::invalid_argument("--time-scale must be a finite number > 0");
  }
  if (!(options.trial_gap_s > 0.0) || !std::isfinite(options.trial_gap_s)) {
    throw std::invalid_argument("--trial-gap must be a finite number > 0");
  }

  // Parse the source.
  ParsedSource source = options.format == ImportFormat::kCsv    ? ReadCsv(path, options)
                        : options.format == ImportFormat::kMcap ? ReadMcapSource(path, options)
                                                                : ReadDeviceLog(path);
  const double time_scale = options.time_scale.value_or(source.default_time_scale);
  std::vector<RawSample>& raw = source.samples;
  const size_t raw_count = raw.size();

  // Keep one trial if asked.
  if (options.select_trial) {
    if (!source.has_trials) {
      throw TraceError(path, 1,
                       "--select needs a trial column (rep, trial, stroke or --trial-column)");
    }
    std::erase_if(raw, [&](const RawSample& s) { return s.trial != *options.select_trial; });
    if (raw.empty()) {
      throw TraceError(path, 0, "no trial " + std::to_string(*options.select_trial));
    }
  }

  // Runs: maximal blocks of one trial. Within a run times must increase; an equal time drops the
  // later sample (loggers repeat a sample when the device did not update); a backwards time is an
  // error.
  std::vector<double> t;          // mapped time [s], trials concatenated
  std::vector<Vec3> p;            // mapped position [m, device frame]
  std::vector<uint32_t> buttons;  // per knot
  std::vector<size_t> run_start;  // knot index where each run starts
  int64_t dropped_duplicates = 0;
  int64_t trials = 0;
  double time_offset = 0.0;  // added to the mapped time of the current trial
  for (size_t i = 0; i < raw.size(); ++i) {
    const RawSample& s = raw[i];
    const bool new_trial = i == 0 || s.trial != raw[i - 1].trial;
    double t_s = time_scale * s.t;
    if (new_trial) {
      ++trials;
      // The next trial starts trial_gap_s after the previous one ends.
      time_offset = i == 0 ? 0.0 : t.back() + options.trial_gap_s - t_s;
      run_start.push_back(t.size());
    } else if (!(s.t >= raw[i - 1].t)) {
      throw TraceError(path, s.line,
                       "time goes backwards: " + Num(s.t) + " after " + Num(raw[i - 1].t));
    } else if (s.t == raw[i - 1].t) {
      ++dropped_duplicates;
      continue;
    }
    t_s += time_offset;
    if (new_trial && !t.empty()) {
      t_s = t.back() + options.trial_gap_s;  // exactly (t_s + offset may round off a huge time)
      if (!(t_s > t.back())) {
        throw TraceError(path, s.line,
                         "trial " + std::to_string(s.trial) + " cannot follow the previous " +
                             "trial's end at " + Num(t.back()) + " s by " +
                             Num(options.trial_gap_s) + " s (a corrupt time?)");
      }
    }
    if (!new_trial && !(t_s > t.back())) {
      // Distinct source times that map to the same double (absurd time scales).
      ++dropped_duplicates;
      continue;
    }
    Vec3 mapped;
    for (int a = 0; a < 3; ++a) {
      mapped[a] = options.axes.sign[static_cast<size_t>(a)] *
                  s.p[options.axes.source_axis[static_cast<size_t>(a)]];
    }
    const Vec3 p_D = options.scale * mapped + options.offset_D_m;
    // MCAP samples are numbered by message, the text sources by line.
    const auto fail = [&](const std::string& message) {
      if (options.format != ImportFormat::kMcap) throw TraceError(path, s.line, message);
      throw TraceError(path, 0, "message " + std::to_string(s.line) + ": " + message);
    };
    if (!std::isfinite(t_s)) fail("time " + Num(s.t) + " is not finite once scaled");
    if (!(p_D.cwiseAbs().maxCoeff() <= kMaxImportPosition_m)) {
      fail("position (" + Num(p_D.x()) + ", " + Num(p_D.y()) + ", " + Num(p_D.z()) +
           ") m after --scale and --offset is beyond " + Num(kMaxImportPosition_m) +
           " m (a corrupt value, or the wrong --scale)");
    }
    t.push_back(t_s);
    p.push_back(p_D);
    buttons.push_back(s.buttons);
  }
  if (t.size() < 2) {
    throw TraceError(
        path, 0, "needs at least two samples with distinct times, has " + std::to_string(t.size()));
  }

  // The median step within runs: the source rate, and the default gap threshold.
  std::vector<double> steps;
  {
    size_t run = 0;
    for (size_t k = 1; k < t.size(); ++k) {
      while (run + 1 < run_start.size() && run_start[run + 1] <= k) ++run;
      if (run_start[run] != k) steps.push_back(t[k] - t[k - 1]);
    }
  }
  if (steps.empty()) throw TraceError(path, 0, "every trial holds a single sample");
  std::nth_element(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2),
                   steps.end());
  const double median_step_s = steps[steps.size() / 2];
  const double max_gap_s = options.max_gap_s > 0.0 ? options.max_gap_s : 10.0 * median_step_s;

  // Split runs at gaps longer than max_gap_s.
  int64_t gaps = 0;
  {
    std::vector<size_t> starts;
    size_t run = 0;
    for (size_t k = 0; k < t.size(); ++k) {
      const bool trial_start = run < run_start.size() && run_start[run] == k;
      if (trial_start) {
        ++run;
        starts.push_back(k);
      } else if (t[k] - t[k - 1] > max_gap_s) {
        ++gaps;
        starts.push_back(k);
      }
    }
    run_start = std::move(starts);
  }

  // Bessel tangents per run: never differenced across a trial boundary or a gap.
  std::vector<Vec3> m(t.size(), Vec3::Zero());
  for (size_t r = 0; r < run_start.size(); ++r) {
    const size_t begin = run_start[r];
    const size_t end = r + 1 < run_start.size() ? run_start[r + 1] : t.size();
    const std::vector<Vec3> tangents =
        BesselTangents(std::span<const double>(t).subspan(begin, end - begin),
                       std::span<const Vec3>(p).subspan(begin, end - begin));
    std::copy(tangents.begin(), tangents.end(), m.begin() + static_cast<std::ptrdiff_t>(begin));
  }
  const double t_first = t.front();
  const double duration_s = t.back() - t_first;
  const HermiteCurve curve(t, p, m);

  // Resample at k / rate: position and velocity from the interpolant, buttons sample-and-hold.
  Trace trace;
  const double steps_out = std::floor(duration_s * options.rate_hz + 1e-9);
  if (!(steps_out < static_cast<double>(kMaxImportSamples))) {
    throw TraceError(path, 0,
                     "the source spans " + Num(duration_s) + " s: at " + Num(options.rate_hz) +
                         " Hz that is more than the " + std::to_string(kMaxImportSamples) +
                         " samples an import makes (a corrupt time, or select one trial or a "
                         "lower --rate)");
  }
  const int64_t count = static_cast<int64_t>(steps_out) + 1;
  trace.samples.reserve(static_cast<size_t>(count));
  size_t hold = 0;
  for (int64_t k = 0; k < count; ++k) {
    const double t_out = static_cast<double>(k) / options.rate_hz;
    const double t_src = t_first + t_out;
    while (hold + 1 < t.size() && t[hold + 1] <= t_src) ++hold;
    const CurvePoint point = curve.Evaluate(t_src);
    if (!point.p.allFinite() || !point.v.allFinite()) {
      // Bounded positions over steps so short that a tangent overflows (times 1e-300 s apart).
      throw TraceError(path, 0,
                       "the interpolant is not finite at t = " + Num(t_out) +
                           " s (source samples too close in time for their positions)");
    }
    trace.samples.push_back({t_out, point.p, point.v, buttons[hold]});
  }

  // Header: where it came from and how it was mapped.
  trace.header = MakeTraceHeader(options.rate_hz, options.device, path);
  TraceHeader& h = trace.header;
  h.Set("source_format", options.format == ImportFormat::kCsv    ? "csv"
                         : options.format == ImportFormat::kMcap ? "mcap"
                                                                 : "devicelog");
  h.Set("source_columns", source.columns);
  h.Set("source_rate_hz", Num(1.0 / median_step_s));
  h.Set("source_samples", std::to_string(raw_count));
  h.Set("source_samples_used", std::to_string(t.size()));
  if (dropped_duplicates > 0) h.Set("dropped_duplicate_times", std::to_string(dropped_duplicates));
  if (source.has_trials) {
    h.Set("trials", std::to_string(trials));
    if (options.select_trial) {
      h.Set("selected_trial", std::to_string(*options.select_trial));
    } else {
      h.Set("trial_gap_s", Num(options.trial_gap_s));
    }
  }
  h.Set("gaps", std::to_string(gaps) + " (steps > " + Num(max_gap_s) + " s)");
  std::string axes;
  for (size_t a = 0; a < 3; ++a) {
    if (a > 0) axes += ",";
    axes += options.axes.sign[a] < 0 ? "-" : "";
    axes += "xyz"[options.axes.source_axis[a]];
  }
  h.Set("mapping", "t_s = " + Num(time_scale) + " * t_source - " + Num(t_first) +
                       " s; p_D = " + Num(options.scale) + " * (" + axes + ")_source + (" +
                       Num(options.offset_D_m.x()) + ", " + Num(options.offset_D_m.y()) + ", " +
                       Num(options.offset_D_m.z()) + ") m");
  h.Set("interpolant",
        "C1 cubic Hermite, Bessel (3-point parabola) tangents; velocity = its derivative");
  return trace;
}

}  // namespace felt
