// The cloth, haptic and loop benchmarks run as a user would run them (`felt bench integrators
// --quick`, `felt bench stability --quick`, `felt bench cloth --grid 10`, `felt bench haptic
// --quick` on one trace, `felt bench loops --seconds 1`),
// each into a temp folder: exit code 0 and the JSON files hold the keys the reports and the issues
// rely on. No timing is asserted.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "proxy/proxy_spec.h"
#include "tests/app/felt_process.h"

namespace felt::test {
namespace {

// A fresh folder of this test's own under the test temp directory.
std::string FreshDir(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::path(::testing::TempDir()) / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir.string();
}

// What one `felt bench NAME` run into a fresh folder left.
struct BenchRun {
  std::string dir;   // the --out folder
  Outcome outcome;   // exit code and output
  std::string json;  // the text of its --json file, DIR/NAME.json ("" if not written)
};

/// Runs `felt bench NAME OPTIONS --out DIR --json DIR/NAME.json --scene <the curtain>` into a
/// fresh folder felt_bench_NAME (no unit) and reads back its JSON file.
BenchRun RunBench(const std::string& name, const std::string& options) {
  BenchRun run;
  run.dir = FreshDir("felt_bench_" + name);
  const std::string json = run.dir + "/" + name + ".json";
  run.outcome = RunFelt("bench " + name + " " + options + " --out " + run.dir + " --json " + json +
                        " --scene " + kSource + "/scenes/curtain.toml");
  run.json = ReadFile(json);
  return run;
}

// Expects every `"key":` in `json`.
void ExpectKeys(const std::string& json, const std::vector<std::string>& keys) {
  for (const std::string& key : keys) {
    EXPECT_NE(json.find("\"" + key + "\":"), std::string::npos) << "missing key " << key;
  }
}

TEST(BenchSmoke, IntegratorsQuickWritesItsFiles) {
  const BenchRun run =
      RunBench("integrators", "--quick --gnuplot-script " + kSource + "/bench/plot_integrators.gp");
  ASSERT_EQ(run.outcome.exit_code, 0) << run.outcome.output;
  const std::string& dir = run.dir;
  const std::string& text = run.json;
  ExpectKeys(text, {"command", "machine", "rows", "stable_steps", "references", "grid", "provot",
                    "integrator", "substeps", "frame_ms_median", "rms_error_m", "energy_drift",
                    "max_stretch", "stable", "h_max_s", "stable_dt_s", "ratio_to_stable_dt"});
  ExpectKeys(text, {"complete", "timed_frames", "unstable_at_s", "energy_blowup_s"});
  // The finished run says so (the files are rewritten, marked partial, while it runs).
  EXPECT_NE(text.find("\"complete\": true"), std::string::npos);
  // Every integrator has rows.
  for (const char* name :
       {"leapfrog_verlet", "explicit_euler", "symplectic_euler", "explicit_midpoint", "rk4",
        "basic_verlet", "velocity_verlet", "implicit_euler"}) {
    EXPECT_NE(text.find(std::string("\"integrator\": \"") + name + "\""), std::string::npos)
        << name;
  }
  EXPECT_TRUE(std::filesystem::exists(dir + "/integrators.md"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/integrators.csv"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/integrators_plot.dat"));
  EXPECT_EQ(ReadFile(dir + "/integrators.md").rfind("# Integrators", 0), 0u);
}

TEST(BenchSmoke, StabilityQuickWritesItsFiles) {
  const BenchRun run = RunBench("stability", "--quick");
  ASSERT_EQ(run.outcome.exit_code, 0) << run.outcome.output;
  const std::string& dir = run.dir;
  const std::string& text = run.json;
  const Outcome& outcome = run.outcome;
  ExpectKeys(text, {"command", "machine", "cases", "case", "parameters", "result", "criterion",
                    "pass", "metrics"});
  for (const char* name :
       {"stiff springs, large dt", "pinned-corner super-elasticity",
        "fast fall onto a thin obstacle", "zero-length springs", "degenerate triangles",
        "NaN injected into one particle", "500 ms stalled frame", "one hour, default",
        "one hour, undamped", "one hour, undamped, resolved"}) {
    EXPECT_NE(text.find(std::string("\"case\": \"") + name + "\""), std::string::npos) << name;
  }
  EXPECT_NE(outcome.output.find("| case | parameters | result | criterion | pass/fail |"),
            std::string::npos)
      << outcome.output;
  EXPECT_TRUE(std::filesystem::exists(dir + "/stability.md"));
}

TEST(BenchSmoke, ClothOneGridWritesItsFiles) {
  const BenchRun run = RunBench("cloth", "--grid 10");
  ASSERT_EQ(run.outcome.exit_code, 0) << run.outcome.output;
  const std::string& dir = run.dir;
  const std::string& text = run.json;
  ExpectKeys(text, {"command", "machine", "grids", "grid", "frame_ms_median", "frame_ms_p99",
                    "max_stretch", "substeps", "particles", "springs", "release_frame_ms_max",
                    "flat_release_max_stretch", "flat_release_frame_ms_max"});
  EXPECT_NE(text.find("\"grid\": 10,"), std::string::npos) << text;
  EXPECT_NE(text.find("\"particles\": 100,"), std::string::npos) << text;
  EXPECT_TRUE(std::filesystem::exists(dir + "/cloth.md"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/cloth.csv"));
}

// `felt bench haptic --quick` on one trace (poke_hold, given with --trace, the bundled and hard
// traces skipped) on the default curtain resized to 32 x 32: the truth, every snapshot mode of
// kSnapshotModes (by name, never listed here) and the truth at twice the rate (the reference's
// convergence, which decides whether the trace judges the force targets) in the tables, JSON and
// CSV, and the plot.
TEST(BenchSmoke, HapticQuickOnOneTraceWritesItsFiles) {
  const std::string dir = FreshDir("felt_bench_haptic");
  const Outcome outcome =
      RunFelt("bench haptic --quick --no-bundled --grid 32 --trace " + kSource +
              "/recordings/poke_hold.trace --scene " + kSource +
              "/scenes/curtain.toml --gnuplot-script " + kSource + "/bench/haptic.gp --json " +
              dir + "/haptic.json --csv " + dir + "/haptic.csv --md " + dir + "/haptic.md");
  ASSERT_EQ(outcome.exit_code, 0) << outcome.output;
  const std::string json = ReadFile(dir + "/haptic.json");
  ExpectKeys(json, {"command",
                    "machine",
                    "load_average_end",
                    "scene",
                    "grid",
                    "triangles",
                    "duration_s",
                    "reference",
                    "targets",
                    "traces",
                    "summary",
                    "main",
                    "hard",
                    "variants",
                    "force_rms_error_N",
                    "force_max_error_N",
                    "peak_minus_ref_peak_N",
                    "pop_through",
                    "max_reach_mm",
                    "contact_mismatches",
                    "tick_us_median",
                    "tick_us_p99",
                    "nan_events",
                    "rms_error_worst_N",
                    "rms_error_median_N",
                    "targets_met",
                    "converged_spread_N",
                    "reference_spread_N",
                    "judged",
                    "judged_traces",
                    "judged_rms_error_worst_N"});
  const Json doc = Json::parse(json, nullptr, false);
  ASSERT_TRUE(doc.is_object()) << json;
  EXPECT_EQ(doc["duration_s"], Json(2.5));
  EXPECT_EQ(doc["triangles"], Json(2 * 31 * 31));
  ASSERT_EQ(doc["traces"].size(), 1u);
  const Json& variants = doc["traces"][0]["variants"];
  ASSERT_EQ(variants.size(), 2u + std::size(kSnapshotModes));
  EXPECT_EQ(variants[0]["name"], Json("truth"));
  EXPECT_EQ(variants[0]["frames"], Json(2501));  // the cloth stepped every tick
  EXPECT_EQ(variants[0]["force_rms_error_N"], Json(0));
  for (size_t m = 0; m < std::size(kSnapshotModes); ++m) {
    const std::string name = SnapshotModeName(kSnapshotModes[m]);
    EXPECT_EQ(variants[m + 1]["name"], Json(name));
    EXPECT_EQ(variants[m + 1]["overrides"], Json("proxy.snapshot_mode=" + name));
    EXPECT_EQ(variants[m + 1]["ticks"], Json(2501));
    EXPECT_GT(variants[m + 1]["force_rms_error_N"].get<double>(), 0.0) << name;
    EXPECT_NE(outcome.output.find("| " + name + " | "), std::string::npos) << name;
  }
  const Json& twice = variants[1 + std::size(kSnapshotModes)];
  EXPECT_EQ(twice["name"], Json("truth_2x"));
  EXPECT_EQ(twice["frames"], Json(5002));  // the cloth stepped twice every tick
  // A held poke converges: the finer truth is within half the RMS target, so the trace judges.
  EXPECT_EQ(doc["traces"][0]["reference_spread_N"], twice["force_rms_error_N"]);
  EXPECT_LT(doc["traces"][0]["reference_spread_N"].get<double>(), 0.075);
  EXPECT_EQ(doc["traces"][0]["judged"], Json(true));
  EXPECT_TRUE(doc["summary"]["hard"].empty());
  EXPECT_NE(outcome.output.find("| poke_hold | truth | 0 | 0 |"), std::string::npos)
      << outcome.output;
  EXPECT_NE(outcome.output.find("Host: "), std::string::npos) << outcome.output;
  const std::string md = ReadFile(dir + "/haptic.md");
  EXPECT_NE(md.find("## Targets per mode"), std::string::npos) << md;
  EXPECT_NE(md.find("Every trace judged"), std::string::npos) << md;
  const std::string csv = ReadFile(dir + "/haptic.csv");
  EXPECT_EQ(csv.rfind("group,trace,variant,ticks,force_rms_error_N,", 0), 0u) << csv;
  EXPECT_NE(csv.find("\nuser,poke_hold,truth,2501,0,"), std::string::npos) << csv;
  if (std::system("command -v gnuplot > /dev/null 2>&1") == 0) {
    EXPECT_TRUE(std::filesystem::exists(dir + "/haptic.png")) << outcome.output;
  }
}

// Issue 5's JSON: empty.lateness_us and server.lateness_us (p50, p99, p999, max), server.overruns,
// server.ticks; with --server-setting-only the empty loop runs under the server's setting alone.
TEST(BenchSmoke, LoopsOneSecondWritesTheIssueKeys) {
  const std::string dir = FreshDir("felt_bench_loops");
  const std::string json = dir + "/loops.json";
  const Outcome outcome =
      RunFelt("bench loops --seconds 1 --server-setting-only --json " + json + " --scene " +
              kSource + "/scenes/curtain.toml --trace " + kSource + "/recordings/poke_hold.trace");
  ASSERT_EQ(outcome.exit_code, 0) << outcome.output;
  const std::string text = ReadFile(json);
  ExpectKeys(text,
             {"empty", "server", "lateness_us", "p50", "p99", "p999", "max", "overruns", "ticks"});
  EXPECT_NE(outcome.output.find("empty loop vs server"), std::string::npos) << outcome.output;
  // One empty-loop setting only: the server's.
  EXPECT_NE(outcome.output.find("fifo_spin"), std::string::npos) << outcome.output;
  EXPECT_EQ(outcome.output.find("\nnormal "), std::string::npos) << outcome.output;
}

// Issue 22's self-collision bench on one small grid: the files and the JSON keys the issue names.
TEST(BenchSmoke, SelfCollisionQuickWritesItsFiles) {
  const std::string dir = FreshDir("felt_bench_self_collision");
  const std::string json = dir + "/self_collision.json";
  const Outcome outcome = RunFelt("bench self-collision --quick --out " + dir + " --json " + json +
                                  " --scene " + kSource + "/scenes/self_fold_drop.toml" +
                                  " --gnuplot-script " + kSource + "/bench/self_collision.gp");
  ASSERT_EQ(outcome.exit_code, 0) << outcome.output;
  ExpectKeys(ReadFile(json), {"command", "machine", "rows", "method", "case", "triangles",
                              "frame_ms_median", "intersections_end_of_frame"});
  const std::string md = ReadFile(dir + "/self_collision.md");
  EXPECT_NE(md.find("| bvh | 16 |"), std::string::npos) << md;
  EXPECT_NE(md.find("| bvox_aabb | 16 |"), std::string::npos) << md;
  EXPECT_EQ(ReadFile(dir + "/self_collision.csv").rfind("# felt bench self-collision", 0), 0u);
  // The cost of every frame over the animation, and its plot.
  const std::string frames = ReadFile(dir + "/self_collision_frames.csv");
  EXPECT_EQ(frames.rfind("kind,method,grid,frame,frame_ms,detect_ms,case,host\n", 0), 0u);
  EXPECT_NE(frames.find("\nresponse,off,16,0,"), std::string::npos) << frames;
  EXPECT_NE(frames.find("\nresponse,bvh_cones,16,19,"), std::string::npos) << frames;
  if (std::system("command -v gnuplot > /dev/null 2>&1") == 0) {
    EXPECT_TRUE(std::filesystem::exists(dir + "/self_collision.png")) << outcome.output;
  }
}

}  // namespace
}  // namespace felt::test
