#pragma once
// Where the haptic tick reads pointer samples and writes forces: two small interfaces with one
// virtual call per device per tick, and the in-process implementations (a preloaded trace
// replayed on the haptic thread's clock, a newest-value source a test or an embedding thread
// writes, and a sink that keeps the newest force and counters). The DDS transport's adapters are
// in server/transport_io.h.
#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "collision/mesh.h"
#include "recordings/trace.h"
#include "rt/arrival_signal.h"
#include "rt/triple_buffer.h"

namespace felt {

/// The newest pointer sample of one device as the haptic tick sees it. Device frame (_D).
struct PointerInput {
  uint64_t seq = 0;                 ///< sample sequence number (a new value = a new sample)
  int64_t device_time_ns = 0;       ///< the device's clock at measurement, ns (any epoch)
  int64_t receive_time_ns = 0;      ///< CLOCK_MONOTONIC when it became available here, ns
  Vec3 p_D_m = Vec3::Zero();        ///< tip position, device frame, m
  Vec3 v_D_m_per_s = Vec3::Zero();  ///< tip velocity, device frame, m/s
  uint32_t buttons = 0;             ///< button bit mask
};

/// A source of pointer samples, read by the haptic thread only.
class PointerSource {
 public:
  virtual ~PointerSource() = default;
  /// The newest sample of device `device_index` at CLOCK_MONOTONIC `now_ns` into `*out`; false
  /// (and `*out` untouched) when the device has sent nothing yet. Haptic thread only.
  /// Implementations must be real-time safe: no allocation, lock, log, exception or I/O.
  virtual bool Latest(uint32_t device_index, int64_t now_ns, PointerInput* out) = 0;
  /// The signal that counts each new sample of device `device_index` as it becomes readable
  /// (after it is published), for the haptic tick on arrival (docs/server.md); nullptr when the
  /// source cannot tell (the tick is then periodic). Lives as long as the source. Set-up.
  virtual const ArrivalSignal* Arrivals(uint32_t /*device_index*/) const { return nullptr; }
};

/// One force for one device as the haptic tick produces it. Device frame (_D).
struct ForceOutput {
  uint64_t answers_seq = 0;            ///< seq of the pointer sample it answers
  int64_t answers_device_time_ns = 0;  ///< device_time_ns of that sample
  Vec3 force_D_N = Vec3::Zero();       ///< force to output, device frame, N
  Vec3 proxy_D_m = Vec3::Zero();       ///< the proxy centre, device frame, m
  bool in_contact = false;             ///< the proxy touches the cloth
  uint32_t flags = 0;                  ///< SafetyFlag bits (= transport kForce* bits)
  int64_t tick_time_ns = 0;            ///< CLOCK_MONOTONIC of the tick that made it
  /// Local contact model (Mark et al. 1996): F(p_D) = k max(0, (point - p_D) . n) n.
  Vec3 contact_point_D_m = Vec3::Zero();   ///< a point of the contact plane (proxy), device, m
  Vec3 contact_normal_D = Vec3::Zero();    ///< unit, toward the free side, device frame (0: none)
  double contact_stiffness_N_per_m = 0.0;  ///< k, device frame, N/m (0: not in contact, or the
                                           ///< force is ramped, stale or NaN: hold force_D_N)
};

/// Where forces go, written by the haptic thread only.
class ForceSink {
 public:
  virtual ~ForceSink() = default;
  /// Hands one force of device `device_index` on. Haptic thread only. Implementations must be
  /// real-time safe; a refusal (full queue) is theirs to count.
  virtual void Push(uint32_t device_index, const ForceOutput& force) = 0;
};

/// Replays preloaded traces (recordings/trace.h), one per device (or none), at their recorded
/// times on the haptic thread's clock: the first Latest() call of any device fixes the time
/// origin t0, and sample i becomes available at t0 + t_s[i] - t_s[0]. After the last sample the
/// source keeps returning it (its age grows, so the server sees the input go stale).
class TracePointerSource final : public PointerSource {
 public:
  /// `traces[d]` feeds device d (an empty trace: the device never sends). Set-up: copies.
  explicit TracePointerSource(std::vector<std::vector<TraceSample>> traces);
  /// Real-time safe: advances a per-device index through the preloaded array.
  bool Latest(uint32_t device_index, int64_t now_ns, PointerInput* out) override;
  /// Whether every device's trace has been played to its last sample. Haptic thread only.
  bool finished() const;

 private:
  struct Cursor {
    std::vector<TraceSample> samples;
    size_t next = 0;  // samples [0, next) have been released
  };
  std::vector<Cursor> cursors_;
  int64_t t0_ns_ = 0;
  bool started_ = false;
};

/// In-process newest-value source: one writer thread calls Set(); the haptic thread reads.
/// One triple buffer per device (lock-free, wait-free both sides).
class LatestPointerSource final : public PointerSource {
 public:
  /// A source for `device_count` devices. Set-up: allocates.
  explicit LatestPointerSource(uint32_t device_count);
  /// Publishes `sample` as device `device_index`'s newest (its seq should grow). Writer thread
  /// only. Real-time safe. Out-of-range indices are ignored.
  void Set(uint32_t device_index, const PointerInput& sample);
  /// Real-time safe.
  bool Latest(uint32_t device_index, int64_t now_ns, PointerInput* out) override;
  /// Counts every Set() of the device (nullptr for an index out of range).
  const ArrivalSignal* Arrivals(uint32_t device_index) const override;

 private:
  struct Slot {
    TripleBuffer<PointerInput> buffer;
    std::atomic<bool> any{false};
    ArrivalSignal arrivals;
  };
  std::vector<std::unique_ptr<Slot>> slots_;
};

/// In-process sink: keeps each device's newest force (readable from any one other thread through
/// a triple buffer) and counters. For `--trace` runs, tests and the benchmark.
class CapturingForceSink final : public ForceSink {
 public:
  /// A sink for `device_count` devices. Set-up: allocates.
  explicit CapturingForceSink(uint32_t device_count);
  /// Real-time safe.
  void Push(uint32_t device_index, const ForceOutput& force) override;
  /// Forces pushed for `device_index` so far. Any thread.
  uint64_t pushed(uint32_t device_index) const;
  /// Largest |force| pushed for `device_index`, N. Any thread.
  double peak_force_N(uint32_t device_index) const;
  /// The newest force of `device_index` into `*out`; false before the first. ONE reader thread.
  bool Newest(uint32_t device_index, ForceOutput* out);

 private:
  struct Slot {
    TripleBuffer<ForceOutput> buffer;
    std::atomic<uint64_t> pushed{0};
    std::atomic<double> peak_N{0.0};
  };
  std::vector<std::unique_ptr<Slot>> slots_;
};

}  // namespace felt
