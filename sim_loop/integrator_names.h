#pragma once
// The names scene files, logs and benchmark tables use for each IntegratorKind.

#include <array>
#include <optional>
#include <string_view>

#include "sim_loop/cloth_spec.h"

namespace felt {

/// One integrator and its scene-file name.
struct IntegratorName {
  IntegratorKind kind;
  std::string_view name;  ///< lower_snake_case, as written in [integration] integrator = "..."
};

/// Every integrator with its name, in the order of IntegratorKind (the default first).
inline constexpr std::array<IntegratorName, 8> kIntegratorNames = {{
    {IntegratorKind::kLeapfrogVerlet, "leapfrog_verlet"},
    {IntegratorKind::kExplicitEuler, "explicit_euler"},
    {IntegratorKind::kSymplecticEuler, "symplectic_euler"},
    {IntegratorKind::kExplicitMidpoint, "explicit_midpoint"},
    {IntegratorKind::kRk4, "rk4"},
    {IntegratorKind::kBasicVerlet, "basic_verlet"},
    {IntegratorKind::kVelocityVerlet, "velocity_verlet"},
    {IntegratorKind::kImplicitEuler, "implicit_euler"},
}};

/// The scene-file name of `kind`, e.g. "leapfrog_verlet"; "unknown" for a value outside the enum.
constexpr std::string_view ToName(IntegratorKind kind) {
  for (const IntegratorName& entry : kIntegratorNames) {
    if (entry.kind == kind) return entry.name;
  }
  return "unknown";
}

/// The integrator named `name` (exact, case-sensitive match), or nullopt when there is none.
constexpr std::optional<IntegratorKind> IntegratorFromName(std::string_view name) {
  for (const IntegratorName& entry : kIntegratorNames) {
    if (entry.name == name) return entry.kind;
  }
  return std::nullopt;
}

}  // namespace felt
