#pragma once
// What the CPU this process runs on can do, asked once. Used by the sim_loop kernels that have an
// AVX2 (or AVX-512) path beside their portable one (bvh.cc, cloth_constraints.cc, cloth_forces.cc).

namespace felt {

/// True if this CPU runs AVX2 instructions (GCC's __builtin_cpu_supports, asked once per process).
inline bool CpuHasAvx2() {
#if defined(__x86_64__)
  static const bool has = __builtin_cpu_supports("avx2") != 0;
  return has;
#else
  return false;
#endif
}

/// True if this CPU runs AVX-512F instructions (asked once per process).
inline bool CpuHasAvx512f() {
#if defined(__x86_64__)
  static const bool has = __builtin_cpu_supports("avx512f") != 0;
  return has;
#else
  return false;
#endif
}

}  // namespace felt
