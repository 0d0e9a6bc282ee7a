#pragma once
// Pieces the cloth benchmarks share beyond base/report.h (whose tables, statistics and machine
// description every bench uses unqualified): the resized default curtain and the energy scale.
// Not real-time safe; for the benchmark commands only.

#include <cstdint>
#include <string>

#include "base/report.h"
#include "sim_loop/cloth_spec.h"

namespace felt::bench {

using namespace ::felt::report;  // NOLINT: the benches' shared vocabulary

/// The default curtain (the scene file at `scene_path`, normally scenes/curtain.toml) resized to
/// `grid` x `grid` particles over the same 0.496 m square: spacing scaled by (W0 - 1) / (grid -
/// 1), per-particle drag scaled by the particle count ratio so the total drag stays (as in
/// scenes/curtain_128.toml); mass, spring constants, pins, integration and Provot unchanged.
/// Throws SceneError for a bad scene file, std::invalid_argument for grid < 2.
SimSpec ResizedCurtain(const std::string& scene_path, int32_t grid);

/// The energy scale the cloth reports use for relative energy figures: M g L [J], the energy of
/// lowering the whole cloth by its own height (spec's total mass, |gravity|, (height - 1) *
/// spacing).
double EnergyScale_J(const SimSpec& spec);

}  // namespace felt::bench
