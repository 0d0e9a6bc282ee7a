#include "base/simd.h"

#include <algorithm>

namespace felt {
namespace {

// What the CPU runs, asked once (the only place that asks).
SimdLevel DetectSimdLevel() {
#if defined(__x86_64__)
  // This may run before libgcc's own constructor has filled in the CPU model (GCC manual,
  // "x86 Built-in Functions": __builtin_cpu_init before use in a constructor).
  __builtin_cpu_init();
  const bool avx2 = __builtin_cpu_supports("avx2") != 0;
  const bool avx512f = __builtin_cpu_supports("avx512f") != 0;
  if (avx2 && avx512f) return SimdLevel::kAvx512;
  if (avx2) return SimdLevel::kAvx2;
#endif
  return SimdLevel::kPortable;
}

}  // namespace

namespace simd_internal {
std::atomic<SimdLevel> g_active_level{CpuSimdLevel()};
}  // namespace simd_internal

SimdLevel CpuSimdLevel() {
  static const SimdLevel level = DetectSimdLevel();
  return level;
}

void LimitSimdLevel(SimdLevel level) {
  simd_internal::g_active_level.store(std::min(level, CpuSimdLevel()), std::memory_order_relaxed);
}

const char* SimdLevelName(SimdLevel level) {
  switch (level) {
    case SimdLevel::kAvx2:
      return "avx2";
    case SimdLevel::kAvx512:
      return "avx512f+avx2";
    case SimdLevel::kPortable:
      break;
  }
  return "portable";
}

}  // namespace felt
