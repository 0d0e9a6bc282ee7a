#pragma once
// Converting other recordings into `felt-trace v1` (`felt trace import`): the text log written by
// H3D/HAPI's DeviceLog node, and CSV files with named columns at any rate. Samples are mapped into
// the device frame, then resampled to the output rate (1 kHz by default) with a C1 cubic Hermite
// interpolant with Bessel tangents (recordings/hermite.h); the velocity column is the
// interpolant's derivative, never a difference of resampled positions. See recordings/README.md.

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "collision/mesh.h"
#include "recordings/mcap_trace.h"
#include "recordings/trace.h"

namespace felt {

/// The most samples an import makes (2^24: 4.7 hours at 1 kHz, about 1 GiB): a source whose time
/// span would need more at the output rate is refused, not allocated.
inline constexpr int64_t kMaxImportSamples = int64_t{1} << 24;
/// The largest |coordinate| of a mapped position, m (device frame, after scale and offset): a
/// device or a pen moves within metres; a larger value is a corrupt or mis-scaled source.
inline constexpr double kMaxImportPosition_m = 1000.0;

/// The source formats `felt trace import` reads.
enum class ImportFormat {
  kDeviceLog,  ///< H3D/HAPI DeviceLog text: a line of field names, then whitespace-separated rows
  kCsv,        ///< comma-separated, a header row of column names, then numeric rows
  kMcap,       ///< an MCAP file's PoseStamped or OmniState topic (recordings/mcap_trace.h), in m
};

/// Parses "devicelog", "csv" or "mcap"; throws std::invalid_argument otherwise.
ImportFormat ParseImportFormat(std::string_view text);

/// A signed axis permutation: device axis i = sign[i] * source axis source_axis[i].
struct AxisMap {
  std::array<int, 3> source_axis = {0, 1, 2};    ///< 0 = x, 1 = y, 2 = z; a permutation
  std::array<double, 3> sign = {1.0, 1.0, 1.0};  ///< +1 or -1
};

/// Parses an axis map: three letters x, y, z, each used once, each optionally preceded by '-' or
/// '+', optionally comma-separated: "xyz", "xzy", "x,-z,y", "-x-zy". Throws std::invalid_argument
/// naming the text otherwise.
AxisMap ParseAxisMap(std::string_view text);

/// How a source is read and placed in the device frame:
///   t_s = time_scale * t_source,   p_D = scale * A(p_source) + offset_D
/// with A the signed axis permutation.
struct ImportOptions {
  ImportFormat format = ImportFormat::kCsv;
  /// CSV: the source column for each of "t", "x", "y", "z" ("" = automatic: t from t_s, t, time or
  /// t_ms (t_ms also sets a default time_scale of 0.001); x from x or x_m, likewise y, z).
  /// When any column is named explicitly, axes not named are constant 0; automatically, x and y
  /// are required and a missing z is constant 0 (planar pen data).
  std::string column_t, column_x, column_y, column_z;
  /// Parses "t=NAME,x=NAME,..." into the column_* fields; throws std::invalid_argument.
  void SetColumns(std::string_view text);
  /// CSV: the trial / stroke id column ("" = automatic: rep, trial or stroke if present).
  std::string trial_column;
  /// CSV with trials: keep only this trial id; unset = concatenate every trial in file order.
  std::optional<int64_t> select_trial;
  /// Concatenated trials: time between one trial's last sample and the next one's first [s];
  /// the gap is bridged by one Hermite segment between the two trials' end knots.
  double trial_gap_s = 0.5;
  /// Seconds per source time unit (unset: 1, or 0.001 for an automatic t_ms column).
  std::optional<double> time_scale;
  double scale = 1.0;              ///< metres (device) per source position unit
  Vec3 offset_D_m = Vec3::Zero();  ///< added after scaling [m, device frame]
  AxisMap axes;                    ///< source axes to device axes
  double rate_hz = 1000.0;         ///< output sample rate [Hz], > 0
  /// A source step longer than this [s] is a gap: tangents are not differenced across it and it
  /// is bridged by one Hermite segment. <= 0: 10 times the median source step.
  double max_gap_s = 0.0;
  std::string device = "imported";  ///< the header's `device` value
  /// MCAP: the pose topic ("" = the first PoseStamped, else the first OmniState) and its time.
  std::string mcap_topic;
  McapTraceTime mcap_time = McapTraceTime::kHeaderStamp;
};

/// Reads `path` as described by `options` and returns the resampled trace: samples at
/// t = k / rate_hz [s], k = 0 .. floor((t_last - t_first) * rate_hz), the first source sample at
/// t = 0. The header holds units, rate_hz, device, source (= path), frame, and source_format,
/// source_rate_hz (1 / median source step), source_samples, trials, gaps, mapping, interpolant.
/// Throws TraceError naming the file and line (and field) for a malformed source: unreadable
/// file, bad header row, unknown or missing column, wrong field count, non-numeric or
/// non-finite value, time going backwards within a trial, a selected trial that does not exist,
/// fewer than two samples, a mapped position beyond kMaxImportPosition_m, a time span needing
/// more than kMaxImportSamples at the output rate, a resampled sample that is not finite. Throws
/// std::invalid_argument for bad options.
Trace ImportTrace(const std::string& path, const ImportOptions& options);

}  // namespace felt
