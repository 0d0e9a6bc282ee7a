#pragma once
// Small scene builders shared by the cloth tests.

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "sim_loop/cloth.h"

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

}  // namespace felt::cloth_test
