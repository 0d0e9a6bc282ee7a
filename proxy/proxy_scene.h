#pragma once
// Scene sections of the proxy (docs/proxy.md is the user's reference):
//
//   [device]                        # one device; also the defaults of every [[devices]] entry
//   stiffness_N_per_m = 400.0       # > 0, device frame
//   damping_N_s_per_m = 0.0         # >= 0
//   radius_m = 0.004                # proxy sphere radius in the world, > 0
//   max_force_N = 3.3               # > 0
//   scale = 3.0                     # world metres per device metre, > 0
//   rotation_axis = [0.0, 1.0, 0.0] # device-to-world rotation as axis and angle ...
//   rotation_deg = 0.0
//   rotation_matrix = [[1,0,0],[0,1,0],[0,0,1]]  # ... or as a 3x3 (rows), not both
//   offset_m = [0.0, 0.0, 0.0]      # world position of the device origin
//
//   [[devices]]                     # several devices (two hands): an id and any [device] key
//   id = "left"
//
//   [proxy]
//   force_shading = true
//   friction_static = 0.0           # mu_s >= 0
//   friction_dynamic = 0.0          # 0 <= mu_d <= mu_s
//   snapshot_mode = "interpolate"   # "newest" | "blend_forces" | "interpolate" | "extrapolate"
//   max_iterations = 10             # 1..100
//   candidate_capacity = 1024       # 16..65536
//   collision_structure = "bvh-aabb-4"    # "naive", "osh",
//   "bvh-{sphere,aabb}-{2,4}[-topdown|-rebuild]"
//
// Every error is a SceneError "file:line:col: field: rule" (scene/scene_file.h).

#include <string>
#include <vector>

#include "proxy/proxy_spec.h"
#include "scene/scene_file.h"

namespace felt {

/// Reads [device] (absent: the defaults). Throws SceneError.
DeviceSpec ParseDeviceSpec(const SceneDocument& doc);

/// Reads the devices of a scene: one per [[devices]] entry (id required, unique; every other key
/// as in [device], defaulting to [device]'s values), or the single [device] (id "default") when
/// there is no [[devices]]. Throws SceneError.
std::vector<DeviceSpec> ParseDeviceSpecs(const SceneDocument& doc);

/// Reads [proxy] (absent: the defaults). Throws SceneError.
ProxySpec ParseProxySpec(const SceneDocument& doc);

/// The collision structure named `name` ("naive", "osh", "bvh-sphere-4", "bvh-aabb-2-topdown",
/// ...), or false when no structure has that name.
bool CollisionStructureFromName(const std::string& name, CollisionStructureSpec* spec);

/// Every accepted collision structure name, for messages and documentation.
std::vector<std::string> CollisionStructureNames();

}  // namespace felt
