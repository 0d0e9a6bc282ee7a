#pragma once
// Real-time settings for the calling thread: SCHED_FIFO, CPU pinning, mlockall, timer slack, and
// holding /dev/cpu_dma_latency at 0. Each step is requested separately and reports whether it was
// granted; a refused step logs one warning and the loop still runs (issue 5, "Timing";
// shared/notes/cyclonedds-and-realtime.md has what each step buys on these machines).

#include <cstdint>
#include <string>

namespace felt {

/// What a loop thread asks for. Every field has an "off" value; the defaults ask for nothing.
struct RealtimeSettings {
  int fifo_priority = 0;     ///< SCHED_FIFO priority 1..99; 0 = keep normal scheduling
  int cpu = -1;              ///< pin the thread to this CPU index; -1 = no pinning
  bool lock_memory = false;  ///< mlockall(MCL_CURRENT | MCL_FUTURE) (process-wide)
  int spin_us = 0;  ///< sleep until this many us before each deadline, then spin; 0 = no spin
  int64_t timer_slack_ns = 0;  ///< prctl(PR_SET_TIMERSLACK) in ns, 1 = minimal; 0 = leave as is
};

/// Outcome of one requested step.
enum class RealtimeStepStatus {
  kNotRequested,  ///< the setting asked for nothing
  kGranted,       ///< the system call succeeded
  kRefused,       ///< the system call failed (see the step's `error`)
};

/// Outcome and, when refused, the reason ("Operation not permitted (EPERM)") of one step.
struct RealtimeStep {
  RealtimeStepStatus status = RealtimeStepStatus::kNotRequested;  ///< what happened
  std::string error;  ///< strerror text and errno name when refused; empty otherwise

  /// True when the step was requested and granted.
  bool granted() const { return status == RealtimeStepStatus::kGranted; }
  /// True when the step was requested and refused.
  bool refused() const { return status == RealtimeStepStatus::kRefused; }
};

/// What ApplyRealtime() obtained for the calling thread.
struct RealtimeReport {
  RealtimeStep fifo;          ///< SCHED_FIFO at `fifo_priority`
  RealtimeStep affinity;      ///< pinning to `cpu`
  RealtimeStep memory_lock;   ///< mlockall
  RealtimeStep timer_slack;   ///< PR_SET_TIMERSLACK
  bool fifo_granted = false;  ///< SCHED_FIFO granted: what the stats call `realtime`

  /// True when no requested step was refused.
  bool all_granted() const;
  /// One line, e.g. "SCHED_FIFO granted, cpu pinning refused (Invalid argument (EINVAL)),
  /// mlockall off, timer slack granted".
  std::string Summary() const;
};

/// Applies `settings` to the calling thread (memory locking is process-wide), step by step: every
/// requested step is attempted even when an earlier one was refused, and each refusal logs one
/// spdlog warning naming the step and the errno text. Never throws for a refusal: the loop runs on
/// without what was refused. Set-up time only (allocates, logs): not real-time safe.
RealtimeReport ApplyRealtime(const RealtimeSettings& settings);

/// Holds /dev/cpu_dma_latency open with the value 0 (no deep C-states) while alive, which cuts
/// wake-up latency on these machines (shared/notes/cyclonedds-and-realtime.md). The kernel drops
/// the request when the file is closed (destruction). A refusal (not root, no such device) logs
/// one warning and leaves held() false. Set-up time only: not real-time safe.
class CpuDmaLatencyHold {
 public:
  /// Opens /dev/cpu_dma_latency and writes a 32-bit 0 (or `path` instead, for tests).
  explicit CpuDmaLatencyHold(const char* path = "/dev/cpu_dma_latency");
  /// Closes the file, which releases the latency request.
  ~CpuDmaLatencyHold();

  CpuDmaLatencyHold(const CpuDmaLatencyHold&) = delete;
  CpuDmaLatencyHold& operator=(const CpuDmaLatencyHold&) = delete;

  /// True when the request is in force.
  bool held() const { return fd_ >= 0; }
  /// Why it was refused (strerror text and errno name); empty when held.
  const std::string& error() const { return error_; }

 private:
  int fd_ = -1;
  std::string error_;
};

}  // namespace felt
