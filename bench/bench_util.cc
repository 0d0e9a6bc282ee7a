#include "bench/bench_util.h"

#include <stdexcept>
#include <string>

#include "scene/scene_file.h"
#include "sim_loop/cloth_scene.h"

namespace felt::bench {

SimSpec ResizedCurtain(const std::string& scene_path, int32_t grid) {
  return ResizedCloth(ParseSimSpec(LoadSceneDocument(scene_path)), grid);
}

double EnergyScale_J(const SimSpec& spec) {
  const ClothSpec& cloth = spec.cloth;
  return cloth.mass_kg * cloth.gravity_m_per_s2.norm() * (cloth.height - 1) * cloth.spacing_m;
}

}  // namespace felt::bench
