#pragma once
// Lock-free loop statistics: fixed-bin histograms the loop thread records into without allocation
// or locks, read by a monitor thread as snapshot copies; per-loop counters; the stats JSON of
// issue 5 and the monitor's one-line summary.
//
// Concurrency: one writer (the loop thread) per Histogram/LoopStats and any number of readers.
// Every bin is a std::atomic written by plain load/store (single writer: no read-modify-write on
// the tick) and read by Snapshot(). A snapshot is a consistent histogram (its count is the sum of
// the bins it copied, every bin only grows), though samples recorded during the copy may or may
// not be in it. TSan-clean.

#include <array>
#include <atomic>
#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <string>

#include "rt/periodic_loop.h"

namespace felt {

/// Geometry of the log-linear bins, in units of a histogram's `unit_ns`:
/// values below 256 units have exact bins 1 unit wide; above, each power of two is split into 128
/// bins, so a bin is at most 1/128 (0.8 %) of its lower edge wide; values from 2^26 units (67 s at
/// 1 us) go to the overflow bin, whose percentile is the exact max.
struct HistogramBins {
  static constexpr int kExactBits = 8;                      ///< 2^8 exact bins
  static constexpr uint64_t kExactBins = 1u << kExactBits;  ///< values 0..255 units: exact
  static constexpr uint64_t kSubBins = kExactBins / 2;      ///< bins per power of two above
  static constexpr int kMaxBits = 26;                       ///< overflow from 2^26 units
  static constexpr int kCount =
      static_cast<int>(kExactBins + (kMaxBits - kExactBits) * kSubBins);  ///< finite bins
  static constexpr int kOverflow = kCount;  ///< index of the overflow bin (kCount + 1 bins in all)

  /// The bin of a value of `units` (>= 0). Real-time safe.
  static int Index(uint64_t units);
  /// The lowest value of bin `index` in units (kOverflow: 2^kMaxBits).
  static uint64_t Lower(int index);
  /// The width of bin `index` in units (kOverflow: 0, meaning unbounded).
  static uint64_t Width(int index);
};

/// A copy of a Histogram at one moment, in ns. Plain data: copy, subtract, query.
struct HistogramSnapshot {
  int64_t unit_ns = 1000;                                  ///< the histogram's resolution unit
  std::array<uint64_t, HistogramBins::kCount + 1> bins{};  ///< counts per bin, overflow last
  uint64_t count = 0;                                      ///< sum of `bins`
  int64_t max_ns = 0;  ///< exact largest value recorded (0 if none)
  int64_t sum_ns = 0;  ///< sum of values (for the mean)

  /// The q-quantile (q in [0, 1], nearest rank: the smallest recorded value with at least
  /// ceil(q * count) values at or below it), in ns, reported as the upper edge of the bin holding
  /// it, capped at max_ns: never below the true value, above it by less than one bin width
  /// (BinWidthNs). 0 when empty; the overflow bin reports max_ns.
  int64_t PercentileNs(double q) const;
  /// The lower edge in ns of the bin holding the q-quantile (the true value is >= this).
  int64_t PercentileLowerNs(double q) const;
  /// The width in ns of the bin that holds a value of `value_ns` (the percentile error bound).
  int64_t BinWidthNs(int64_t value_ns) const;
  /// Values at or above `threshold_ns`: counts every bin whose lower edge is >= the threshold,
  /// so it is exact when the threshold is a bin edge (any whole number of units below 256 units,
  /// e.g. 1 ms at a 1 us unit) and otherwise may miss values in the bin straddling it.
  uint64_t CountAtLeastNs(int64_t threshold_ns) const;
  /// Mean value in ns (0 when empty).
  double MeanNs() const;
  /// What was recorded between `earlier` (a snapshot of the same histogram) and this one. The
  /// window's max is known to its bin: the upper edge of its highest non-empty bin, capped at
  /// max_ns.
  HistogramSnapshot Minus(const HistogramSnapshot& earlier) const;

 private:
  int QuantileBin(double q) const;
};

/// A fixed-bin histogram of durations in ns (log-linear bins, see HistogramBins). One thread
/// records, any thread takes snapshots. Allocation-free after construction.
class Histogram {
 public:
  /// A histogram whose exact bins are `unit_ns` (> 0) wide; throws std::invalid_argument if not.
  explicit Histogram(int64_t unit_ns = 1000);

  Histogram(const Histogram&) = delete;
  Histogram& operator=(const Histogram&) = delete;

  /// Records one value in ns (negative values count as 0). Writer thread only. Real-time safe:
  /// a few relaxed/release atomic stores, no read-modify-write, no allocation.
  void Record(int64_t value_ns);

  /// Copies the bins into `*out` (about 20 KB). Any thread; lock-free; does not allocate.
  void Snapshot(HistogramSnapshot* out) const;

  /// The resolution unit in ns.
  int64_t unit_ns() const { return unit_ns_; }

 private:
  int64_t unit_ns_;
  std::array<std::atomic<uint64_t>, HistogramBins::kCount + 1> bins_{};
  std::atomic<int64_t> max_ns_{0};
  std::atomic<int64_t> sum_ns_{0};
};

/// A copy of one loop's statistics. Times in ns; histograms as above.
struct LoopStatsSnapshot {
  int64_t taken_ns = 0;            ///< CLOCK_MONOTONIC time of the snapshot
  int64_t first_wake_ns = 0;       ///< wake time of the first recorded tick (0: none yet)
  int64_t period_ns = 0;           ///< the loop's nominal period
  uint64_t ticks = 0;              ///< ticks (frames) recorded
  uint64_t overruns = 0;           ///< ticks whose work ended after the next deadline
  uint64_t skipped_periods = 0;    ///< period boundaries skipped after overruns
  HistogramSnapshot period;        ///< time between consecutive wake-ups
  HistogramSnapshot lateness;      ///< wake-up minus deadline
  HistogramSnapshot compute;       ///< work time per tick (wake-up to end of work)
  HistogramSnapshot snapshot_age;  ///< age of the sim snapshot used at each tick (haptic loop)
  uint64_t arrival_ticks = 0;      ///< ticks woken by an arrival (PeriodicLoop::WakeOnArrival)
  HistogramSnapshot arrival_wake;  ///< those ticks' wake-up minus the arrival's Notify()

  /// What happened between `earlier` (of the same LoopStats) and this snapshot; counters are
  /// differences, histograms as HistogramSnapshot::Minus.
  LoopStatsSnapshot Minus(const LoopStatsSnapshot& earlier) const;
  /// Ticks per second between first_wake_ns and taken_ns (0 before two ticks).
  double TicksPerSecond() const;
};

/// One loop's statistics: written by the loop thread each tick, read by a monitor thread.
class LoopStats {
 public:
  /// Statistics of a loop of nominal period `period_ns`; histograms with `unit_ns` resolution.
  explicit LoopStats(int64_t period_ns, int64_t unit_ns = 1000);

  LoopStats(const LoopStats&) = delete;
  LoopStats& operator=(const LoopStats&) = delete;

  /// Records a tick from PeriodicLoop::WaitNext() and its work time `compute_ns`. Loop thread
  /// only. Real-time safe.
  void RecordTick(const TickInfo& tick, int64_t compute_ns);
  /// Records the wake-up that ended a timed run (its deadline at or past the end, so no tick
  /// runs): its overrun, if the last tick's work overran, and `skipped_before_end` skipped
  /// periods (those of its skipped boundaries that were due before the end). Loop thread only.
  /// Real-time safe.
  void RecordEndOfRun(const TickInfo& tick, uint64_t skipped_before_end);
  /// Records the age of the snapshot used this tick (now minus the snapshot's publication time).
  /// Loop thread only. Real-time safe.
  void RecordSnapshotAge(int64_t age_ns);

  /// Copies everything into `*out` (about 80 KB; keep it off small stacks). Any thread;
  /// lock-free; does not allocate.
  void Snapshot(LoopStatsSnapshot* out) const;

 private:
  int64_t period_ns_;
  std::atomic<int64_t> first_wake_ns_{0};
  std::atomic<uint64_t> ticks_{0};
  std::atomic<uint64_t> overruns_{0};
  std::atomic<uint64_t> skipped_periods_{0};
  Histogram period_;
  Histogram lateness_;
  Histogram compute_;
  Histogram snapshot_age_;
  std::atomic<uint64_t> arrival_ticks_{0};
  Histogram arrival_wake_;
};

/// `{"p50", "p99", "p999", "max", "mean", "count"}` of `h`, values in ns divided by `ns_per_unit`
/// (1e3 for us, 1e6 for ms). Not real-time safe.
nlohmann::ordered_json HistogramJson(const HistogramSnapshot& h, double ns_per_unit);

/// The haptic loop: ticks, overruns, skipped_periods, period_nominal_us, period_us, lateness_us,
/// lateness_bins_us (the non-empty bins, rt/histogram_plot.h PlotBinsJson), compute_us,
/// snapshot_age_us, arrival_ticks, arrival_wake_us (percentiles in us). Not real-time safe.
nlohmann::ordered_json HapticJson(const LoopStatsSnapshot& haptic);

/// The sim loop: frames, overruns, skipped_periods, period_nominal_ms, period_ms, lateness_us,
/// lateness_bins_us (as HapticJson's), frame_ms (the work time of a frame). Not real-time safe.
nlohmann::ordered_json SimJson(const LoopStatsSnapshot& sim);

/// The server's stats document (issue 5): {"realtime", "haptic": {... "lateness_us", "overruns",
/// "ticks"}, "sim": {... "frame_ms", "frames"}}, percentiles under p50, p99, p999, max.
/// `realtime` is RealtimeReport::fifo_granted of the haptic thread. Not real-time safe.
std::string ServerStatsJson(const LoopStatsSnapshot& haptic, const LoopStatsSnapshot& sim,
                            bool realtime);

/// "haptic: 1000 ticks/s lateness p50 12 us p99 40 us p99.9 90 us max 300 us overruns 0":
/// the rate and percentiles over the window since `previous` (or since the start when null),
/// overruns since the start. Not real-time safe.
std::string FormatHapticSummary(const LoopStatsSnapshot& now, const LoopStatsSnapshot* previous);

/// "sim: 60 frames/s frame p50 3.1 ms p99 4.0 ms p99.9 4.2 ms max 4.3 ms overruns 0", windowed
/// as FormatHapticSummary. Not real-time safe.
std::string FormatSimSummary(const LoopStatsSnapshot& now, const LoopStatsSnapshot* previous);

/// The monitor's line: FormatHapticSummary + " | " + FormatSimSummary. Not real-time safe.
std::string FormatMonitorLine(const LoopStatsSnapshot& haptic,
                              const LoopStatsSnapshot* haptic_previous,
                              const LoopStatsSnapshot& sim, const LoopStatsSnapshot* sim_previous);

}  // namespace felt
