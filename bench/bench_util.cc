#include "bench/bench_util.h"

#include <stdexcept>
#include <string>

#include "scene/scene_file.h"
#include "sim_loop/cloth_scene.h"

namespace felt::bench {

SimSpec ResizedCurtain(const std::string& scene_path, int32_t grid) {
  if (grid < 2) throw std::invalid_argument("grid must be >= 2, got " + std::to_string(grid));
  SimSpec spec = ParseSimSpec(LoadSceneDocument(scene_path));
  ClothSpec& cloth = spec.cloth;
  // Same square, finer or coarser grid; the same total drag (scenes/curtain_128.toml's rule).
  const double span_m = cloth.spacing_m * (cloth.width - 1);
  const double particles_before = static_cast<double>(cloth.width) * cloth.height;
  cloth.spacing_m = span_m / (grid - 1);
  cloth.drag_N_s_per_m *= particles_before / (static_cast<double>(grid) * grid);
  cloth.width = grid;
  cloth.height = grid;
  return spec;
}

double EnergyScale_J(const SimSpec& spec) {
  const ClothSpec& cloth = spec.cloth;
  return cloth.mass_kg * cloth.gravity_m_per_s2.norm() * (cloth.height - 1) * cloth.spacing_m;
}

}  // namespace felt::bench
