#include "rt/loop_stats.h"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <stdexcept>

#include "base/json.h"
#include "rt/histogram_plot.h"

namespace felt {

// ---- bins ----

int HistogramBins::Index(uint64_t units) {
  if (units < kExactBins) return static_cast<int>(units);
  const int msb = 63 - std::countl_zero(units);  // >= kExactBits
  if (msb >= kMaxBits) return kOverflow;
  // kSubBins bins per power of two: keep the top kExactBits bits of the value.
  const int shift = msb - (kExactBits - 1);
  const uint64_t sub = (units >> shift) - kSubBins;  // 0 .. kSubBins - 1
  return static_cast<int>(kExactBins + static_cast<uint64_t>(msb - kExactBits) * kSubBins + sub);
}

uint64_t HistogramBins::Lower(int index) {
  if (index >= kOverflow) return uint64_t{1} << kMaxBits;
  if (static_cast<uint64_t>(index) < kExactBins) return static_cast<uint64_t>(index);
  const uint64_t above = static_cast<uint64_t>(index) - kExactBins;
  const int group = static_cast<int>(above / kSubBins);  // msb - kExactBits
  const uint64_t sub = above % kSubBins + kSubBins;
  return sub << (group + 1);
}

uint64_t HistogramBins::Width(int index) {
  if (index >= kOverflow) return 0;
  if (static_cast<uint64_t>(index) < kExactBins) return 1;
  const int group = static_cast<int>((static_cast<uint64_t>(index) - kExactBins) / kSubBins);
  return uint64_t{1} << (group + 1);
}

// ---- snapshot queries ----

int HistogramSnapshot::QuantileBin(double q) const {
  if (count == 0) return -1;
  // Nearest rank: the smallest bin whose cumulative count reaches ceil(q * count) (at least 1).
  const double clamped = std::clamp(q, 0.0, 1.0);
  uint64_t rank = static_cast<uint64_t>(std::ceil(clamped * static_cast<double>(count)));
  rank = std::clamp<uint64_t>(rank, 1, count);
  uint64_t cumulative = 0;
  for (int i = 0; i <= HistogramBins::kOverflow; ++i) {
    cumulative += bins[static_cast<size_t>(i)];
    if (cumulative >= rank) return i;
  }
  return HistogramBins::kOverflow;
}

int64_t HistogramSnapshot::PercentileNs(double q) const {
  const int bin = QuantileBin(q);
  if (bin < 0) return 0;
  if (bin == HistogramBins::kOverflow) return max_ns;
  const uint64_t upper = HistogramBins::Lower(bin) + HistogramBins::Width(bin);
  return std::min(static_cast<int64_t>(upper) * unit_ns, max_ns);
}

int64_t HistogramSnapshot::PercentileLowerNs(double q) const {
  const int bin = QuantileBin(q);
  if (bin < 0) return 0;
  return static_cast<int64_t>(HistogramBins::Lower(bin)) * unit_ns;
}

int64_t HistogramSnapshot::BinWidthNs(int64_t value_ns) const {
  const uint64_t units = static_cast<uint64_t>(std::max<int64_t>(value_ns, 0) / unit_ns);
  return static_cast<int64_t>(HistogramBins::Width(HistogramBins::Index(units))) * unit_ns;
}

uint64_t HistogramSnapshot::CountAtLeastNs(int64_t threshold_ns) const {
  uint64_t total = 0;
  for (int i = HistogramBins::kOverflow; i >= 0; --i) {
    if (static_cast<int64_t>(HistogramBins::Lower(i)) * unit_ns < threshold_ns) break;
    total += bins[static_cast<size_t>(i)];
  }
  return total;
}

double HistogramSnapshot::MeanNs() const {
  return count == 0 ? 0.0 : static_cast<double>(sum_ns) / static_cast<double>(count);
}

HistogramSnapshot HistogramSnapshot::Minus(const HistogramSnapshot& earlier) const {
  HistogramSnapshot window;
  window.unit_ns = unit_ns;
  int highest = -1;
  for (size_t i = 0; i < bins.size(); ++i) {
    window.bins[i] = bins[i] >= earlier.bins[i] ? bins[i] - earlier.bins[i] : 0;
    window.count += window.bins[i];
    if (window.bins[i] != 0) highest = static_cast<int>(i);
  }
  window.sum_ns = sum_ns - earlier.sum_ns;
  if (highest == HistogramBins::kOverflow) {
    window.max_ns = max_ns;
  } else if (highest >= 0) {
    const uint64_t upper = HistogramBins::Lower(highest) + HistogramBins::Width(highest);
    window.max_ns = std::min(static_cast<int64_t>(upper) * unit_ns, max_ns);
  }
  return window;
}

// ---- histogram ----

Histogram::Histogram(int64_t unit_ns) : unit_ns_(unit_ns) {
  if (unit_ns <= 0) {
    throw std::invalid_argument("Histogram: unit_ns must be > 0, got " + std::to_string(unit_ns));
  }
}

void Histogram::Record(int64_t value_ns) {
  const int64_t value = std::max<int64_t>(value_ns, 0);
  // Max and sum first, then the bin with release: a reader that sees the bin sees the max too.
  if (value > max_ns_.load(std::memory_order_relaxed)) {
    max_ns_.store(value, std::memory_order_relaxed);
  }
  sum_ns_.store(sum_ns_.load(std::memory_order_relaxed) + value, std::memory_order_relaxed);
  std::atomic<uint64_t>& bin =
      bins_[static_cast<size_t>(HistogramBins::Index(static_cast<uint64_t>(value / unit_ns_)))];
  bin.store(bin.load(std::memory_order_relaxed) + 1, std::memory_order_release);
}

void Histogram::Snapshot(HistogramSnapshot* out) const {
  out->unit_ns = unit_ns_;
  out->count = 0;
  for (size_t i = 0; i < bins_.size(); ++i) {
    out->bins[i] = bins_[i].load(std::memory_order_acquire);
    out->count += out->bins[i];
  }
  out->max_ns = max_ns_.load(std::memory_order_relaxed);
  out->sum_ns = sum_ns_.load(std::memory_order_relaxed);
}

// ---- loop stats ----

LoopStatsSnapshot LoopStatsSnapshot::Minus(const LoopStatsSnapshot& earlier) const {
  LoopStatsSnapshot window;
  window.taken_ns = taken_ns;
  window.first_wake_ns = earlier.taken_ns;
  window.period_ns = period_ns;
  window.ticks = ticks - earlier.ticks;
  window.overruns = overruns - earlier.overruns;
  window.skipped_periods = skipped_periods - earlier.skipped_periods;
  window.arrival_ticks = arrival_ticks - earlier.arrival_ticks;
  window.period = period.Minus(earlier.period);
  window.lateness = lateness.Minus(earlier.lateness);
  window.compute = compute.Minus(earlier.compute);
  window.snapshot_age = snapshot_age.Minus(earlier.snapshot_age);
  window.arrival_wake = arrival_wake.Minus(earlier.arrival_wake);
  return window;
}

double LoopStatsSnapshot::TicksPerSecond() const {
  if (ticks == 0 || first_wake_ns == 0 || taken_ns <= first_wake_ns) return 0.0;
  return static_cast<double>(ticks) * 1e9 / static_cast<double>(taken_ns - first_wake_ns);
}

LoopStats::LoopStats(int64_t period_ns, int64_t unit_ns)
    : period_ns_(period_ns),
      period_(unit_ns),
      lateness_(unit_ns),
      compute_(unit_ns),
      snapshot_age_(unit_ns),
      arrival_wake_(unit_ns) {}

void LoopStats::RecordTick(const TickInfo& tick, int64_t compute_ns) {
  // Histograms first, counters last: a reader that sees a tick count sees its samples.
  if (first_wake_ns_.load(std::memory_order_relaxed) == 0) {
    first_wake_ns_.store(tick.wake_ns, std::memory_order_relaxed);
  }
  if (tick.previous_wake_ns != 0) period_.Record(tick.wake_ns - tick.previous_wake_ns);
  lateness_.Record(tick.lateness_ns);
  compute_.Record(compute_ns);
  if (tick.on_arrival) {
    arrival_wake_.Record(tick.wake_ns - tick.arrival_ns);
    arrival_ticks_.store(arrival_ticks_.load(std::memory_order_relaxed) + 1,
                         std::memory_order_relaxed);
  }
  if (tick.overrun) {
    overruns_.store(overruns_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
    skipped_periods_.store(skipped_periods_.load(std::memory_order_relaxed) + tick.periods_skipped,
                           std::memory_order_relaxed);
  }
  ticks_.store(ticks_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
}

void LoopStats::RecordEndOfRun(const TickInfo& tick, uint64_t skipped_before_end) {
  if (!tick.overrun) return;
  overruns_.store(overruns_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
  skipped_periods_.store(skipped_periods_.load(std::memory_order_relaxed) + skipped_before_end,
                         std::memory_order_release);
}

void LoopStats::RecordSnapshotAge(int64_t age_ns) { snapshot_age_.Record(age_ns); }

void LoopStats::Snapshot(LoopStatsSnapshot* out) const {
  out->taken_ns = MonotonicNowNs();
  out->period_ns = period_ns_;
  out->ticks = ticks_.load(std::memory_order_acquire);
  out->first_wake_ns = first_wake_ns_.load(std::memory_order_relaxed);
  out->overruns = overruns_.load(std::memory_order_relaxed);
  out->skipped_periods = skipped_periods_.load(std::memory_order_relaxed);
  period_.Snapshot(&out->period);
  lateness_.Snapshot(&out->lateness);
  compute_.Snapshot(&out->compute);
  snapshot_age_.Snapshot(&out->snapshot_age);
  out->arrival_ticks = arrival_ticks_.load(std::memory_order_relaxed);
  arrival_wake_.Snapshot(&out->arrival_wake);
}

// ---- JSON ----

Json HistogramJson(const HistogramSnapshot& h, double ns_per_unit) {
  return Json{{"p50", static_cast<double>(h.PercentileNs(0.50)) / ns_per_unit},
              {"p99", static_cast<double>(h.PercentileNs(0.99)) / ns_per_unit},
              {"p999", static_cast<double>(h.PercentileNs(0.999)) / ns_per_unit},
              {"max", static_cast<double>(h.max_ns) / ns_per_unit},
              {"mean", h.MeanNs() / ns_per_unit},
              {"count", h.count}};
}

namespace {

// The counts every loop reports: its ticks under `ticks_key`, overruns, skipped periods, and the
// nominal period under `period_key` in units of `ns_per_unit` ns.
Json LoopCountsJson(const LoopStatsSnapshot& s, const char* ticks_key, const char* period_key,
                    double ns_per_unit) {
  return Json{{ticks_key, s.ticks},
              {"overruns", s.overruns},
              {"skipped_periods", s.skipped_periods},
              {period_key, static_cast<double>(s.period_ns) / ns_per_unit}};
}

}  // namespace

Json HapticJson(const LoopStatsSnapshot& haptic) {
  Json json = LoopCountsJson(haptic, "ticks", "period_nominal_us", 1e3);
  json["period_us"] = HistogramJson(haptic.period, 1e3);
  json["lateness_us"] = HistogramJson(haptic.lateness, 1e3);
  json["lateness_bins_us"] = PlotBinsJson(haptic.lateness, 1e3);
  json["compute_us"] = HistogramJson(haptic.compute, 1e3);
  json["snapshot_age_us"] = HistogramJson(haptic.snapshot_age, 1e3);
  json["arrival_ticks"] = haptic.arrival_ticks;
  json["arrival_wake_us"] = HistogramJson(haptic.arrival_wake, 1e3);
  return json;
}

Json SimJson(const LoopStatsSnapshot& sim) {
  Json json = LoopCountsJson(sim, "frames", "period_nominal_ms", 1e6);
  json["period_ms"] = HistogramJson(sim.period, 1e6);
  json["lateness_us"] = HistogramJson(sim.lateness, 1e3);
  json["lateness_bins_us"] = PlotBinsJson(sim.lateness, 1e3);
  json["frame_ms"] = HistogramJson(sim.compute, 1e6);
  return json;
}

std::string ServerStatsJson(const LoopStatsSnapshot& haptic, const LoopStatsSnapshot& sim,
                            bool realtime) {
  return JsonText(
      Json{{"realtime", realtime}, {"haptic", HapticJson(haptic)}, {"sim", SimJson(sim)}});
}

// ---- one-line summaries ----

namespace {

// A duration in `unit` (1e3: us, 1e6: ms), integer when large, with decimals when small.
std::string Value(int64_t ns, double ns_per_unit) {
  const double v = static_cast<double>(ns) / ns_per_unit;
  if (v >= 100.0) return fmt::format("{:.0f}", v);
  if (v >= 10.0) return fmt::format("{:.1f}", v);
  return fmt::format("{:.2f}", v);
}

std::string Summary(const char* name, const char* rate_word, const char* what,
                    const HistogramSnapshot& h, double ns_per_unit, const char* unit,
                    const LoopStatsSnapshot& window, uint64_t total_overruns) {
  return fmt::format(
      "{}: {:.0f} {}/s {} p50 {} {} p99 {} {} p99.9 {} {} max {} {} overruns {}", name,
      window.TicksPerSecond(), rate_word, what, Value(h.PercentileNs(0.5), ns_per_unit), unit,
      Value(h.PercentileNs(0.99), ns_per_unit), unit, Value(h.PercentileNs(0.999), ns_per_unit),
      unit, Value(h.max_ns, ns_per_unit), unit, total_overruns);
}

LoopStatsSnapshot Window(const LoopStatsSnapshot& now, const LoopStatsSnapshot* previous) {
  return previous != nullptr ? now.Minus(*previous) : now;
}

}  // namespace

std::string FormatHapticSummary(const LoopStatsSnapshot& now, const LoopStatsSnapshot* previous) {
  const LoopStatsSnapshot window = Window(now, previous);
  return Summary("haptic", "ticks", "lateness", window.lateness, 1e3, "us", window, now.overruns);
}

std::string FormatSimSummary(const LoopStatsSnapshot& now, const LoopStatsSnapshot* previous) {
  const LoopStatsSnapshot window = Window(now, previous);
  return Summary("sim", "frames", "frame", window.compute, 1e6, "ms", window, now.overruns);
}

std::string FormatMonitorLine(const LoopStatsSnapshot& haptic,
                              const LoopStatsSnapshot* haptic_previous,
                              const LoopStatsSnapshot& sim, const LoopStatsSnapshot* sim_previous) {
  return FormatHapticSummary(haptic, haptic_previous) + " | " + FormatSimSummary(sim, sim_previous);
}

}  // namespace felt
