#pragma once
// The simulation sections of a scene file ([cloth], [[obstacles]], [integration], [provot]) read
// into a SimSpec, with scene/scene_file.h's file:line:field errors. docs/scenes.md is the
// reference.

#include "scene/scene_file.h"
#include "sim_loop/cloth_spec.h"

namespace felt {

/// Reads the simulation part of a scene: [cloth] with [cloth.structural], [cloth.shear],
/// [cloth.bend] and [[cloth.pins]], [[obstacles]], [integration] and [provot]. [cloth] is
/// required. A spring table that is absent means that spring type is left out (no springs of that
/// type); present, its missing keys take cloth_spec.h's defaults for that type. Every value is
/// checked here (ranges, unit axes, box min < max, pins inside the grid...) so the error carries
/// its line; then the cloth is built once (BuildClothModel, sim_loop/cloth.h), so that what only
/// the built cloth shows (the auto substep count) is refused at its line too. Throws SceneError.
SimSpec ParseSimSpec(const SceneDocument& doc);

/// `spec` with its cloth regridded to `grid` x `grid` particles over the same square (spacing
/// scaled so that (width - 1) spacing [m] is kept) and the same total drag (drag per particle
/// scaled by the particle count: scenes/curtain_128.toml's rule); springs, mass per particle,
/// pins by name and everything else as they were. Throws std::invalid_argument for grid < 2.
SimSpec ResizedCloth(SimSpec spec, int32_t grid);

}  // namespace felt
