#include "rt/loop_runner.h"

#include <stdexcept>
#include <string>

namespace felt {

void ValidateLoopRunOptions(const LoopRunOptions& options) {
  if (options.duration_ns <= 0 && options.stop == nullptr) {
    throw std::invalid_argument("RunLoop: needs duration_ns > 0 or a stop flag");
  }
  if (options.period_ns <= 0) {
    throw std::invalid_argument("RunLoop: period_ns must be > 0, got " +
                                std::to_string(options.period_ns));
  }
  if (options.realtime.spin_us < 0 ||
      int64_t{options.realtime.spin_us} * 1000 >= options.period_ns) {
    throw std::invalid_argument("RunLoop: realtime.spin_us must be in [0, period), got " +
                                std::to_string(options.realtime.spin_us) + " us");
  }
}

}  // namespace felt
