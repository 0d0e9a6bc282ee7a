// `felt bench integrators [--json FILE] [--quick]`: speed against error of the eight integrators
// on the default curtain (scenes/curtain.toml resized to 32 x 32 and 64 x 64), issue 2 "Speed
// against error".
//
// Row sets: (32, Provot off), (64, Provot off) for the accuracy comparison (Provot's projection
// is not part of the ODE, so with it on the error would mix the integrator's error with the
// projection's dependence on h), and (32, Provot on), the scene's default, for reference. One row
// per integrator and substep count (auto, then fixed counts: one list below 64 x 64, from 64 x 64
// on counts around each integrator's theory bound):
//   - ms per 60 Hz frame: median wall time of StepFrame over the timed frames (300; also this
//     thread's CPU time), on the scene as written (damped); an unstable row stops at its first
//     unstable frame and is timed over the frames run; a row over 1 s of CPU a frame is timed
//     over its 2 s run only (120 frames);
//   - RMS position error after 2 s against a reference: RK4 with 1/16 of its stable step, same
//     initial state, same Provot setting; the reference's own error is estimated by Richardson
//     extrapolation against RK4 with 1/8 of its stable step;
//   - energy drift: a separate 2 s run with every damping and drag set to zero, same substeps:
//     (E(2 s) - E(0)) / (M g L) and max |E - E(0)| / (M g L), stopped at a blow-up;
//   - max stretch over the 2 s; stable = every value finite (no NaN event) and the energy of the
//     damped run never above its start by more than 1% of M g L.
// Then, per integrator and grid (Provot off, damped), the largest stable step: bisection on the
// substep count over 2 s (geometric midpoints, to 5% or adjacent counts), reported as h_max and
// its ratio to the model's theory bound stable_dt_s. Where the time goes at 64 x 64: explicit
// Euler, whose auto count is 22375 substeps (~3.9 s of CPU a frame); everything else takes a
// few minutes. Writes <out>/integrators.{md,csv,json}, <out>/integrators_plot.dat (rewritten after
// each row set and stable step, marked partial until the end) and, if gnuplot is found,
// <out>/integrators.png from bench/plot_integrators.gp.
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
#include "base/json.h"
#include "bench/bench_util.h"
#include "scene/scene_file.h"
#include "sim_loop/cloth.h"
#include "sim_loop/integrator_names.h"

namespace felt::bench::bench_integrators {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr int32_t kMaxProbeSubsteps = 100000;  // the model's cap on substeps per frame

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
  std::vector<int32_t> implicit_counts;        // fixed substep counts of implicit Euler
  // At grids >= fine_grid the explicit methods' fixed counts follow each one's theory bound
  // instead of explicit_counts: p, 2p, ..., with p the largest power of two <= (1/60 s) /
  // stable_dt_s, fine_counts of them, each at most max_fine_substeps.
  int32_t fine_grid = 64;
  int32_t fine_counts = 3;
  int32_t max_fine_substeps = 1024;
  int32_t timed_frames = 300;
  int32_t error_frames = 120;  // 2 s
  int32_t reference_divisor = 16;
  // A row whose median frame over the error_frames costs more than this [ms] of CPU time is
  // timed over those frames only (explicit Euler at its auto count on 64 x 64: ~3.5 s a frame).
  double slow_frame_cpu_ms = 1000.0;
  // The undamped run stops once |E - E(0)| exceeds this many M g L (a blow-up).
  double energy_blowup = 100.0;
  // The stable-step bisection stops when the bracket (lo unstable, hi stable) has hi <= lo + 1
  // or hi <= lo * (1 + stable_step_tolerance).
  double stable_step_tolerance = 0.05;
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
  int32_t timed_frames = 0;       // frames in the medians
  double rms_error_m = kNaN;      // after 2 s; NaN for an unstable row (its run stops early)
  double energy_drift = kNaN;     // (E(2 s) - E(0)) / MgL, undamped run; NaN after a blow-up
  double energy_max_dev = kNaN;   // max |E - E(0)| / MgL, undamped run (up to its stop)
  bool energy_finite = false;     // the undamped run reached 2 s without a blow-up
  double energy_blowup_s = kNaN;  // when the undamped run stopped (blow-up), s
  double max_stretch = kInf;
  bool stable = false;
  double unstable_at_s = kNaN;  // when the damped run first broke the stability rule, s
  uint64_t nan_events = 0;
  double cpu_s = 0.0;  // CPU time of the row's two runs, s
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
  int32_t search_cap = 0;  // the largest count the doubling would probe (0: no doubling needed)
  double cpu_s = 0.0;      // CPU time of the probes, s
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
  double cpu_s = 0.0;  // CPU time of the two runs, s
};

Reference MakeReference(const Args& args, const Settings& s, int32_t grid, bool provot) {
  const double cpu0 = ThreadCpuMs();
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
  ref.cpu_s = (ThreadCpuMs() - cpu0) / 1e3;
  return ref;
}

Row RunRow(const Args& args, const Settings& s, const Reference& ref, int32_t grid, bool provot,
           IntegratorKind kind, int32_t fixed_substeps) {
  const double row_cpu0 = ThreadCpuMs();
  const SimSpec spec = RowSpec(args, grid, provot, kind, fixed_substeps);
  const ClothModel model = BuildClothModel(spec);
  Row row;
  row.grid = grid;
  row.provot = provot;
  row.kind = kind;
  row.is_auto = fixed_substeps == 0;
  row.substeps = model.substeps;
  row.h_s = (1.0 / 60.0) / model.substeps;

  // The damped scene: time every frame; error, stretch and stability over the first 2 s. The
  // run stops at the first frame that breaks the stability rule (what follows is no result).
  ClothState state = MakeClothState(model);
  const double e0 = TotalEnergy(model, state);
  const double bound = e0 + 0.01 * EnergyScale_J(spec);
  const std::span<const ExternalForce> none;
  const int32_t frames = std::max(s.timed_frames, s.error_frames);
  std::vector<double> wall, cpu;
  wall.reserve(static_cast<size_t>(frames));
  cpu.reserve(static_cast<size_t>(frames));
  row.max_stretch = 1.0;
  row.stable = true;
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
    if (f >= s.error_frames) continue;
    row.max_stretch = std::max(row.max_stretch, MaxStretch(model, state));
    row.nan_events = state.counters.nan_events;
    if (row.nan_events > 0 || !(TotalEnergy(model, state) <= bound)) {
      row.stable = false;
      row.unstable_at_s = (f + 1) / 60.0;
      break;
    }
    if (f + 1 == s.error_frames) {
      row.rms_error_m = RmsDistance(state.x, ref.x);
      // A slow row is timed over the 2 s run only.
      if (Median(cpu) > s.slow_frame_cpu_ms) break;
    }
  }
  row.timed_frames = static_cast<int32_t>(wall.size());
  row.ms_median = Median(wall);
  row.ms_p99 = Percentile(wall, 99);
  row.cpu_ms_median = Median(cpu);

  // The same substeps without any damping: the energy drift of the integrator (and Provot),
  // stopped at a blow-up (non-finite, or |E - E(0)| over energy_blowup M g L).
  SimSpec undamped = Undamped(spec);
  undamped.integration.substeps = model.substeps;
  const ClothModel free_model = BuildClothModel(undamped);
  ClothState free_state = MakeClothState(free_model);
  const double scale = EnergyScale_J(spec);
  const double f0 = TotalEnergy(free_model, free_state);
  double dev = 0.0;
  row.energy_finite = true;
  for (int32_t f = 0; f < s.error_frames; ++f) {
    StepFrame(free_model, none, 1.0 / 60.0, &free_state);
    const double d = std::abs(TotalEnergy(free_model, free_state) - f0);
    if (free_state.counters.nan_events > 0 || !(d <= s.energy_blowup * scale)) {
      row.energy_finite = false;
      row.energy_blowup_s = (f + 1) / 60.0;
      if (std::isfinite(d)) dev = std::max(dev, d);
      break;
    }
    dev = std::max(dev, d);
  }
  if (row.energy_finite) row.energy_drift = (TotalEnergy(free_model, free_state) - f0) / scale;
  row.energy_max_dev = dev / scale;
  row.cpu_s = (ThreadCpuMs() - row_cpu0) / 1e3;
  return row;
}

// Bisection on the substep count between the sweep's largest unstable and smallest stable count
// (geometric midpoints, stopped at the tolerance), each probe a 2 s RunPlain that stops at the
// first unstable frame.
StableStepResult FindStableStep(const Args& args, const Settings& s, int32_t grid,
                                IntegratorKind kind, const std::vector<Row>& rows) {
  StableStepResult r;
  r.grid = grid;
  r.kind = kind;
  const ClothModel model = BuildClothModel(RowSpec(args, grid, false, kind, 0));
  r.theory_dt_s = model.stable_dt_s;
  r.auto_substeps = model.substeps;
  const double cpu0 = ThreadCpuMs();
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
    // Nothing stable in the sweep: double until stable, up to 4 x max(auto, lo) (bounded cost).
    r.search_cap = std::min(kMaxProbeSubsteps, 4 * std::max(r.auto_substeps, lo));
    hi = std::max(1, lo) * 2;
    while (hi <= r.search_cap && !stable(hi)) {
      lo = hi;
      hi *= 2;
    }
    if (hi > r.search_cap) {
      r.cpu_s = (ThreadCpuMs() - cpu0) / 1e3;
      return r;
    }
  }
  lo = std::min(lo, hi - 1);
  if (lo == 0 && hi > 1) (stable(1) ? hi : lo) = 1;
  while (hi - lo > 1 && hi > lo * (1.0 + s.stable_step_tolerance)) {
    const auto geometric =
        static_cast<int32_t>(std::lround(std::sqrt(static_cast<double>(lo) * hi)));
    const int32_t mid = std::clamp(geometric, lo + 1, hi - 1);
    (stable(mid) ? hi : lo) = mid;
  }
  r.min_stable_substeps = hi;
  r.h_max_s = (1.0 / 60.0) / hi;
  r.h_unstable_s = lo > 0 ? (1.0 / 60.0) / lo : kInf;
  r.cpu_s = (ThreadCpuMs() - cpu0) / 1e3;
  return r;
}

// Substep counts as "1, 2, 4" for the legend.
std::string JoinCounts(const std::vector<int32_t>& counts) {
  std::string list;
  for (const int32_t n : counts) list += (list.empty() ? "" : ", ") + std::to_string(n);
  return list;
}

std::string SetName(int32_t grid, bool provot) {
  return std::to_string(grid) + " x " + std::to_string(grid) +
         (provot ? ", Provot on (scene default)" : ", Provot off");
}

std::vector<std::string> RowCells(const Settings& s, const Row& r) {
  // A stable row timed on fewer frames than the rest (a slow row) says how many: "[120]".
  const bool short_timing = r.stable && r.timed_frames < s.timed_frames;
  return {
      std::to_string(r.grid),
      r.provot ? "on" : "off",
      std::string(ToName(r.kind)),
      r.is_auto ? "auto (" + std::to_string(r.substeps) + ")" : std::to_string(r.substeps),
      Sig(r.h_s * 1e3, 4),
      Fixed(r.ms_median, 4) + (short_timing ? " [" + std::to_string(r.timed_frames) + "]" : ""),
      Fixed(r.cpu_ms_median, 4),
      r.stable ? Sig(r.rms_error_m, 3) : "-",
      r.energy_finite ? Sig(r.energy_drift, 3) : "blow-up (" + Fixed(r.energy_blowup_s, 2) + " s)",
      r.energy_finite                      ? Sig(r.energy_max_dev, 3)
      : r.energy_max_dev > s.energy_blowup ? "> " + Sig(s.energy_blowup, 3)
                                           : "non-finite",
      Sig(r.max_stretch, 4),
      r.stable ? "yes" : "no (" + Fixed(r.unstable_at_s, 2) + " s)"};
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

// Everything a run has measured so far.
struct Results {
  std::vector<Row> rows;
  std::map<std::pair<int32_t, bool>, Reference> references;
  std::vector<StableStepResult> steps;
};

// The fixed substep counts of one integrator on one set (the auto count is left out).
std::vector<int32_t> FixedCounts(const Settings& s, int32_t grid, const ClothModel& auto_model,
                                 IntegratorKind kind) {
  std::vector<int32_t> counts;
  if (kind == IntegratorKind::kImplicitEuler) {
    counts = s.implicit_counts;
  } else if (grid < s.fine_grid || !std::isfinite(auto_model.stable_dt_s)) {
    counts = s.explicit_counts;
  } else {
    // Around the theory bound: p, 2p, 4p with p the largest power of two <= (1/60) / stable_dt.
    const double bound_count = (1.0 / 60.0) / auto_model.stable_dt_s;
    int32_t p = 1;
    while (2.0 * p <= bound_count) p *= 2;
    for (int32_t k = 0; k < s.fine_counts && p <= s.max_fine_substeps; ++k, p *= 2) {
      counts.push_back(p);
    }
  }
  std::erase(counts, auto_model.substeps);
  return counts;
}

// Writes <out>/integrators.{md,csv,json} and integrators_plot.dat from what `results` holds.
// `progress` is empty for the finished run, else it says what is still missing (the files are
// rewritten after each row set and each stable step, so a stopped run leaves a labelled partial
// result). Draws the plot for the finished run only. Returns false when gnuplot failed.
bool WriteReports(const Args& args, const Settings& s, const std::string& cmd,
                  const MachineInfo& machine, const Results& results, const std::string& progress) {
  const std::string load_end = LoadAverage();
  const std::vector<Row>& rows = results.rows;
  const std::vector<std::string> header = {"grid",           "Provot",      "integrator",
                                           "substeps",       "h ms",        "frame ms median",
                                           "cpu ms median",  "RMS error m", "energy drift",
                                           "max energy dev", "max stretch", "stable"};
  const std::vector<bool> right = {true, false, false, true, true, true,
                                   true, true,  true,  true, true, false};
  std::vector<std::vector<std::string>> all_cells;
  for (const Row& r : rows) all_cells.push_back(RowCells(s, r));
  std::vector<std::vector<std::string>> step_cells;
  for (const StableStepResult& st : results.steps) {
    step_cells.push_back(
        {std::to_string(st.grid), std::string(ToName(st.kind)),
         st.min_stable_substeps > 0 ? std::to_string(st.min_stable_substeps)
                                    : "none <= " + std::to_string(st.search_cap),
         st.min_stable_substeps > 0
             ? (std::isfinite(st.h_unstable_s) ? "" : ">= ") + Sig(st.h_max_s * 1e3, 4)
             : "-",
         std::isfinite(st.h_unstable_s) ? Sig(st.h_unstable_s * 1e3, 4) : "- (1 substep stable)",
         std::isfinite(st.theory_dt_s) ? Sig(st.theory_dt_s * 1e3, 4) : "inf",
         std::isfinite(st.theory_dt_s) && st.min_stable_substeps > 0
             ? Sig(st.h_max_s / st.theory_dt_s, 3)
             : "-",
         std::to_string(st.auto_substeps), std::to_string(st.probes), Fixed(st.cpu_s, 1)});
  }

  std::string md = ReportHeader("Integrators: speed against error (`felt bench integrators`)", cmd,
                                machine, load_end);
  if (!progress.empty()) {
    md += "**Partial result: the run had not finished when this was written (" + progress +
          ").**\n\n";
  }
  md +=
      "The default curtain (scenes/curtain.toml) resized over the same 0.496 m square, starting "
      "at rest, flat, pinned at its two top corners. Provot is **off** for the accuracy "
      "comparison (the error then measures the integrator alone: Provot's projection after "
      "each substep depends on h and is no part of the ODE); one row set with the scene's "
      "default **Provot on** follows, its error measured against an RK4 reference with Provot "
      "on at the same tiny step.\n\n"
      "- substeps: auto (the model's count, 0.5 of the theory bound stable_dt_s), then fixed "
      "counts: " +
      JoinCounts(s.explicit_counts) + " for the explicit methods below " +
      std::to_string(s.fine_grid) + " x " + std::to_string(s.fine_grid) + "; from " +
      std::to_string(s.fine_grid) + " x " + std::to_string(s.fine_grid) +
      " on, p, 2p, 4p around each one's theory bound (p the "
      "largest power of two <= (1/60 s) / stable_dt_s), counts over " +
      std::to_string(s.max_fine_substeps) + " left out; implicit Euler " +
      JoinCounts(s.implicit_counts) +
      ".\n"
      "- frame ms: median wall time of StepFrame over " +
      std::to_string(s.timed_frames) +
      " frames of 1/60 s (cpu ms: this thread's CPU time, which excludes preemption by other "
      "processes), the scene as written (damped). An unstable row's run stops at the frame "
      "that broke the stability rule, so its medians are over the frames run until then "
      "(the time in its 'stable' cell). A stable row whose median frame costs over " +
      Fixed(s.slow_frame_cpu_ms / 1e3, 1) +
      " s of CPU is timed over the 2 s run only, the frame count in brackets.\n"
      "- RMS error: sqrt(mean over particles |x - x_ref|^2) after " +
      Fixed(s.error_frames / 60.0, 1) + " s, the reference being RK4 with 1/" +
      std::to_string(s.reference_divisor) +
      " of its stable step from the same initial state; '-' for unstable rows (their run "
      "stopped before 2 s).\n"
      "- energy drift: a separate run of the same integrator and substeps with every spring "
      "damping and the drag set to zero: (E(2 s) - E(0)) / (M g L) and max |E - E(0)| / "
      "(M g L) over the 2 s, M g L = 0.487 J (the cloth lowered by its own height). With "
      "Provot on, the projection's own energy loss is included. The run stops at a blow-up: "
      "a non-finite value or |E - E(0)| over " +
      Sig(s.energy_blowup, 3) +
      " M g L ('blow-up (t s)', the time it stopped; max energy dev then '> " +
      Sig(s.energy_blowup, 3) +
      "' or 'non-finite').\n"
      "- max stretch: largest structural length / rest length over the 2 s (over the frames "
      "run, for an unstable row).\n"
      "- stable: no non-finite value in the 2 s (no NaN event) and the damped run's energy "
      "never above its start by more than 1% of M g L; 'no (t s)': the rule first failed at "
      "t.\n\n";
  md += "## References\n\n";
  for (const auto& [grid, provot] : s.sets) {
    const auto it = results.references.find({grid, provot});
    if (it == results.references.end()) continue;
    const Reference& ref = it->second;
    md += "- " + SetName(grid, provot) + ": RK4, " + std::to_string(ref.substeps) +
          " substeps per frame (h = " + Sig(ref.h_s * 1e3, 4) +
          " ms); its own error, estimated by Richardson extrapolation against " +
          std::to_string(ref.substeps / 2) +
          " substeps (|x_h - x_2h| / 15): " + Sig(ref.error_estimate_m, 3) + " m RMS\n";
  }
  for (const auto& [grid, provot] : s.sets) {
    std::vector<std::vector<std::string>> cells;
    for (size_t k = 0; k < rows.size(); ++k) {
      if (rows[k].grid == grid && rows[k].provot == provot) cells.push_back(all_cells[k]);
    }
    if (cells.empty()) continue;
    md += "\n## " + SetName(grid, provot) + "\n\n";
    md += MarkdownTable(header, right, cells);
  }
  md +=
      "\n## Largest stable step (Provot off, damped scene, 2 s)\n\n"
      "Bisection on the substep count between the sweep's largest unstable and smallest "
      "stable count (or, when the sweep has no stable row, the first stable count found by "
      "doubling up to 4 x max(auto, largest unstable)), at geometric midpoints, each probe a "
      "2 s run judged by the stability rule above and stopped at its first unstable frame. The "
      "bisection stops at adjacent counts or when the stable count is within " +
      Fixed(s.stable_step_tolerance * 100.0, 0) +
      "% of the unstable one. h_max = 1/60 s / (smallest stable count); 'first unstable h' is "
      "the step of the largest count found unstable (one substep fewer when the bisection "
      "reached adjacent counts). Theory bound: the model's stable_dt_s (the integrator's "
      "stability limit on the grid-symbol bound of the highest natural frequency, damping "
      "included); auto substeps use 0.5 of it.\n\n";
  md += MarkdownTable(
      {"grid", "integrator", "min stable substeps", "h_max ms", "first unstable h ms",
       "theory stable_dt_s ms", "h_max / stable_dt_s", "auto substeps", "probes", "probes cpu s"},
      {true, false, true, true, true, true, true, true, true, true}, step_cells);
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
  Json row_items = Json::array(), step_items = Json::array(), ref_items = Json::array();
  for (const Row& r : rows) {
    row_items.push_back(Json{{"grid", r.grid},
                             {"provot", r.provot},
                             {"integrator", ToName(r.kind)},
                             {"auto", r.is_auto},
                             {"substeps", r.substeps},
                             {"h_s", r.h_s},
                             {"timed_frames", r.timed_frames},
                             {"frame_ms_median", r.ms_median},
                             {"frame_ms_p99", r.ms_p99},
                             {"cpu_ms_median", r.cpu_ms_median},
                             {"rms_error_m", r.rms_error_m},
                             {"energy_drift", r.energy_drift},
                             {"energy_max_dev", r.energy_max_dev},
                             {"energy_finite", r.energy_finite},
                             {"energy_blowup_s", r.energy_blowup_s},
                             {"max_stretch", r.max_stretch},
                             {"stable", r.stable},
                             {"unstable_at_s", r.unstable_at_s},
                             {"nan_events", static_cast<int64_t>(r.nan_events)},
                             {"row_cpu_s", r.cpu_s}});
  }
  for (const StableStepResult& st : results.steps) {
    step_items.push_back(
        Json{{"grid", st.grid},
             {"integrator", ToName(st.kind)},
             {"min_stable_substeps", st.min_stable_substeps},
             {"h_max_s", st.h_max_s},
             {"h_first_unstable_s", st.h_unstable_s},
             {"stable_dt_s", st.theory_dt_s},
             {"ratio_to_stable_dt", std::isfinite(st.theory_dt_s) && st.min_stable_substeps > 0
                                        ? st.h_max_s / st.theory_dt_s
                                        : kNaN},
             {"auto_substeps", st.auto_substeps},
             {"probes", st.probes},
             {"probes_cpu_s", st.cpu_s}});
  }
  for (const auto& [key, ref] : results.references) {
    ref_items.push_back(Json{{"grid", key.first},
                             {"provot", key.second},
                             {"substeps", ref.substeps},
                             {"h_s", ref.h_s},
                             {"error_estimate_m", ref.error_estimate_m},
                             {"cpu_s", ref.cpu_s}});
  }
  Json top{{"command", cmd}, {"complete", progress.empty()}};
  AppendMachineJson(machine, load_end, &top);
  top["timed_frames"] = s.timed_frames;
  top["error_time_s"] = s.error_frames / 60.0;
  top["references"] = ref_items;
  top["rows"] = row_items;
  top["stable_steps"] = step_items;
  const std::string json = JsonText(top);
  const std::string json_path = args.json.empty() ? args.out + "/integrators.json" : args.json;
  WriteTextFile(json_path, json);
  const std::string dat = args.out + "/integrators_plot.dat";
  WriteTextFile(dat, PlotData(s, rows));
  if (!progress.empty()) return true;
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
      return false;
    }
    std::printf("wrote %s\n", png.c_str());
  } else {
    std::printf("gnuplot not found; to draw the plot run:\n  %s\n", plot.c_str());
  }
  return true;
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

  // Set by set: the reference, the sweep, then (Provot off) the largest stable steps; the
  // reports are rewritten after each step so that a stopped run leaves a partial result.
  Results results;
  for (size_t k = 0; k < s.sets.size(); ++k) {
    const auto [grid, provot] = s.sets[k];
    const Reference& ref = results.references[{grid, provot}] =
        MakeReference(args, s, grid, provot);
    std::printf("%s: reference RK4 %d substeps (h = %.4g ms), its error ~ %.3g m, %.1f s cpu\n",
                SetName(grid, provot).c_str(), ref.substeps, ref.h_s * 1e3, ref.error_estimate_m,
                ref.cpu_s);
    std::fflush(stdout);
    for (const IntegratorName& in : kIntegratorNames) {
      const ClothModel auto_model = BuildClothModel(RowSpec(args, grid, provot, in.kind, 0));
      std::vector<int32_t> counts = {0};
      for (const int32_t n : FixedCounts(s, grid, auto_model, in.kind)) counts.push_back(n);
      for (const int32_t n : counts) {
        results.rows.push_back(RunRow(args, s, ref, grid, provot, in.kind, n));
        const Row& r = results.rows.back();
        std::printf(
            "  %-18s %6d substeps  %9.4f ms  err %-10.3g drift %-10.3g stretch %-9.4g %s  "
            "(%d frames timed, %.1f s cpu)\n",
            std::string(in.name).c_str(), r.substeps, r.ms_median, r.rms_error_m, r.energy_drift,
            r.max_stretch, r.stable ? "stable" : "UNSTABLE", r.timed_frames, r.cpu_s);
        std::fflush(stdout);
      }
      WriteReports(args, s, cmd, machine, results,
                   "stopped in the " + SetName(grid, provot) + " sweep");
    }
    if (provot) continue;
    for (const IntegratorName& in : kIntegratorNames) {
      results.steps.push_back(FindStableStep(args, s, grid, in.kind, results.rows));
      const StableStepResult& st = results.steps.back();
      std::printf(
          "grid %d %-18s h_max %.4g ms (%d substeps), theory %.4g ms, ratio %.3g, %d probes, "
          "%.1f s cpu\n",
          grid, std::string(in.name).c_str(), st.h_max_s * 1e3, st.min_stable_substeps,
          st.theory_dt_s * 1e3, st.h_max_s / st.theory_dt_s, st.probes, st.cpu_s);
      std::fflush(stdout);
      WriteReports(args, s, cmd, machine, results,
                   "stopped in the " + SetName(grid, provot) + " stable-step search");
    }
  }
  return WriteReports(args, s, cmd, machine, results, "") ? 0 : 1;
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
