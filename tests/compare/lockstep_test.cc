// The lock-step comparison engine (compare/lockstep.h): the variant syntax and its errors,
// overrides reaching the parsed spec, the metrics against closed forms, the virtual clock (ticks,
// frames, no stall), and bitwise determinism: repeated runs give the same forces bit for bit, and
// the reference (or any variant equal to it) has zero error. The truth (issue 20): its spec, its
// place as variant 0, its stability on every bundled trace and its agreement with a truth whose
// cloth takes two frames per tick.
#include "compare/lockstep.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <vector>

#include "proxy/proxy_scene.h"
#include "recordings/generate.h"
#include "recordings/trace.h"
#include "scene/scene_file.h"
#include "tests/test_env.h"

namespace felt {
namespace {

// The message of the std::invalid_argument `f` throws ("" when it throws none).
template <typename F>
std::string ErrorOf(F&& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

// scenes/curtain.toml at 16 x 16 particles over the same 0.496 m (as tests/haptic_loop's
// SmallCurtain), with a 50 ms ramp-in so a short press reaches its full force.
SceneDocument SmallCurtainScene() {
  SceneDocument doc = LoadSceneDocument(std::string(FELT_SOURCE_DIR "/scenes/curtain.toml"));
  toml::table& cloth = *doc.root["cloth"].as_table();
  cloth.insert_or_assign("width", 16);
  cloth.insert_or_assign("height", 16);
  cloth.insert_or_assign("spacing_m", 0.496 / 15.0);
  toml::table haptic;
  haptic.insert_or_assign("ramp_in_s", 0.05);
  doc.root.insert_or_assign("haptic", haptic);
  return doc;
}

// The press of poke_hold.trace: 1 s from t = 1.5 s (the tip meets the cloth at about 1.68 s).
std::vector<TraceSample> PokeSamples() {
  const Trace trace = ReadTrace(FELT_SOURCE_DIR "/recordings/poke_hold.trace");
  return std::vector<TraceSample>(trace.samples.begin() + 1500, trace.samples.begin() + 2500);
}

bool BitIdentical(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(Vec3)) == 0;
}

TEST(LockstepTicks, OnePerPeriodFromTheFirstSampleToTheLastAndBounded) {
  std::vector<TraceSample> samples(2);
  samples[0].t_s = 1.0;
  samples[1].t_s = 3.0;
  EXPECT_EQ(LockstepTicks(samples, 1000.0, 0.0), 2001);
  EXPECT_EQ(LockstepTicks(samples, 1000.0, 0.5), 501);
  EXPECT_THROW(LockstepTicks({}, 1000.0, 0.0), std::invalid_argument);
  // A corrupt time: 1e12 s would be 1e15 ticks. Refused before anything is allocated.
  samples[1].t_s = 1e12;
  try {
    (void)LockstepTicks(samples, 1000.0, 0.0);
    ADD_FAILURE() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("the trace spans 999999999999 s"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(LockstepTicks(samples, 1000.0, 2.0), 2001);  // --duration runs its start
}

TEST(LockstepVariants, ParsesNamesOverridesAndDefaults) {
  const std::vector<LockstepVariant> v = ParseVariantList(
      "ref: snapshot=newest ; blend:snapshot=blend_forces, structure=bvh-aabb-4;"
      "shading=off,proxy.max_iterations=4; plain: ; scene; device.offset_m=[0, 0, 0.01]");
  ASSERT_EQ(v.size(), 6u);
  EXPECT_EQ(v[0].name, "ref");
  ASSERT_EQ(v[0].overrides.size(), 1u);
  EXPECT_EQ(v[0].overrides[0].key, "snapshot");
  EXPECT_EQ(v[0].overrides[0].value, "newest");
  EXPECT_EQ(v[1].name, "blend");
  EXPECT_EQ(v[1].OverridesText(), "snapshot=blend_forces,structure=bvh-aabb-4");
  EXPECT_EQ(v[2].name, "shading=off,proxy.max_iterations=4");  // unnamed: named by its overrides
  EXPECT_EQ(v[3].name, "plain");
  EXPECT_TRUE(v[3].overrides.empty());
  EXPECT_EQ(v[4].name, "scene");
  EXPECT_TRUE(v[4].overrides.empty());
  ASSERT_EQ(v[5].overrides.size(), 1u);  // the commas inside [...] do not split
  EXPECT_EQ(v[5].overrides[0].value, "[0, 0, 0.01]");
}

TEST(LockstepVariants, BadListsNameTheVariantAndThePart) {
  EXPECT_NE(ErrorOf([] { ParseVariantList("  "); }).find("the list is empty"), std::string::npos);
  const std::string no_eq = ErrorOf([] { ParseVariantList("a: snapshot=newest; b: snapshot"); });
  EXPECT_NE(no_eq.find("variant 2 'b'"), std::string::npos) << no_eq;
  EXPECT_NE(no_eq.find("'snapshot' is not key=value"), std::string::npos) << no_eq;
  const std::string unknown = ErrorOf([] { ParseVariantList("a: snap=newest"); });
  EXPECT_NE(unknown.find("variant 1 'a': unknown key 'snap'"), std::string::npos) << unknown;
  const std::string section = ErrorOf([] { ParseVariantList("x: proxxy.radius_m=1"); });
  EXPECT_NE(section.find("unknown section 'proxxy'"), std::string::npos) << section;
  const std::string array = ErrorOf([] { ParseVariantList("x: obstacles.kind=box"); });
  EXPECT_NE(array.find("[[obstacles]] is an array of tables"), std::string::npos) << array;
  const std::string twice = ErrorOf([] { ParseVariantList("snapshot=newest; snapshot=newest"); });
  EXPECT_NE(twice.find("variant 2 'snapshot=newest': the name is used twice"), std::string::npos)
      << twice;
  const std::string empty = ErrorOf([] { ParseVariantList("a: ;; b: "); });
  EXPECT_NE(empty.find("variant 2 is empty"), std::string::npos) << empty;
  const std::string no_value = ErrorOf([] { ParseVariantList("a: snapshot="); });
  EXPECT_NE(no_value.find("key 'snapshot' has no value"), std::string::npos) << no_value;
}

TEST(LockstepVariants, TruthIsABareWordAShorthandAndAFunction) {
  const std::vector<LockstepVariant> v =
      ParseVariantList("truth; fine: truth=2; truth=on; t: truth, snapshot=blend_forces");
  ASSERT_EQ(v.size(), 4u);
  EXPECT_EQ(v[0].name, "truth");
  EXPECT_EQ(v[0].OverridesText(), "truth=on");
  EXPECT_EQ(v[1].OverridesText(), "truth=2");
  EXPECT_EQ(v[2].name, "truth=on");
  EXPECT_EQ(TruthVariant().name, kTruthName);
  EXPECT_EQ(TruthVariant().OverridesText(), "truth=on");
  EXPECT_EQ(TruthVariant(2).name, "truth_2x");
  EXPECT_EQ(TruthVariant(2).OverridesText(), "truth=2");
  EXPECT_NE(ErrorOf([] { TruthVariant(0); }).find("frames_per_tick must be >= 1"),
            std::string::npos);

  // The cloth steps once (or N times) per haptic tick, read from the scene, the proxy in newest.
  SceneDocument scene = SmallCurtainScene();
  const ServerSpec truth = VariantSpec(scene, v[0], 1);
  EXPECT_EQ(truth.sim.integration.frame_rate_hz, 1000.0);
  EXPECT_EQ(truth.haptic.haptic_rate_hz, 1000.0);
  EXPECT_EQ(truth.proxy.snapshot_mode, SnapshotMode::kNewest);
  EXPECT_EQ(VariantSpec(scene, v[1], 2).sim.integration.frame_rate_hz, 2000.0);
  scene.root["haptic"].as_table()->insert_or_assign("haptic_rate_hz", 500);
  EXPECT_EQ(VariantSpec(scene, v[0], 1).sim.integration.frame_rate_hz, 500.0);
  // An override after truth wins (overrides apply in order).
  EXPECT_EQ(VariantSpec(scene, v[3], 4).proxy.snapshot_mode, SnapshotMode::kBlendForces);

  const std::string bad =
      ErrorOf([&] { VariantSpec(scene, ParseVariantList("t: truth=often")[0], 1); });
  EXPECT_NE(bad.find("variant 1 't': truth=often: expected on or an integer N in [1, 10]"),
            std::string::npos)
      << bad;
}

// --truth runs the scene's own cloth: a variant on another cloth is named, with its keys.
TEST(LockstepVariants, TruthNamesVariantsThatRunAnotherCloth) {
  const std::vector<LockstepVariant> v = ParseVariantList(
      "a: snapshot=patch; b: snapshot=patch, cloth.width=64, proxy.patch_radius=6, "
      "cloth.spacing_m=0.008; c: provot.iterations=5");
  const std::vector<std::string> w = TruthClothMismatches(v);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("variant 'b' overrides cloth.width, cloth.spacing_m;"), std::string::npos)
      << w[0];
  EXPECT_TRUE(TruthClothMismatches(ParseVariantList("snapshot=newest; truth")).empty());
}

TEST(LockstepVariants, OverridesReachTheParsedSpec) {
  const SceneDocument scene = SmallCurtainScene();
  const ServerSpec base = VariantSpec(scene, LockstepVariant{"scene", {}}, 1);
  EXPECT_EQ(base.proxy.snapshot_mode, SnapshotMode::kPatch);  // the default (issue 20)
  const LockstepVariant v = ParseVariantList(
      "v: snapshot=extrapolate, structure=bvh-aabb-2, shading=off, friction=0.4/0.3, "
      "integrator=rk4, substeps=6, provot=off, proxy.max_iterations=4, device.radius_m=0.006")[0];
  const ServerSpec s = VariantSpec(scene, v, 1);
  EXPECT_EQ(s.proxy.snapshot_mode, SnapshotMode::kExtrapolate);
  CollisionStructureSpec aabb2;
  ASSERT_TRUE(CollisionStructureFromName("bvh-aabb-2", &aabb2));
  EXPECT_EQ(CollisionStructureName(s.proxy.structure), CollisionStructureName(aabb2));
  EXPECT_FALSE(s.proxy.force_shading);
  EXPECT_EQ(s.proxy.friction_static, 0.4);
  EXPECT_EQ(s.proxy.friction_dynamic, 0.3);
  EXPECT_EQ(s.sim.integration.integrator, IntegratorKind::kRk4);
  EXPECT_EQ(s.sim.integration.substeps, 6);
  EXPECT_FALSE(s.sim.provot.enabled);
  EXPECT_EQ(s.proxy.max_iterations, 4);
  EXPECT_EQ(s.devices[0].radius_m, 0.006);
  // Untouched values stay the scene's.
  EXPECT_EQ(s.sim.cloth.width, 16);
  EXPECT_EQ(s.haptic.safety.ramp_in_s, 0.05);
}

TEST(LockstepVariants, BadValuesNameTheVariantKeyAndSceneField) {
  const SceneDocument scene = SmallCurtainScene();
  auto error = [&](const std::string& list) {
    return ErrorOf([&] {
      const std::vector<LockstepVariant> v = ParseVariantList(list);
      VariantSpec(scene, v.back(), static_cast<int>(v.size()));
    });
  };
  const std::string mode = error("ref: ; bad: snapshot=sideways");
  EXPECT_NE(mode.find("variant 2 'bad': snapshot=sideways: "), std::string::npos) << mode;
  EXPECT_NE(mode.find("proxy.snapshot_mode: unknown value 'sideways'; expected one of"),
            std::string::npos)
      << mode;
  const std::string range = error("r: proxy.max_iterations=0");
  EXPECT_NE(range.find("variant 1 'r': proxy.max_iterations=0: "), std::string::npos) << range;
  EXPECT_NE(range.find("must be in [1, 100], got 0"), std::string::npos) << range;
  const std::string typo = error("t: proxy.radiuss_m=0.1");
  EXPECT_NE(typo.find("unknown key 'radiuss_m'"), std::string::npos) << typo;
  const std::string onoff = error("s: shading=maybe");
  EXPECT_NE(onoff.find("shading=maybe: expected on or off, got 'maybe'"), std::string::npos)
      << onoff;
  const std::string friction = error("f: friction=0.2/0.5");
  EXPECT_NE(friction.find("friction_dynamic: must be <= friction_static"), std::string::npos)
      << friction;
}

TEST(LockstepMetrics, ErrorsAndJumpsMatchClosedForms) {
  // Two devices, four ticks. Reference: zero force, then 1 N along x from tick 2 on device 0.
  LockstepRun ref;
  ref.name = "ref";
  ref.devices = 2;
  ref.ticks = 4;
  ref.force_D_N.assign(8, Vec3::Zero());
  ref.in_contact.assign(8, 0);
  ref.force_D_N[2 * 2 + 0] = Vec3(1, 0, 0);
  ref.force_D_N[3 * 2 + 0] = Vec3(1, 0, 0);
  ref.in_contact[2 * 2 + 0] = 1;
  ref.in_contact[3 * 2 + 0] = 1;
  ref.reach_m.assign(8, 0.0);
  ref.popped.assign(8, 0);
  // Variant: the reference plus (0.3, 0.4, 0) on every sample (error 0.5 N everywhere), and a
  // 2 N jump on device 1 at tick 3.
  LockstepRun var = ref;
  var.name = "var";
  for (Vec3& f : var.force_D_N) f += Vec3(0.3, 0.4, 0.0);
  var.force_D_N[3 * 2 + 1] += Vec3(0, 0, 2);
  var.in_contact[3 * 2 + 1] = 1;
  // ... and the probes: 0.25 mm and 1.5 mm of reach, one tick popped.
  var.reach_m[1 * 2 + 0] = 0.25e-3;
  var.reach_m[2 * 2 + 1] = 1.5e-3;
  var.popped[2 * 2 + 1] = 1;
  const std::vector<VariantSummary> s = SummarizeRuns({ref, var});
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s[0].force_rms_error_N, 0.0);
  EXPECT_EQ(s[0].force_max_error_N, 0.0);
  EXPECT_EQ(s[0].max_jump_N, 1.0);
  EXPECT_EQ(s[0].max_jump_vs_ref_N, 0.0);
  EXPECT_EQ(s[0].contacts, 2u);
  EXPECT_EQ(s[0].peak_force_N, 1.0);
  EXPECT_EQ(s[0].peak_minus_ref_peak_N, 0.0);
  EXPECT_EQ(s[0].pop_through, 0u);
  EXPECT_EQ(s[0].max_reach_mm, 0.0);
  // Errors: seven samples of 0.5 N, one of |(0.3, 0.4, 2)| = sqrt(4.25) N.
  EXPECT_NEAR(s[1].force_rms_error_N, std::sqrt((7 * 0.25 + 4.25) / 8.0), 1e-15);
  EXPECT_NEAR(s[1].force_max_error_N, std::sqrt(4.25), 1e-15);
  EXPECT_NEAR(s[1].max_jump_N, 2.0, 1e-15);
  EXPECT_NEAR(s[1].max_jump_vs_ref_N, 1.0, 1e-15);
  EXPECT_EQ(s[1].contacts, 3u);
  EXPECT_EQ(s[1].contact_mismatches, 1u);
  // Peak: |(0.3, 0.4, 2)| against the reference's 1 N.
  EXPECT_NEAR(s[1].peak_force_N, std::sqrt(4.25), 1e-15);
  EXPECT_NEAR(s[1].peak_minus_ref_peak_N, std::sqrt(4.25) - 1.0, 1e-15);
  EXPECT_EQ(s[1].pop_through, 1u);
  EXPECT_NEAR(s[1].max_reach_mm, 1.5, 1e-12);
  // Runs that cannot be paired are refused, naming the variant.
  LockstepRun shorter = var;
  shorter.ticks = 3;
  const std::string message = ErrorOf([&] { SummarizeRuns({ref, shorter}); });
  EXPECT_NE(message.find("variant 'var': 3 ticks"), std::string::npos) << message;
}

TEST(Lockstep, VirtualClockRunsEveryTickAndFrameWithoutStalls) {
  const SceneDocument scene = SmallCurtainScene();
  const ServerSpec spec = VariantSpec(scene, LockstepVariant{"scene", {}}, 1);
  LockstepOptions options;
  options.max_duration_s = 0.5;
  const LockstepRun run = RunLockstep(spec, PokeSamples(), options);
  // 0.5 s: ticks at 1..501 ms, frames at multiples of 1/60 s up to 501 ms.
  EXPECT_EQ(run.ticks, 501);
  EXPECT_EQ(run.frames, 30);
  EXPECT_EQ(run.tick_cpu_us.size(), 501u);
  EXPECT_EQ(run.frame_cpu_ms.size(), 30u);
  EXPECT_EQ(run.force_D_N.size(), 501u);
  // The snapshots' ages come from the virtual clock: never stalled, however slow the machine.
  EXPECT_EQ(run.stalled_ticks, 0u);
  EXPECT_EQ(run.nan_events + run.cloth_nan_events, 0u);
  for (double us : run.tick_cpu_us) EXPECT_GE(us, 0.0);
  // Every device tick was probed.
  ASSERT_EQ(run.reach_m.size(), 501u);
  ASSERT_EQ(run.popped.size(), 501u);
  for (double reach : run.reach_m) {
    EXPECT_GE(reach, 0.0);
    EXPECT_LT(reach, spec.devices[0].radius_m);
  }
}

TEST(Lockstep, RepeatedRunsAreBitIdenticalAndTheReferenceHasZeroError) {
  const SceneDocument scene = SmallCurtainScene();
  const std::vector<TraceSample> samples = PokeSamples();
  const std::vector<LockstepVariant> variants = ParseVariantList(
      "ref: snapshot=newest; same: snapshot=newest; blend: snapshot=blend_forces, "
      "structure=bvh-aabb-4");
  const CompareResult first = CompareVariants(scene, samples, variants);
  const CompareResult second = CompareVariants(scene, samples, variants);
  ASSERT_EQ(first.runs.size(), 3u);
  ASSERT_EQ(second.runs.size(), 3u);
  // The press touched the cloth with a real force (so the comparison is not of zeros).
  EXPECT_GT(first.summaries[0].contacts, 100u);
  EXPECT_GT(first.summaries[0].peak_force_N, 0.2);
  // Every force sample of every variant is the same bit for bit in both runs.
  for (size_t v = 0; v < variants.size(); ++v) {
    EXPECT_EQ(first.runs[v].ticks, second.runs[v].ticks) << v;
    EXPECT_EQ(first.runs[v].frames, second.runs[v].frames) << v;
    EXPECT_TRUE(BitIdentical(first.runs[v].force_D_N, second.runs[v].force_D_N)) << v;
    EXPECT_EQ(first.runs[v].in_contact, second.runs[v].in_contact) << v;
    EXPECT_EQ(first.summaries[v].force_rms_error_N, second.summaries[v].force_rms_error_N) << v;
  }
  // The reference, and a variant equal to it on a fresh server, have exactly zero error.
  for (int v : {0, 1}) {
    EXPECT_EQ(first.summaries[v].force_rms_error_N, 0.0) << v;
    EXPECT_EQ(first.summaries[v].force_max_error_N, 0.0) << v;
    EXPECT_EQ(first.summaries[v].max_jump_vs_ref_N, 0.0) << v;
    EXPECT_EQ(first.summaries[v].contact_mismatches, 0u) << v;
  }
  // A different variant is seen to differ.
  EXPECT_GT(first.summaries[2].force_rms_error_N, 0.0);
  EXPECT_GE(first.summaries[2].force_max_error_N, first.summaries[2].force_rms_error_N);
}

TEST(Lockstep, AHeldPressWithTremorStaysInContactInEverySnapshotMode) {
  // poke_hold.trace's press and hold (3 s from t = 1.5 s, hand tremor included) on the default
  // curtain, closed loop. Mode extrapolate used to fall into a limit cycle here (contact lost each
  // frame the sim's cloth was pushed away from the hand, regained when it sprang back freely:
  // 74 % of the reference's contact ticks over the whole trace, 0.58 N RMS from it); the sim now
  // keeps the hand's sphere while the free proxy is near its last contact (proxy/proxy.cc).
  const SceneDocument scene =
      LoadSceneDocument(std::string(FELT_SOURCE_DIR "/scenes/curtain.toml"));
  const Trace trace = ReadTrace(FELT_SOURCE_DIR "/recordings/poke_hold.trace");
  const std::vector<TraceSample> samples(trace.samples.begin() + 1500,
                                         trace.samples.begin() + 4500);
  const CompareResult result = CompareVariants(
      scene, samples,
      ParseVariantList("interpolate: snapshot=interpolate; newest: snapshot=newest; "
                       "blend: snapshot=blend_forces; extrapolate: snapshot=extrapolate; "
                       "patch: snapshot=patch"));
  const VariantSummary& ref = result.summaries[0];
  ASSERT_GT(ref.contacts, 2000u);
  for (const VariantSummary& s : result.summaries) {
    SCOPED_TRACE(s.name);
    EXPECT_GT(static_cast<double>(s.contacts), 0.95 * static_cast<double>(ref.contacts));
    EXPECT_LT(s.force_rms_error_N, 0.2);
    EXPECT_LT(s.peak_force_N, 1.5 * ref.peak_force_N);
  }
}

TEST(Lockstep, PrependedTruthIsVariantZeroAndTheReference) {
  const SceneDocument scene = SmallCurtainScene();
  LockstepOptions options;
  options.prepend_truth = true;
  options.max_duration_s = 0.3;
  const CompareResult result = CompareVariants(
      scene, PokeSamples(), ParseVariantList("newest: snapshot=newest; again: truth"), options);
  ASSERT_EQ(result.runs.size(), 3u);
  EXPECT_EQ(result.runs[0].name, "truth");
  EXPECT_EQ(result.runs[0].overrides, "truth=on");
  EXPECT_EQ(result.runs[0].frames, result.runs[0].ticks);  // one cloth frame per tick
  EXPECT_EQ(result.runs[1].frames, 18);                    // 60 Hz over 0.301 s
  EXPECT_EQ(result.summaries[2].force_rms_error_N, 0.0);   // the truth again, bit for bit
  // The given variants keep their numbers; the truth is variant 0.
  const std::string twice = ErrorOf([&] {
    CompareVariants(scene, PokeSamples(), ParseVariantList("newest: snapshot=newest; truth"),
                    options);
  });
  EXPECT_NE(twice.find("variant 2 'truth': the name is used twice"), std::string::npos) << twice;
  const std::string bad = ErrorOf([&] {
    CompareVariants(scene, PokeSamples(), ParseVariantList("bad: snapshot=sideways"), options);
  });
  EXPECT_NE(bad.find("variant 1 'bad': snapshot=sideways"), std::string::npos) << bad;
}

// The truth on the default curtain (32 x 32) is stable on every bundled trace, and agrees with a
// finer truth (two cloth frames per tick, the same 1 kHz haptic rate) on poke_hold and
// fast_swipe. Measured (docs/compare.md, "The truth"): RMS force difference 0.008 N (poke_hold)
// and 0.041 N (fast_swipe). Bound: 0.06 N, well under the 0.15 N `felt bench haptic` asks of the
// snapshot modes: the truth's own discretisation must be finer than what it judges. The forces
// are deterministic, so the bound is loose only against compilers and libraries, not machines.
TEST(LockstepTruth, StableOnEveryBundledTraceAndAgreesWithATwoFramePerTickTruth) {
  const SceneDocument scene =
      LoadSceneDocument(std::string(FELT_SOURCE_DIR "/scenes/curtain.toml"));
  for (const std::string& name : BundledTraceNames()) {
    SCOPED_TRACE(name);
    const bool pressed_or_swiped = name == "poke_hold" || name == "fast_swipe";
    // Under a sanitizer those two only (the same code paths as the other three).
    if (testing::Sanitized() && !pressed_or_swiped) continue;
    // The truth at twice the rate (convergence: physics) in the release run only (test_env.h).
    const bool converge = pressed_or_swiped && !testing::Sanitized();
    std::vector<LockstepVariant> variants = {TruthVariant(1)};
    if (converge) variants.push_back(TruthVariant(2));
    const Trace trace = ReadTrace(std::string(FELT_SOURCE_DIR "/recordings/") + name + ".trace");
    LockstepOptions options;  // under a sanitizer, each trace's first 3 s (the same paths)
    if (testing::Sanitized()) options.max_duration_s = 3.0;
    const CompareResult result = CompareVariants(scene, trace.samples, variants, options);
    for (size_t v = 0; v < result.runs.size(); ++v) {
      const LockstepRun& run = result.runs[v];
      SCOPED_TRACE(run.name);
      EXPECT_EQ(run.nan_events, 0u);
      EXPECT_EQ(run.cloth_nan_events, 0u);
      EXPECT_EQ(run.frames, run.ticks * static_cast<int64_t>(v + 1));
      for (const Vec3& f : run.force_D_N) ASSERT_TRUE(f.allFinite());
      EXPECT_EQ(result.summaries[v].pop_through, 0u);
    }
    EXPECT_GT(result.summaries[0].contacts, 100u);  // the trace touches the cloth
    if (converge) {
      EXPECT_LT(result.summaries[1].force_rms_error_N, 0.06);
    }
  }
}

TEST(Lockstep, VariantsThatCannotBePairedAreRefusedBeforeRunning) {
  const SceneDocument scene = SmallCurtainScene();
  const std::string message = ErrorOf([&] {
    CompareVariants(scene, PokeSamples(),
                    ParseVariantList("ref: ; slow: haptic.haptic_rate_hz=500"));
  });
  EXPECT_NE(message.find("variant 2 'slow': haptic.haptic_rate_hz 500 differs"), std::string::npos)
      << message;
}

}  // namespace
}  // namespace felt

namespace felt {
namespace {

// Mode patch never lets the proxy through or deep into the cloth it renders, on the hard traces
// and fast_swipe, on the 64 x 64 curtain of `felt bench haptic` (the same square, the same total
// drag): no pop-through, no reach beyond 0.5 mm (1/8 of the 4 mm radius; the bench measured
// 0.1 mm at most, and 3.8 mm on fast_swipe while a window followed a contact hopping in a crease
// every tick), no NaN. Whole traces in the release run, their first 1.5 s under a sanitizer.
TEST(LockstepPatch, HardTracesNeitherPopThroughNorReachIntoThePatch) {
  const SceneDocument scene =
      LoadSceneDocument(std::string(FELT_SOURCE_DIR "/scenes/curtain.toml"));
  LockstepOptions options;
  if (testing::Sanitized()) options.max_duration_s = 1.5;
  const std::string grid =
      "cloth.width=64, cloth.height=64, cloth.spacing_m=0.007873015873015873, "
      "cloth.drag_N_s_per_m=1.25e-5";
  std::vector<std::string> names = HardTraceNames();
  names.push_back("fast_swipe");
  for (const std::string& name : names) {
    SCOPED_TRACE(name);
    const std::string dir = name == "fast_swipe" ? "/recordings/" : "/recordings/hard/";
    const Trace trace = ReadTrace(std::string(FELT_SOURCE_DIR) + dir + name + ".trace");
    const CompareResult result = CompareVariants(
        scene, trace.samples, ParseVariantList("patch: snapshot=patch, " + grid), options);
    const VariantSummary& s = result.summaries[0];
    EXPECT_EQ(s.pop_through, 0u);
    EXPECT_LT(s.max_reach_mm, 0.5);
    EXPECT_EQ(s.nan_events, 0u);
    EXPECT_GT(s.contacts, 100u);
  }
}

// Real handwriting played 2 and 4 times faster than it was written (every 2nd / 4th sample of the
// 1 kHz trace, velocities scaled): real hand motion harder than any bundled trace. On the shipped
// curtain the truth does not converge there (the truth at twice the rate is 0.2-1.0 N RMS from
// it), so forces are not judged; what must hold whatever the motion: no pop-through, no NaN, the
// force within the device's limit. Trials 1, 11 and 15: over all 20, played from trace files (6
// decimals), the proxy reached furthest into the cloth on 15 and 11 at 2x (3.5 and 1.0 mm); at
// full precision, as here, their contacts take other courses (0.1 mm). Reads
// ../shared/data/real-motion in place; skipped without it, and under a sanitizer (physics; the
// bundled hard traces cover the code paths).
TEST(LockstepRealMotion, HandwritingTwiceAndFourTimesFasterNeverPopsThrough) {
  if (testing::Sanitized()) GTEST_SKIP() << "physics only; the release run checks it";
  const std::string dir = FELT_SOURCE_DIR "/../shared/data/real-motion";
  if (!std::filesystem::exists(dir + "/" + kRealPenFile)) {
    GTEST_SKIP() << "no real-motion data at " << dir;
  }
  const SceneDocument scene =
      LoadSceneDocument(std::string(FELT_SOURCE_DIR "/scenes/curtain.toml"));
  const ServerSpec spec = VariantSpec(scene, ParseVariantList("scene").front(), 1);
  for (const int64_t trial : {1, 11, 15}) {
    const Trace pen = RealPenTrace(dir, trial);
    for (const int speed : {2, 4}) {
      SCOPED_TRACE("trial " + std::to_string(trial) + " at " + std::to_string(speed) + "x");
      std::vector<TraceSample> fast;
      for (size_t k = 0; k < pen.samples.size(); k += static_cast<size_t>(speed)) {
        TraceSample s = pen.samples[k];
        s.t_s = static_cast<double>(k / static_cast<size_t>(speed)) * 1e-3;
        s.v_D *= speed;
        fast.push_back(s);
      }
      const LockstepRun run = RunLockstep(spec, fast);
      size_t popped = 0, contacts = 0;
      for (size_t k = 0; k < run.force_D_N.size(); ++k) {
        popped += run.popped[k];
        contacts += run.in_contact[k];
        ASSERT_TRUE(run.force_D_N[k].allFinite()) << "tick " << k;
        ASSERT_LE(run.force_D_N[k].norm(), spec.devices[0].max_force_N * (1 + 1e-12)) << k;
      }
      EXPECT_EQ(popped, 0u);
      EXPECT_EQ(run.nan_events, 0u);
      EXPECT_GT(contacts, 300u);  // the pen wrote on the cloth
      // Reported, not judged here: how far the proxy was inside the cloth (ProbeProxy), where the
      // bundled hard traces are held under 0.5 mm on the 64 x 64 cloth (LockstepPatch above).
      std::printf("real_pen_%lld at %dx: %zu contact ticks, max reach %.3f mm\n",
                  static_cast<long long>(trial), speed, contacts,
                  1e3 * *std::max_element(run.reach_m.begin(), run.reach_m.end()));
    }
  }
}

}  // namespace
}  // namespace felt

namespace felt {
namespace {

// On the 128 x 128 curtain a burst of the random walk folds the cloth under the hand and the
// proxy touches both layers; its window used to follow whichever layer's contact came first,
// jumping 7-9 rows each tick, and at 3.04 s the cloth under the proxy jumped with the particles
// that left the window: the proxy went through (reach 3.8 mm, one pop-through). The window now
// follows the contact nearest where it is. Physics only: not run under a sanitizer (the 128 x
// 128 frames take ~40 ms each even in the release build). One trajectory: on seven burst_walk
// traces of 10 s the patch still reached 3-4 mm into a fold on two, with the previous limiter
// settings and with these (docs/proxy.md, "The patch's own sweeps"); what this pins is the
// window's rule, not that folds are solved.
TEST(LockstepPatch, AFoldUnderTheHandDoesNotPullTheWindowAcrossIt) {
  if (testing::Sanitized()) GTEST_SKIP() << "physics only; the release run checks it";
  const SceneDocument scene =
      LoadSceneDocument(std::string(FELT_SOURCE_DIR "/scenes/curtain_128.toml"));
  const Trace trace = ReadTrace(std::string(FELT_SOURCE_DIR "/recordings/hard/burst_walk.trace"));
  LockstepOptions options;
  options.max_duration_s = 3.2;
  const CompareResult result =
      CompareVariants(scene, trace.samples, ParseVariantList("patch: snapshot=patch"), options);
  const VariantSummary& s = result.summaries[0];
  EXPECT_EQ(s.pop_through, 0u);
  EXPECT_LT(s.max_reach_mm, 1.0);
  EXPECT_EQ(s.nan_events, 0u);
}

}  // namespace
}  // namespace felt

namespace felt {
namespace {

// Mode patch against the truth on the shipped curtain (scenes/curtain.toml, 32 x 32) meets issue
// 20's targets (RMS error at most 0.15 N, peak at most 0.5 N above the truth's, no pop-through,
// no NaN) on the generated trace `name` of each seed (generated in memory: unrounded, unlike the
// files of `felt trace generate`).
void ExpectPatchFollowsTheTruthOnTheShippedCurtain(const char* name,
                                                   std::initializer_list<uint64_t> seeds) {
  const SceneDocument scene =
      LoadSceneDocument(std::string(FELT_SOURCE_DIR "/scenes/curtain.toml"));
  LockstepOptions options;
  options.prepend_truth = true;
  for (const uint64_t seed : seeds) {
    SCOPED_TRACE(seed);
    const Trace trace = GenerateTrace(name, seed);
    const CompareResult result =
        CompareVariants(scene, trace.samples, ParseVariantList("patch: snapshot=patch"), options);
    ASSERT_EQ(result.summaries.size(), 2u);
    const VariantSummary& s = result.summaries[1];
    EXPECT_LE(s.force_rms_error_N, 0.15);
    EXPECT_LE(s.peak_minus_ref_peak_N, 0.5);
    EXPECT_EQ(s.pop_through, 0u);
    EXPECT_EQ(s.nan_events, 0u);
  }
}

// Pressing and dragging toward a pinned corner, seeds 5 and 6. Before the patch held the long
// range attachments to the pins in its window seed 5 gave +1.01 N here (from the files: seed 5
// +0.71 N, seed 6 +1.32 N; docs/proxy.md, "Pins in the window"): the patch's three sweeps let the
// particles by the pin stretch, and the contact there rang at about 80 Hz. The truth converges
// on both (2 kHz against 1 kHz: 0.03 N RMS). Physics only: not run under a sanitizer
// (ClothPatchTest covers the attachments' code there).
TEST(LockstepPatch, DraggingTowardAPinFollowsTheTruthOnTheShippedCurtain) {
  if (testing::Sanitized()) GTEST_SKIP() << "physics only; the release run checks it";
  ExpectPatchFollowsTheTruthOnTheShippedCurtain("pin_drag", {5u, 6u});
}

// Vibrating while pressed (250 Hz, 0.4 mm), seeds 4 and 5. With the hand predicted over the frame
// from its instantaneous velocity (proxy.predict_hand, the default until 2026-11-27) the sim's
// contact sphere swept up to a centimetre each frame along a velocity sampled at a 10 Hz beat of
// 250 Hz against 60 Hz, the 60 Hz cloth that drives the patch's rings followed it, and the force
// rose 0.5 N over the truth's (+0.76 and +0.53 N here, against +0.04 and +0.05 N without;
// docs/proxy.md, "The hand over the frame"). Physics only: not run under a sanitizer.
TEST(LockstepPatch, VibratingWhilePressedFollowsTheTruthOnTheShippedCurtain) {
  if (testing::Sanitized()) GTEST_SKIP() << "physics only; the release run checks it";
  ExpectPatchFollowsTheTruthOnTheShippedCurtain("vibrate", {4u, 5u});
}

}  // namespace
}  // namespace felt
