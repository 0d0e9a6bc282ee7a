#pragma once
// A fixed histogram of short durations (the cost of one transport hop), written by one thread and
// read by any: 100 ns buckets up to 100 us plus an overflow bucket and the exact maximum.
// No allocation after construction; Record is real-time safe.

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdint>

namespace felt::transport {

/// Percentiles of a hop's cost, microseconds; resolution 0.1 us (bucket upper edges).
struct HopSummary {
  uint64_t count = 0;  ///< durations recorded
  double mean_us = 0;  ///< mean, us
  double p50_us = 0;   ///< median, us
  double p99_us = 0;   ///< 99th percentile, us
  double p999_us = 0;  ///< 99.9th percentile, us
  double max_us = 0;   ///< largest, us (exact)
};

/// Histogram of durations in ns. One writer thread at a time (writers must be serialised by the
/// caller); Summary() from any thread (relaxed reads: a summary taken while recording may be off
/// by the samples in flight).
class HopHistogram {
 public:
  static constexpr int64_t kBucketNs = 100;  ///< bucket width, ns
  static constexpr size_t kBuckets = 1000;   ///< buckets below the overflow: 0..100 us

  /// Adds one duration `ns` (negative counts as 0). Writer only. Real-time safe.
  void Record(int64_t ns) {
    ns = std::max<int64_t>(ns, 0);
    const size_t bucket = std::min<size_t>(static_cast<size_t>(ns / kBucketNs), kBuckets);
    Bump(buckets_[bucket], 1);
    Bump(count_, 1);
    Bump(sum_ns_, static_cast<uint64_t>(ns));
    if (static_cast<uint64_t>(ns) > max_ns_.load(std::memory_order_relaxed)) {
      max_ns_.store(static_cast<uint64_t>(ns), std::memory_order_relaxed);
    }
  }

  /// Percentiles of everything recorded so far. Any thread.
  HopSummary Summary() const {
    HopSummary s;
    s.count = count_.load(std::memory_order_relaxed);
    if (s.count == 0) return s;
    s.mean_us = static_cast<double>(sum_ns_.load(std::memory_order_relaxed)) / 1e3 /
                static_cast<double>(s.count);
    s.max_us = static_cast<double>(max_ns_.load(std::memory_order_relaxed)) / 1e3;
    s.p50_us = Quantile(0.5, s);
    s.p99_us = Quantile(0.99, s);
    s.p999_us = Quantile(0.999, s);
    return s;
  }

 private:
  static void Bump(std::atomic<uint64_t>& a, uint64_t by) {
    a.store(a.load(std::memory_order_relaxed) + by, std::memory_order_relaxed);
  }

  double Quantile(double q, const HopSummary& s) const {
    // The upper edge of the bucket holding the q-quantile, capped at the exact maximum.
    const auto rank = static_cast<uint64_t>(q * static_cast<double>(s.count - 1)) + 1;
    uint64_t seen = 0;
    for (size_t b = 0; b < kBuckets; ++b) {
      seen += buckets_[b].load(std::memory_order_relaxed);
      if (seen >= rank) {
        return std::min(static_cast<double>((b + 1) * kBucketNs) / 1e3, s.max_us);
      }
    }
    return s.max_us;
  }

  std::array<std::atomic<uint64_t>, kBuckets + 1> buckets_{};
  std::atomic<uint64_t> count_{0};
  std::atomic<uint64_t> sum_ns_{0};
  std::atomic<uint64_t> max_ns_{0};
};

}  // namespace felt::transport
