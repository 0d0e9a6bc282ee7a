#include <optional>

#include "proxy/proxy_scene.h"
#include "server/server_spec.h"
#include "sim_loop/cloth_scene.h"

namespace felt {

ServerSpec ParseServerSpec(const SceneDocument& doc) {
  ServerSpec spec;
  spec.scene_name = ParseSceneInfo(doc).name;
  spec.sim = ParseSimSpec(doc);
  spec.proxy = ParseProxySpec(doc);
  // The proxy cannot enter the scene's obstacles either: the same [[obstacles]] as the cloth's.
  spec.proxy.obstacles = spec.sim.cloth.obstacles;
  spec.devices = ParseDeviceSpecs(doc);
  spec.haptic = ParseHapticSpec(doc);
  return spec;
}

}  // namespace felt
