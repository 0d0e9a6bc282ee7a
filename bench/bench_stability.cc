// `felt bench stability [--json FILE] [--quick]`: the hard cases of issue 2, each run on the real
// cloth (sim_loop/cloth.h) and judged against a criterion fixed before the run. Prints a table
// (case, parameters, result, pass/fail) and writes <out>/stability.{md,json}.
//
// Cases: stiff springs at a large frame dt with auto substeps; pinned-corner super-elasticity on
// 10 ... 128 grids with Provot off and on; a cloth thrown fast onto a thin plate; zero-length
// springs and degenerate triangles; NaN injected into one particle; a 500 ms stalled frame; one
// hour of simulated time (on a 10 x 10 curtain) with bounded energy: as the scene is (damped),
// undamped at the auto substep count, and undamped at a count that resolves its motion.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/command.h"
#include "base/json.h"
#include "bench/bench_util.h"
#include "sim_loop/cloth.h"

namespace felt::bench::bench_stability {
namespace {

constexpr double kFrame_s = 1.0 / 60.0;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Args {
  std::string json;
  std::string out = "bench/results";
  std::string scene = "scenes/curtain.toml";
  bool quick = false;
};

// One row of the table.
struct Case {
  std::string name;
  std::string parameters;
  std::string result;
  std::string criterion;
  bool pass = false;
  Json metrics = Json::object();  // the numbers behind `result`
};

// True if every position, velocity and normal of `state` is finite.
bool Finite(const ClothState& state) {
  for (size_t p = 0; p < state.x.size(); ++p) {
    if (!state.x[p].allFinite() || !state.v[p].allFinite() || !state.normals[p].allFinite()) {
      return false;
    }
  }
  return true;
}

// What a run of frames saw.
struct RunSummary {
  double energy_start_J = 0.0;
  double energy_min_J = 0.0;
  double energy_max_J = 0.0;
  double energy_final_J = 0.0;
  double max_stretch = 1.0;
  double final_stretch = 1.0;
  bool finite = true;  // after every frame
  int64_t frames = 0;
};

// Steps `frames` frames of `frame_dt_s` each, tracking energy, stretch and finiteness.
RunSummary RunFrames(const ClothModel& model, int64_t frames, double frame_dt_s,
                     ClothState* state) {
  RunSummary s;
  s.energy_start_J = s.energy_min_J = s.energy_max_J = s.energy_final_J =
      TotalEnergy(model, *state);
  const std::span<const ExternalForce> none;
  for (int64_t f = 0; f < frames; ++f) {
    StepFrame(model, none, frame_dt_s, state);
    const double e = TotalEnergy(model, *state);
    s.energy_min_J = std::min(s.energy_min_J, e);
    s.energy_max_J = std::max(s.energy_max_J, e);
    s.energy_final_J = e;
    s.final_stretch = MaxStretch(model, *state);
    s.max_stretch = std::max(s.max_stretch, s.final_stretch);
    s.finite = s.finite && Finite(*state);
  }
  s.frames = frames;
  return s;
}

std::string PassText(bool pass) { return pass ? "pass" : "FAIL"; }

// Stiff springs (1000 x the curtain's) stepped at the largest frame dt the clamp allows, auto
// substeps: the auto count must keep the run finite and its energy bounded.
Case StiffSprings(const Args& args, double factor) {
  SimSpec spec = ResizedCurtain(args.scene, 32);
  for (std::optional<SpringSpec>* s :
       {&spec.cloth.structural, &spec.cloth.shear, &spec.cloth.bend}) {
    (*s)->stiffness_N_per_m *= factor;
    (*s)->damping_N_s_per_m *= factor;
  }
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  const double dt = spec.integration.max_frame_dt_s;
  const int64_t frames = args.quick ? 6 : 60;
  const RunSummary run = RunFrames(model, frames, dt, &state);
  const double scale = EnergyScale_J(spec);
  const double rise = (run.energy_max_J - run.energy_start_J) / scale;
  Case c;
  c.name = "stiff springs, large dt";
  c.parameters = "32 x 32 curtain, springs x" + Sig(factor, 4) +
                 " (structural k = " + Sig(spec.cloth.structural->stiffness_N_per_m, 4) +
                 " N/m), leapfrog, auto substeps, Provot on, " + std::to_string(frames) +
                 " frames of " + Fixed(dt * 1e3, 1) + " ms";
  c.criterion = "finite, no NaN events, energy never above its start by > 1% of M g L";
  c.pass = run.finite && state.counters.nan_events == 0 && rise <= 0.01;
  c.result = std::to_string(model.substeps) +
             " substeps per 1/60 s (h = " + Sig(1e3 / (60.0 * model.substeps), 3) +
             " ms, stable step " + Sig(model.stable_dt_s * 1e3, 3) + " ms); finite " +
             (run.finite ? "yes" : "no") + ", NaN events " +
             std::to_string(state.counters.nan_events) + ", max energy rise " + Sig(rise, 3) +
             " M g L, max stretch " + Fixed(run.max_stretch, 4);
  c.metrics = Json{{"spring_factor", factor},
                   {"substeps", model.substeps},
                   {"stable_dt_s", model.stable_dt_s},
                   {"finite", run.finite},
                   {"nan_events", static_cast<int64_t>(state.counters.nan_events)},
                   {"energy_rise_over_MgL", rise},
                   {"max_stretch", run.max_stretch}};
  return c;
}

// The pinned corners of a hanging curtain: max stretch over 2 s with Provot off and on.
Case SuperElasticity(const Args& args, int32_t grid) {
  double stretch[2] = {kNaN, kNaN};
  double final_stretch[2] = {kNaN, kNaN};
  bool finite[2] = {false, false};
  int32_t substeps = 0;
  const int64_t frames = args.quick ? 30 : 120;
  for (int on = 0; on < 2; ++on) {
    SimSpec spec = ResizedCurtain(args.scene, grid);
    spec.provot.enabled = on == 1;
    const ClothModel model = BuildClothModel(spec);
    ClothState state = MakeClothState(model);
    const RunSummary run = RunFrames(model, frames, kFrame_s, &state);
    stretch[on] = run.max_stretch;
    final_stretch[on] = run.final_stretch;
    finite[on] = run.finite && state.counters.nan_events == 0;
    substeps = model.substeps;
  }
  Case c;
  c.name = "pinned-corner super-elasticity";
  c.parameters = std::to_string(grid) + " x " + std::to_string(grid) +
                 " curtain, leapfrog, auto substeps (" + std::to_string(substeps) + "), " +
                 Fixed(static_cast<double>(frames) * kFrame_s, 1) + " s";
  c.criterion = "max stretch with Provot on <= 1.10";
  c.pass = finite[1] && stretch[1] <= 1.10;
  c.result = "max stretch Provot off " + Fixed(stretch[0], 3) + " (final " +
             Fixed(final_stretch[0], 3) + "), Provot on " + Fixed(stretch[1], 4) + " (final " +
             Fixed(final_stretch[1], 4) + ")";
  c.metrics = Json{{"grid", grid},
                   {"substeps", substeps},
                   {"max_stretch_provot_off", stretch[0]},
                   {"final_stretch_provot_off", final_stretch[0]},
                   {"max_stretch_provot_on", stretch[1]},
                   {"final_stretch_provot_on", final_stretch[1]},
                   {"finite", finite[0] && finite[1]}};
  return c;
}

// A horizontal 20 x 20 cloth thrown down at `speed` onto a 1 mm plate: no particle may end a frame
// inside it or below it.
Case ThinObstacle(const Args& args, double speed_m_per_s) {
  SimSpec spec = ResizedCurtain(args.scene, 20);
  spec.cloth.pins.clear();
  spec.cloth.spacing_m = 0.3 / 19;
  spec.cloth.origin_m = Vec3(-0.15, 0.05, -0.15);
  spec.cloth.u_axis = Vec3::UnitX();
  spec.cloth.v_axis = Vec3::UnitZ();
  BoxSpec plate;
  plate.min_m = Vec3(-0.3, -0.001, -0.3);
  plate.max_m = Vec3(0.3, 0.0, 0.3);
  ObstacleSpec obstacle;
  obstacle.shape = plate;
  obstacle.friction = 0.3;
  spec.cloth.obstacles = {obstacle};
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  for (Vec3& v : state.v) v = Vec3(0.0, -speed_m_per_s, 0.0);
  ResetIntegratorHistory(&state);
  const int64_t frames = args.quick ? 20 : 120;
  const std::span<const ExternalForce> none;
  double min_distance_m = std::numeric_limits<double>::infinity();
  int64_t below = 0;
  bool finite = true;
  for (int64_t f = 0; f < frames; ++f) {
    StepFrame(model, none, kFrame_s, &state);
    finite = finite && Finite(state);
    for (const Vec3& x : state.x) {
      Vec3 normal;
      min_distance_m = std::min(min_distance_m, ObstacleDistance(obstacle, x, &normal));
      if (x.y() < plate.min_m.y()) ++below;
    }
  }
  const double h_ms = 1e3 * kFrame_s / model.substeps;
  Case c;
  c.name = "fast fall onto a thin obstacle";
  c.parameters = "20 x 20 cloth (0.3 m, no pins) thrown down at " + Sig(speed_m_per_s, 3) +
                 " m/s onto a 1 mm plate (margin 2 mm), " + std::to_string(model.substeps) +
                 " substeps (" + Sig(speed_m_per_s * h_ms, 3) + " mm per substep), " +
                 Fixed(static_cast<double>(frames) * kFrame_s, 1) + " s";
  c.criterion = "no particle below the plate, never inside it (min distance >= 0), finite";
  c.pass = below == 0 && min_distance_m >= 0.0 && finite;
  c.result = std::string(below == 0 ? "did not pass through" : "PASSED THROUGH") +
             " (particle-frames below the plate: " + std::to_string(below) +
             "); min distance to the plate surface " + Sig(min_distance_m * 1e3, 4) + " mm";
  c.metrics = Json{{"speed_m_per_s", speed_m_per_s},
                   {"substeps", model.substeps},
                   {"particle_frames_below", below},
                   {"min_distance_m", min_distance_m},
                   {"finite", finite}};
  return c;
}

// Every particle at one point (every spring of zero length, every triangle degenerate), or every
// row folded onto the top row (zero-length vertical springs, zero-area triangles).
Case Degenerate(const Args& args, bool to_point) {
  const SimSpec spec = ResizedCurtain(args.scene, 32);
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  for (int32_t r = 0; r < model.height; ++r) {
    for (int32_t c = 0; c < model.width; ++c) {
      state.x[GridIndex(model.width, c, r)] =
          to_point ? Vec3(0.0, 0.25, 0.0) : model.rest_position_m[GridIndex(model.width, c, 0)];
    }
  }
  ResetIntegratorHistory(&state);
  const int64_t frames = args.quick ? 10 : 60;
  const RunSummary run = RunFrames(model, frames, kFrame_s, &state);
  Case c;
  c.name = to_point ? "zero-length springs" : "degenerate triangles";
  c.parameters = to_point ? "32 x 32 curtain, every particle moved to one point (all springs of "
                            "length 0, all triangles of area 0), " +
                                std::to_string(frames) + " frames"
                          : "32 x 32 curtain, every row folded onto the top row (vertical "
                            "springs of length 0, triangles of area 0), " +
                                std::to_string(frames) + " frames";
  c.criterion = "positions, velocities and normals finite after every frame";
  c.pass = run.finite;
  c.result = std::string("finite ") + (run.finite ? "yes" : "no") + ", NaN events " +
             std::to_string(state.counters.nan_events) + ", max stretch after 1 s " +
             Fixed(run.final_stretch, 4);
  c.metrics = Json{{"finite", run.finite},
                   {"nan_events", static_cast<int64_t>(state.counters.nan_events)},
                   {"final_stretch", run.final_stretch}};
  return c;
}

// A zero rest length is refused at validation: the spec cannot describe it.
Case ZeroSpacing(const Args& args) {
  SimSpec spec = ResizedCurtain(args.scene, 32);
  spec.cloth.spacing_m = 0.0;
  std::string message = "accepted";
  bool refused = false;
  try {
    BuildClothModel(spec);
  } catch (const std::invalid_argument& error) {
    message = error.what();
    refused = true;
  }
  Case c;
  c.name = "zero rest length";
  c.parameters = "32 x 32 curtain with cloth.spacing_m = 0";
  c.criterion = "refused by BuildClothModel with a message naming the field";
  c.pass = refused && message.find("cloth.spacing_m") != std::string::npos;
  c.result = refused ? "refused: \"" + message + "\"" : "accepted";
  c.metrics = Json{{"refused", refused}, {"message", message}};
  return c;
}

// NaN (or inf) written into one particle between frames: the next frame must restore the last
// good state, count it once, and the run must go on finite.
Case InjectNaN(const Args& args, bool velocity) {
  const SimSpec spec = ResizedCurtain(args.scene, 32);
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  const int64_t before = args.quick ? 10 : 60;
  RunFrames(model, before, kFrame_s, &state);
  const int32_t p = GridIndex(model.width, model.width / 2, model.height / 2);
  if (velocity) {
    state.v[p] = Vec3(std::numeric_limits<double>::infinity(), 0.0, 0.0);
  } else {
    state.x[p] = Vec3(kNaN, 0.0, 0.0);
  }
  const std::span<const ExternalForce> none;
  const FrameResult hit = StepFrame(model, none, kFrame_s, &state);
  const bool finite_after = Finite(state);
  const RunSummary rest = RunFrames(model, before, kFrame_s, &state);
  Case c;
  c.name = velocity ? "inf injected into one velocity" : "NaN injected into one particle";
  c.parameters = "32 x 32 curtain, particle (" + std::to_string(model.width / 2) + ", " +
                 std::to_string(model.height / 2) + ") " + (velocity ? "v.x = inf" : "x.x = NaN") +
                 " after " + std::to_string(before) + " frames, then " + std::to_string(before) +
                 " more frames";
  c.criterion = "that frame recovered, counted once, finite then and after";
  c.pass = hit.recovered && state.counters.nan_events == 1 && finite_after && rest.finite;
  c.result = std::string("recovered ") + (hit.recovered ? "yes" : "no") + ", nan_events " +
             std::to_string(state.counters.nan_events) + ", finite after " +
             (finite_after && rest.finite ? "yes" : "no");
  c.metrics = Json{{"recovered", hit.recovered},
                   {"nan_events", static_cast<int64_t>(state.counters.nan_events)},
                   {"finite_after", finite_after && rest.finite}};
  return c;
}

// One frame of 500 ms after a second of normal frames: clamped to max_frame_dt_s.
Case StalledFrame(const Args& args) {
  const SimSpec spec = ResizedCurtain(args.scene, 32);
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  RunFrames(model, args.quick ? 10 : 60, kFrame_s, &state);
  const double e_before = TotalEnergy(model, state);
  const std::span<const ExternalForce> none;
  const FrameResult late = StepFrame(model, none, 0.5, &state);
  const double e_after = TotalEnergy(model, state);
  const bool finite = Finite(state);
  const double jump = (e_after - e_before) / EnergyScale_J(spec);
  Case c;
  c.name = "500 ms stalled frame";
  c.parameters =
      "32 x 32 curtain after " + std::to_string(args.quick ? 10 : 60) +
      " frames, one StepFrame(0.5 s), max_frame_dt_s = " + Sig(spec.integration.max_frame_dt_s, 4) +
      " s";
  c.criterion = "clamped, finite, energy not raised by > 1% of M g L";
  c.pass = late.clamped && finite && jump <= 0.01;
  c.result = std::string("clamped ") + (late.clamped ? "yes" : "no") + " (integrated " +
             Sig(late.dt_s * 1e3, 4) + " ms in " + std::to_string(late.substeps) +
             " substeps), finite " + (finite ? "yes" : "no") + ", energy change " +
             Sig(e_after - e_before, 3) + " J (" + Sig(jump, 3) + " M g L)";
  c.metrics = Json{{"clamped", late.clamped},
                   {"integrated_dt_s", late.dt_s},
                   {"substeps", late.substeps},
                   {"finite", finite},
                   {"energy_jump_J", e_after - e_before},
                   {"energy_jump_over_MgL", jump}};
  return c;
}

// Substeps of the resolved undamped hour: 16 times the count the stability bound gives the 10 x 10
// curtain (2). That count holds the linearised cloth stable in every configuration, but springs
// folded to near zero length have a transverse stiffness k (1 - L / l) without a lower bound, and
// the undamped curtain, stretched 4-7 times by its weight, folds springs that short; only a shorter
// step follows that motion. Auto now gives such a conservative cloth omega_max h <= 0.03 (51 here;
// sim_loop/cloth_build.cc), so the auto row and this one both resolve it.
constexpr int32_t kResolvedHourSubsteps = 32;

// One hour of simulated time on a 10 x 10 curtain; `undamped`: springs and drag without damping
// and Provot off, so only the integrator can make energy drift; `substeps` > 0: that fixed count
// instead of the scene's (auto).
Case OneHour(const Args& args, bool undamped, int32_t substeps = 0) {
  SimSpec spec = ResizedCurtain(args.scene, 10);
  if (undamped) {
    spec.cloth.drag_N_s_per_m = 0.0;
    for (std::optional<SpringSpec>* s :
         {&spec.cloth.structural, &spec.cloth.shear, &spec.cloth.bend}) {
      (*s)->damping_N_s_per_m = 0.0;
    }
    spec.provot.enabled = false;
  }
  if (substeps > 0) spec.integration.substeps = substeps;
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  const double seconds = args.quick ? 10.0 : 3600.0;
  const int64_t frames = std::llround(seconds * 60.0);
  const double wall0 = WallMs();
  const RunSummary run = RunFrames(model, frames, kFrame_s, &state);
  const double wall_s = (WallMs() - wall0) * 1e-3;
  const double scale = EnergyScale_J(spec);
  const double rise = (run.energy_max_J - run.energy_start_J) / scale;
  const double drift = (run.energy_final_J - run.energy_start_J) / scale;
  const double spread = (run.energy_max_J - run.energy_min_J) / scale;
  Case c;
  c.name = !undamped ? "one hour, default"
                     : (substeps > 0 ? "one hour, undamped, resolved" : "one hour, undamped");
  c.parameters = "10 x 10 curtain, leapfrog, " + std::to_string(model.substeps) +
                 (substeps > 0 ? " substeps (fixed), " : " substeps (auto), ") +
                 (undamped ? "no damping, no drag, Provot off" : "scene damping, Provot on") +
                 ", " + Sig(seconds, 5) + " s simulated (" + Sig(wall_s, 3) + " s wall)";
  c.criterion = undamped ? "finite; energy within E0 +- 1% of M g L throughout"
                         : "finite; energy never above E0 by > 1% of M g L";
  c.pass = run.finite && state.counters.nan_events == 0 &&
           (undamped ? (run.energy_max_J - run.energy_start_J) <= 0.01 * scale &&
                           (run.energy_start_J - run.energy_min_J) <= 0.01 * scale
                     : rise <= 0.01);
  c.result = "energy J: start " + Sig(run.energy_start_J, 5) + ", min " + Sig(run.energy_min_J, 5) +
             ", max " + Sig(run.energy_max_J, 5) + ", final " + Sig(run.energy_final_J, 5) +
             "; drift (final - start) " + Sig(drift, 3) + " M g L, spread " + Sig(spread, 3) +
             " M g L; finite " + (run.finite ? "yes" : "no") + ", max stretch " +
             Fixed(run.max_stretch, 3);
  c.metrics = Json{{"simulated_s", seconds},
                   {"wall_s", wall_s},
                   {"substeps", model.substeps},
                   {"energy_start_J", run.energy_start_J},
                   {"energy_min_J", run.energy_min_J},
                   {"energy_max_J", run.energy_max_J},
                   {"energy_final_J", run.energy_final_J},
                   {"energy_scale_MgL_J", scale},
                   {"drift_over_MgL", drift},
                   {"spread_over_MgL", spread},
                   {"finite", run.finite},
                   {"nan_events", static_cast<int64_t>(state.counters.nan_events)},
                   {"max_stretch", run.max_stretch}};
  return c;
}

std::string Command(const Args& args) {
  std::string cmd = "felt bench stability";
  if (args.quick) cmd += " --quick";
  if (args.scene != "scenes/curtain.toml") cmd += " --scene " + args.scene;
  if (args.out != "bench/results") cmd += " --out " + args.out;
  if (!args.json.empty()) cmd += " --json " + args.json;
  return cmd;
}

int Run(const Args& args) {
  const MachineInfo machine = ReadMachineInfo();
  const std::string cmd = Command(args);
  std::printf("%s\nload average %s\n", cmd.c_str(), machine.load_average.c_str());
  std::vector<Case> cases;
  const auto add = [&](Case c) {
    std::printf("%-32s %s  %s\n", c.name.c_str(), PassText(c.pass).c_str(), c.result.c_str());
    std::fflush(stdout);
    cases.push_back(std::move(c));
  };
  add(StiffSprings(args, 100.0));
  add(StiffSprings(args, 1000.0));
  const std::vector<int32_t> grids =
      args.quick ? std::vector<int32_t>{10} : std::vector<int32_t>{10, 20, 30, 40, 50, 64, 128};
  for (const int32_t grid : grids) add(SuperElasticity(args, grid));
  add(ThinObstacle(args, 10.0));
  add(ThinObstacle(args, 50.0));
  add(Degenerate(args, true));
  add(Degenerate(args, false));
  add(ZeroSpacing(args));
  add(InjectNaN(args, false));
  add(InjectNaN(args, true));
  add(StalledFrame(args));
  add(OneHour(args, false));
  add(OneHour(args, true));
  add(OneHour(args, true, kResolvedHourSubsteps));
  const std::string load_end = LoadAverage();

  // The table, on stdout and in Markdown; the JSON.
  std::vector<std::vector<std::string>> rows;
  int passed = 0;
  for (const Case& c : cases) {
    rows.push_back({c.name, c.parameters, c.result, c.criterion, PassText(c.pass)});
    passed += c.pass ? 1 : 0;
  }
  const std::string table =
      MarkdownTable({"case", "parameters", "result", "criterion", "pass/fail"},
                    {false, false, false, false, false}, rows);
  std::printf("\n%s\n%d of %zu cases pass\n", table.c_str(), passed, cases.size());
  std::string md = ReportHeader("Hard cases (`felt bench stability`)", cmd, machine, load_end);
  md +=
      "Each case runs the real cloth (sim_loop/cloth.h) built from scenes/curtain.toml, resized "
      "as stated (same 0.496 m square, same springs and mass, total drag kept), at 60 Hz "
      "frames. M g L is the energy of lowering the whole cloth by its own height (0.487 J for "
      "the curtain); energy is TotalEnergy (kinetic + gravity + springs). The criteria were "
      "fixed before the runs.\n\n" +
      table + "\n" + std::to_string(passed) + " of " + std::to_string(cases.size()) +
      " cases pass.\n";
  WriteTextFile(args.out + "/stability.md", md);
  Json items = Json::array();
  for (const Case& c : cases) {
    items.push_back(Json{{"case", c.name},
                         {"parameters", c.parameters},
                         {"result", c.result},
                         {"criterion", c.criterion},
                         {"pass", c.pass},
                         {"metrics", c.metrics}});
  }
  Json top{{"command", cmd}};
  AppendMachineJson(machine, load_end, &top);
  top["passed"] = passed;
  top["cases"] = items;
  const std::string json = JsonText(top);
  const std::string json_path = args.json.empty() ? args.out + "/stability.json" : args.json;
  WriteTextFile(json_path, json);
  std::printf("wrote %s/stability.md, %s\n", args.out.c_str(), json_path.c_str());
  return 0;
}

app::CommandRun Setup(CLI::App& cmd) {
  auto args = std::make_shared<Args>();
  cmd.add_option("--json", args->json, "JSON output file (default <out>/stability.json)");
  cmd.add_option("--out", args->out, "folder for stability.md")->capture_default_str();
  cmd.add_option("--scene", args->scene, "the curtain scene the cases start from")
      ->capture_default_str();
  cmd.add_flag("--quick", args->quick,
               "tiny runs (grid 10 only, 10 s instead of one hour; for CI): not a result");
  return [args]() { return Run(*args); };
}

const bool kRegistered = app::RegisterCommand(
    {"bench", "stability", "the hard cases of the cloth (issue 2) as a pass/fail table", Setup});

}  // namespace
}  // namespace felt::bench::bench_stability
