#include "recordings/trace.h"

#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <system_error>

namespace felt {
namespace {

constexpr std::array<const char*, 8> kColumnNames = {"t_s", "x",  "y",  "z",
                                                     "vx",  "vy", "vz", "buttons"};
constexpr std::array<const char*, 5> kRequiredKeys = {"units", "rate_hz", "device", "source",
                                                      "frame"};

// Strips one trailing '\r' (files written on Windows).
void StripCr(std::string* line) {
  if (!line->empty() && line->back() == '\r') line->pop_back();
}

bool ValidKey(std::string_view key) {
  if (key.empty()) return false;
  for (char c : key) {
    if (c == ':' || c == '#' || c == '\n' || c == '\r' || c == ' ' || c == '\t') return false;
  }
  return true;
}

// Parses a finite positive number (the rate_hz value); nullopt otherwise.
std::optional<double> ParsePositive(std::string_view text) {
  double value = 0.0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || ptr != text.data() + text.size()) return std::nullopt;
  if (!std::isfinite(value) || value <= 0.0) return std::nullopt;
  return value;
}

// Text of a field for an error message, shortened so a binary file does not flood the terminal.
std::string Quote(std::string_view field) {
  constexpr size_t kMax = 40;
  std::string out = "'";
  out.append(field.substr(0, kMax));
  if (field.size() > kMax) out += "...";
  out += "'";
  return out;
}

}  // namespace

std::optional<std::string> TraceHeader::Get(std::string_view key) const {
  for (const auto& [k, v] : entries) {
    if (k == key) return v;
  }
  return std::nullopt;
}

void TraceHeader::Set(std::string_view key, std::string_view value) {
  if (!ValidKey(key)) {
    throw std::invalid_argument("trace header key " + Quote(key) +
                                " must be non-empty without ':', '#', spaces or newlines");
  }
  if (value.find_first_of("\r\n") != std::string_view::npos) {
    throw std::invalid_argument("trace header value for '" + std::string(key) +
                                "' must not hold a newline");
  }
  for (auto& [k, v] : entries) {
    if (k == key) {
      v = value;
      return;
    }
  }
  entries.emplace_back(std::string(key), std::string(value));
}

double TraceHeader::rate_hz() const {
  const std::optional<std::string> text = Get("rate_hz");
  if (!text) throw std::invalid_argument("trace header has no rate_hz");
  const std::optional<double> rate = ParsePositive(*text);
  if (!rate) throw std::invalid_argument("trace header rate_hz " + Quote(*text) + " is not > 0");
  return *rate;
}

TraceHeader MakeTraceHeader(double rate_hz, std::string_view device, std::string_view source) {
  TraceHeader header;
  header.Set("units", kTraceUnits);
  std::string rate;
  AppendTraceNumber(rate_hz, -1, &rate);
  header.Set("rate_hz", rate);
  header.Set("device", device);
  header.Set("source", source);
  header.Set("frame", "device");
  return header;
}

namespace {
// "FILE:LINE: message", or "FILE: message" for line 0. Built by appending (GCC 12 warns falsely
// about operator+ chains on std::string with -Wrestrict at -O3).
std::string ErrorText(const std::string& file, int64_t line, const std::string& message) {
  std::string text = file;
  if (line > 0) {
    text.push_back(':');
    text.append(std::to_string(line));
  }
  text.append(": ");
  text.append(message);
  return text;
}
}  // namespace

TraceError::TraceError(std::string file, int64_t line, const std::string& message)
    : std::runtime_error(ErrorText(file, line, message)), file_(std::move(file)), line_(line) {}

// ---------------------------------------------------------------------------------------------
// Reader

TraceReader::TraceReader(std::string path) : path_(std::move(path)) {
  in_.open(path_, std::ios::in | std::ios::binary);
  if (!in_) throw TraceError(path_, 0, "cannot open for reading: " + std::string(strerror(errno)));

  // The magic line.
  if (!std::getline(in_, buffer_)) Fail("empty file: expected '" + std::string(kTraceMagic) + "'");
  ++line_;
  StripCr(&buffer_);
  if (buffer_ != kTraceMagic) {
    Fail("bad header: first line must be exactly '" + std::string(kTraceMagic) + "', got " +
         Quote(buffer_));
  }

  // `# key: value` lines until the column line.
  bool have_columns = false;
  while (std::getline(in_, buffer_)) {
    ++line_;
    StripCr(&buffer_);
    if (buffer_.empty() || buffer_[0] != '#') {
      if (buffer_ != kTraceColumns) {
        Fail("bad header: expected a '# key: value' line or the column line '" +
             std::string(kTraceColumns) + "', got " + Quote(buffer_));
      }
      have_columns = true;
      break;
    }
    if (buffer_.size() < 2 || buffer_[1] != ' ') {
      Fail("bad header line " + Quote(buffer_) + ": expected '# key: value'");
    }
    const size_t colon = buffer_.find(':', 2);
    if (colon == std::string::npos) {
      Fail("bad header line " + Quote(buffer_) + ": expected '# key: value' (no ':')");
    }
    const std::string key = buffer_.substr(2, colon - 2);
    if (!ValidKey(key)) {
      Fail("bad header line " + Quote(buffer_) + ": key must be non-empty without spaces");
    }
    std::string value = buffer_.substr(colon + 1);
    if (!value.empty() && value[0] == ' ') value.erase(0, 1);
    if (header_.Get(key)) Fail("bad header: duplicate key '" + key + "'");
    header_.entries.emplace_back(key, std::move(value));
  }
  if (!have_columns) {
    Fail("bad header: missing the column line '" + std::string(kTraceColumns) + "'");
  }

  // The required keys and their fixed values.
  for (const char* key : kRequiredKeys) {
    if (!header_.Get(key)) Fail("bad header: missing required key '" + std::string(key) + "'");
  }
  if (*header_.Get("units") != kTraceUnits) {
    Fail("bad header: units must be '" + std::string(kTraceUnits) + "', got " +
         Quote(*header_.Get("units")));
  }
  if (*header_.Get("frame") != "device") {
    Fail("bad header: frame must be 'device', got " + Quote(*header_.Get("frame")));
  }
  if (!ParsePositive(*header_.Get("rate_hz"))) {
    Fail("bad header: rate_hz must be a finite number > 0, got " + Quote(*header_.Get("rate_hz")));
  }
}

void TraceReader::Fail(const std::string& message) const {
  throw TraceError(path_, line_, message);
}

void TraceReader::FailField(int field, const std::string& message) const {
  throw TraceError(
      path_, line_,
      "field " + std::to_string(field + 1) + " (" + kColumnNames[field] + "): " + message);
}

bool TraceReader::Next(TraceSample* sample) {
  if (!std::getline(in_, buffer_)) {
    if (in_.bad()) Fail("read error: " + std::string(strerror(errno)));
    return false;
  }
  ++line_;
  StripCr(&buffer_);
  if (buffer_.empty()) Fail("empty line (a sample line needs 8 comma-separated fields)");

  // Split into exactly eight fields, parsing each as it is found.
  const char* const begin = buffer_.data();
  const char* const end = begin + buffer_.size();
  const char* p = begin;
  std::array<double, 7> values{};
  uint32_t buttons = 0;
  int field = 0;
  while (true) {
    const char* comma = static_cast<const char*>(std::memchr(p, ',', static_cast<size_t>(end - p)));
    const char* field_end = comma ? comma : end;
    if (field >= 8) {
      // Count every field for the message.
      int count = field + 1;
      for (const char* q = p; q < end; ++q) count += (*q == ',');
      Fail("wrong column count: expected 8 fields (" + std::string(kTraceColumns) + "), got " +
           std::to_string(count));
    }
    const std::string_view text(p, static_cast<size_t>(field_end - p));
    if (text.empty()) FailField(field, "empty value");
    if (field < 7) {
      // A finite double.
      double value = 0.0;
      const auto [ptr, ec] = std::from_chars(p, field_end, value);
      if (ptr != field_end || (ec != std::errc() && ec != std::errc::result_out_of_range)) {
        FailField(field, "non-numeric value " + Quote(text));
      }
      if (ec == std::errc::result_out_of_range || !std::isfinite(value)) {
        FailField(field, "non-finite value " + Quote(text));
      }
      values[static_cast<size_t>(field)] = value;
    } else {
      // An unsigned 32-bit integer.
      if (text[0] == '-') FailField(field, "negative buttons " + Quote(text));
      uint32_t value = 0;
      const auto [ptr, ec] = std::from_chars(p, field_end, value);
      if (ec == std::errc::result_out_of_range) {
        FailField(field, "buttons " + Quote(text) + " do not fit in 32 bits");
      }
      if (ec != std::errc() || ptr != field_end) {
        FailField(field, "buttons must be an unsigned integer bit mask, got " + Quote(text));
      }
      buttons = value;
    }
    ++field;
    if (!comma) break;
    p = comma + 1;
  }
  if (field != 8) {
    Fail("wrong column count: expected 8 fields (" + std::string(kTraceColumns) + "), got " +
         std::to_string(field));
  }

  // Time strictly increases.
  const double t_s = values[0];
  if (samples_read_ > 0 && !(t_s > last_t_s_)) {
    char text[96];
    std::snprintf(text, sizeof text, "%s: t_s %.17g after %.17g",
                  t_s == last_t_s_ ? "duplicate time" : "time goes backwards", t_s, last_t_s_);
    FailField(0, text);
  }
  last_t_s_ = t_s;
  ++samples_read_;

  sample->t_s = t_s;
  sample->p_D = Vec3(values[1], values[2], values[3]);
  sample->v_D = Vec3(values[4], values[5], values[6]);
  sample->buttons = buttons;
  return true;
}

Trace ReadTrace(const std::string& path) {
  TraceReader reader(path);
  Trace trace;
  trace.header = reader.header();
  TraceSample sample;
  while (reader.Next(&sample)) trace.samples.push_back(sample);
  if (trace.samples.empty()) throw TraceError(path, reader.line(), "no samples after the header");
  return trace;
}

// ---------------------------------------------------------------------------------------------
// Writer

void AppendTraceNumber(double value, int decimals, std::string* out) {
  char text[64];
  if (decimals < 0) {
    // Shortest representation that reads back bitwise (std::to_chars, C++17 [charconv.to.chars]).
    const auto [ptr, ec] = std::to_chars(text, text + sizeof text, value);
    out->append(text, ptr);
    return;
  }
  const auto [ptr, ec] =
      std::to_chars(text, text + sizeof text, value, std::chars_format::fixed, decimals);
  char* last = ptr;
  // Remove trailing zeros after the point, then a bare point.
  if (std::memchr(text, '.', static_cast<size_t>(last - text)) != nullptr) {
    while (last > text && last[-1] == '0') --last;
    if (last > text && last[-1] == '.') --last;
  }
  // "-0" (a tiny negative rounded away) reads as -0.0: print it as "0".
  if (last - text == 2 && text[0] == '-' && text[1] == '0') {
    out->push_back('0');
    return;
  }
  out->append(text, last);
}

TraceWriter::TraceWriter(std::string path, const TraceHeader& header, TraceWriteOptions options)
    : path_(std::move(path)), options_(options) {
  for (const char* key : kRequiredKeys) {
    if (!header.Get(key)) {
      throw std::invalid_argument("trace header for " + path_ + " lacks required key '" + key +
                                  "'");
    }
  }
  if (*header.Get("units") != kTraceUnits || *header.Get("frame") != "device") {
    throw std::invalid_argument("trace header for " + path_ + ": units must be '" +
                                std::string(kTraceUnits) + "' and frame 'device'");
  }
  header.rate_hz();  // validates
  out_.open(path_, std::ios::out | std::ios::binary | std::ios::trunc);
  if (!out_) {
    throw std::runtime_error(path_ + ": cannot open for writing: " + std::string(strerror(errno)));
  }
  out_ << kTraceMagic << '\n';
  for (const auto& [key, value] : header.entries) out_ << "# " << key << ": " << value << '\n';
  out_ << kTraceColumns << '\n';
}

TraceWriter::~TraceWriter() {
  if (out_.is_open()) out_.close();
}

void TraceWriter::Write(const TraceSample& sample) {
  // Validate before writing anything of this sample.
  const bool finite = std::isfinite(sample.t_s) && sample.p_D.allFinite() && sample.v_D.allFinite();
  if (!finite) throw std::invalid_argument(path_ + ": sample holds a non-finite value");
  line_.clear();
  AppendTraceNumber(sample.t_s, options_.decimals, &line_);
  // Times must increase as printed (rounding to `decimals` could merge two close times).
  double t_printed = 0.0;
  std::from_chars(line_.data(), line_.data() + line_.size(), t_printed);
  if (have_last_ && !(t_printed > last_t_s_)) {
    throw std::invalid_argument(path_ + ": sample times must strictly increase (as printed)");
  }
  for (int i = 0; i < 3; ++i) {
    line_.push_back(',');
    AppendTraceNumber(sample.p_D[i], options_.decimals, &line_);
  }
  for (int i = 0; i < 3; ++i) {
    line_.push_back(',');
    AppendTraceNumber(sample.v_D[i], options_.decimals, &line_);
  }
  line_.push_back(',');
  line_ += std::to_string(sample.buttons);
  line_.push_back('\n');
  out_.write(line_.data(), static_cast<std::streamsize>(line_.size()));
  have_last_ = true;
  last_t_s_ = t_printed;
}

void TraceWriter::Close() {
  out_.flush();
  const bool ok = static_cast<bool>(out_);
  out_.close();
  if (!ok || out_.fail()) throw std::runtime_error(path_ + ": write failed");
}

void WriteTrace(const std::string& path, const Trace& trace, TraceWriteOptions options) {
  TraceWriter writer(path, trace.header, options);
  for (const TraceSample& sample : trace.samples) writer.Write(sample);
  writer.Close();
}

}  // namespace felt
