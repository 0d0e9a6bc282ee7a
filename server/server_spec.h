#pragma once
// Everything the server runs, read from one scene: the cloth, the proxy, the devices and the loops.
#include <string>
#include <vector>

#include "haptic_loop/haptic_spec.h"
#include "proxy/proxy_spec.h"
#include "scene/scene_file.h"
#include "sim_loop/cloth_spec.h"

namespace felt {

/// Everything the server runs: the cloth, the proxy, the devices and the loops.
struct ServerSpec {
  std::string scene_name;           ///< [scene] name (for logs and the status's server id)
  SimSpec sim;                      ///< the cloth ([cloth], [integration], ...)
  ProxySpec proxy;                  ///< [proxy]
  std::vector<DeviceSpec> devices;  ///< [[devices]] or the single [device]; order = index
  HapticSpec haptic;                ///< [haptic]
};

/// Reads everything the server needs from a loaded scene. Throws SceneError.
ServerSpec ParseServerSpec(const SceneDocument& doc);

/// Checks every section of a loaded scene as `felt serve` reads it ([transport] included), so that
/// a command using only part of the scene (`felt run`: the cloth) still refuses a typo anywhere in
/// the file; returns what ParseServerSpec returns. Throws SceneError naming file, line and field.
ServerSpec CheckWholeScene(const SceneDocument& doc);

/// The index in spec.devices of the device whose arrivals trigger the haptic tick
/// (haptic.tick_device, "" = 0), or -1 when no device has that id.
int TickDeviceIndex(const ServerSpec& spec);

}  // namespace felt
