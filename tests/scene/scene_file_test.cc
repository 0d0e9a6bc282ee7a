// Scene files: every bundled scene parses; every documented error names file, line, column,
// field and rule (shared/STYLE.md: error paths are tested by their message).
#include "scene/scene_file.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <variant>

#include "sim_loop/cloth_scene.h"
#include "sim_loop/integrator_names.h"

namespace felt {
namespace {

const std::filesystem::path kScenes = std::filesystem::path(FELT_SOURCE_DIR) / "scenes";

// The message of the SceneError that parsing `text` as "t.toml" (document and sim spec) throws.
std::string ErrorOf(const std::string& text) {
  try {
    const SceneDocument doc = ParseSceneText(text, "t.toml");
    ParseSceneInfo(doc);
    ParseSimSpec(doc);
  } catch (const SceneError& error) {
    return error.what();
  }
  return "(no error)";
}

SimSpec Parse(const std::string& text) { return ParseSimSpec(ParseSceneText(text, "t.toml")); }

TEST(SceneFile, EveryBundledSceneParses) {
  int count = 0;
  for (const auto& entry : std::filesystem::directory_iterator(kScenes)) {
    if (entry.path().extension() != ".toml") continue;
    SCOPED_TRACE(entry.path().string());
    const SceneDocument doc = LoadSceneDocument(entry.path());
    const SceneInfo info = ParseSceneInfo(doc);
    EXPECT_EQ(info.name, entry.path().stem().string());
    EXPECT_FALSE(info.description.empty());
    EXPECT_GT(info.duration_s, 0.0);
    const SimSpec spec = ParseSimSpec(doc);
    EXPECT_GE(spec.cloth.width, 2);
    ++count;
  }
  EXPECT_GE(count, 6);
}

TEST(SceneFile, DefaultCurtainMatchesSpecDefaultsAndTraceGeometry) {
  const SimSpec spec = ParseSimSpec(LoadSceneDocument(kScenes / "curtain.toml"));
  const ClothSpec defaults;
  EXPECT_EQ(spec.cloth.width, 32);
  EXPECT_EQ(spec.cloth.height, 32);
  EXPECT_EQ(spec.cloth.spacing_m, defaults.spacing_m);
  EXPECT_EQ(spec.cloth.origin_m, defaults.origin_m);
  EXPECT_EQ(spec.cloth.u_axis, defaults.u_axis);
  EXPECT_EQ(spec.cloth.v_axis, defaults.v_axis);
  EXPECT_EQ(spec.cloth.mass_kg, defaults.mass_kg);
  EXPECT_EQ(spec.cloth.gravity_m_per_s2, defaults.gravity_m_per_s2);
  // Top edge at y = 0.25 m, x from -0.248 m to 0.248 m, plane z = 0.
  const Vec3 top_right =
      spec.cloth.origin_m + (spec.cloth.width - 1) * spec.cloth.spacing_m * spec.cloth.u_axis;
  EXPECT_NEAR(top_right.x(), 0.248, 1e-12);
  EXPECT_EQ(top_right.y(), 0.25);
  EXPECT_EQ(top_right.z(), 0.0);
  ASSERT_EQ(spec.cloth.pins.size(), 2u);
  EXPECT_EQ(spec.cloth.pins[0].kind, PinKind::kCorner);
  EXPECT_EQ(spec.cloth.pins[0].name, "top_left");
  EXPECT_EQ(spec.cloth.pins[1].name, "top_right");
  ASSERT_TRUE(spec.cloth.structural && spec.cloth.shear && spec.cloth.bend);
  EXPECT_EQ(spec.cloth.structural->stiffness_N_per_m, defaults.structural->stiffness_N_per_m);
  EXPECT_EQ(spec.cloth.structural->damping_N_s_per_m, defaults.structural->damping_N_s_per_m);
  EXPECT_EQ(spec.cloth.shear->stiffness_N_per_m, defaults.shear->stiffness_N_per_m);
  EXPECT_EQ(spec.cloth.shear->damping_N_s_per_m, defaults.shear->damping_N_s_per_m);
  EXPECT_EQ(spec.cloth.bend->stiffness_N_per_m, defaults.bend->stiffness_N_per_m);
  EXPECT_EQ(spec.cloth.bend->damping_N_s_per_m, defaults.bend->damping_N_s_per_m);
  EXPECT_EQ(spec.cloth.drag_N_s_per_m, defaults.drag_N_s_per_m);
  EXPECT_EQ(spec.integration.integrator, IntegratorKind::kLeapfrogVerlet);
  EXPECT_EQ(spec.integration.substeps, 0);  // "auto"
  EXPECT_TRUE(spec.provot.enabled);
  EXPECT_EQ(spec.provot.max_elongation, 0.10);
  EXPECT_TRUE(spec.provot.long_range_attachments);
  EXPECT_TRUE(spec.cloth.obstacles.empty());
}

TEST(SceneFile, Curtain128HasTheDefaultCurtainsExtent) {
  const SimSpec spec = ParseSimSpec(LoadSceneDocument(kScenes / "curtain_128.toml"));
  EXPECT_EQ(spec.cloth.width, 128);
  EXPECT_EQ(spec.cloth.height, 128);
  EXPECT_NEAR((spec.cloth.width - 1) * spec.cloth.spacing_m, 0.496, 1e-12);
  EXPECT_EQ(spec.cloth.origin_m, Vec3(-0.248, 0.25, 0.0));
}

TEST(SceneFile, SceneShapesAndObstacles) {
  const SimSpec flag = ParseSimSpec(LoadSceneDocument(kScenes / "flag.toml"));
  ASSERT_EQ(flag.cloth.pins.size(), 1u);
  EXPECT_EQ(flag.cloth.pins[0].kind, PinKind::kEdge);
  EXPECT_EQ(flag.cloth.pins[0].name, "left");

  const SimSpec table = ParseSimSpec(LoadSceneDocument(kScenes / "tablecloth.toml"));
  EXPECT_TRUE(table.cloth.pins.empty());
  ASSERT_EQ(table.cloth.obstacles.size(), 2u);
  ASSERT_TRUE(std::holds_alternative<BoxSpec>(table.cloth.obstacles[0].shape));
  EXPECT_GT(table.cloth.obstacles[0].friction, 0.0);
  EXPECT_EQ(std::get<BoxSpec>(table.cloth.obstacles[0].shape).max_m, Vec3(0.3, 0.0, 0.2));
  EXPECT_TRUE(std::holds_alternative<PlaneSpec>(table.cloth.obstacles[1].shape));

  const SimSpec drop = ParseSimSpec(LoadSceneDocument(kScenes / "sphere_drop.toml"));
  ASSERT_FALSE(drop.cloth.obstacles.empty());
  ASSERT_TRUE(std::holds_alternative<SphereSpec>(drop.cloth.obstacles[0].shape));
  EXPECT_EQ(std::get<SphereSpec>(drop.cloth.obstacles[0].shape).radius_m, 0.12);
}

TEST(SceneFile, CurtainRailPinsMove) {
  const SimSpec spec = ParseSimSpec(LoadSceneDocument(kScenes / "curtain_rail.toml"));
  ASSERT_EQ(spec.cloth.pins.size(), 3u);
  // Inline motion table.
  EXPECT_EQ(spec.cloth.pins[0].motion.velocity_m_per_s, Vec3(0.3, 0.0, 0.0));
  EXPECT_EQ(spec.cloth.pins[0].motion.start_s, 0.5);
  EXPECT_EQ(spec.cloth.pins[0].motion.stop_s, 1.5);
  // [cloth.pins.motion] belongs to the pin declared just above it.
  EXPECT_EQ(spec.cloth.pins[1].kind, PinKind::kParticle);
  EXPECT_EQ(spec.cloth.pins[1].col, 15);
  EXPECT_EQ(spec.cloth.pins[1].row, 0);
  EXPECT_EQ(spec.cloth.pins[1].motion.velocity_m_per_s, Vec3(0.15, 0.0, 0.0));
  // Sinusoid, drift never stops.
  EXPECT_EQ(spec.cloth.pins[2].motion.amplitude_m, Vec3(0.0, 0.0, 0.01));
  EXPECT_EQ(spec.cloth.pins[2].motion.frequency_hz, 2.0);
  EXPECT_TRUE(std::isinf(spec.cloth.pins[2].motion.stop_s));
}

TEST(SceneFile, MinimalSceneTakesDefaultsAndLeavesSpringTypesOut) {
  const SceneDocument doc = ParseSceneText("[cloth]\n", "scenes/minimal.toml");
  const SceneInfo info = ParseSceneInfo(doc);
  EXPECT_EQ(info.name, "minimal");
  EXPECT_EQ(info.duration_s, 5.0);
  const SimSpec spec = ParseSimSpec(doc);
  const SimSpec defaults;
  EXPECT_EQ(spec.cloth.width, defaults.cloth.width);
  EXPECT_EQ(spec.cloth.origin_m, defaults.cloth.origin_m);
  // An absent spring table means no springs of that type.
  EXPECT_FALSE(spec.cloth.structural.has_value());
  EXPECT_FALSE(spec.cloth.shear.has_value());
  EXPECT_FALSE(spec.cloth.bend.has_value());
  EXPECT_TRUE(spec.cloth.pins.empty());
  EXPECT_EQ(spec.integration.integrator, defaults.integration.integrator);
  EXPECT_EQ(spec.integration.substeps, defaults.integration.substeps);
  EXPECT_EQ(spec.provot.enabled, defaults.provot.enabled);
}

TEST(SceneFile, EmptySpringTableTakesThatTypesDefaults) {
  const SimSpec spec = Parse("[cloth.bend]\n[cloth.shear]\ndamping_N_s_per_m = 0\n");
  const ClothSpec defaults;
  ASSERT_TRUE(spec.cloth.bend.has_value());
  EXPECT_EQ(spec.cloth.bend->stiffness_N_per_m, defaults.bend->stiffness_N_per_m);
  EXPECT_EQ(spec.cloth.bend->damping_N_s_per_m, defaults.bend->damping_N_s_per_m);
  ASSERT_TRUE(spec.cloth.shear.has_value());
  EXPECT_EQ(spec.cloth.shear->stiffness_N_per_m, defaults.shear->stiffness_N_per_m);
  EXPECT_EQ(spec.cloth.shear->damping_N_s_per_m, 0.0);
  EXPECT_FALSE(spec.cloth.structural.has_value());
}

TEST(SceneFile, ReadsEveryKey) {
  const SimSpec spec = Parse(R"(
[cloth]
width = 4
height = 3
spacing_m = 0.5
mass_kg = 2
origin_m = [1, 2, 3]
u_axis = [0, 0, 2]            # normalised on reading
v_axis = [1, 0, 0.0005]       # within tolerance of orthogonal: made exact
drag_N_s_per_m = 0.25
gravity_m_per_s2 = [0, 0, -1]
[[cloth.pins]]
kind = "particle"
col = 3
row = 2
[[cloth.pins]]
kind = "edge"
name = "bottom"
[[obstacles]]
type = "capsule"
a_m = [0, 0, 0]
b_m = [0, 1, 0]
radius_m = 0.2
friction = 0.1
margin_m = 0
[integration]
integrator = "implicit_euler"
substeps = 7
frame_rate_hz = 120
max_frame_dt_s = 0.05
auto_safety = 1
cg_max_iterations = 50
cg_tolerance = 1e-6
[provot]
enabled = false
max_elongation = 0.2
iterations = 3
shear = false
long_range_attachments = false
)");
  EXPECT_EQ(spec.cloth.width, 4);
  EXPECT_EQ(spec.cloth.height, 3);
  EXPECT_EQ(spec.cloth.spacing_m, 0.5);
  EXPECT_EQ(spec.cloth.mass_kg, 2.0);
  EXPECT_EQ(spec.cloth.origin_m, Vec3(1, 2, 3));
  EXPECT_EQ(spec.cloth.u_axis, Vec3(0, 0, 1));
  EXPECT_NEAR(spec.cloth.v_axis.norm(), 1.0, 1e-15);
  EXPECT_NEAR(spec.cloth.u_axis.dot(spec.cloth.v_axis), 0.0, 1e-15);
  EXPECT_EQ(spec.cloth.drag_N_s_per_m, 0.25);
  EXPECT_EQ(spec.cloth.gravity_m_per_s2, Vec3(0, 0, -1));
  ASSERT_EQ(spec.cloth.pins.size(), 2u);
  EXPECT_EQ(spec.cloth.pins[0].col, 3);
  EXPECT_EQ(spec.cloth.pins[0].row, 2);
  EXPECT_EQ(spec.cloth.pins[1].kind, PinKind::kEdge);
  ASSERT_EQ(spec.cloth.obstacles.size(), 1u);
  const auto& capsule = std::get<CapsuleSpec>(spec.cloth.obstacles[0].shape);
  EXPECT_EQ(capsule.b_m, Vec3(0, 1, 0));
  EXPECT_EQ(capsule.radius_m, 0.2);
  EXPECT_EQ(spec.cloth.obstacles[0].friction, 0.1);
  EXPECT_EQ(spec.cloth.obstacles[0].margin_m, 0.0);
  EXPECT_EQ(spec.integration.integrator, IntegratorKind::kImplicitEuler);
  EXPECT_EQ(spec.integration.substeps, 7);
  EXPECT_EQ(spec.integration.frame_rate_hz, 120.0);
  EXPECT_EQ(spec.integration.max_frame_dt_s, 0.05);
  EXPECT_EQ(spec.integration.auto_safety, 1.0);
  EXPECT_EQ(spec.integration.cg_max_iterations, 50);
  EXPECT_EQ(spec.integration.cg_tolerance, 1e-6);
  EXPECT_FALSE(spec.provot.enabled);
  EXPECT_EQ(spec.provot.max_elongation, 0.2);
  EXPECT_EQ(spec.provot.iterations, 3);
  EXPECT_FALSE(spec.provot.shear);
  EXPECT_FALSE(spec.provot.long_range_attachments);
}

TEST(SceneFile, IntegratorNamesRoundTrip) {
  for (const IntegratorName& entry : kIntegratorNames) {
    EXPECT_EQ(ToName(entry.kind), entry.name);
    EXPECT_EQ(IntegratorFromName(entry.name), entry.kind);
    const SimSpec spec =
        Parse("[cloth]\n[integration]\nintegrator = \"" + std::string(entry.name) + "\"\n");
    EXPECT_EQ(spec.integration.integrator, entry.kind);
  }
  EXPECT_FALSE(IntegratorFromName("RK4").has_value());
}

// ---- Documented errors, by message ----------------------------------------------------------

TEST(SceneFileErrors, MissingFile) {
  try {
    LoadSceneDocument("scenes/no_such_scene.toml");
    FAIL() << "no error";
  } catch (const SceneError& error) {
    EXPECT_STREQ(error.what(),
                 "scenes/no_such_scene.toml: cannot read scene file: No such file or directory");
  }
}

TEST(SceneFileErrors, DirectoryInsteadOfFile) {
  try {
    LoadSceneDocument(kScenes);
    FAIL() << "no error";
  } catch (const SceneError& error) {
    EXPECT_EQ(std::string(error.what()),
              kScenes.string() + ": cannot read scene file: it is a directory");
  }
}

TEST(SceneFileErrors, SyntaxErrorNamesLineAndColumn) {
  EXPECT_EQ(ErrorOf("[cloth]\nwidth = 32\nheight = = 3\n"),
            "t.toml:3:10: syntax error: Error while parsing value: could not determine value "
            "type");
}

TEST(SceneFileErrors, SyntaxErrorFromAFileNamesTheFile) {
  const std::filesystem::path path =
      std::filesystem::path(::testing::TempDir()) / "felt_scene_syntax_error.toml";
  {
    std::ofstream file(path);
    file << "[scene]\nname = \"unterminated\n";
  }
  try {
    LoadSceneDocument(path);
    FAIL() << "no error";
  } catch (const SceneError& error) {
    EXPECT_EQ(std::string(error.what()).rfind(path.string() + ":2:", 0), 0u) << error.what();
    EXPECT_NE(std::string(error.what()).find("syntax error"), std::string::npos);
  }
  std::filesystem::remove(path);
}

TEST(SceneFileErrors, WrongType) {
  EXPECT_EQ(ErrorOf("[cloth]\nwidth = \"wide\"\n"),
            "t.toml:2:1: cloth.width: must be an integer, got a string \"wide\"");
  EXPECT_EQ(ErrorOf("[cloth]\nwidth = 32.0\n"),
            "t.toml:2:1: cloth.width: must be an integer, got a float 32.0");
  EXPECT_EQ(ErrorOf("[cloth]\nspacing_m = true\n"),
            "t.toml:2:1: cloth.spacing_m: must be a number, got a boolean true");
  EXPECT_EQ(ErrorOf("[cloth]\n[provot]\nenabled = 1\n"),
            "t.toml:3:1: provot.enabled: must be true or false, got an integer 1");
  EXPECT_EQ(ErrorOf("[scene]\nname = 3\n[cloth]\n"),
            "t.toml:2:1: scene.name: must be a string, got an integer 3");
  EXPECT_EQ(ErrorOf("[cloth]\nstructural = 5\n"),
            "t.toml:2:1: cloth.structural: must be a table, got an integer 5");
  EXPECT_EQ(ErrorOf("[cloth]\n[cloth.pins]\nkind = \"corner\"\n"),
            "t.toml:2:8: cloth.pins: must be an array of tables ([[cloth.pins]]), got a table");
  EXPECT_EQ(ErrorOf("[cloth]\n[obstacles]\ntype = \"plane\"\n"),
            "t.toml:2:2: obstacles: must be an array of tables [[obstacles]], got a table");
  EXPECT_EQ(ErrorOf("[[cloth]]\n"),
            "t.toml:1:3: cloth: must be a table [cloth], got an array of 1 value");
}

TEST(SceneFileErrors, OutOfRange) {
  EXPECT_EQ(ErrorOf("[cloth]\n[cloth.structural]\n  stiffness_N_per_m = -5\n"),
            "t.toml:3:3: cloth.structural.stiffness_N_per_m: must be > 0, got -5");
  EXPECT_EQ(ErrorOf("[cloth]\nwidth = 1\n"),
            "t.toml:2:1: cloth.width: must be in [2, 4096], got 1");
  // The same rules as BuildClothModel's (sim_loop/cloth_spec.h's limits), with the line.
  EXPECT_EQ(ErrorOf("[cloth]\nwidth = 4096\nheight = 2048\n"),
            "t.toml:2:1: cloth.width: width * height must be <= 4194304, got 8388608");
  EXPECT_EQ(ErrorOf("[cloth]\nspacing_m = 0.0\n"),
            "t.toml:2:1: cloth.spacing_m: must be > 0, got 0.0");
  EXPECT_EQ(ErrorOf("[cloth]\ndrag_N_s_per_m = -0.5\n"),
            "t.toml:2:1: cloth.drag_N_s_per_m: must be >= 0, got -0.5");
  EXPECT_EQ(ErrorOf("[cloth]\nmass_kg = nan\n"), "t.toml:2:1: cloth.mass_kg: must be > 0, got nan");
  EXPECT_EQ(ErrorOf("[cloth]\n[integration]\nauto_safety = 1.5\n"),
            "t.toml:3:1: integration.auto_safety: must be in (0, 1], got 1.5");
  EXPECT_EQ(ErrorOf("[cloth]\n[integration]\nmax_frame_dt_s = 0.01\n"),
            "t.toml:3:1: integration.max_frame_dt_s: must be >= 1 / frame_rate_hz = "
            "0.016666666666666666 s, got 0.01");
  EXPECT_EQ(ErrorOf("[cloth]\n[provot]\niterations = 0\n"),
            "t.toml:3:1: provot.iterations: must be in [1, 10000], got 0");
  EXPECT_EQ(ErrorOf("[cloth]\nwidth = 5000000000\n"),
            "t.toml:2:1: cloth.width: must fit in a 32-bit integer, got 5000000000");
  EXPECT_EQ(ErrorOf("[scene]\nduration_s = 0\n[cloth]\n"),
            "t.toml:2:1: scene.duration_s: must be > 0, got 0");
  EXPECT_EQ(ErrorOf("[cloth]\n[[obstacles]]\ntype = \"sphere\"\ncenter_m = [0, 0, 0]\n"
                    "radius_m = 0\n"),
            "t.toml:5:1: obstacles[0].radius_m: must be > 0, got 0");
  EXPECT_EQ(ErrorOf("[cloth]\n[provot]\nsweep_headroom = 0.5\n"),
            "t.toml:3:1: provot.sweep_headroom: must be in [0, 0.5), got 0.5");
  EXPECT_EQ(ErrorOf("[cloth]\n[provot]\npatch_iterations = 0\n"),
            "t.toml:3:1: provot.patch_iterations: must be in [1, 10000], got 0");
  EXPECT_EQ(ErrorOf("[cloth]\n[provot]\npatch_sweep_headroom = -0.01\n"),
            "t.toml:3:1: provot.patch_sweep_headroom: must be in [0, 0.5), got -0.01");
}

TEST(SceneFileErrors, UnknownKey) {
  EXPECT_EQ(ErrorOf("[cloth]\n[cloth.structural]\nstifness_N_per_m = 5\n"),
            "t.toml:3:1: cloth.structural.stifness_N_per_m: unknown key 'stifness_N_per_m' in "
            "[cloth.structural] (did you mean 'stiffness_N_per_m'?)");
  // No close match: the known keys are listed. The first unknown key in file order is reported.
  EXPECT_EQ(ErrorOf("[cloth]\n[provot]\nzzz = 1\naaa = 2\n"),
            "t.toml:3:1: provot.zzz: unknown key 'zzz' in [provot]; known keys: enabled, "
            "max_elongation, iterations, shear, long_range_attachments, multiresolution, "
            "coarse_sweeps, sweep_headroom, finish, patch_iterations, patch_sweep_headroom");
  EXPECT_EQ(ErrorOf("[cloth]\n[[cloth.pins]]\nkind = \"corner\"\nname = \"top_left\"\ncol = 3\n"),
            "t.toml:5:1: cloth.pins[0].col: unknown key 'col' in cloth.pins[0]; known keys: kind, "
            "name, motion");
  EXPECT_EQ(ErrorOf("[cloth]\n[[obstacles]]\ntype = \"plane\"\nradius_m = 1\n"),
            "t.toml:4:1: obstacles[0].radius_m: unknown key 'radius_m' in obstacles[0]; known "
            "keys: type, friction, margin_m, point_m, normal");
  EXPECT_EQ(ErrorOf("[scene]\ntitle = \"x\"\n[cloth]\n"),
            "t.toml:2:1: scene.title: unknown key 'title' in [scene]; known keys: name, "
            "description, duration_s");
}

TEST(SceneFileErrors, UnknownSection) {
  EXPECT_EQ(ErrorOf("[clth]\nwidth = 3\n"),
            "t.toml:1:2: unknown section [clth] (did you mean [cloth]?); known sections: scene, "
            "cloth, obstacles, integration, provot, self_collision, device, devices, proxy, haptic, "
            "transport");
  EXPECT_EQ(ErrorOf("name = \"x\"\n[cloth]\n"),
            "t.toml:1:1: unknown top-level key 'name'; every setting belongs in a section such "
            "as [scene] or [cloth]");
}

TEST(SceneFileErrors, MissingCloth) {
  EXPECT_EQ(ErrorOf("[scene]\nname = \"x\"\n"),
            "t.toml:1:1: cloth: missing required section [cloth]");
}

TEST(SceneFileErrors, UnknownEnumValue) {
  EXPECT_EQ(ErrorOf("[cloth]\n[integration]\nintegrator = \"rk5\"\n"),
            "t.toml:3:1: integration.integrator: unknown value 'rk5' (did you mean 'rk4'?); "
            "expected one of: leapfrog_verlet, explicit_euler, symplectic_euler, "
            "explicit_midpoint, rk4, basic_verlet, velocity_verlet, implicit_euler");
  EXPECT_EQ(ErrorOf("[cloth]\n[[obstacles]]\ntype = \"cube\"\n"),
            "t.toml:3:1: obstacles[0].type: unknown value 'cube'; "
            "expected one of: plane, sphere, box, capsule");
  EXPECT_EQ(ErrorOf("[cloth]\n[[obstacles]]\nfriction = 0.2\n"),
            "t.toml:2:1: obstacles[0].type: missing required key 'type', one of: plane, sphere, "
            "box, capsule");
  EXPECT_EQ(ErrorOf("[cloth]\n[[cloth.pins]]\nkind = \"pinch\"\n"),
            "t.toml:3:1: cloth.pins[0].kind: unknown value 'pinch'; expected one of: corner, "
            "edge, particle");
}

TEST(SceneFileErrors, PinCornerOrEdgeNameUnknown) {
  EXPECT_EQ(ErrorOf("[cloth]\n[[cloth.pins]]\nkind = \"corner\"\nname = \"top_middle\"\n"),
            "t.toml:4:1: cloth.pins[0].name: unknown value 'top_middle'; expected one of: "
            "top_left, top_right, bottom_left, bottom_right");
  EXPECT_EQ(ErrorOf("[cloth]\n[[cloth.pins]]\nkind = \"corner\"\nname = \"top_lft\"\n"),
            "t.toml:4:1: cloth.pins[0].name: unknown value 'top_lft' (did you mean 'top_left'?); "
            "expected one of: top_left, top_right, bottom_left, bottom_right");
  EXPECT_EQ(ErrorOf("[cloth]\n[[cloth.pins]]\nkind = \"edge\"\nname = \"top_left\"\n"),
            "t.toml:4:1: cloth.pins[0].name: unknown value 'top_left'; expected one of: top, "
            "bottom, left, right");
  EXPECT_EQ(ErrorOf("[cloth]\n[[cloth.pins]]\nkind = \"corner\"\n"),
            "t.toml:2:1: cloth.pins[0].name: missing required key 'name', one of: top_left, "
            "top_right, bottom_left, bottom_right");
}

TEST(SceneFileErrors, PinParticleOutsideTheGrid) {
  EXPECT_EQ(ErrorOf("[cloth]\nwidth = 8\n[[cloth.pins]]\nkind = \"particle\"\ncol = 8\nrow = 0\n"),
            "t.toml:5:1: cloth.pins[0].col: must be in [0, 7], got 8");
}

TEST(SceneFileErrors, PinMotion) {
  EXPECT_EQ(ErrorOf("[cloth]\n[[cloth.pins]]\nkind = \"corner\"\nname = \"top_left\"\n"
                    "motion = { start_s = 2, stop_s = 1 }\n"),
            "t.toml:5:25: cloth.pins[0].motion.stop_s: must be >= start_s = 2, got 1");
  EXPECT_EQ(ErrorOf("[cloth]\n[[cloth.pins]]\nkind = \"corner\"\nname = \"top_left\"\n"
                    "[cloth.pins.motion]\namplitude_m = [0, 0.1, 0]\n"),
            "t.toml:6:1: cloth.pins[0].motion.amplitude_m: a non-zero amplitude_m needs "
            "frequency_hz > 0");
  EXPECT_EQ(ErrorOf("[cloth]\n[[cloth.pins]]\nkind = \"corner\"\nname = \"top_left\"\n"
                    "[cloth.pins.motion]\nvelocity = [1, 0, 0]\n"),
            "t.toml:6:1: cloth.pins[0].motion.velocity: unknown key 'velocity' in "
            "[cloth.pins[0].motion]; known keys: velocity_m_per_s, amplitude_m, frequency_hz, "
            "start_s, stop_s");
}

TEST(SceneFileErrors, BadVector) {
  EXPECT_EQ(ErrorOf("[cloth]\norigin_m = [0, 1]\n"),
            "t.toml:2:1: cloth.origin_m: must be an array of 3 numbers [x, y, z], got an array "
            "of 2 values");
  EXPECT_EQ(ErrorOf("[cloth]\norigin_m = 0\n"),
            "t.toml:2:1: cloth.origin_m: must be an array of 3 numbers [x, y, z], got an "
            "integer 0");
  EXPECT_EQ(ErrorOf("[cloth]\norigin_m = [0, \"y\", 0]\n"),
            "t.toml:2:16: cloth.origin_m[1]: must be a number, got a string \"y\"");
  EXPECT_EQ(ErrorOf("[cloth]\ngravity_m_per_s2 = [0, -inf, 0]\n"),
            "t.toml:2:24: cloth.gravity_m_per_s2[1]: must be a finite number, got -inf");
}

TEST(SceneFileErrors, Axes) {
  EXPECT_EQ(ErrorOf("[cloth]\nu_axis = [0, 0, 0]\n"),
            "t.toml:2:1: cloth.u_axis: must be a non-zero vector (a direction), got a vector of "
            "length 0");
  EXPECT_EQ(ErrorOf("[cloth]\nu_axis = [1, 0, 0]\nv_axis = [1, 1, 0]\n"),
            "t.toml:3:1: cloth.v_axis: must be orthogonal to u_axis, got u_axis [1, 0, 0] and "
            "v_axis [0.7071067811865475, 0.7071067811865475, 0] (normalised)");
}

TEST(SceneFileErrors, BoxMinNotBelowMax) {
  EXPECT_EQ(ErrorOf("[cloth]\n\n[[obstacles]]\ntype = \"box\"\nmin_m = [0, 0, 0]\n"
                    "max_m = [1, 0, 1]\n"),
            "t.toml:6:1: obstacles[0].max_m: must be greater than min_m on every axis, got "
            "min_m [0, 0, 0] and max_m [1, 0, 1]");
  EXPECT_EQ(ErrorOf("[cloth]\n[[obstacles]]\ntype = \"box\"\nmin_m = [0, 0, 0]\n"),
            "t.toml:2:1: obstacles[0].max_m: missing required key 'max_m'");
}

TEST(SceneFileErrors, CapsuleEndsMustDiffer) {
  EXPECT_EQ(ErrorOf("[cloth]\n[[obstacles]]\ntype = \"capsule\"\na_m = [0, 1, 0]\n"
                    "b_m = [0, 1, 0]\nradius_m = 0.1\n"),
            "t.toml:5:1: obstacles[0].b_m: must differ from a_m (for a ball, use type = "
            "\"sphere\")");
}

TEST(SceneFileErrors, Substeps) {
  EXPECT_EQ(ErrorOf("[cloth]\n[integration]\nsubsteps = \"sometimes\"\n"),
            "t.toml:3:1: integration.substeps: must be \"auto\" or an integer in [1, 100000], "
            "got a string \"sometimes\"");
  EXPECT_EQ(ErrorOf("[cloth]\n[integration]\nsubsteps = 0\n"),
            "t.toml:3:1: integration.substeps: must be \"auto\" or an integer in [1, 100000], "
            "got an integer 0");
  EXPECT_EQ(ErrorOf("[cloth]\n[integration]\nsubsteps = 2.5\n"),
            "t.toml:3:1: integration.substeps: must be \"auto\" or an integer in [1, 100000], "
            "got a float 2.5");
  // What only the built cloth shows, at the substeps key, else at [integration], else unplaced.
  const std::string stiff = "[cloth]\n[cloth.structural]\nstiffness_N_per_m = 1e20\n";
  const std::string too_many =
      "integration.substeps: auto needs 450359962737063 substeps per frame";
  EXPECT_EQ(
      ErrorOf(stiff + "[integration]\nsubsteps = \"auto\"\n").rfind("t.toml:5:1: " + too_many, 0),
      0u);
  EXPECT_EQ(ErrorOf(stiff + "[integration]\n").rfind("t.toml:4:1: " + too_many, 0), 0u)
      << ErrorOf(stiff + "[integration]\n");
  EXPECT_EQ(ErrorOf(stiff).rfind("t.toml: " + too_many, 0), 0u);
}

// ---- The field reader, as another module would use it ----------------------------------------

TEST(SceneTable, ReadsAnotherModulesSection) {
  const SceneDocument doc = ParseSceneText(R"([cloth]
[proxy]
radius_m = 0.004
shading = true
[[devices]]
id = "left"
offset_m = [0.1, 0, 0]
[[devices]]
id = "right"
)",
                                           "t.toml");
  const std::optional<SceneTable> proxy = SceneTable::Section(doc, "proxy");
  ASSERT_TRUE(proxy.has_value());
  proxy->ExpectKeys({"radius_m", "shading", "friction"});
  EXPECT_EQ(proxy->Number("radius_m", 0.005, Positive()), 0.004);
  EXPECT_TRUE(proxy->Bool("shading", false));
  EXPECT_FALSE(proxy->Bool("friction", false));
  const std::vector<SceneTable> devices = SceneTable::SectionArray(doc, "devices");
  ASSERT_EQ(devices.size(), 2u);
  EXPECT_EQ(devices[1].path(), "devices[1]");
  EXPECT_EQ(devices[0].String("id", kRequired, true), "left");
  EXPECT_EQ(devices[0].Vector("offset_m", Vec3::Zero()), Vec3(0.1, 0, 0));
  EXPECT_EQ(devices[1].Vector("offset_m", Vec3::Zero()), Vec3::Zero());
  EXPECT_FALSE(SceneTable::Section(doc, "haptic").has_value());
  try {
    proxy->ExpectKeys({"radius_m"});
    FAIL() << "no error";
  } catch (const SceneError& error) {
    EXPECT_STREQ(error.what(),
                 "t.toml:4:1: proxy.shading: unknown key 'shading' in [proxy]; known keys: "
                 "radius_m");
  }
  try {
    devices[1].Fail("offset_m", "must be inside the workspace");
  } catch (const SceneError& error) {
    EXPECT_STREQ(error.what(), "t.toml:8:1: devices[1].offset_m: must be inside the workspace");
  }
}

TEST(SceneTable, KnownSectionsAreUnique) {
  const std::span<const SceneSectionInfo> sections = KnownSceneSections();
  for (size_t i = 0; i < sections.size(); ++i) {
    for (size_t j = i + 1; j < sections.size(); ++j) EXPECT_NE(sections[i].name, sections[j].name);
  }
}

}  // namespace
}  // namespace felt
