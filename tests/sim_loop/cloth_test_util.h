#pragma once
// Small scene builders shared by the cloth tests.

#include <cstdint>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "sim_loop/cloth.h"
#include "sim_loop/cloth_internal.h"

namespace felt::cloth_test {

/// One 60 Hz frame, s.
inline constexpr double kFrame_s = 1.0 / 60.0;

/// True if the two position (or velocity) arrays hold the same bits.
inline bool BitwiseEqual(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(Vec3)) == 0;
}

/// A corner pin.
inline PinSpec Corner(const std::string& name) {
  PinSpec pin;
  pin.kind = PinKind::kCorner;
  pin.name = name;
  return pin;
}

/// An edge pin ("top", "bottom", "left" or "right").
inline PinSpec EdgePin(const std::string& name) {
  PinSpec pin;
  pin.kind = PinKind::kEdge;
  pin.name = name;
  return pin;
}

/// A pin on the particle at column `col`, row `row`.
inline PinSpec ParticlePin(int32_t col, int32_t row) {
  PinSpec pin;
  pin.kind = PinKind::kParticle;
  pin.col = col;
  pin.row = row;
  return pin;
}

/// A `grid` x `grid` curtain 0.5 m wide hanging in the x-y plane from its two top corners.
inline SimSpec Curtain(int32_t grid) {
  SimSpec spec;
  spec.cloth.width = grid;
  spec.cloth.height = grid;
  spec.cloth.spacing_m = 0.5 / (grid - 1);
  spec.cloth.origin_m = Vec3(-0.25, 0.25, 0.0);
  spec.cloth.pins = {Corner("top_left"), Corner("top_right")};
  return spec;
}

/// The same cloth starting horizontal (rows along +z), so it swings down from its two corners.
inline SimSpec HorizontalCurtain(int32_t grid) {
  SimSpec spec = Curtain(grid);
  spec.cloth.v_axis = Vec3::UnitZ();
  return spec;
}

/// `model`'s rest state with every free particle moved by up to `amplitude` spacings per axis and
/// stretched down from the top row by `stretch` (1: not stretched), random velocities [m/s] and
/// external forces [N], from `seed`: a hard, reproducible input for the kernels.
inline ClothState ScrambledState(const ClothModel& model, double amplitude, double stretch,
                                 uint32_t seed) {
  ClothState state = MakeClothState(model);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double a = amplitude * model.spacing_m;
  const double top = state.x[0].y();
  for (size_t p = 0; p < state.x.size(); ++p) {
    state.scratch->external_N[p] = 1e-3 * Vec3(u(rng), u(rng), u(rng));
    if (model.inv_mass_per_kg[p] == 0.0) continue;
    state.x[p] += a * Vec3(u(rng), u(rng), u(rng));
    state.x[p].y() = top + stretch * (state.x[p].y() - top);
    state.v[p] = Vec3(u(rng), u(rng), u(rng));
  }
  return state;
}

/// One setting of Provot's sweeps that the kernel tests cover.
struct ProvotCase {
  bool multiresolution;  ///< multiresolution families and long range attachments on
  int32_t iterations;    ///< sweeps per call
};

/// With and without the multiresolution families and attachments, one sweep and several.
inline constexpr ProvotCase kProvotCases[] = {{false, 1}, {false, 4}, {true, 1}, {true, 4}};

/// `spec` with the sweep settings of `c`.
inline SimSpec WithProvotCase(SimSpec spec, const ProvotCase& c) {
  spec.provot.multiresolution = c.multiresolution;
  spec.provot.long_range_attachments = c.multiresolution;
  spec.provot.iterations = c.iterations;
  return spec;
}

/// "grid 7 multiresolution 1 sweeps 4", for failure messages.
inline std::string ProvotCaseName(int32_t grid, const ProvotCase& c) {
  return "grid " + std::to_string(grid) + " multiresolution " + std::to_string(c.multiresolution) +
         " sweeps " + std::to_string(c.iterations);
}

}  // namespace felt::cloth_test
