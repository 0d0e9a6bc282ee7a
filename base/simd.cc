#include "base/simd.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>

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

// The level to start with: CpuSimdLevel(), capped by the environment variable FELT_SIMD
// ("portable", "avx2" or "avx512") if it is set and not empty, so that one machine measures what
// a narrower CPU would run (bench/results/cloth.md's AVX2-only figure). Read once, at start. An
// unknown value stops the process with a message naming the variable and the values it takes:
// a benchmark must not silently run at a level it was not asked for.
SimdLevel StartSimdLevel() {
  const SimdLevel cpu = CpuSimdLevel();
  const char* cap = std::getenv("FELT_SIMD");
  if (cap == nullptr || cap[0] == '\0') return cpu;
  if (const std::optional<SimdLevel> level = SimdLevelFromEnvName(cap)) {
    return std::min(*level, cpu);
  }
  std::fprintf(stderr,
               "felt: environment variable FELT_SIMD = \"%s\": expected portable, avx2 or avx512 "
               "(or unset for the CPU's own level, %s)\n",
               cap, SimdLevelEnvName(cpu));
  std::exit(2);
}

}  // namespace

namespace simd_internal {
std::atomic<SimdLevel> g_active_level{StartedSimdLevel()};
}  // namespace simd_internal

SimdLevel CpuSimdLevel() {
  static const SimdLevel level = DetectSimdLevel();
  return level;
}

const char* SimdLevelEnvName(SimdLevel level) {
  switch (level) {
    case SimdLevel::kAvx2:
      return "avx2";
    case SimdLevel::kAvx512:
      return "avx512";
    case SimdLevel::kPortable:
      break;
  }
  return "portable";
}

std::optional<SimdLevel> SimdLevelFromEnvName(const char* name) {
  for (SimdLevel level : {SimdLevel::kPortable, SimdLevel::kAvx2, SimdLevel::kAvx512}) {
    if (std::strcmp(name, SimdLevelEnvName(level)) == 0) return level;
  }
  return std::nullopt;
}

SimdLevel StartedSimdLevel() {
  static const SimdLevel level = StartSimdLevel();
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
