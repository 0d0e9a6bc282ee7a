#pragma once
// The `felt-trace v1` pointer-trace format: a recorded or generated haptic pointer path, one
// sample per haptic tick, replayed to compare algorithms on identical input
// (001_0f9f1b7fedff7723.txt §6: "at each haptic loop, the haptic pointer's position and velocity
// is recorded. Afterwards, all algorithms are executed using the saved positions and velocities").
//
// A file is text:
//
//   # felt-trace v1
//   # units: m, s, m/s
//   # rate_hz: 1000
//   # device: touch
//   # source: generated poke_hold (seed 1)
//   # frame: device
//   t_s,x,y,z,vx,vy,vz,buttons
//   0,0.001,-0.002,0.05,0,0,0,0
//   ...
//
// Positions are in the device frame (_D) in metres, velocities in m/s, times in seconds, buttons
// an unsigned 32-bit bit mask. Times are strictly increasing (a duplicate time is an error: a
// trace is a function of time). See recordings/README.md for the full specification.

#include <cstdint>
#include <fstream>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "collision/mesh.h"

namespace felt {

/// The exact first line of every trace file.
inline constexpr std::string_view kTraceMagic = "# felt-trace v1";
/// The exact column line that ends the header.
inline constexpr std::string_view kTraceColumns = "t_s,x,y,z,vx,vy,vz,buttons";
/// The value the `units` header key must have.
inline constexpr std::string_view kTraceUnits = "m, s, m/s";

/// One pointer sample: the haptic device's tip at time t_s, in the device frame.
struct TraceSample {
  double t_s = 0.0;         ///< time since the trace's time origin [s]
  Vec3 p_D = Vec3::Zero();  ///< tip position in the device frame [m]
  Vec3 v_D = Vec3::Zero();  ///< tip velocity in the device frame [m/s]
  uint32_t buttons = 0;     ///< button bit mask (bit i = button i pressed)

  /// Bitwise equality of every field (so NaN != NaN and -0 != +0 never matter: files hold neither).
  bool operator==(const TraceSample& other) const = default;
};

/// The `# key: value` lines of a trace header, in file order. Keys are unique.
/// Required keys: units (= "m, s, m/s"), rate_hz (nominal sample rate, finite and > 0),
/// device, source, frame (= "device"). Any other key is allowed and kept.
struct TraceHeader {
  std::vector<std::pair<std::string, std::string>> entries;  ///< (key, value), file order

  /// The value of `key`, or nullopt when the header has no such key.
  std::optional<std::string> Get(std::string_view key) const;
  /// Sets `key` to `value`, replacing an existing value in place or appending a new key.
  /// Throws std::invalid_argument if the key is empty or holds ':', '#', a newline or a space, or
  /// the value holds a newline.
  void Set(std::string_view key, std::string_view value);
  /// The nominal sample rate from the `rate_hz` key [Hz]; throws std::invalid_argument when the key
  /// is missing or not a finite positive number.
  double rate_hz() const;
};

/// A header with the required keys set: units, rate_hz, device, source, frame = device.
TraceHeader MakeTraceHeader(double rate_hz, std::string_view device, std::string_view source);

/// A whole trace in memory.
struct Trace {
  TraceHeader header;
  std::vector<TraceSample> samples;  ///< strictly increasing t_s
};

/// A malformed trace (or import source) file. what() reads "FILE:LINE: message" or
/// "FILE:LINE: field N (NAME): message" so an editor can jump to it.
class TraceError : public std::runtime_error {
 public:
  /// `line` is 1-based; 0 means the error concerns the whole file (e.g. it cannot be opened).
  TraceError(std::string file, int64_t line, const std::string& message);
  const std::string& file() const { return file_; }  ///< the file's path as given
  int64_t line() const { return line_; }             ///< 1-based line, 0 = whole file

 private:
  std::string file_;
  int64_t line_;
};

/// Streams a trace file sample by sample in bounded memory: the constructor reads and validates
/// the header; Next() parses one line at a time into a reused buffer (after the longest line has
/// been seen, reading allocates nothing). Every check of ReadTrace is made, line by line, so an
/// error may surface after earlier samples were returned: use ReadTrace when nothing partial may
/// be used.
class TraceReader {
 public:
  /// Opens `path` and reads the header. Throws TraceError (cannot open, bad or missing magic line,
  /// malformed `# key: value` line, duplicate key, missing required key, bad units/frame/rate_hz,
  /// missing or wrong column line).
  explicit TraceReader(std::string path);

  /// The validated header.
  const TraceHeader& header() const { return header_; }

  /// Reads the next sample into *sample and returns true, or returns false at the end of the file.
  /// Throws TraceError naming the line and field: wrong column count, empty field, non-numeric
  /// value, non-finite value, negative / non-integer / too large buttons, time not strictly
  /// increasing (backwards or duplicate), empty line.
  bool Next(TraceSample* sample);

  /// Number of samples returned so far.
  int64_t samples_read() const { return samples_read_; }
  /// The 1-based number of the last line read.
  int64_t line() const { return line_; }
  /// The path being read.
  const std::string& path() const { return path_; }

 private:
  [[noreturn]] void Fail(const std::string& message) const;
  [[noreturn]] void FailField(int field, const std::string& message) const;

  std::string path_;
  std::ifstream in_;
  std::string buffer_;  // the current line, reused
  TraceHeader header_;
  int64_t line_ = 0;
  int64_t samples_read_ = 0;
  double last_t_s_ = 0.0;
};

/// Reads and validates a whole trace file; returns nothing unless every line is valid and there is
/// at least one sample. Throws TraceError as TraceReader does, and for a file without samples.
Trace ReadTrace(const std::string& path);

/// How TraceWriter prints numbers.
struct TraceWriteOptions {
  /// < 0: shortest text that reads back to the same double (std::to_chars), a bitwise round trip.
  /// >= 0: fixed notation with this many decimals, trailing zeros removed (e.g. 6 = 1 um, 1 um/s,
  /// 1 us); for compact generated files.
  int decimals = -1;
};

/// Writes a trace file sample by sample. The header is written by the constructor; samples must
/// come in strictly increasing time and be finite (std::invalid_argument otherwise, before anything
/// of that sample is written). Throws std::runtime_error if the file cannot be opened or written.
class TraceWriter {
 public:
  /// Creates (truncates) `path` and writes the magic line, `header` and the column line. The
  /// header must hold the required keys (std::invalid_argument otherwise).
  TraceWriter(std::string path, const TraceHeader& header, TraceWriteOptions options = {});
  /// Flushes and closes; a write error here is lost, so call Close() to see it.
  ~TraceWriter();
  TraceWriter(const TraceWriter&) = delete;
  TraceWriter& operator=(const TraceWriter&) = delete;

  /// Appends one sample line.
  void Write(const TraceSample& sample);
  /// Flushes and closes the file; throws std::runtime_error if any write failed.
  void Close();

 private:
  std::string path_;
  std::ofstream out_;
  TraceWriteOptions options_;
  std::string line_;  // reused line buffer
  bool have_last_ = false;
  double last_t_s_ = 0.0;
};

/// Writes a whole trace (see TraceWriter).
void WriteTrace(const std::string& path, const Trace& trace, TraceWriteOptions options = {});

/// Appends `value` to *out as TraceWriter prints it (see TraceWriteOptions::decimals).
void AppendTraceNumber(double value, int decimals, std::string* out);

}  // namespace felt
