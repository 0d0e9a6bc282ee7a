#include "proxy/proxy_scene.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <set>
#include <string_view>

namespace felt {
namespace {

constexpr std::array<NamedValue<SnapshotMode>, 5> kSnapshotModeNames = {{
    {"newest", SnapshotMode::kNewest},
    {"blend_forces", SnapshotMode::kBlendForces},
    {"interpolate", SnapshotMode::kInterpolate},
    {"extrapolate", SnapshotMode::kExtrapolate},
    {"patch", SnapshotMode::kPatch},
}};

// Every structure spec a scene can name, with its full name (CollisionStructureName).
std::vector<CollisionStructureSpec> AllStructureSpecs() {
  std::vector<CollisionStructureSpec> specs;
  CollisionStructureSpec naive;
  naive.kind = CollisionStructureSpec::Kind::kNaive;
  specs.push_back(naive);
  CollisionStructureSpec hash;
  hash.kind = CollisionStructureSpec::Kind::kSpatialHash;
  specs.push_back(hash);
  for (BoundingVolume volume : {BoundingVolume::kSphere, BoundingVolume::kAabb}) {
    for (int32_t arity : {2, 4}) {
      for (BvhRepair repair : {BvhRepair::kBottomUp, BvhRepair::kTopDown, BvhRepair::kRebuild}) {
        CollisionStructureSpec bvh;
        bvh.kind = CollisionStructureSpec::Kind::kBvh;
        bvh.bvh.volume = volume;
        bvh.bvh.arity = arity;
        bvh.bvh.repair = repair;
        specs.push_back(bvh);
      }
    }
  }
  return specs;
}

// A name as a scene writes it: the bottom-up repair (001 §6.3, the default) needs no suffix.
std::string ShortName(const CollisionStructureSpec& spec) {
  std::string name = CollisionStructureName(spec);
  constexpr std::string_view kSuffix = "-bottomup";
  if (name.size() > kSuffix.size() &&
      name.compare(name.size() - kSuffix.size(), kSuffix.size(), kSuffix) == 0) {
    name.resize(name.size() - kSuffix.size());
  }
  return name;
}

// A 3x3 matrix written as three rows of three numbers; must be a proper rotation.
Eigen::Matrix3d ReadRotationMatrix(const SceneTable& table, std::string_view key) {
  const toml::node* node = table.Node(key);
  const toml::array* rows = node != nullptr ? node->as_array() : nullptr;
  const std::string shape = "must be a 3x3 matrix written as three rows of three numbers";
  if (rows == nullptr || rows->size() != 3) table.Fail(key, shape);
  Eigen::Matrix3d m;
  for (size_t i = 0; i < 3; ++i) {
    const toml::node* row_node = rows->get(i);
    const toml::array* row = row_node != nullptr ? row_node->as_array() : nullptr;
    if (row == nullptr || row->size() != 3) table.Fail(key, shape);
    for (size_t j = 0; j < 3; ++j) {
      const toml::node* v = row->get(j);
      const std::optional<double> value =
          v != nullptr && v->is_number() ? v->value<double>() : std::nullopt;
      if (!(value && std::isfinite(*value))) table.Fail(key, shape);
      m(static_cast<int>(i), static_cast<int>(j)) = *value;
    }
  }
  const double err = (m.transpose() * m - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (!(err <= 1e-6) || !(m.determinant() > 0.0)) {
    table.Fail(key, "must be a rotation (orthonormal rows, determinant +1)");
  }
  return m;
}

// The device keys of `table` on top of `base` (the [device] values for [[devices]] entries).
DeviceSpec ReadDeviceKeys(const SceneTable& table, DeviceSpec base) {
  DeviceSpec d = std::move(base);
  d.stiffness_N_per_m = table.Number("stiffness_N_per_m", d.stiffness_N_per_m, Positive());
  d.damping_N_s_per_m = table.Number("damping_N_s_per_m", d.damping_N_s_per_m, NonNegative());
  d.radius_m = table.Number("radius_m", d.radius_m, Positive());
  d.max_force_N = table.Number("max_force_N", d.max_force_N, Positive());
  d.scale = table.Number("scale", d.scale, Positive());
  d.offset_W_m = table.Vector("offset_m", d.offset_W_m);
  const bool axis_angle = table.Has("rotation_axis") || table.Has("rotation_deg");
  if (table.Has("rotation_matrix")) {
    if (axis_angle) {
      table.Fail("rotation_matrix",
                 "give either rotation_matrix or rotation_axis/rotation_deg, not both");
    }
    d.rotation_WD = ReadRotationMatrix(table, "rotation_matrix");
  } else if (axis_angle) {
    const Vec3 axis = table.Direction("rotation_axis", Vec3::UnitY());
    const double deg = table.Number("rotation_deg", 0.0, InRange(-360.0, 360.0));
    d.rotation_WD = Eigen::AngleAxisd(deg * M_PI / 180.0, axis).toRotationMatrix();
  }
  return d;
}

}  // namespace

const char* SnapshotModeName(SnapshotMode mode) {
  for (const auto& m : kSnapshotModeNames) {
    if (m.value == mode) return m.name.data();
  }
  return "?";
}

bool CollisionStructureFromName(const std::string& name, CollisionStructureSpec* spec) {
  for (const CollisionStructureSpec& s : AllStructureSpecs()) {
    if (name == CollisionStructureName(s) || name == ShortName(s)) {
      *spec = s;
      return true;
    }
  }
  return false;
}

std::vector<std::string> CollisionStructureNames() {
  std::vector<std::string> names;
  for (const CollisionStructureSpec& s : AllStructureSpecs()) names.push_back(ShortName(s));
  return names;
}

DeviceSpec ParseDeviceSpec(const SceneDocument& doc) {
  const std::optional<SceneTable> table = SceneTable::Section(doc, "device");
  if (!table) return DeviceSpec{};
  table->ExpectKeys({"stiffness_N_per_m", "damping_N_s_per_m", "radius_m", "max_force_N", "scale",
                     "rotation_axis", "rotation_deg", "rotation_matrix", "offset_m"});
  return ReadDeviceKeys(*table, DeviceSpec{});
}

std::vector<DeviceSpec> ParseDeviceSpecs(const SceneDocument& doc) {
  const DeviceSpec base = ParseDeviceSpec(doc);
  const std::vector<SceneTable> entries = SceneTable::SectionArray(doc, "devices");
  if (entries.empty()) return {base};
  std::vector<DeviceSpec> devices;
  std::set<std::string> ids;
  for (const SceneTable& entry : entries) {
    entry.ExpectKeys({"id", "stiffness_N_per_m", "damping_N_s_per_m", "radius_m", "max_force_N",
                      "scale", "rotation_axis", "rotation_deg", "rotation_matrix", "offset_m"});
    DeviceSpec d = ReadDeviceKeys(entry, base);
    d.id = entry.String("id", kRequired, /*non_empty=*/true);
    if (!ids.insert(d.id).second) entry.Fail("id", "duplicate device id '" + d.id + "'");
    devices.push_back(std::move(d));
  }
  return devices;
}

ProxySpec ParseProxySpec(const SceneDocument& doc) {
  ProxySpec p;
  const std::optional<SceneTable> table = SceneTable::Section(doc, "proxy");
  if (!table) return p;
  table->ExpectKeys({"force_shading", "friction_static", "friction_dynamic", "snapshot_mode",
                     "max_iterations", "candidate_capacity", "collision_structure", "patch_radius",
                     "patch_follow", "predict_hand"});
  p.force_shading = table->Bool("force_shading", p.force_shading);
  p.friction_static = table->Number("friction_static", p.friction_static, NonNegative());
  p.friction_dynamic = table->Number("friction_dynamic", p.friction_dynamic, NonNegative());
  if (p.friction_dynamic > p.friction_static) {
    table->Fail("friction_dynamic", "must be <= friction_static (" +
                                        FormatSceneNumber(p.friction_static) + "), got " +
                                        FormatSceneNumber(p.friction_dynamic));
  }
  p.snapshot_mode = table->Choice<SnapshotMode>("snapshot_mode", p.snapshot_mode,
                                                kSnapshotModeNames);
  p.patch_radius =
      table->Integer("patch_radius", p.patch_radius, InRange(kMinPatchRadius, kMaxPatchRadius));
  p.patch_follow = table->Integer("patch_follow", p.patch_follow, InRange(1, p.patch_radius));
  p.predict_hand = table->Bool("predict_hand", p.predict_hand);
  p.max_iterations =
      table->Integer("max_iterations", p.max_iterations, InRange(1, kMaxProxyIterations));
  p.candidate_capacity = table->Integer("candidate_capacity", p.candidate_capacity,
                                        InRange(kMinCandidateCapacity, kMaxCandidateCapacity));
  const std::vector<std::string> names = CollisionStructureNames();
  std::vector<std::string_view> views(names.begin(), names.end());
  const std::string default_name = ShortName(DefaultCollisionStructure());
  const size_t default_index =
      static_cast<size_t>(std::find(names.begin(), names.end(), default_name) - names.begin());
  const size_t index = table->ChoiceIndex("collision_structure", default_index, views);
  CollisionStructureFromName(names[index], &p.structure);
  return p;
}

}  // namespace felt
