#include <optional>
#include <string>

#include "proxy/proxy_scene.h"
#include "server/server_spec.h"
#include "sim_loop/cloth_scene.h"
#include "transport/transport_scene.h"

namespace felt {

int TickDeviceIndex(const ServerSpec& spec) {
  if (spec.devices.empty()) return -1;
  if (spec.haptic.tick_device.empty()) return 0;
  for (size_t i = 0; i < spec.devices.size(); ++i) {
    if (spec.devices[i].id == spec.haptic.tick_device) return static_cast<int>(i);
  }
  return -1;
}

ServerSpec ParseServerSpec(const SceneDocument& doc) {
  ServerSpec spec;
  spec.scene_name = ParseSceneInfo(doc).name;
  spec.sim = ParseSimSpec(doc);
  spec.proxy = ParseProxySpec(doc);
  // The proxy cannot enter the scene's obstacles either: the same [[obstacles]] as the cloth's.
  spec.proxy.obstacles = spec.sim.cloth.obstacles;
  spec.devices = ParseDeviceSpecs(doc);
  spec.haptic = ParseHapticSpec(doc);
  if (!spec.haptic.tick_device.empty() && TickDeviceIndex(spec) < 0) {
    std::string ids;
    for (const DeviceSpec& d : spec.devices) ids += (ids.empty() ? "" : ", ") + d.id;
    SceneTable::Section(doc, "haptic")
        ->Fail("tick_device",
               "'" + spec.haptic.tick_device + "' is not a device of this scene (" + ids + ")");
  }
  return spec;
}

ServerSpec CheckWholeScene(const SceneDocument& doc) {
  ServerSpec spec = ParseServerSpec(doc);
  (void)transport::ParseTransportConfig(doc, spec.devices);
  return spec;
}

}  // namespace felt
