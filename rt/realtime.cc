#include "rt/realtime.h"

#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <spdlog/spdlog.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace felt {
namespace {

// "Operation not permitted (EPERM)" for an errno value.
std::string ErrnoText(int error) {
  char buffer[128];
  const char* text = strerror_r(error, buffer, sizeof(buffer));  // GNU variant
  const char* name = strerrorname_np(error);
  return std::string(text) + " (" + (name != nullptr ? name : std::to_string(error)) + ")";
}

// Turns a pthread-style return code (0 or an errno value) into a step, warning when refused.
RealtimeStep Step(int error, const std::string& what) {
  RealtimeStep step;
  if (error == 0) {
    step.status = RealtimeStepStatus::kGranted;
    return step;
  }
  step.status = RealtimeStepStatus::kRefused;
  step.error = ErrnoText(error);
  spdlog::warn("realtime: {} refused: {}; the loop runs without it", what, step.error);
  return step;
}

std::string StepText(const RealtimeStep& step) {
  switch (step.status) {
    case RealtimeStepStatus::kNotRequested:
      return "off";
    case RealtimeStepStatus::kGranted:
      return "granted";
    case RealtimeStepStatus::kRefused:
      return "refused (" + step.error + ")";
  }
  return "?";
}

}  // namespace

bool RealtimeReport::all_granted() const {
  return !fifo.refused() && !affinity.refused() && !memory_lock.refused() && !timer_slack.refused();
}

std::string RealtimeReport::Summary() const {
  return "SCHED_FIFO " + StepText(fifo) + ", cpu pinning " + StepText(affinity) + ", mlockall " +
         StepText(memory_lock) + ", timer slack " + StepText(timer_slack);
}

RealtimeReport ApplyRealtime(const RealtimeSettings& settings) {
  RealtimeReport report;

  // SCHED_FIFO at the requested priority (EPERM without CAP_SYS_NICE, EINVAL out of 1..99).
  if (settings.fifo_priority != 0) {
    sched_param param{};
    param.sched_priority = settings.fifo_priority;
    report.fifo = Step(pthread_setschedparam(pthread_self(), SCHED_FIFO, &param),
                       "SCHED_FIFO priority " + std::to_string(settings.fifo_priority));
  }
  report.fifo_granted = report.fifo.granted();

  // Pinning to one CPU; an index outside cpu_set_t cannot even be expressed: refused as EINVAL.
  if (settings.cpu >= 0) {
    int error = EINVAL;
    if (settings.cpu < CPU_SETSIZE) {
      cpu_set_t set;
      CPU_ZERO(&set);
      CPU_SET(settings.cpu, &set);
      error = pthread_setaffinity_np(pthread_self(), sizeof(set), &set);
    }
    report.affinity = Step(error, "pinning to CPU " + std::to_string(settings.cpu));
  } else if (settings.cpu != -1) {
    report.affinity = Step(EINVAL, "pinning to CPU " + std::to_string(settings.cpu));
  }

  // Locking every present and future page (process-wide), so no tick waits on a page fault.
  if (settings.lock_memory) {
    const int error = mlockall(MCL_CURRENT | MCL_FUTURE) == 0 ? 0 : errno;
    report.memory_lock = Step(error, "mlockall");
  }

  // Timer slack: normal threads carry 50 us, which delays every timed wake-up.
  if (settings.timer_slack_ns != 0) {
    int error = EINVAL;
    if (settings.timer_slack_ns > 0) {
      error = prctl(PR_SET_TIMERSLACK, static_cast<unsigned long>(settings.timer_slack_ns), 0, 0,
                    0) == 0
                  ? 0
                  : errno;
    }
    report.timer_slack =
        Step(error, "timer slack " + std::to_string(settings.timer_slack_ns) + " ns");
  }
  return report;
}

CpuDmaLatencyHold::CpuDmaLatencyHold(const char* path) {
  // Open and write a binary 32-bit 0; the request lasts as long as the file stays open.
  const int fd = open(path, O_WRONLY | O_CLOEXEC);
  if (fd < 0) {
    error_ = ErrnoText(errno);
  } else {
    const int32_t zero = 0;
    const ssize_t written = write(fd, &zero, sizeof(zero));
    if (written != static_cast<ssize_t>(sizeof(zero))) {
      error_ = ErrnoText(written < 0 ? errno : EIO);
      close(fd);
    } else {
      fd_ = fd;
    }
  }
  if (fd_ < 0) {
    spdlog::warn("realtime: holding {} at 0 refused: {}; idle CPUs may wake up slowly", path,
                 error_);
  }
}

CpuDmaLatencyHold::~CpuDmaLatencyHold() {
  if (fd_ >= 0) close(fd_);
}

}  // namespace felt
