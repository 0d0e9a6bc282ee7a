#include "proxy/proxy_scene.h"

#include <gtest/gtest.h>

#include <string>

#include "proxy/proxy_model.h"

namespace felt {
namespace {

// The SceneError message for `text`, or "" when it parses.
template <typename Parse>
std::string ErrorOf(const std::string& text, Parse parse) {
  try {
    const SceneDocument doc = ParseSceneText(text, "test.toml");
    parse(doc);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

std::string DeviceError(const std::string& text) {
  return ErrorOf(text, [](const SceneDocument& d) { ParseDeviceSpecs(d); });
}
std::string ProxyError(const std::string& text) {
  return ErrorOf(text, [](const SceneDocument& d) { ParseProxySpec(d); });
}

TEST(ProxySceneTest, DefaultsWhenSectionsAreAbsent) {
  const SceneDocument doc = ParseSceneText("", "empty.toml");
  const DeviceSpec d = ParseDeviceSpec(doc);
  EXPECT_EQ(d.stiffness_N_per_m, 400.0);
  EXPECT_EQ(d.max_force_N, 3.3);
  EXPECT_EQ(d.scale, 3.0);
  EXPECT_TRUE(d.rotation_WD.isIdentity());
  const ProxySpec p = ParseProxySpec(doc);
  EXPECT_TRUE(p.force_shading);
  EXPECT_EQ(p.friction_static, 0.0);
  EXPECT_FALSE(p.predict_hand);
  EXPECT_FALSE(CompileProxyModel(d, p).predict_hand);
  EXPECT_EQ(CollisionStructureName(p.structure), "bvh-aabb-4-bottomup");  // the fastest (README-collision)
  const std::vector<DeviceSpec> all = ParseDeviceSpecs(doc);
  ASSERT_EQ(all.size(), 1u);
  EXPECT_EQ(all[0].id, "default");
}

TEST(ProxySceneTest, ReadsEveryKey) {
  const SceneDocument doc = ParseSceneText(R"(
[device]
stiffness_N_per_m = 600
damping_N_s_per_m = 1.5
radius_m = 0.003
max_force_N = 2.0
scale = 2.5
rotation_axis = [0, 0, 2]
rotation_deg = 90
offset_m = [0.1, 0.2, 0.3]

[proxy]
force_shading = false
friction_static = 0.4
friction_dynamic = 0.2
snapshot_mode = "blend_forces"
max_iterations = 7
candidate_capacity = 64
collision_structure = "bvh-aabb-2-topdown"
predict_hand = true
)",
                                           "full.toml");
  const DeviceSpec d = ParseDeviceSpec(doc);
  EXPECT_EQ(d.stiffness_N_per_m, 600.0);
  EXPECT_EQ(d.damping_N_s_per_m, 1.5);
  EXPECT_EQ(d.radius_m, 0.003);
  EXPECT_EQ(d.max_force_N, 2.0);
  EXPECT_EQ(d.scale, 2.5);
  EXPECT_NEAR((d.rotation_WD * Vec3::UnitX() - Vec3::UnitY()).norm(), 0.0, 1e-12);
  EXPECT_EQ(d.offset_W_m, Vec3(0.1, 0.2, 0.3));
  EXPECT_NEAR((DeviceToWorld(d, WorldToDevice(d, Vec3(1, 2, 3))) - Vec3(1, 2, 3)).norm(), 0.0,
              1e-12);
  const ProxySpec p = ParseProxySpec(doc);
  EXPECT_FALSE(p.force_shading);
  EXPECT_EQ(p.friction_static, 0.4);
  EXPECT_EQ(p.friction_dynamic, 0.2);
  EXPECT_EQ(p.snapshot_mode, SnapshotMode::kBlendForces);
  EXPECT_EQ(p.max_iterations, 7);
  EXPECT_EQ(p.candidate_capacity, 64);
  EXPECT_EQ(CollisionStructureName(p.structure), "bvh-aabb-2-topdown");
  EXPECT_TRUE(p.predict_hand);
  // The prediction is mode patch's only.
  EXPECT_FALSE(CompileProxyModel(d, p).predict_hand);
  ProxySpec patch = p;
  patch.snapshot_mode = SnapshotMode::kPatch;
  EXPECT_TRUE(CompileProxyModel(d, patch).predict_hand);
}

TEST(ProxySceneTest, RotationMatrixAndDevicesList) {
  const SceneDocument doc = ParseSceneText(R"(
[device]
stiffness_N_per_m = 500
rotation_matrix = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]

[[devices]]
id = "left"
offset_m = [-0.2, 0, 0]

[[devices]]
id = "right"
stiffness_N_per_m = 300
)",
                                           "two.toml");
  const std::vector<DeviceSpec> all = ParseDeviceSpecs(doc);
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[0].id, "left");
  EXPECT_EQ(all[0].stiffness_N_per_m, 500.0);
  EXPECT_EQ(all[0].offset_W_m, Vec3(-0.2, 0, 0));
  EXPECT_NEAR((all[0].rotation_WD * Vec3::UnitX() - Vec3::UnitY()).norm(), 0.0, 1e-15);
  EXPECT_EQ(all[1].id, "right");
  EXPECT_EQ(all[1].stiffness_N_per_m, 300.0);
}

TEST(ProxySceneTest, EveryErrorNamesFileLineColumnFieldAndRule) {
  EXPECT_EQ(DeviceError("[device]\nstiffness_N_per_m = -5\n"),
            "test.toml:2:1: device.stiffness_N_per_m: must be > 0, got -5");
  EXPECT_EQ(DeviceError("[device]\nmax_force_N = 0\n"),
            "test.toml:2:1: device.max_force_N: must be > 0, got 0");
  EXPECT_EQ(DeviceError("[device]\ndamping_N_s_per_m = -1\n"),
            "test.toml:2:1: device.damping_N_s_per_m: must be >= 0, got -1");
  EXPECT_EQ(DeviceError("[device]\nradius_m = \"big\"\n"),
            "test.toml:2:1: device.radius_m: must be a number, got a string \"big\"");
  EXPECT_NE(DeviceError("[device]\nstifness_N_per_m = 400\n")
                .find("test.toml:2:1: device.stifness_N_per_m: unknown key 'stifness_N_per_m' in "
                      "[device] (did you mean "
                      "'stiffness_N_per_m'?)"),
            std::string::npos);
  EXPECT_EQ(
      DeviceError("[device]\nrotation_deg = 10\nrotation_matrix = [[1,0,0],[0,1,0],[0,0,1]]\n"),
      "test.toml:3:1: device.rotation_matrix: give either rotation_matrix or "
      "rotation_axis/rotation_deg, not both");
  EXPECT_EQ(DeviceError("[device]\nrotation_matrix = [[1,0,0],[0,1,0],[0,0,-1]]\n"),
            "test.toml:2:1: device.rotation_matrix: must be a rotation (orthonormal rows, "
            "determinant +1)");
  EXPECT_EQ(DeviceError("[device]\nrotation_matrix = [[1,0,0],[0,1,0]]\n"),
            "test.toml:2:1: device.rotation_matrix: must be a 3x3 matrix written as three rows "
            "of three numbers");
  EXPECT_EQ(DeviceError("[device]\nrotation_axis = [0, 0, 0]\n").substr(0, 37),
            "test.toml:2:1: device.rotation_axis: ");
  EXPECT_EQ(DeviceError("[[devices]]\nid = \"a\"\n[[devices]]\nid = \"a\"\n"),
            "test.toml:4:1: devices[1].id: duplicate device id 'a'");
  EXPECT_EQ(DeviceError("[[devices]]\nscale = 2\n").substr(0, 29), "test.toml:1:1: devices[0].id:");
  EXPECT_EQ(ProxyError("[proxy]\nsnapshot_mode = \"latest\"\n"),
            "test.toml:2:1: proxy.snapshot_mode: unknown value 'latest'; expected one of: "
            "newest, blend_forces, interpolate, extrapolate, patch");
  EXPECT_EQ(ProxyError("[proxy]\npatch_radius = 2\n"),
            "test.toml:2:1: proxy.patch_radius: must be in [3, 32], got 2");
  EXPECT_EQ(ProxyError("[proxy]\npatch_radius = 5\npatch_follow = 6\n"),
            "test.toml:3:1: proxy.patch_follow: must be in [1, 5], got 6");
  EXPECT_EQ(ProxyError("[proxy]\npatch_follow = 0\n"),
            "test.toml:2:1: proxy.patch_follow: must be in [1, 8], got 0");
  EXPECT_EQ(ProxyError("[proxy]\npredict_hand = 1\n"),
            "test.toml:2:1: proxy.predict_hand: must be true or false, got an integer 1");
  EXPECT_NE(ProxyError("[proxy]\ncollision_structure = \"bvh-sphere-3\"\n")
                .find("test.toml:2:1: proxy.collision_structure: unknown value 'bvh-sphere-3' "
                      "(did you mean 'bvh-sphere-2'?)"),
            std::string::npos);
  EXPECT_EQ(ProxyError("[proxy]\nfriction_static = 0.2\nfriction_dynamic = 0.3\n"),
            "test.toml:3:1: proxy.friction_dynamic: must be <= friction_static (0.2), got 0.3");
  EXPECT_EQ(ProxyError("[proxy]\nfriction_static = -0.2\n"),
            "test.toml:2:1: proxy.friction_static: must be >= 0, got -0.2");
  EXPECT_EQ(ProxyError("[proxy]\nmax_iterations = 0\n"),
            "test.toml:2:1: proxy.max_iterations: must be in [1, 100], got 0");
  EXPECT_EQ(ProxyError("[proxy]\ncandidate_capacity = 8\n"),
            "test.toml:2:1: proxy.candidate_capacity: must be in [16, 65536], got 8");
  EXPECT_EQ(ProxyError("[proxy]\nforce_shading = 1\n").substr(0, 37),
            "test.toml:2:1: proxy.force_shading: m");
}

TEST(ProxySceneTest, EveryStructureNameRoundTrips) {
  for (const std::string& name : CollisionStructureNames()) {
    CollisionStructureSpec spec;
    ASSERT_TRUE(CollisionStructureFromName(name, &spec)) << name;
    EXPECT_EQ(CollisionStructureName(spec).rfind(name, 0), 0u) << name;
  }
  CollisionStructureSpec spec;
  EXPECT_FALSE(CollisionStructureFromName("octree", &spec));
}

}  // namespace
}  // namespace felt
