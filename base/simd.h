#pragma once
// SIMD behind one door: the vector instruction level the kernels of sim_loop/ and collision/ use
// (spring forces in cloth_forces.cc, Provot's sweeps, attachments and structure-of-arrays
// conversion in cloth_constraints.cc, the AABB repair in bvh.cc), chosen once at start from what
// the CPU runs, and the one test switch that caps it. Every level gives the same bits; a level only
// changes speed. Each kernel family keeps a table with one entry per level (SimdTable) and picks
// its entry with PickSimd, one relaxed atomic load. The environment variable
// FELT_SIMD=portable|avx2|avx512, read once at start, caps the level for a whole process (to
// measure a narrower CPU's speed on a wider one). Depends on the standard library only.

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <optional>

namespace felt {

/// Vector instruction levels the kernels are written for, narrowest first; each includes the ones
/// below it.
enum class SimdLevel : uint8_t {
  kPortable = 0,  ///< scalar (and baseline SSE2) loops only, any CPU
  kAvx2 = 1,      ///< AVX2 kernels: four doubles or eight floats a step
  kAvx512 = 2,    ///< also the AVX-512F kernels, sixteen floats a step (Provot across rows)
};

/// The widest level there is: LimitSimdLevel(kWidestSimdLevel) lifts any cap.
inline constexpr SimdLevel kWidestSimdLevel = SimdLevel::kAvx512;

/// How many levels SimdLevel has (the length of a SimdTable).
inline constexpr size_t kNumSimdLevels = static_cast<size_t>(kWidestSimdLevel) + 1;

/// One entry per SimdLevel, indexed by its value: a kernel family's implementations (usually a
/// struct of function pointers); a level without its own kernel repeats the one below it.
template <class Kernels>
using SimdTable = std::array<Kernels, kNumSimdLevels>;

/// The widest level this CPU runs (GCC's __builtin_cpu_supports, asked once per process);
/// kPortable off x86-64.
SimdLevel CpuSimdLevel();

/// The level the process started with: CpuSimdLevel() capped by the environment variable
/// FELT_SIMD ("portable", "avx2" or "avx512"; unset or empty: no cap), read once. An unknown value
/// stops the process at start with a message on stderr (exit status 2).
SimdLevel StartedSimdLevel();

/// "portable", "avx2" or "avx512": the name FELT_SIMD gives a level.
const char* SimdLevelEnvName(SimdLevel level);

/// The level FELT_SIMD's value `name` stands for ("portable", "avx2", "avx512"); nullopt if none.
std::optional<SimdLevel> SimdLevelFromEnvName(const char* name);

/// Tests only (FELT_SIMD caps a whole process): caps every kernel at `level` (the CPU's own level
/// if that is narrower), so one machine checks every level it has; LimitSimdLevel(kWidestSimdLevel)
/// lifts the cap. Not thread-safe against kernels running at the same time (they may use either
/// level: same bits).
void LimitSimdLevel(SimdLevel level);

/// "portable", "avx2" or "avx512f+avx2": the name of a level as reports show it.
const char* SimdLevelName(SimdLevel level);

namespace simd_internal {
/// The level in use: CpuSimdLevel() capped by LimitSimdLevel. Set by simd.cc's initialiser at
/// start (kPortable, which is 0, until then: the same bits, only slower).
extern std::atomic<SimdLevel> g_active_level;
}  // namespace simd_internal

/// The level the kernels use now (one relaxed atomic load).
inline SimdLevel ActiveSimdLevel() {
  return simd_internal::g_active_level.load(std::memory_order_relaxed);
}

/// The entry of `table` for the level in use.
template <class Kernels>
const Kernels& PickSimd(const SimdTable<Kernels>& table) {
  return table[static_cast<size_t>(ActiveSimdLevel())];
}

}  // namespace felt
