// `felt bench cloth [--grid N] [--json FILE]`: the cost of one 60 Hz frame of the default curtain
// (scenes/curtain.toml resized, auto substeps + Provot, the scene's own settings) at grids 10 to
// 128, with its max stretch, against the targets (64 x 64: <= 1 ms median with max stretch <= 1.10,
// issue 2; 128 x 128: <= 5.6 ms median, issue 21).
//
// Each grid: the curtain settles for --settle-frames frames (not timed), then --frames frames are
// timed one by one (wall clock and this thread's CPU time). Writes <out>/cloth.{md,csv,json}.
//
// `felt bench cloth --tradeoff`: frame cost against max stretch for each setting of Felt's solver
// and for Bullet's btSoftBody with its iterations swept, at grids 32, 64 and 128 (or --grid N);
// bench/cloth_tradeoff.h. Writes <out>/cloth_tradeoff.{md,csv,json,png}.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/command.h"
#include "base/json.h"
#include "bench/bench_util.h"
#include "bench/cloth_tradeoff.h"
#include "sim_loop/cloth.h"

namespace felt::bench::bench_cloth {
namespace {

constexpr double kStretchTarget = 1.10;

struct Args {
  std::optional<int32_t> grid;
  std::string json;
  std::string out = "bench/results";
  std::string scene = "scenes/curtain.toml";
  std::optional<int32_t> frames;  // 300, or 120 with --tradeoff
  int32_t settle_frames = 120;
  // --tradeoff and its options (TradeoffOptions).
  bool tradeoff = false;
  bool quick = false;
  double point_budget_s = TradeoffOptions{}.point_budget_s;
  std::vector<int32_t> bullet_iterations = TradeoffOptions{}.bullet_iterations;
  std::vector<int32_t> felt_substeps = TradeoffOptions{}.substeps;
  std::vector<int32_t> felt_sweeps = TradeoffOptions{}.sweeps;
  std::vector<int32_t> felt_small_steps = TradeoffOptions{}.small_steps;
  std::vector<double> felt_limits = TradeoffOptions{}.limits;
  std::vector<int32_t> felt_sweeps_alone = TradeoffOptions{}.sweeps_alone;
  bool no_bullet = false;
  std::string gnuplot_script = TradeoffOptions{}.gnuplot_script;
  bool no_plot = false;

  int32_t timed_frames() const { return frames.value_or(tradeoff ? (quick ? 10 : 120) : 300); }
};

// One grid's measurements.
struct GridResult {
  int32_t grid = 0;
  int32_t particles = 0;
  int64_t springs = 0;
  int64_t provot_constraints = 0;
  int32_t substeps = 0;
  std::vector<double> wall_ms;
  std::vector<double> cpu_ms;
  double max_stretch = 1.0;    // over every frame, settling included
  double timed_stretch = 1.0;  // over the timed frames only (the settled cloth)
  double final_stretch = 1.0;  // after the last frame
  double max_shear = 1.0;      // the same three over the shear springs (Provot's `shear`)
  double timed_shear = 1.0;
  double final_shear = 1.0;
  uint64_t nan_events = 0;
  // The finishing worklist (sim_loop/cloth_limiter.cc) over the timed frames: projections per
  // substep, and substeps whose worklist ran out of budget (over every frame, settling included).
  double worklist_per_substep = 0.0;
  uint64_t worklist_unconverged = 0;
  // The release as a real-time frame sees it: the slowest settling frame of the hanging release,
  // and the same cloth released flat (v_axis along +z, as ClothStepTest's second case) for as
  // many frames: its largest structural stretch after any frame and its slowest frame, wall ms.
  double release_max_ms = 0.0;
  double flat_max_stretch = 1.0;
  double flat_max_ms = 0.0;
  // The target for this grid, if it has one: median ms, and whether stretch is part of it.
  std::optional<double> target_ms;
  bool stretch_target = false;
};

std::optional<double> TargetMs(int32_t grid) {
  if (grid == 64) return 1.0;
  if (grid == 128) return 5.6;
  return std::nullopt;
}

GridResult RunGrid(const Args& args, int32_t grid) {
  const SimSpec spec = ResizedCurtain(args.scene, grid);
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  GridResult r;
  r.grid = grid;
  r.particles = model.num_particles();
  r.springs = static_cast<int64_t>(model.springs.size());
  r.provot_constraints = ProvotPairCount(model);
  r.substeps = model.substeps;
  r.target_ms = TargetMs(grid);
  r.stretch_target = grid == 64;
  const double frame_dt_s = 1.0 / spec.integration.frame_rate_hz;
  const std::span<const ExternalForce> none;

  // Settle (untimed), then time each frame; stretch is tracked over both.
  for (int32_t f = 0; f < args.settle_frames; ++f) {
    const double wall0 = WallMs();
    StepFrame(model, none, frame_dt_s, &state);
    r.release_max_ms = std::max(r.release_max_ms, WallMs() - wall0);
    r.max_stretch = std::max(r.max_stretch, MaxStretch(model, state));
    r.max_shear = std::max(r.max_shear, MaxStretchOf(model, state, SpringType::kShear));
  }
  const uint64_t projections0 = state.counters.limiter_projections;
  r.wall_ms.reserve(static_cast<size_t>(args.timed_frames()));
  r.cpu_ms.reserve(static_cast<size_t>(args.timed_frames()));
  for (int32_t f = 0; f < args.timed_frames(); ++f) {
    const double cpu0 = ThreadCpuMs();
    const double wall0 = WallMs();
    StepFrame(model, none, frame_dt_s, &state);
    const double wall1 = WallMs();
    const double cpu1 = ThreadCpuMs();
    r.wall_ms.push_back(wall1 - wall0);
    r.cpu_ms.push_back(cpu1 - cpu0);
    const double stretch = MaxStretch(model, state);
    r.max_stretch = std::max(r.max_stretch, stretch);
    r.timed_stretch = std::max(r.timed_stretch, stretch);
    const double shear = MaxStretchOf(model, state, SpringType::kShear);
    r.max_shear = std::max(r.max_shear, shear);
    r.timed_shear = std::max(r.timed_shear, shear);
  }
  r.final_stretch = MaxStretch(model, state);
  r.final_shear = MaxStretchOf(model, state, SpringType::kShear);
  r.nan_events = state.counters.nan_events;
  r.worklist_per_substep =
      static_cast<double>(state.counters.limiter_projections - projections0) /
      (static_cast<double>(args.timed_frames()) * std::max<int32_t>(1, r.substeps));
  r.worklist_unconverged = state.counters.limiter_unconverged;

  // Released flat: the hardest release of ClothStepTest.FinishingLimiter...AfterEveryFrame.
  SimSpec flat_spec = spec;
  flat_spec.cloth.v_axis = Vec3::UnitZ();
  const ClothModel flat = BuildClothModel(flat_spec);
  ClothState flat_state = MakeClothState(flat);
  for (int32_t f = 0; f < args.settle_frames; ++f) {
    const double wall0 = WallMs();
    StepFrame(flat, none, frame_dt_s, &flat_state);
    r.flat_max_ms = std::max(r.flat_max_ms, WallMs() - wall0);
    r.flat_max_stretch = std::max(r.flat_max_stretch, MaxStretch(flat, flat_state));
  }
  r.nan_events += flat_state.counters.nan_events;
  r.worklist_unconverged += flat_state.counters.limiter_unconverged;
  return r;
}

// "met", "missed", or "-" (no target at this grid).
std::string TargetText(const GridResult& r) {
  if (!r.target_ms) return "-";
  const bool time_ok = Median(r.wall_ms) <= *r.target_ms;
  const bool stretch_ok = !r.stretch_target || r.max_stretch <= kStretchTarget;
  std::string text = "<= " + Fixed(*r.target_ms, *r.target_ms == std::floor(*r.target_ms) ? 0 : 1) +
                     " ms" + (r.stretch_target ? ", stretch <= 1.10" : "") + ": ";
  if (time_ok && stretch_ok) return text + "met";
  text += "missed (";
  if (!time_ok) text += "median " + Fixed(Median(r.wall_ms), 3) + " ms";
  if (!time_ok && !stretch_ok) text += ", ";
  if (!stretch_ok) text += "stretch " + Fixed(r.max_stretch, 4);
  return text + ")";
}

bool TargetMet(const GridResult& r) {
  if (!r.target_ms) return true;
  return Median(r.wall_ms) <= *r.target_ms &&
         (!r.stretch_target || r.max_stretch <= kStretchTarget);
}

std::string Command(const Args& args) {
  std::string cmd = "felt bench cloth";
  if (args.tradeoff) cmd += " --tradeoff";
  if (args.quick) cmd += " --quick";
  if (args.grid) cmd += " --grid " + std::to_string(*args.grid);
  if (args.scene != "scenes/curtain.toml") cmd += " --scene " + args.scene;
  if (args.out != "bench/results") cmd += " --out " + args.out;
  if (!args.json.empty()) cmd += " --json " + args.json;
  if (args.frames) cmd += " --frames " + std::to_string(*args.frames);
  if (args.settle_frames != 120) cmd += " --settle-frames " + std::to_string(args.settle_frames);
  if (args.tradeoff) {
    const TradeoffOptions defaults;
    if (args.point_budget_s != defaults.point_budget_s) {
      cmd += " --point-budget-s " + Sig(args.point_budget_s, 6);
    }
    if (args.bullet_iterations != defaults.bullet_iterations) {
      cmd += " --bullet-iterations";
      for (const int32_t it : args.bullet_iterations) cmd += " " + std::to_string(it);
    }
    const auto list = [&](const char* name, const auto& values, const auto& default_values) {
      if (values == default_values) return;
      cmd += std::string(" ") + name;
      for (const auto v : values) cmd += " " + Sig(static_cast<double>(v), 6);
    };
    list("--felt-substeps", args.felt_substeps, defaults.substeps);
    list("--felt-sweeps", args.felt_sweeps, defaults.sweeps);
    list("--felt-small-steps", args.felt_small_steps, defaults.small_steps);
    list("--felt-limits", args.felt_limits, defaults.limits);
    list("--felt-sweeps-alone", args.felt_sweeps_alone, defaults.sweeps_alone);
    if (args.no_bullet) cmd += " --no-bullet";
    if (args.gnuplot_script != defaults.gnuplot_script) {
      cmd += " --gnuplot-script " + args.gnuplot_script;
    }
    if (args.no_plot) cmd += " --no-plot";
  }
  return cmd;
}

// --tradeoff: the options for bench/cloth_tradeoff.h; --quick is a smoke run (grid 10 unless
// --grid, 10 + 10 frames unless given, one setting per Felt curve, Bullet at 1 and 10 iterations).
int RunTradeoff(const Args& args) {
  TradeoffOptions o;
  if (args.quick) {
    o.grids = {10};
    o.substeps = {6};
    o.sweeps = {1};
    o.small_steps = {6};
    o.limits = {0.05};
    o.sweeps_alone = {3};
    o.bullet_iterations = {1, 10};
    o.settle_frames = 10;
  }
  if (args.grid) o.grids = {*args.grid};
  o.scene = args.scene;
  o.out = args.out;
  o.json = args.json;
  if (!args.quick || args.settle_frames != 120) o.settle_frames = args.settle_frames;
  o.frames = args.timed_frames();
  o.point_budget_s = args.point_budget_s;
  // A list given on the command line replaces the (--quick or full) default.
  const TradeoffOptions defaults;
  if (args.bullet_iterations != defaults.bullet_iterations) {
    o.bullet_iterations = args.bullet_iterations;
  }
  if (args.felt_substeps != defaults.substeps) o.substeps = args.felt_substeps;
  if (args.felt_sweeps != defaults.sweeps) o.sweeps = args.felt_sweeps;
  if (args.felt_small_steps != defaults.small_steps) o.small_steps = args.felt_small_steps;
  if (args.felt_limits != defaults.limits) o.limits = args.felt_limits;
  if (args.felt_sweeps_alone != defaults.sweeps_alone) o.sweeps_alone = args.felt_sweeps_alone;
  o.bullet = !args.no_bullet;
  o.gnuplot_script = args.gnuplot_script;
  o.plot = !args.no_plot;
  o.command = Command(args);
  return RunClothTradeoff(o);
}

std::vector<std::vector<std::string>> Rows(const std::vector<GridResult>& results) {
  std::vector<std::vector<std::string>> rows;
  for (const GridResult& r : results) {
    rows.push_back({std::to_string(r.grid),
                    std::to_string(r.particles),
                    std::to_string(r.springs),
                    std::to_string(r.substeps),
                    Fixed(Median(r.wall_ms), 4),
                    Fixed(Percentile(r.wall_ms, 99), 4),
                    Fixed(Median(r.cpu_ms), 4),
                    Fixed(Percentile(r.cpu_ms, 99), 4),
                    Fixed(r.max_stretch, 4),
                    Fixed(r.timed_stretch, 4),
                    Fixed(r.final_stretch, 4),
                    Fixed(r.max_shear, 4),
                    Fixed(r.timed_shear, 4),
                    Fixed(r.worklist_per_substep, 1),
                    std::to_string(r.worklist_unconverged),
                    Fixed(r.release_max_ms, 2),
                    Fixed(r.flat_max_stretch, 4),
                    Fixed(r.flat_max_ms, 2),
                    std::to_string(r.nan_events),
                    TargetText(r)});
  }
  return rows;
}

// The scene's integration and limiter settings in words, for the table's header.
std::string SettingsText(const SimSpec& spec) {
  const ProvotSpec& p = spec.provot;
  std::string out =
      "auto substeps at " + Fixed(spec.integration.auto_safety, 2) + " of the stable step";
  if (!p.enabled) return out + ", Provot off";
  out += ", Provot " + Fixed(100.0 * p.max_elongation, 0) + " %";
  if (p.long_range_attachments) out += " with long range attachments";
  if (p.multiresolution) {
    out += " and multiresolution families along rows, columns and diagonals";
    if (p.coarse_sweeps < p.iterations) {
      out += " (in the first " + std::to_string(p.coarse_sweeps) + " sweep" +
             (p.coarse_sweeps == 1 ? "" : "s") + ")";
    }
  }
  const auto sweeps = [](int32_t n, double headroom) {
    std::string text = std::to_string(n) + (n == 1 ? " sweep" : " sweeps");
    if (headroom > 0.0) text += " aiming " + Fixed(100.0 * headroom, 1) + " % under the limit";
    return text;
  };
  out += ", " + sweeps(p.iterations, p.sweep_headroom);
  if (p.finish) out += ", then the finishing worklist";
  if (p.patch_iterations || p.patch_sweep_headroom) {
    out += "; the haptic patch: " + sweeps(p.patch_iterations.value_or(p.iterations),
                                           p.patch_sweep_headroom.value_or(p.sweep_headroom));
  }
  return out;
}

int Run(const Args& args) {
  if (args.tradeoff) return RunTradeoff(args);
  if (args.quick) throw std::invalid_argument("--quick needs --tradeoff");
  if (args.timed_frames() < 300) throw std::invalid_argument("--frames must be >= 300");
  if (args.settle_frames < 0) throw std::invalid_argument("--settle-frames must be >= 0");
  const std::vector<int32_t> grids = args.grid ? std::vector<int32_t>{*args.grid}
                                               : std::vector<int32_t>{10, 20, 32, 40, 50, 64, 128};
  const MachineInfo machine = ReadMachineInfo();
  const std::string cmd = Command(args);
  std::printf("%s\nload average %s\n", cmd.c_str(), machine.load_average.c_str());
  std::vector<GridResult> results;
  for (const int32_t grid : grids) {
    results.push_back(RunGrid(args, grid));
    const GridResult& r = results.back();
    std::printf(
        "grid %4d  %2d substeps  frame ms median %.4f p99 %.4f (cpu %.4f)  max stretch %.4f  %s\n",
        grid, r.substeps, Median(r.wall_ms), Percentile(r.wall_ms, 99), Median(r.cpu_ms),
        r.max_stretch, TargetText(r).c_str());
    std::fflush(stdout);
  }
  const std::string load_end = LoadAverage();

  // Markdown, CSV, JSON.
  const std::vector<std::string> header = {"grid",
                                           "particles",
                                           "springs",
                                           "substeps",
                                           "frame ms median",
                                           "frame ms p99",
                                           "cpu ms median",
                                           "cpu ms p99",
                                           "max stretch",
                                           "timed max stretch",
                                           "final stretch",
                                           "max shear stretch",
                                           "timed max shear stretch",
                                           "worklist / substep",
                                           "worklist unconverged",
                                           "release frame ms max",
                                           "flat release max stretch",
                                           "flat release frame ms max",
                                           "nan events",
                                           "target"};
  std::string md = ReportHeader("Cloth frame cost (`felt bench cloth`)", cmd, machine, load_end);
  md += "The curtain of " + args.scene + " (pinned at its two top corners, leapfrog Verlet, " +
        SettingsText(ResizedCurtain(args.scene, grids.front())) +
        ") resized to each grid over the same 0.496 m square. " +
        std::to_string(args.settle_frames) + " frames settle (not timed), then " +
        std::to_string(args.timed_frames()) +
        " frames of 1/60 s are timed one by one. `frame ms` is wall time of StepFrame, `cpu ms` "
        "this thread's CPU time (it does not count time preempted by other processes). Max "
        "stretch: the largest structural spring length / rest length after any frame, settling "
        "included (the release transient peaks at frames 5-8); `timed max stretch` only over the "
        "timed frames, the settled cloth; `max shear stretch` and `timed max shear stretch` the "
        "same over the shear springs (constrained too; the target is on the structural ones). "
        "`worklist / substep`: the finishing worklist's projections per substep over the timed "
        "frames; `worklist unconverged`: substeps whose worklist ran out of its budget (every "
        "frame, both releases). `release frame ms max`: the slowest settling frame (wall), the "
        "release transient as a 60 Hz sim thread meets it; `flat release`: the same cloth "
        "released flat (v_axis along +z, the second case of the stretch test) for as many "
        "frames, its largest structural stretch after any frame and its slowest frame (wall). "
        "Targets: 64 x 64 <= 1 ms median with max stretch <= 1.10 (issue 2); 128 x 128 <= 5.6 ms "
        "median (issue 21: a third of the 60 Hz budget, on every host, AVX2-only CPUs included); "
        "judged on the wall-clock median.\n\n";
  md += MarkdownTable(header, {true, true, true, true, true, true, true, true, true, true,
                               true, true, true, true, true, true, true, true, true, false},
                      Rows(results));
  WriteTextFile(args.out + "/cloth.md", md);
  WriteTextFile(args.out + "/cloth.csv", CsvTable({"grid",
                                                   "particles",
                                                   "springs",
                                                   "substeps",
                                                   "frame_ms_median",
                                                   "frame_ms_p99",
                                                   "cpu_ms_median",
                                                   "cpu_ms_p99",
                                                   "max_stretch",
                                                   "timed_max_stretch",
                                                   "final_stretch",
                                                   "max_shear_stretch",
                                                   "timed_max_shear_stretch",
                                                   "worklist_per_substep",
                                                   "worklist_unconverged",
                                                   "release_frame_ms_max",
                                                   "flat_release_max_stretch",
                                                   "flat_release_frame_ms_max",
                                                   "nan_events",
                                                   "target"},
                                                  Rows(results)));
  Json items = Json::array();
  for (const GridResult& r : results) {
    Json rec{{"grid", r.grid},
             {"frame_ms_median", Median(r.wall_ms)},
             {"frame_ms_p99", Percentile(r.wall_ms, 99)},
             {"cpu_ms_median", Median(r.cpu_ms)},
             {"cpu_ms_p99", Percentile(r.cpu_ms, 99)},
             {"max_stretch", r.max_stretch},
             {"timed_max_stretch", r.timed_stretch},
             {"final_stretch", r.final_stretch},
             {"max_shear_stretch", r.max_shear},
             {"timed_max_shear_stretch", r.timed_shear},
             {"final_shear_stretch", r.final_shear},
             {"substeps", r.substeps},
             {"particles", r.particles},
             {"springs", r.springs},
             {"provot_constraints", r.provot_constraints},
             {"frames", static_cast<int64_t>(r.wall_ms.size())},
             {"worklist_per_substep", r.worklist_per_substep},
             {"worklist_unconverged", static_cast<int64_t>(r.worklist_unconverged)},
             {"release_frame_ms_max", r.release_max_ms},
             {"flat_release_max_stretch", r.flat_max_stretch},
             {"flat_release_frame_ms_max", r.flat_max_ms},
             {"nan_events", static_cast<int64_t>(r.nan_events)}};
    if (r.target_ms) {
      rec["target_ms"] = *r.target_ms;
      rec["target_met"] = TargetMet(r);
    }
    items.push_back(rec);
  }
  Json top{{"command", cmd}};
  AppendMachineJson(machine, load_end, &top);
  top["settle_frames"] = args.settle_frames;
  top["grids"] = items;
  const std::string json = JsonText(top);
  const std::string json_path = args.json.empty() ? args.out + "/cloth.json" : args.json;
  WriteTextFile(json_path, json);
  std::printf("wrote %s/cloth.md, %s/cloth.csv, %s\n", args.out.c_str(), args.out.c_str(),
              json_path.c_str());
  return 0;
}

app::CommandRun Setup(CLI::App& cmd) {
  auto args = std::make_shared<Args>();
  cmd.add_option("--grid", args->grid,
                 "one grid N (N x N particles) instead of 10 ... 128 (--tradeoff: 32, 64, 128)")
      ->check(CLI::Range(2, 2048));
  cmd.add_option("--json", args->json, "JSON output file (default <out>/cloth.json)");
  cmd.add_option("--out", args->out, "folder for cloth.md and cloth.csv")->capture_default_str();
  cmd.add_option("--scene", args->scene, "the curtain scene to resize")->capture_default_str();
  cmd.add_option("--frames", args->frames,
                 "timed frames per grid (default 300, >= 300; --tradeoff: per point, default 120)");
  cmd.add_option("--settle-frames", args->settle_frames, "untimed frames before timing")
      ->capture_default_str();
  cmd.add_flag("--tradeoff", args->tradeoff,
               "frame cost against max stretch: Felt's solver settings and Bullet's btSoftBody "
               "(iterations swept) at grids 32, 64, 128; writes <out>/cloth_tradeoff.{md,csv,json,"
               "png}");
  cmd.add_flag("--quick", args->quick,
               "with --tradeoff: a smoke run (grid 10, 10 + 10 frames, few settings)");
  cmd.add_option("--point-budget-s", args->point_budget_s,
                 "with --tradeoff: stop a point whose projected run time exceeds this, s")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  cmd.add_option("--bullet-iterations", args->bullet_iterations,
                 "with --tradeoff: Bullet's piterations to sweep")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  cmd.add_option("--felt-substeps", args->felt_substeps,
                 "with --tradeoff: integration.substeps to sweep with the scene's sweeps")
      ->capture_default_str()
      ->check(CLI::Range(1, kMaxSubstepsPerFrame));
  cmd.add_option("--felt-sweeps", args->felt_sweeps,
                 "with --tradeoff: provot.iterations to sweep with auto substeps")
      ->capture_default_str()
      ->check(CLI::Range(1, kMaxProvotIterations));
  cmd.add_option("--felt-small-steps", args->felt_small_steps,
                 "with --tradeoff: integration.substeps to sweep with provot.iterations=1")
      ->capture_default_str()
      ->check(CLI::Range(1, kMaxSubstepsPerFrame));
  cmd.add_option("--felt-limits", args->felt_limits,
                 "with --tradeoff: provot.max_elongation values to sweep (auto substeps, the "
                 "scene's sweeps)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  cmd.add_option("--felt-sweeps-alone", args->felt_sweeps_alone,
                 "with --tradeoff: provot.iterations to sweep without the finishing worklist "
                 "(provot.finish=false, provot.sweep_headroom=0; auto substeps)")
      ->capture_default_str()
      ->check(CLI::Range(1, kMaxProvotIterations));
  cmd.add_flag("--no-bullet", args->no_bullet, "with --tradeoff: leave Bullet's rows out");
  cmd.add_option("--gnuplot-script", args->gnuplot_script, "with --tradeoff: the plot's script")
      ->capture_default_str();
  cmd.add_flag("--no-plot", args->no_plot, "with --tradeoff: do not run gnuplot");
  return [args]() { return Run(*args); };
}

const bool kRegistered = app::RegisterCommand(
    {"bench", "cloth", "60 Hz frame cost and max stretch of the curtain at grids 10 to 128",
     Setup});

}  // namespace
}  // namespace felt::bench::bench_cloth
