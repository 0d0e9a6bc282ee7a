// Histogram and LoopStats: bin geometry, percentiles against a sorted reference, windows,
// concurrent snapshots (TSan), the stats JSON and the monitor line.
#include "rt/loop_stats.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <memory>
#include <random>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "tests/alloc_counter.h"
#include "tests/stress_scale.h"

namespace felt {
namespace {

constexpr uint64_t kConcurrentTicks = test::StressIterations(1'000'000);

TEST(HistogramBinsTest, BinsAreContiguousAndHoldTheirValues) {
  // Contiguous: each bin starts where the previous one ends; widths 1 then doubling per octave.
  for (int i = 1; i <= HistogramBins::kOverflow; ++i) {
    ASSERT_EQ(HistogramBins::Lower(i), HistogramBins::Lower(i - 1) + HistogramBins::Width(i - 1))
        << "bin " << i;
  }
  EXPECT_EQ(HistogramBins::Width(0), 1u);
  EXPECT_EQ(HistogramBins::Width(static_cast<int>(HistogramBins::kExactBins) - 1), 1u);
  EXPECT_EQ(HistogramBins::Lower(HistogramBins::kOverflow), uint64_t{1} << HistogramBins::kMaxBits);
  // Every value lands in the bin that holds it, and the bin is at most 1/128 of its value wide.
  std::mt19937_64 rng(42);
  for (int n = 0; n < 100'000; ++n) {
    const int bits = static_cast<int>(rng() % 27);
    const uint64_t units = rng() % (uint64_t{1} << bits);
    const int i = HistogramBins::Index(units);
    ASSERT_LT(i, HistogramBins::kOverflow);
    ASSERT_LE(HistogramBins::Lower(i), units);
    ASSERT_LT(units, HistogramBins::Lower(i) + HistogramBins::Width(i));
    if (units >= HistogramBins::kExactBins) {
      ASSERT_LE(HistogramBins::Width(i) * 128, units);
    }
  }
  EXPECT_EQ(HistogramBins::Index(uint64_t{1} << 26), HistogramBins::kOverflow);
  EXPECT_EQ(HistogramBins::Index(UINT64_MAX), HistogramBins::kOverflow);
}

// Percentiles of `values` (ns) against the sorted reference: never below, less than a bin above.
void CheckAgainstReference(std::vector<int64_t> values, int64_t unit_ns) {
  auto histogram = std::make_unique<Histogram>(unit_ns);
  for (int64_t v : values) histogram->Record(v);
  auto snapshot = std::make_unique<HistogramSnapshot>();
  histogram->Snapshot(snapshot.get());
  std::sort(values.begin(), values.end());
  ASSERT_EQ(snapshot->count, values.size());
  EXPECT_EQ(snapshot->max_ns, values.back());
  double sum = 0.0;
  for (int64_t v : values) sum += static_cast<double>(v);
  EXPECT_NEAR(snapshot->MeanNs(), sum / static_cast<double>(values.size()), 1e-6 * sum);
  for (double q : {0.0, 0.1, 0.5, 0.9, 0.99, 0.999, 0.9999, 1.0}) {
    const size_t rank =
        std::max<size_t>(1, static_cast<size_t>(std::ceil(q * static_cast<double>(values.size()))));
    const int64_t reference = values[rank - 1];
    const int64_t estimate = snapshot->PercentileNs(q);
    EXPECT_GE(estimate, reference) << "q " << q;
    EXPECT_LT(estimate - reference, snapshot->BinWidthNs(reference)) << "q " << q;
    EXPECT_LE(snapshot->PercentileLowerNs(q), reference) << "q " << q;
  }
}

TEST(HistogramTest, PercentilesMatchSortedReferenceWithinOneBin) {
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const size_t n = 1000 + rng() % 50'000;
    std::vector<int64_t> values(n);
    // Uniform sub-ms, heavy-tailed (log-normal around 50 us), and exponential mixes.
    std::uniform_int_distribution<int64_t> uniform(0, 1'000'000);
    std::lognormal_distribution<double> lognormal(std::log(50'000.0), 1.5);
    std::exponential_distribution<double> exponential(1.0 / 200'000.0);
    for (size_t i = 0; i < n; ++i) {
      switch (trial % 3) {
        case 0:
          values[i] = uniform(rng);
          break;
        case 1:
          values[i] = static_cast<int64_t>(lognormal(rng));
          break;
        default:
          values[i] = static_cast<int64_t>(exponential(rng));
      }
    }
    CheckAgainstReference(values, trial < 10 ? 1000 : 100);
  }
}

TEST(HistogramTest, EmptyNegativeAndOverflow) {
  Histogram histogram(1000);
  HistogramSnapshot snapshot;
  histogram.Snapshot(&snapshot);
  EXPECT_EQ(snapshot.count, 0u);
  EXPECT_EQ(snapshot.PercentileNs(0.99), 0);
  histogram.Record(-5);                               // counts as 0
  const int64_t huge = int64_t{100} * 1'000'000'000;  // 100 s: beyond 2^26 us
  histogram.Record(huge);
  histogram.Snapshot(&snapshot);
  EXPECT_EQ(snapshot.count, 2u);
  EXPECT_EQ(snapshot.bins[HistogramBins::kOverflow], 1u);
  EXPECT_EQ(snapshot.PercentileNs(0.5), 1000);  // 0 reported as its bin's upper edge: 1 us
  EXPECT_EQ(snapshot.PercentileLowerNs(0.5), 0);
  EXPECT_EQ(snapshot.PercentileNs(1.0), huge);  // the overflow bin reports the exact max
  EXPECT_THROW(Histogram(0), std::invalid_argument);
}

TEST(HistogramTest, WindowHoldsOnlyTheNewValues) {
  Histogram histogram(1000);
  auto before = std::make_unique<HistogramSnapshot>();
  auto after = std::make_unique<HistogramSnapshot>();
  for (int i = 0; i < 1000; ++i) histogram.Record(900'000);  // 900 us
  histogram.Snapshot(before.get());
  for (int i = 0; i < 100; ++i) histogram.Record(10'000 + i * 100);  // 10.0 .. 19.9 us
  histogram.Snapshot(after.get());
  const HistogramSnapshot window = after->Minus(*before);
  EXPECT_EQ(window.count, 100u);
  EXPECT_EQ(window.PercentileNs(0.5), 15'000);    // 10 us + 49 * 0.1 us = 14.9 us -> bin [14, 15)
  EXPECT_EQ(window.max_ns, 20'000);               // known to its bin: [19, 20) us
  EXPECT_EQ(window.CountAtLeastNs(15'000), 50u);  // 15.0 .. 19.9 us
  EXPECT_EQ(after->CountAtLeastNs(900'000), 1000u);
  EXPECT_EQ(after->CountAtLeastNs(1'000'000), 0u);
  EXPECT_EQ(after->max_ns, 900'000);
}

TEST(LoopStatsTest, RecordsTicksOverrunsAndSkips) {
  auto stats = std::make_unique<LoopStats>(1'000'000);
  TickInfo tick;
  for (uint64_t i = 0; i < 10; ++i) {
    tick.index = i;
    tick.previous_wake_ns = tick.wake_ns;
    tick.deadline_ns = 1'000'000'000 + static_cast<int64_t>(i) * 1'000'000;
    tick.lateness_ns = static_cast<int64_t>(i) * 1000;
    tick.wake_ns = tick.deadline_ns + tick.lateness_ns;
    tick.overrun = i == 5;
    tick.periods_skipped = i == 5 ? 3 : 0;
    stats->RecordTick(tick, 200'000);
  }
  auto snapshot = std::make_unique<LoopStatsSnapshot>();
  stats->Snapshot(snapshot.get());
  EXPECT_EQ(snapshot->ticks, 10u);
  EXPECT_EQ(snapshot->overruns, 1u);
  EXPECT_EQ(snapshot->skipped_periods, 3u);
  EXPECT_EQ(snapshot->period.count, 9u);  // no period before the first tick
  EXPECT_EQ(snapshot->lateness.max_ns, 9000);
  EXPECT_EQ(snapshot->compute.PercentileNs(0.5), 200'000);
  EXPECT_EQ(snapshot->first_wake_ns, 1'000'000'000);
  EXPECT_EQ(snapshot->period_ns, 1'000'000);
}

TEST(LoopStatsTest, ConcurrentSnapshotsAreConsistent) {
  auto stats = std::make_unique<LoopStats>(1'000'000);
  std::atomic<bool> done{false};
  std::thread writer([&] {
    TickInfo tick;
    std::mt19937_64 rng(3);
    for (uint64_t i = 0; i < kConcurrentTicks; ++i) {
      tick.index = i;
      tick.previous_wake_ns = tick.wake_ns;
      tick.deadline_ns = 1'000'000 + static_cast<int64_t>(i) * 1'000'000;
      tick.lateness_ns = static_cast<int64_t>(rng() % 2'000'000);
      tick.wake_ns = tick.deadline_ns + tick.lateness_ns;
      tick.overrun = i % 1000 == 999;
      tick.periods_skipped = tick.overrun ? 2 : 0;
      stats->RecordTick(tick, static_cast<int64_t>(rng() % 500'000));
      stats->RecordSnapshotAge(static_cast<int64_t>(i % 17) * 1'000'000);
    }
    done.store(true, std::memory_order_release);
  });

  // Reader: counts only grow; a snapshot holds every tick its counter announces; the max covers
  // every bin seen (release/acquire between the bin and the max).
  auto previous = std::make_unique<LoopStatsSnapshot>();
  auto current = std::make_unique<LoopStatsSnapshot>();
  uint64_t snapshots = 0;
  uint64_t failures = 0;
  while (!done.load(std::memory_order_acquire) || snapshots == 0) {
    stats->Snapshot(current.get());
    if (current->lateness.count < current->ticks) ++failures;
    if (current->compute.count < current->ticks) ++failures;
    if (current->lateness.count < previous->lateness.count) ++failures;
    if (current->ticks < previous->ticks) ++failures;
    if (current->lateness.count > 0 &&
        current->lateness.max_ns < current->lateness.PercentileLowerNs(1.0)) {
      ++failures;
    }
    std::swap(previous, current);
    ++snapshots;
  }
  writer.join();
  stats->Snapshot(current.get());
  EXPECT_EQ(failures, 0u);
  EXPECT_GT(snapshots, 0u);
  EXPECT_EQ(current->ticks, kConcurrentTicks);
  EXPECT_EQ(current->lateness.count, kConcurrentTicks);
  EXPECT_EQ(current->snapshot_age.count, kConcurrentTicks);
  EXPECT_EQ(current->overruns, kConcurrentTicks / 1000);
  EXPECT_EQ(current->skipped_periods, 2 * (kConcurrentTicks / 1000));
}

TEST(LoopStatsTest, SnapshotDoesNotAllocate) {
  auto stats = std::make_unique<LoopStats>(1'000'000);
  auto snapshot = std::make_unique<LoopStatsSnapshot>();
  AllocationGuard guard;
  stats->Snapshot(snapshot.get());
  EXPECT_EQ(guard.allocations(), 0u);
}

// Two loops' snapshots with known contents: haptic lateness 10..109 us, sim frames 2..3 ms.
void MakeServerSnapshots(LoopStatsSnapshot* haptic, LoopStatsSnapshot* sim) {
  auto haptic_stats = std::make_unique<LoopStats>(1'000'000);
  auto sim_stats = std::make_unique<LoopStats>(16'666'667);
  TickInfo tick;
  for (int i = 0; i < 100; ++i) {
    tick.previous_wake_ns = tick.wake_ns;
    tick.deadline_ns = 1'000'000'000 + int64_t{i} * 1'000'000;
    tick.lateness_ns = (10 + i) * 1000;
    tick.wake_ns = tick.deadline_ns + tick.lateness_ns;
    haptic_stats->RecordTick(tick, 50'000);
  }
  for (int i = 0; i < 6; ++i) {
    tick.previous_wake_ns = 0;
    tick.wake_ns = 1'000'000'000 + int64_t{i} * 16'666'667;
    tick.deadline_ns = tick.wake_ns;
    tick.lateness_ns = 0;
    sim_stats->RecordTick(tick, 2'000'000 + i * 200'000);
  }
  haptic_stats->Snapshot(haptic);
  sim_stats->Snapshot(sim);
}

TEST(StatsJsonTest, ServerJsonHasTheIssueKeys) {
  auto haptic = std::make_unique<LoopStatsSnapshot>();
  auto sim = std::make_unique<LoopStatsSnapshot>();
  MakeServerSnapshots(haptic.get(), sim.get());
  const std::string json = ServerStatsJson(*haptic, *sim, true);
  for (const char* key :
       {"\"realtime\": true", "\"haptic\": {", "\"lateness_us\": {", "\"p50\": 60", "\"p99\": 109",
        "\"p999\": 109", "\"max\": 109", "\"overruns\": 0", "\"ticks\": 100", "\"sim\": {",
        "\"frame_ms\": {", "\"frames\": 6"}) {
    EXPECT_NE(json.find(key), std::string::npos) << key << " missing in\n" << json;
  }
  // Balanced braces, ends with a newline.
  EXPECT_EQ(std::count(json.begin(), json.end(), '{'), std::count(json.begin(), json.end(), '}'));
  EXPECT_EQ(json.back(), '\n');
}

TEST(StatsSummaryTest, MonitorLineFormat) {
  auto haptic = std::make_unique<LoopStatsSnapshot>();
  auto sim = std::make_unique<LoopStatsSnapshot>();
  MakeServerSnapshots(haptic.get(), sim.get());
  const std::string line = FormatMonitorLine(*haptic, nullptr, *sim, nullptr);
  const std::regex pattern(
      R"(haptic: \d+ ticks/s lateness p50 60\.0 us p99 109 us p99\.9 109 us max 109 us )"
      R"(overruns 0 \| sim: \d+ frames/s frame p50 2\.\d+ ms p99 3\.\d+ ms p99\.9 3\.\d+ ms )"
      R"(max 3\.\d+ ms overruns 0)");
  EXPECT_TRUE(std::regex_match(line, pattern)) << line;

  // Windowed: only what happened since `previous`.
  auto later = std::make_unique<LoopStatsSnapshot>(*haptic);
  later->taken_ns = haptic->taken_ns + 1'000'000'000;
  later->ticks += 1000;
  const std::string windowed = FormatHapticSummary(*later, haptic.get());
  EXPECT_EQ(windowed.rfind("haptic: 1000 ticks/s", 0), 0u) << windowed;
}

}  // namespace
}  // namespace felt
