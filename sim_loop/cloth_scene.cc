#include "sim_loop/cloth_scene.h"

#include <array>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "sim_loop/cloth.h"
#include "sim_loop/integrator_names.h"

namespace felt {

namespace {

constexpr double kAxisOrthogonalityTolerance = 1e-3;  // |cos| between u_axis and v_axis

constexpr std::array<NamedValue<PinKind>, 3> kPinKinds = {{
    {"corner", PinKind::kCorner},
    {"edge", PinKind::kEdge},
    {"particle", PinKind::kParticle},
}};
constexpr std::array<std::string_view, 4> kCornerNames = {"top_left", "top_right", "bottom_left",
                                                          "bottom_right"};
constexpr std::array<std::string_view, 4> kEdgeNames = {"top", "bottom", "left", "right"};
constexpr std::array<std::string_view, 4> kObstacleTypes = {"plane", "sphere", "box", "capsule"};

// "[x, y, z]" as a user would write it. Appended piece by piece: GCC 12 reports a false
// -Wstringop-overflow for the one-expression concatenation here (GCC bug 105651).
std::string VectorText(const Vec3& v) {
  std::string text = "[";
  text += FormatSceneNumber(v.x());
  text += ", ";
  text += FormatSceneNumber(v.y());
  text += ", ";
  text += FormatSceneNumber(v.z());
  text += "]";
  return text;
}

// One spring type's table; absent means the type is left out.
std::optional<SpringSpec> ParseSpring(const SceneTable& cloth, std::string_view key,
                                      const SpringSpec& defaults) {
  const std::optional<SceneTable> table = cloth.Table(key);
  if (!table) return std::nullopt;
  table->ExpectKeys({"stiffness_N_per_m", "damping_N_s_per_m"});
  SpringSpec spring;
  spring.stiffness_N_per_m =
      table->Number("stiffness_N_per_m", defaults.stiffness_N_per_m, Positive());
  spring.damping_N_s_per_m =
      table->Number("damping_N_s_per_m", defaults.damping_N_s_per_m, NonNegative());
  return spring;
}

PinMotionSpec ParsePinMotion(const SceneTable& motion) {
  motion.ExpectKeys({"velocity_m_per_s", "amplitude_m", "frequency_hz", "start_s", "stop_s"});
  PinMotionSpec spec;
  spec.velocity_m_per_s = motion.Vector("velocity_m_per_s", spec.velocity_m_per_s);
  spec.amplitude_m = motion.Vector("amplitude_m", spec.amplitude_m);
  spec.frequency_hz = motion.Number("frequency_hz", spec.frequency_hz, NonNegative());
  spec.start_s = motion.Number("start_s", spec.start_s, NonNegative());
  NumberLimits stop_limits = NonNegative();
  stop_limits.allow_infinite = true;
  spec.stop_s = motion.Number("stop_s", spec.stop_s, stop_limits);
  if (spec.stop_s < spec.start_s) {
    motion.Fail("stop_s", "must be >= start_s = " + FormatSceneNumber(spec.start_s) + ", got " +
                              FormatSceneNumber(spec.stop_s));
  }
  // A sinusoid needs a frequency: amplitude with frequency 0 would silently do nothing.
  if (!spec.amplitude_m.isZero(0.0) && spec.frequency_hz == 0.0) {
    motion.Fail(motion.Has("frequency_hz") ? "frequency_hz" : "amplitude_m",
                "a non-zero amplitude_m needs frequency_hz > 0");
  }
  return spec;
}

PinSpec ParsePin(const SceneTable& table, int32_t width, int32_t height) {
  PinSpec pin;
  // The keys a pin may hold depend on its kind.
  pin.kind = table.Choice<PinKind>("kind", kRequired, kPinKinds);
  if (pin.kind == PinKind::kParticle) {
    table.ExpectKeys({"kind", "col", "row", "motion"});
    pin.col = table.Integer("col", kRequired, InRange(0, width - 1));
    pin.row = table.Integer("row", kRequired, InRange(0, height - 1));
  } else {
    table.ExpectKeys({"kind", "name", "motion"});
    const std::span<const std::string_view> names =
        pin.kind == PinKind::kCorner ? std::span<const std::string_view>(kCornerNames)
                                     : std::span<const std::string_view>(kEdgeNames);
    pin.name = std::string(names[table.ChoiceIndex("name", std::nullopt, names)]);
  }
  if (const std::optional<SceneTable> motion = table.Table("motion")) {
    pin.motion = ParsePinMotion(*motion);
  }
  return pin;
}

ObstacleSpec ParseObstacle(const SceneTable& table) {
  ObstacleSpec obstacle;
  const size_t type = table.ChoiceIndex("type", std::nullopt, kObstacleTypes);
  switch (type) {
    case 0: {  // plane: a ground or wall, defaults to the ground y = 0
      table.ExpectKeys({"type", "friction", "margin_m", "point_m", "normal"});
      PlaneSpec plane;
      plane.point_m = table.Vector("point_m", plane.point_m);
      plane.normal = table.Direction("normal", plane.normal);
      obstacle.shape = plane;
      break;
    }
    case 1: {  // sphere
      table.ExpectKeys({"type", "friction", "margin_m", "center_m", "radius_m"});
      SphereSpec sphere;
      sphere.center_m = table.Vector("center_m", kRequired);
      sphere.radius_m = table.Number("radius_m", kRequired, Positive());
      obstacle.shape = sphere;
      break;
    }
    case 2: {  // axis-aligned box
      table.ExpectKeys({"type", "friction", "margin_m", "min_m", "max_m"});
      BoxSpec box;
      box.min_m = table.Vector("min_m", kRequired);
      box.max_m = table.Vector("max_m", kRequired);
      if (!(box.min_m.array() < box.max_m.array()).all()) {
        table.Fail("max_m", "must be greater than min_m on every axis, got min_m " +
                                VectorText(box.min_m) + " and max_m " + VectorText(box.max_m));
      }
      obstacle.shape = box;
      break;
    }
    default: {  // capsule
      table.ExpectKeys({"type", "friction", "margin_m", "a_m", "b_m", "radius_m"});
      CapsuleSpec capsule;
      capsule.a_m = table.Vector("a_m", kRequired);
      capsule.b_m = table.Vector("b_m", kRequired);
      capsule.radius_m = table.Number("radius_m", kRequired, Positive());
      if (capsule.a_m == capsule.b_m) {
        table.Fail("b_m", "must differ from a_m (for a ball, use type = \"sphere\")");
      }
      obstacle.shape = capsule;
      break;
    }
  }
  obstacle.friction = table.Number("friction", obstacle.friction, NonNegative());
  obstacle.margin_m = table.Number("margin_m", obstacle.margin_m, NonNegative());
  return obstacle;
}

ClothSpec ParseCloth(const SceneTable& cloth) {
  cloth.ExpectKeys({"width", "height", "spacing_m", "mass_kg", "origin_m", "u_axis", "v_axis",
                    "drag_N_s_per_m", "gravity_m_per_s2", "structural", "shear", "bend", "pins"});
  ClothSpec spec;
  // Grid and placement.
  spec.width = cloth.Integer("width", spec.width, InRange(2, kMaxGridSide));
  spec.height = cloth.Integer("height", spec.height, InRange(2, kMaxGridSide));
  if (int64_t{spec.width} * spec.height > kMaxParticles) {
    cloth.Fail("width", "width * height must be <= " + std::to_string(kMaxParticles) + ", got " +
                            std::to_string(int64_t{spec.width} * spec.height));
  }
  spec.spacing_m = cloth.Number("spacing_m", spec.spacing_m, Positive());
  spec.mass_kg = cloth.Number("mass_kg", spec.mass_kg, Positive());
  spec.origin_m = cloth.Vector("origin_m", spec.origin_m);
  spec.u_axis = cloth.Direction("u_axis", spec.u_axis);
  spec.v_axis = cloth.Direction("v_axis", spec.v_axis);
  // The axes span the cloth's plane: orthogonal (within a tolerance, then made exact).
  const double cosine = spec.u_axis.dot(spec.v_axis);
  if (std::abs(cosine) > kAxisOrthogonalityTolerance) {
    cloth.Fail("v_axis", "must be orthogonal to u_axis, got u_axis " + VectorText(spec.u_axis) +
                             " and v_axis " + VectorText(spec.v_axis) + " (normalised)");
  }
  spec.v_axis = (spec.v_axis - cosine * spec.u_axis).normalized();
  // Forces.
  spec.drag_N_s_per_m = cloth.Number("drag_N_s_per_m", spec.drag_N_s_per_m, NonNegative());
  spec.gravity_m_per_s2 = cloth.Vector("gravity_m_per_s2", spec.gravity_m_per_s2);
  // Springs: an absent table leaves that type out.
  const ClothSpec defaults;
  spec.structural = ParseSpring(cloth, "structural", *defaults.structural);
  spec.shear = ParseSpring(cloth, "shear", *defaults.shear);
  spec.bend = ParseSpring(cloth, "bend", *defaults.bend);
  // Pins.
  for (const SceneTable& pin : cloth.ArrayOfTables("pins")) {
    spec.pins.push_back(ParsePin(pin, spec.width, spec.height));
  }
  return spec;
}

IntegrationSpec ParseIntegration(const SceneTable& table) {
  table.ExpectKeys({"integrator", "substeps", "frame_rate_hz", "max_frame_dt_s", "auto_safety",
                    "cg_max_iterations", "cg_tolerance"});
  IntegrationSpec spec;
  // The integrator by name.
  std::vector<NamedValue<IntegratorKind>> integrators;
  for (const IntegratorName& entry : kIntegratorNames) {
    integrators.push_back({entry.name, entry.kind});
  }
  spec.integrator = table.Choice<IntegratorKind>("integrator", spec.integrator, integrators);
  // substeps = "auto" (0 in the spec) or an integer >= 1.
  if (const toml::node* substeps = table.Node("substeps")) {
    const std::string rule =
        "must be \"auto\" or an integer in [1, " + std::to_string(kMaxSubstepsPerFrame) + "], got ";
    if (const auto* text = substeps->as_string()) {
      if (text->get() != "auto") table.Fail("substeps", rule + DescribeSceneValue(*substeps));
      spec.substeps = 0;
    } else if (const auto* count = substeps->as_integer()) {
      if (count->get() < 1 || count->get() > kMaxSubstepsPerFrame) {
        table.Fail("substeps", rule + DescribeSceneValue(*substeps));
      }
      spec.substeps = static_cast<int32_t>(count->get());
    } else {
      table.Fail("substeps", rule + DescribeSceneValue(*substeps));
    }
  }
  // Timing.
  spec.frame_rate_hz =
      table.Number("frame_rate_hz", spec.frame_rate_hz, InRangeOpenMin(0, kMaxFrameRate_hz));
  const double nominal_dt_s = 1.0 / spec.frame_rate_hz;
  spec.max_frame_dt_s = table.Number("max_frame_dt_s", spec.max_frame_dt_s, Positive());
  if (spec.max_frame_dt_s < nominal_dt_s) {
    table.Fail("max_frame_dt_s",
               "must be >= 1 / frame_rate_hz = " + FormatSceneNumber(nominal_dt_s) + " s, got " +
                   FormatSceneNumber(spec.max_frame_dt_s));
  }
  spec.auto_safety = table.Number("auto_safety", spec.auto_safety, InRangeOpenMin(0, 1));
  // Implicit Euler's conjugate-gradient solve.
  spec.cg_max_iterations = table.Integer("cg_max_iterations", spec.cg_max_iterations, AtLeast(1));
  NumberLimits tolerance = Positive();
  tolerance.max = 1.0;
  tolerance.max_exclusive = true;
  spec.cg_tolerance = table.Number("cg_tolerance", spec.cg_tolerance, tolerance);
  return spec;
}

ProvotSpec ParseProvot(const SceneTable& table) {
  table.ExpectKeys({"enabled", "max_elongation", "iterations", "shear", "long_range_attachments",
                    "multiresolution", "coarse_sweeps", "sweep_headroom", "finish",
                    "patch_iterations", "patch_sweep_headroom"});
  ProvotSpec spec;
  spec.enabled = table.Bool("enabled", spec.enabled);
  spec.max_elongation = table.Number("max_elongation", spec.max_elongation, Positive());
  spec.iterations = table.Integer("iterations", spec.iterations, InRange(1, kMaxProvotIterations));
  spec.shear = table.Bool("shear", spec.shear);
  spec.long_range_attachments = table.Bool("long_range_attachments", spec.long_range_attachments);
  spec.multiresolution = table.Bool("multiresolution", spec.multiresolution);
  spec.coarse_sweeps =
      table.Integer("coarse_sweeps", spec.coarse_sweeps, InRange(1, kMaxProvotIterations));
  NumberLimits headroom = NonNegative();
  headroom.max = 0.5;
  headroom.max_exclusive = true;
  spec.sweep_headroom = table.Number("sweep_headroom", spec.sweep_headroom, headroom);
  spec.finish = table.Bool("finish", spec.finish);
  if (table.Has("patch_iterations")) {
    spec.patch_iterations =
        table.Integer("patch_iterations", std::nullopt, InRange(1, kMaxProvotIterations));
  }
  if (table.Has("patch_sweep_headroom")) {
    spec.patch_sweep_headroom = table.Number("patch_sweep_headroom", std::nullopt, headroom);
  }
  return spec;
}

SelfCollisionSpec ParseSelfCollision(const SceneTable& table, const ClothSpec& cloth) {
  table.ExpectKeys({"thickness_m", "method", "iterations", "friction", "fail_safe",
                    "repulsion_stiffness_N_per_m", "count_intersections", "passes_per_frame",
                    "min_passes_per_frame", "slow_pass_motion", "hand_pass_motion", "guard_proxy"});
  SelfCollisionSpec spec;
  spec.thickness_m = table.Number("thickness_m", spec.thickness_m, Positive());
  // Thicker than half the spacing, a flat cloth's own non-adjacent primitives would repel.
  if (spec.thickness_m >= 0.5 * cloth.spacing_m) {
    table.Fail("thickness_m",
               "must be < cloth.spacing_m / 2 = " + FormatSceneNumber(0.5 * cloth.spacing_m) +
                   " m, got " + FormatSceneNumber(spec.thickness_m));
  }
  static constexpr std::array<NamedValue<SelfCullingMethod>, 5> kMethods = {
      {{"spatial_hash", SelfCullingMethod::kSpatialHash},
       {"bvh", SelfCullingMethod::kBvh},
       {"bvh_cones", SelfCullingMethod::kBvhCones},
       {"bvox_aabb", SelfCullingMethod::kBvox},
       {"apccd", SelfCullingMethod::kApccd}}};
  spec.method = table.Choice<SelfCullingMethod>("method", spec.method, kMethods);
  spec.iterations = table.Integer("iterations", spec.iterations, InRange(0, 100));
  spec.friction = table.Number("friction", spec.friction, AtLeast(0.0));
  spec.fail_safe = table.Bool("fail_safe", spec.fail_safe);
  if (table.Node("repulsion_stiffness_N_per_m")) {
    spec.repulsion_stiffness_N_per_m =
        table.Number("repulsion_stiffness_N_per_m", 0.0, AtLeast(0.0));
  }
  spec.count_intersections = table.Bool("count_intersections", spec.count_intersections);
  spec.passes_per_frame =
      table.Integer("passes_per_frame", spec.passes_per_frame, InRange(1, 1000));
  spec.min_passes_per_frame =
      table.Integer("min_passes_per_frame", spec.min_passes_per_frame, InRange(1, 1000));
  spec.slow_pass_motion = table.Number("slow_pass_motion", spec.slow_pass_motion, AtLeast(0.0));
  spec.hand_pass_motion = table.Number("hand_pass_motion", spec.hand_pass_motion, AtLeast(0.0));
  spec.guard_proxy = table.Bool("guard_proxy", spec.guard_proxy);
  return spec;
}

// What only the built cloth shows (the auto substep count: a stable step, and at most
// kMaxSubstepsPerFrame of them): BuildClothModel's "field: rule" errors as SceneErrors at the
// field's line (or its section's, or the file's when the file does not write it).
void CheckClothBuilds(const SceneDocument& doc, const SimSpec& spec) {
  try {
    (void)BuildClothModel(spec);
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    const size_t colon = what.find(": ");
    const std::string field = colon == std::string::npos ? "" : what.substr(0, colon);
    const std::string rule = colon == std::string::npos ? what : what.substr(colon + 2);
    throw SceneError(SceneErrorMessage(doc.source_name, SceneFieldRegion(doc, field), field, rule));
  }
}

}  // namespace

SimSpec ParseSimSpec(const SceneDocument& doc) {
  SimSpec spec;
  // [cloth] is required: a scene is about a cloth.
  const std::optional<SceneTable> cloth = SceneTable::Section(doc, "cloth");
  if (!cloth) {
    SceneTable::Root(doc).Fail("cloth", "missing required section [cloth]");
  }
  spec.cloth = ParseCloth(*cloth);
  // Obstacles: only the declared ones exist.
  for (const SceneTable& obstacle : SceneTable::SectionArray(doc, "obstacles")) {
    spec.cloth.obstacles.push_back(ParseObstacle(obstacle));
  }
  // Integration and Provot: every key optional.
  if (const std::optional<SceneTable> integration = SceneTable::Section(doc, "integration")) {
    spec.integration = ParseIntegration(*integration);
  }
  if (const std::optional<SceneTable> provot = SceneTable::Section(doc, "provot")) {
    spec.provot = ParseProvot(*provot);
  }
  // Self-collision: built only when declared.
  if (const std::optional<SceneTable> self = SceneTable::Section(doc, "self_collision")) {
    spec.self_collision = ParseSelfCollision(*self, spec.cloth);
  }
  CheckClothBuilds(doc, spec);
  return spec;
}

SimSpec ResizedCloth(SimSpec spec, int32_t grid) {
  if (grid < 2) throw std::invalid_argument("grid must be >= 2, got " + std::to_string(grid));
  ClothSpec& cloth = spec.cloth;
  const double span_m = cloth.spacing_m * (cloth.width - 1);
  const double particles_before = static_cast<double>(cloth.width) * cloth.height;
  cloth.spacing_m = span_m / (grid - 1);
  cloth.drag_N_s_per_m *= particles_before / (static_cast<double>(grid) * grid);
  cloth.width = grid;
  cloth.height = grid;
  return spec;
}

}  // namespace felt
