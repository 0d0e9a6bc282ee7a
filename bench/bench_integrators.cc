// `felt bench integrators [--json FILE] [--quick]`: speed against error of the eight integrators
// on the default curtain (scenes/curtain.toml resized to 32 x 32 and 64 x 64), issue 2 "Speed
// against error".
//
// Row sets: (32, Provot off), (64, Provot off) for the accuracy comparison (Provot's projection
// is not part of the ODE, so with it on the error would mix the integrator's error with the
// projection's dependence on h), and (32, Provot on), the scene's default, for reference. One row
// per integrator and substep count (auto, then fixed counts):
//   - ms per 60 Hz frame: median wall time of StepFrame over the timed frames (>= 300; also this
//     thread's CPU time), on the scene as written (damped);
//   - RMS position error after 2 s against a reference: RK4 with 1/16 of its stable step, same
//     initial state, same Provot setting; the reference's own error is estimated by Richardson
//     extrapolation against RK4 with 1/8 of its stable step;
//   - energy drift: a separate 2 s run with every damping and drag set to zero, same substeps:
//     (E(2 s) - E(0)) / (M g L) and max |E - E(0)| / (M g L);
//   - max stretch over the 2 s; stable = every value finite (no NaN event) and the energy of the
//     damped run never above its start by more than 1% of M g L.
// Then, per integrator and grid (Provot off, damped), the largest stable step: bisection on the
// substep count over 2 s, reported as h_max and its ratio to the model's theory bound
// stable_dt_s. Writes <out>/integrators.{md,csv,json}, <out>/integrators_plot.dat and, if
// gnuplot is found, <out>/integrators.png from bench/plot_integrators.gp.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/command.h"
#include "bench/bench_util.h"
#include "haptic_loop/json_writer.h"
#include "sim_loop/cloth.h"
#include "sim_loop/integrator_names.h"
#include "sim_loop/scene_file.h"

namespace felt::bench::bench_integrators {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Args {
  std::string json;
  std::string out = "bench/results";
  std::string scene = "scenes/curtain.toml";
  std::string gnuplot_script = "bench/plot_integrators.gp";
  bool quick = false;
  std::vector<int32_t> grids;  // run only the row sets of these grids (empty: all)
};

// How much each run does (the full run or --quick).
struct Settings {
  std::vector<std::pair<int32_t, bool>> sets;  // (grid, Provot on)
  std::vector<int32_t> explicit_counts;        // fixed substep counts of the explicit methods
  std::vector<int32_t> explicit_counts_fine;   // the same at grids >= 64 (cost: fewer counts)
  std::vector<int32_t> implicit_counts;        // fixed substep counts of implicit Euler
  int32_t timed_frames = 300;
  int32_t error_frames = 120;  // 2 s
  int32_t reference_divisor = 16;
};

Settings MakeSettings(bool quick) {
  Settings s;
  if (quick) {
    s.sets = {{6, false}, {6, true}};
    s.explicit_counts = {2};
    s.implicit_counts = {2};
    s.timed_frames = 12;
    s.error_frames = 12;
    s.reference_divisor = 4;
    return s;
  }
  s.sets = {{32, false}, {64, false}, {32, true}};
  s.explicit_counts = {1, 2, 4, 8, 16, 32};
  s.explicit_counts_fine = {2, 4, 8, 16};
  s.implicit_counts = {1, 2, 4, 8};
  return s;
}

// One row of the table.
struct Row {
  int32_t grid = 0;
  bool provot = false;
  IntegratorKind kind = IntegratorKind::kLeapfrogVerlet;
  bool is_auto = false;
  int32_t substeps = 0;
  double h_s = 0.0;
  double ms_median = kInf;
  double ms_p99 = kInf;
  double cpu_ms_median = kInf;
  double rms_error_m = kInf;
  double energy_drift = kInf;    // (E(2 s) - E(0)) / MgL, undamped run
  double energy_max_dev = kInf;  // max |E - E(0)| / MgL, undamped run
  bool energy_finite = false;
  double max_stretch = kInf;
  bool stable = false;
  uint64_t nan_events = 0;
};

// The largest stable step of one integrator at one grid.
struct StableStepResult {
  int32_t grid = 0;
  IntegratorKind kind = IntegratorKind::kLeapfrogVerlet;
  int32_t min_stable_substeps = 0;  // smallest substep count found stable (0: none up to cap)
  double h_max_s = 0.0;             // 1/60 / min_stable_substeps
  double h_unstable_s = kInf;       // 1/60 / (min_stable_substeps - 1): the next longer step
  double theory_dt_s = 0.0;         // model.stable_dt_s
  int32_t auto_substeps = 0;
  int32_t probes = 0;
};

SimSpec RowSpec(const Args& args, int32_t grid, bool provot, IntegratorKind kind,
                int32_t substeps) {
  SimSpec spec = ResizedCurtain(args.scene, grid);
  spec.provot.enabled = provot;
  spec.integration.integrator = kind;
  spec.integration.substeps = substeps;
  return spec;
}

SimSpec Undamped(SimSpec spec) {
  spec.cloth.drag_N_s_per_m = 0.0;
  for (std::optional<SpringSpec>* s :
       {&spec.cloth.structural, &spec.cloth.shear, &spec.cloth.bend}) {
    if (*s) (*s)->damping_N_s_per_m = 0.0;
  }
  return spec;
}

double RmsDistance(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  double sum = 0.0;
  for (size_t p = 0; p < a.size(); ++p) sum += (a[p] - b[p]).squaredNorm();
  return std::sqrt(sum / static_cast<double>(a.size()));
}

// Positions after `frames` frames of `spec`; also whether the run stayed finite and bounded.
struct PlainRun {
  std::vector<Vec3> x;
  bool stable = false;
  double max_stretch = 1.0;
};

// A run is stable when every frame is finite (no NaN event) and the damped energy never rises
// above its start by more than 1% of M g L (the exact damped system only loses energy).
PlainRun RunPlain(const SimSpec& spec, int32_t frames) {
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  const double e0 = TotalEnergy(model, state);
  const double bound = e0 + 0.01 * EnergyScale_J(spec);
  const std::span<const ExternalForce> none;
  PlainRun run;
  run.stable = true;
  for (int32_t f = 0; f < frames; ++f) {
    StepFrame(model, none, 1.0 / 60.0, &state);
    run.max_stretch = std::max(run.max_stretch, MaxStretch(model, state));
    if (state.counters.nan_events > 0 || !(TotalEnergy(model, state) <= bound)) {
      run.stable = false;
      break;
    }
  }
  run.x = state.x;
  return run;
}

// The reference of one set: RK4 with 1/divisor of its stable step; `estimate` its error by
// Richardson extrapolation against half as many substeps (fourth order: err ~ diff / 15).
struct Reference {
  std::vector<Vec3> x;
  int32_t substeps = 0;
  double h_s = 0.0;
  double error_estimate_m = 0.0;
};

Reference MakeReference(const Args& args, const Settings& s, int32_t grid, bool provot) {
  const ClothModel probe = BuildClothModel(RowSpec(args, grid, provot, IntegratorKind::kRk4, 0));
  const double h = probe.stable_dt_s / s.reference_divisor;
  Reference ref;
  ref.substeps = static_cast<int32_t>(std::ceil((1.0 / 60.0) / h));
  ref.substeps += ref.substeps % 2;  // even, so the coarse check has exactly half
  ref.h_s = (1.0 / 60.0) / ref.substeps;
  const PlainRun fine =
      RunPlain(RowSpec(args, grid, provot, IntegratorKind::kRk4, ref.substeps), s.error_frames);
  const PlainRun coarse =
      RunPlain(RowSpec(args, grid, provot, IntegratorKind::kRk4, ref.substeps / 2), s.error_frames);
  ref.x = fine.x;
  ref.error_estimate_m = RmsDistance(fine.x, coarse.x) / 15.0;
  return ref;
}

Row RunRow(const Args& args, const Settings& s, const Reference& ref, int32_t grid, bool provot,
           IntegratorKind kind, int32_t fixed_substeps) {
  const SimSpec spec = RowSpec(args, grid, provot, kind, fixed_substeps);
  const ClothModel model = BuildClothModel(spec);
  Row row;
  row.grid = grid;
  row.provot = provot;
  row.kind = kind;
  row.is_auto = fixed_substeps == 0;
  row.substeps = model.substeps;
  row.h_s = (1.0 / 60.0) / model.substeps;

  // The damped scene: time every frame; error, stretch and stability over the first 2 s.
  ClothState state = MakeClothState(model);
  const double e0 = TotalEnergy(model, state);
  const double bound = e0 + 0.01 * EnergyScale_J(spec);
  const std::span<const ExternalForce> none;
  const int32_t frames = std::max(s.timed_frames, s.error_frames);
  std::vector<double> wall, cpu;
  wall.reserve(static_cast<size_t>(frames));
  cpu.reserve(static_cast<size_t>(frames));
  bool bounded = true;
  row.max_stretch = 1.0;
  for (int32_t f = 0; f < frames; ++f) {
    const double cpu0 = ThreadCpuMs();
    const double wall0 = WallMs();
    StepFrame(model, none, 1.0 / 60.0, &state);
    const double wall1 = WallMs();
    const double cpu1 = ThreadCpuMs();
    if (f < s.timed_frames) {
      wall.push_back(wall1 - wall0);
      cpu.push_back(cpu1 - cpu0);
    }
    if (f < s.error_frames) {
      row.max_stretch = std::max(row.max_stretch, MaxStretch(model, state));
      bounded = bounded && TotalEnergy(model, state) <= bound;
      if (f + 1 == s.error_frames) {
        row.rms_error_m = RmsDistance(state.x, ref.x);
        row.nan_events = state.counters.nan_events;
      }
    }
  }
  row.ms_median = Median(wall);
  row.ms_p99 = Percentile(wall, 99);
  row.cpu_ms_median = Median(cpu);
  row.stable = bounded && row.nan_events == 0;

  // The same substeps without any damping: the energy drift of the integrator (and Provot).
  SimSpec undamped = Undamped(spec);
  undamped.integration.substeps = model.substeps;
  const ClothModel free_model = BuildClothModel(undamped);
  ClothState free_state = MakeClothState(free_model);
  const double scale = EnergyScale_J(spec);
  const double f0 = TotalEnergy(free_model, free_state);
  double dev = 0.0;
  for (int32_t f = 0; f < s.error_frames; ++f) {
    StepFrame(free_model, none, 1.0 / 60.0, &free_state);
    dev = std::max(dev, std::abs(TotalEnergy(free_model, free_state) - f0));
  }
  row.energy_finite = free_state.counters.nan_events == 0;
  row.energy_drift = (TotalEnergy(free_model, free_state) - f0) / scale;
  row.energy_max_dev = dev / scale;
  return row;
}

// Bisection on the substep count between the sweep's largest unstable and smallest stable count.
StableStepResult FindStableStep(const Args& args, const Settings& s, int32_t grid,
                                IntegratorKind kind, const std::vector<Row>& rows) {
  StableStepResult r;
  r.grid = grid;
  r.kind = kind;
  const ClothModel model = BuildClothModel(RowSpec(args, grid, false, kind, 0));
  r.theory_dt_s = model.stable_dt_s;
  r.auto_substeps = model.substeps;
  const auto stable = [&](int32_t n) {
    ++r.probes;
    return RunPlain(RowSpec(args, grid, false, kind, n), s.error_frames).stable;
  };
  // Bracket from the sweep (Provot off rows of this grid and integrator).
  int32_t lo = 0, hi = 0;  // lo: largest known unstable (0 = none), hi: smallest known stable
  for (const Row& row : rows) {
    if (row.grid != grid || row.provot || row.kind != kind) continue;
    if (row.stable && (hi == 0 || row.substeps < hi)) hi = row.substeps;
    if (!row.stable && row.substeps > lo) lo = row.substeps;
  }
  if (hi == 0) {
    // Nothing stable in the sweep: double until stable (the model's cap is 100000).
    hi = std::max(1, lo) * 2;
    while (hi <= 100000 && !stable(hi)) {
      lo = hi;
      hi *= 2;
    }
    if (hi > 100000) return r;
  }
  lo = std::min(lo, hi - 1);
  while (hi - lo > 1) {
    const int32_t mid = lo + (hi - lo) / 2;
    (stable(mid) ? hi : lo) = mid;
  }
  r.min_stable_substeps = hi;
  r.h_max_s = (1.0 / 60.0) / hi;
  r.h_unstable_s = lo > 0 ? (1.0 / 60.0) / lo : kInf;
  return r;
}

std::string SetName(int32_t grid, bool provot) {
  return std::to_string(grid) + " x " + std::to_string(grid) +
         (provot ? ", Provot on (scene default)" : ", Provot off");
}

std::vector<std::string> RowCells(const Row& r) {
  return {std::to_string(r.grid),
          r.provot ? "on" : "off",
          std::string(ToName(r.kind)),
          r.is_auto ? "auto (" + std::to_string(r.substeps) + ")" : std::to_string(r.substeps),
          Sig(r.h_s * 1e3, 4),
          Fixed(r.ms_median, 4),
          Fixed(r.cpu_ms_median, 4),
          r.stable ? Sig(r.rms_error_m, 3) : "(" + Sig(r.rms_error_m, 3) + ")",
          r.energy_finite ? Sig(r.energy_drift, 3) : "non-finite",
          r.energy_finite ? Sig(r.energy_max_dev, 3) : "non-finite",
          Sig(r.max_stretch, 4),
          r.stable ? "yes" : "no"};
}

std::string Command(const Args& args) {
  std::string cmd = "felt bench integrators";
  if (args.quick) cmd += " --quick";
  for (size_t k = 0; k < args.grids.size(); ++k) {
    cmd += (k == 0 ? " --grids " : ",") + std::to_string(args.grids[k]);
  }
  if (args.scene != "scenes/curtain.toml") cmd += " --scene " + args.scene;
  if (args.out != "bench/results") cmd += " --out " + args.out;
  if (!args.json.empty()) cmd += " --json " + args.json;
  return cmd;
}

// Gnuplot data: one block per (set, integrator), header line "<name> ms rms_error_m", then the
// stable rows in order of cost: substeps ms error. Blocks are separated by two blank lines.
std::string PlotData(const Settings& s, const std::vector<Row>& rows) {
  std::string out =
      "# felt bench integrators: RMS position error after 2 s [m] against ms per 60 Hz frame,\n"
      "# stable rows only; one block per (grid, Provot, integrator), sets in the order:\n";
  for (const auto& [grid, provot] : s.sets) out += "#   " + SetName(grid, provot) + "\n";
  for (const auto& [grid, provot] : s.sets) {
    for (const IntegratorName& in : kIntegratorNames) {
      std::vector<const Row*> block;
      for (const Row& r : rows) {
        if (r.grid == grid && r.provot == provot && r.kind == in.kind && r.stable &&
            r.rms_error_m > 0.0) {
          block.push_back(&r);
        }
      }
      std::sort(block.begin(), block.end(),
                [](const Row* a, const Row* b) { return a->ms_median < b->ms_median; });
      out += "\n\n" + std::string(in.name) + " ms rms_error_m\n";
      // An integrator without a stable row still gets its block (NaN: nothing drawn).
      if (block.empty()) out += "0 NaN NaN\n";
      for (const Row* r : block) {
        out += std::to_string(r->substeps) + " " + Sig(r->ms_median, 6) + " " +
               Sig(r->rms_error_m, 6) + "\n";
      }
    }
  }
  return out;
}

int Run(const Args& args) {
  Settings s = MakeSettings(args.quick);
  if (!args.grids.empty()) {
    std::erase_if(s.sets, [&](const std::pair<int32_t, bool>& set) {
      return std::find(args.grids.begin(), args.grids.end(), set.first) == args.grids.end();
    });
    if (s.sets.empty()) throw std::invalid_argument("--grids: no row set has these grids");
  }
  const MachineInfo machine = ReadMachineInfo();
  const std::string cmd = Command(args);
  std::printf("%s\nload average %s\n", cmd.c_str(), machine.load_average.c_str());
  std::fflush(stdout);

  // The sweep, set by set.
  std::vector<Row> rows;
  std::map<std::pair<int32_t, bool>, Reference> references;
  for (const auto& [grid, provot] : s.sets) {
    const Reference& ref = references[{grid, provot}] = MakeReference(args, s, grid, provot);
    std::printf("%s: reference RK4 %d substeps (h = %.4g ms), its error ~ %.3g m\n",
                SetName(grid, provot).c_str(), ref.substeps, ref.h_s * 1e3, ref.error_estimate_m);
    std::fflush(stdout);
    for (const IntegratorName& in : kIntegratorNames) {
      const bool implicit = in.kind == IntegratorKind::kImplicitEuler;
      std::vector<int32_t> counts = {0};
      const ClothModel auto_model = BuildClothModel(RowSpec(args, grid, provot, in.kind, 0));
      const std::vector<int32_t>& fixed = implicit     ? s.implicit_counts
                                          : grid >= 64 ? s.explicit_counts_fine
                                                       : s.explicit_counts;
      for (const int32_t n : fixed) {
        if (n != auto_model.substeps) counts.push_back(n);
      }
      for (const int32_t n : counts) {
        rows.push_back(RunRow(args, s, ref, grid, provot, in.kind, n));
        const Row& r = rows.back();
        std::printf("  %-18s %6d substeps  %9.4f ms  err %-10.3g drift %-10.3g stretch %-9.4g %s\n",
                    std::string(in.name).c_str(), r.substeps, r.ms_median, r.rms_error_m,
                    r.energy_drift, r.max_stretch, r.stable ? "stable" : "UNSTABLE");
        std::fflush(stdout);
      }
    }
  }

  // Largest stable step per grid (Provot off sets) and integrator.
  std::vector<StableStepResult> steps;
  for (const auto& [grid, provot] : s.sets) {
    if (provot) continue;
    for (const IntegratorName& in : kIntegratorNames) {
      steps.push_back(FindStableStep(args, s, grid, in.kind, rows));
      const StableStepResult& st = steps.back();
      std::printf("grid %d %-18s h_max %.4g ms (%d substeps), theory %.4g ms, ratio %.3g\n", grid,
                  std::string(in.name).c_str(), st.h_max_s * 1e3, st.min_stable_substeps,
                  st.theory_dt_s * 1e3, st.h_max_s / st.theory_dt_s);
      std::fflush(stdout);
    }
  }
  const std::string load_end = LoadAverage();

  // Tables.
  const std::vector<std::string> header = {"grid",           "Provot",      "integrator",
                                           "substeps",       "h ms",        "frame ms median",
                                           "cpu ms median",  "RMS error m", "energy drift",
                                           "max energy dev", "max stretch", "stable"};
  const std::vector<bool> right = {true, false, false, true, true, true,
                                   true, true,  true,  true, true, false};
  std::vector<std::vector<std::string>> all_cells;
  for (const Row& r : rows) all_cells.push_back(RowCells(r));
  std::vector<std::vector<std::string>> step_cells;
  for (const StableStepResult& st : steps) {
    step_cells.push_back(
        {std::to_string(st.grid), std::string(ToName(st.kind)),
         st.min_stable_substeps > 0 ? std::to_string(st.min_stable_substeps) : "none <= 100000",
         st.min_stable_substeps > 0
             ? (std::isfinite(st.h_unstable_s) ? "" : ">= ") + Sig(st.h_max_s * 1e3, 4)
             : "-",
         std::isfinite(st.h_unstable_s) ? Sig(st.h_unstable_s * 1e3, 4) : "- (1 substep stable)",
         std::isfinite(st.theory_dt_s) ? Sig(st.theory_dt_s * 1e3, 4) : "inf",
         std::isfinite(st.theory_dt_s) && st.min_stable_substeps > 0
             ? Sig(st.h_max_s / st.theory_dt_s, 3)
             : "-",
         std::to_string(st.auto_substeps), std::to_string(st.probes)});
  }

  std::string md = ReportHeader("Integrators: speed against error (`felt bench integrators`)", cmd,
                                machine, load_end);
  md +=
      "The default curtain (scenes/curtain.toml) resized over the same 0.496 m square, starting "
      "at rest, flat, pinned at its two top corners. Provot is **off** for the accuracy "
      "comparison (the error then measures the integrator alone: Provot's projection after "
      "each substep depends on h and is no part of the ODE); one row set with the scene's "
      "default **Provot on** follows, its error measured against an RK4 reference with Provot "
      "on at the same tiny step.\n\n"
      "- frame ms: median wall time of StepFrame over " +
      std::to_string(s.timed_frames) +
      " frames of 1/60 s (cpu ms: this thread's CPU time, which excludes preemption by other "
      "processes), the scene as written (damped).\n"
      "- RMS error: sqrt(mean over particles |x - x_ref|^2) after " +
      Fixed(s.error_frames / 60.0, 1) + " s, the reference being RK4 with 1/" +
      std::to_string(s.reference_divisor) +
      " of its stable step from the same initial state; in parentheses for unstable rows.\n"
      "- energy drift: a separate run of the same integrator and substeps with every spring "
      "damping and the drag set to zero: (E(2 s) - E(0)) / (M g L) and max |E - E(0)| / "
      "(M g L) over the 2 s, M g L = 0.487 J (the cloth lowered by its own height). With "
      "Provot on, the projection's own energy loss is included.\n"
      "- max stretch: largest structural length / rest length over the 2 s.\n"
      "- stable: no non-finite value in the 2 s (no NaN event) and the damped run's energy "
      "never above its start by more than 1% of M g L.\n\n";
  md += "## References\n\n";
  for (const auto& [grid, provot] : s.sets) {
    const Reference& ref = references[{grid, provot}];
    md += "- " + SetName(grid, provot) + ": RK4, " + std::to_string(ref.substeps) +
          " substeps per frame (h = " + Sig(ref.h_s * 1e3, 4) +
          " ms); its own error, estimated by Richardson extrapolation against " +
          std::to_string(ref.substeps / 2) +
          " substeps (|x_h - x_2h| / 15): " + Sig(ref.error_estimate_m, 3) + " m RMS\n";
  }
  for (const auto& [grid, provot] : s.sets) {
    md += "\n## " + SetName(grid, provot) + "\n\n";
    std::vector<std::vector<std::string>> cells;
    for (size_t k = 0; k < rows.size(); ++k) {
      if (rows[k].grid == grid && rows[k].provot == provot) cells.push_back(all_cells[k]);
    }
    md += MarkdownTable(header, right, cells);
  }
  md +=
      "\n## Largest stable step (Provot off, damped scene, 2 s)\n\n"
      "Bisection on the substep count between the sweep's largest unstable and smallest "
      "stable count, each probe a 2 s run judged by the stability rule above. h_max = 1/60 s "
      "/ (smallest stable count); 'first unstable h' is the step of one substep fewer. Theory "
      "bound: the model's stable_dt_s (the integrator's stability limit on the grid-symbol "
      "bound of the highest natural frequency, damping included); auto substeps use 0.5 of "
      "it.\n\n";
  md +=
      MarkdownTable({"grid", "integrator", "min stable substeps", "h_max ms", "first unstable h ms",
                     "theory stable_dt_s ms", "h_max / stable_dt_s", "auto substeps", "probes"},
                    {true, false, true, true, true, true, true, true, true}, step_cells);
  md +=
      "\nPlot: integrators.png (bench/plot_integrators.gp on integrators_plot.dat), RMS error "
      "against frame ms, log-log, stable rows only.\n";
  WriteTextFile(args.out + "/integrators.md", md);

  // CSV, JSON, plot data.
  WriteTextFile(args.out + "/integrators.csv",
                CsvTable({"grid", "provot", "integrator", "substeps", "h_ms", "frame_ms_median",
                          "cpu_ms_median", "rms_error_m", "energy_drift", "energy_max_dev",
                          "max_stretch", "stable"},
                         all_cells));
  std::vector<std::string> row_items, step_items, ref_items;
  for (const Row& r : rows) {
    row_items.push_back(JsonRecord()
                            .Integer("grid", r.grid)
                            .Bool("provot", r.provot)
                            .String("integrator", ToName(r.kind))
                            .Bool("auto", r.is_auto)
                            .Integer("substeps", r.substeps)
                            .Number("h_s", r.h_s)
                            .Number("frame_ms_median", r.ms_median)
                            .Number("frame_ms_p99", r.ms_p99)
                            .Number("cpu_ms_median", r.cpu_ms_median)
                            .Number("rms_error_m", r.rms_error_m)
                            .Number("energy_drift", r.energy_drift)
                            .Number("energy_max_dev", r.energy_max_dev)
                            .Bool("energy_finite", r.energy_finite)
                            .Number("max_stretch", r.max_stretch)
                            .Bool("stable", r.stable)
                            .Integer("nan_events", static_cast<int64_t>(r.nan_events))
                            .str());
  }
  for (const StableStepResult& st : steps) {
    step_items.push_back(JsonRecord()
                             .Integer("grid", st.grid)
                             .String("integrator", ToName(st.kind))
                             .Integer("min_stable_substeps", st.min_stable_substeps)
                             .Number("h_max_s", st.h_max_s)
                             .Number("h_first_unstable_s", st.h_unstable_s)
                             .Number("stable_dt_s", st.theory_dt_s)
                             .Number("ratio_to_stable_dt",
                                     std::isfinite(st.theory_dt_s) && st.min_stable_substeps > 0
                                         ? st.h_max_s / st.theory_dt_s
                                         : kNaN)
                             .Integer("auto_substeps", st.auto_substeps)
                             .Integer("probes", st.probes)
                             .str());
  }
  for (const auto& [key, ref] : references) {
    ref_items.push_back(JsonRecord()
                            .Integer("grid", key.first)
                            .Bool("provot", key.second)
                            .Integer("substeps", ref.substeps)
                            .Number("h_s", ref.h_s)
                            .Number("error_estimate_m", ref.error_estimate_m)
                            .str());
  }
  const std::string json = "{\n  \"command\": " + JsonQuote(cmd) +
                           ",\n  \"machine\": " + MachineJson(machine) +
                           ",\n  \"load_average_end\": " + JsonQuote(load_end) +
                           ",\n  \"timed_frames\": " + std::to_string(s.timed_frames) +
                           ",\n  \"error_time_s\": " + FormatSceneNumber(s.error_frames / 60.0) +
                           ",\n  \"references\": " + JsonArray(ref_items, 2) +
                           ",\n  \"rows\": " + JsonArray(row_items, 2) +
                           ",\n  \"stable_steps\": " + JsonArray(step_items, 2) + "\n}\n";
  const std::string json_path = args.json.empty() ? args.out + "/integrators.json" : args.json;
  WriteTextFile(json_path, json);
  const std::string dat = args.out + "/integrators_plot.dat";
  WriteTextFile(dat, PlotData(s, rows));
  std::printf("wrote %s/integrators.md, %s/integrators.csv, %s, %s\n", args.out.c_str(),
              args.out.c_str(), json_path.c_str(), dat.c_str());

  // The plot: gnuplot if it is installed, else the command to run.
  const std::string png = args.out + "/integrators.png";
  std::string titles;
  for (size_t k = 0; k < s.sets.size(); ++k) {
    titles +=
        "; t" + std::to_string(k + 1) + "='" + SetName(s.sets[k].first, s.sets[k].second) + "'";
  }
  const std::string plot = "gnuplot -e \"dat='" + dat + "'; png='" + png +
                           "'; panels=" + std::to_string(s.sets.size()) + titles + "\" " +
                           args.gnuplot_script;
  if (std::system("command -v gnuplot > /dev/null 2>&1") == 0) {
    if (std::system(plot.c_str()) != 0) {
      std::fprintf(stderr, "felt bench integrators: gnuplot failed: %s\n", plot.c_str());
      return 1;
    }
    std::printf("wrote %s\n", png.c_str());
  } else {
    std::printf("gnuplot not found; to draw the plot run:\n  %s\n", plot.c_str());
  }
  return 0;
}

app::CommandRun Setup(CLI::App& cmd) {
  auto args = std::make_shared<Args>();
  cmd.add_option("--json", args->json, "JSON output file (default <out>/integrators.json)");
  cmd.add_option("--out", args->out, "folder for integrators.{md,csv,png} and the plot data")
      ->capture_default_str();
  cmd.add_option("--scene", args->scene, "the curtain scene to resize")->capture_default_str();
  cmd.add_option("--gnuplot-script", args->gnuplot_script, "the gnuplot script for the plot")
      ->capture_default_str();
  cmd.add_option("--grids", args->grids,
                 "only the row sets of these grids (comma-separated; full run: 32 and 64)")
      ->delimiter(',');
  cmd.add_flag("--quick", args->quick,
               "a 6 x 6 curtain, one fixed count, 12 frames (seconds; for CI): not a result");
  return [args]() { return Run(*args); };
}

const bool kRegistered = app::RegisterCommand(
    {"bench", "integrators",
     "speed against error of the eight integrators on the curtain (32 x 32, 64 x 64)", Setup});

}  // namespace
}  // namespace felt::bench::bench_integrators
