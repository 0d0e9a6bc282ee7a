// `felt bench haptic`: the god-object proxy's snapshot modes compared (issue 4, "Report";
// 001_0f9f1b7fedff7723.txt §6.4 and §7: force discontinuities when the cloth changes outside the
// haptic loop, and the remedy of rendering against two cloths).
//
// For each pointer trace the cloth of a 64 x 64 curtain is known exactly at every 1 ms tick (the
// reference: the proxy sees the exact cloth every tick) and is published to the four modes as
// 60 Hz snapshots, as the server's sim thread would. Every mode runs on the same input; the table
// gives, per mode, the RMS force error against the reference, the largest force jump between
// consecutive ticks, the pop-through count, how deep the proxy sphere reached into the cloth it
// was rendered against, and the cost per tick.
//
// Cloth sources:
//  - "sim": the real cloth (sim_loop/cloth.h) stepped at 1 kHz, coupled both ways with the
//    reference proxy (its reaction applied each millisecond); the modes replay that cloth;
//  - "swing": a kinematic curtain swinging like a pendulum with a travelling ripple, exact at
//    any time (positions and velocities analytic), for the swinging-cloth traces.
#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/command.h"
#include "base/json.h"
#include "base/report.h"
#include "proxy/proxy.h"
#include "proxy/proxy_scene.h"
#include "recordings/generate.h"
#include "recordings/trace.h"
#include "scene/scene_file.h"
#include "sim_loop/cloth.h"
#include "sim_loop/cloth_scene.h"
#include "sim_loop/snapshot.h"

namespace felt::bench::bench_haptic {
namespace {

constexpr double kTickS = 1e-3;
constexpr double kFrameS = 1.0 / 60.0;
// A tick is counted deep when the proxy sphere reaches more than this fraction of its radius into
// the cloth it was rendered against.
constexpr double kDeepFraction = 0.1;
constexpr SnapshotMode kModes[] = {SnapshotMode::kNewest, SnapshotMode::kBlendForces,
                                   SnapshotMode::kInterpolate, SnapshotMode::kExtrapolate};

struct Args {
  std::string json_path;
  std::string csv_path;
  std::string md_path;
  bool quick = false;
  int grid = 64;
};

// One mode's metrics over one run, or summed over several runs (Add).
struct ModeStats {
  double err2_sum = 0.0;
  int64_t ticks = 0;
  double max_jump_N = 0.0;
  int64_t pop_through = 0;
  double max_penetration_m = 0.0;  ///< deepest reach of the proxy sphere into its cloth, m
  int64_t deep_ticks = 0;          ///< ticks reaching deeper than kDeepFraction of the radius
  std::vector<double> tick_us;
  uint64_t overflow_ticks = 0;
  uint64_t catches = 0;

  /// Adds `other`'s run: squared force errors [N^2], ticks and counts add up, the largest jump
  /// [N] and penetration [m] stay the larger, tick times [us] are appended.
  void Add(const ModeStats& other) {
    err2_sum += other.err2_sum;
    ticks += other.ticks;
    max_jump_N = std::max(max_jump_N, other.max_jump_N);
    pop_through += other.pop_through;
    max_penetration_m = std::max(max_penetration_m, other.max_penetration_m);
    deep_ticks += other.deep_ticks;
    tick_us.insert(tick_us.end(), other.tick_us.begin(), other.tick_us.end());
    overflow_ticks += other.overflow_ticks;
    catches += other.catches;
  }

  double rms() const { return ticks > 0 ? std::sqrt(err2_sum / ticks) : 0.0; }
  double median_us() const { return tick_us.empty() ? 0.0 : report::Median(tick_us); }
  double max_us() const {
    return tick_us.empty() ? 0.0 : *std::max_element(tick_us.begin(), tick_us.end());
  }
};

struct RunResult {
  std::string trace;
  std::string source;
  bool sim_healthy = true;
  double reference_max_jump_N = 0.0;
  double reference_max_penetration_m = 0.0;  ///< the reference proxy's, against the exact cloth
  ModeStats modes[4];
};

// The curtain scene at grid x grid particles, same size (0.496 m square), from the scene file.
SimSpec CurtainSpec(int grid) {
  const SceneDocument doc = LoadSceneDocument("scenes/curtain.toml");
  SimSpec spec = ParseSimSpec(doc);
  spec.cloth.width = grid;
  spec.cloth.height = grid;
  spec.cloth.spacing_m = 0.496 / (grid - 1);
  return spec;
}

// The kinematic swinging curtain: rest place r (top edge at y = 0.25), swung along z.
void SwingAt(const std::vector<Vec3>& rest, double t, std::vector<Vec3>* x, std::vector<Vec3>* v) {
  constexpr double kA = 0.06;  // pendulum amplitude at the bottom edge, m
  constexpr double kF = 1.2;   // Hz
  constexpr double kRipple = 0.008;
  constexpr double kL = 0.496;
  const double w = 2.0 * M_PI * kF;
  for (size_t i = 0; i < rest.size(); ++i) {
    const double d = (0.25 - rest[i].y()) / kL;  // 0 at the pinned top, 1 at the bottom
    const double phase = 2.0 * M_PI * (rest[i].x() / 0.25 - 2.0 * t);
    (*x)[i] = rest[i];
    (*x)[i].z() += kA * d * d * std::sin(w * t) + kRipple * d * std::sin(phase);
    (*v)[i] = Vec3(
        0.0, 0.0, kA * d * d * w * std::cos(w * t) + kRipple * d * std::cos(phase) * (-4.0 * M_PI));
  }
}

// The cloth a mode's main proxy used this tick (as ProxyTick chooses it).
ClothView ModeView(SnapshotMode mode, const ClothSnapshot& next, const ClothSnapshot& prev,
                   double since) {
  switch (mode) {
    case SnapshotMode::kInterpolate:
      return ClothView{&prev, &next,
                       next.frame_dt_s > 0 ? std::clamp(since / next.frame_dt_s, 0.0, 1.0) : 1.0,
                       0.0};
    case SnapshotMode::kExtrapolate:
      return ClothView{&next, &next, 0.0, since};
    default:
      return ClothView::Of(next);
  }
}

// Pop-through: the proxy's last contact triangle has it on the other side now, while its closest
// point is inside that triangle (going around the cloth's border is a legitimate release).
struct SideTracker {
  int32_t triangle = -1;
  int32_t side = 0;
  bool Check(const ClothView& view, const GodObject& body) {
    bool popped = false;
    if (triangle >= 0) {
      Vec3 a, b, c;
      view.Corners(triangle, &a, &b, &c);
      const TrianglePoint cp = ClosestPointOnTriangle(body.p_W_m, a, b, c);
      const int32_t s = SideOfTriangle(body.p_W_m, a, b, c);
      const bool interior = cp.barycentric.minCoeff() > 1e-6;
      popped = interior && s != 0 && side != 0 && s != side;
    }
    if (body.num_contacts > 0 && body.contacts[0].triangle >= 0) {  // < 0: an obstacle
      triangle = body.contacts[0].triangle;
      Vec3 a, b, c;
      view.Corners(triangle, &a, &b, &c);
      side = SideOfTriangle(body.p_W_m, a, b, c);
    } else {
      triangle = -1;
    }
    return popped;
  }
};

// How deep the proxy sphere (centre p, radius r, m) reaches into the cloth `view` of `triangles`
// triangles: r less the distance from p to the nearest triangle, 0 when no triangle is nearer than
// r. Exact, over every triangle. The god-object keeps this at 0 up to its tolerances; a proxy that
// went through the cloth reaches into it on the way (unless it crossed a whole sphere in one tick).
double Penetration(const ClothView& view, size_t triangles, const Vec3& p, double r) {
  double nearest2 = r * r;
  for (size_t t = 0; t < triangles; ++t) {
    Vec3 a, b, c;
    view.Corners(static_cast<int32_t>(t), &a, &b, &c);
    nearest2 = std::min(nearest2, ClosestPointOnTriangle(p, a, b, c).distance_sq);
  }
  return r - std::sqrt(nearest2);
}

RunResult RunOne(const std::string& trace_name, const std::vector<TraceSample>& samples,
                 const std::string& source, const Args& args) {
  RunResult res;
  res.trace = trace_name;
  res.source = source;
  const SimSpec spec = CurtainSpec(args.grid);
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  std::vector<Vec3> x = state.x;
  std::vector<Vec3> v = state.v;
  std::vector<Vec3> normals = state.normals;
  const std::vector<Vec3> rest = state.x;
  const bool swing = source == "swing";
  auto cloth_at = [&](double t) {
    if (swing) {
      SwingAt(rest, t, &x, &v);
      ComputeVertexNormals(x, model.triangles, normals);
    } else {
      x = state.x;
      v = state.v;
      normals = state.normals;
    }
  };
  DeviceSpec device;  // the defaults: a Touch-class device, world = 3 x device
  ProxySpec base;
  cloth_at(0.0);
  auto tris = std::make_shared<const std::vector<Triangle>>(model.triangles);
  ClothSnapshot ref_snap = MakeClothSnapshot(tris, x, base.structure);
  // The reference's previous tick's cloth: without it ProxyTick would neither carry the proxy
  // with the cloth nor catch it when the cloth sweeps over it.
  ClothSnapshot ref_prev = MakeClothSnapshot(tris, x, base.structure);
  ClothSnapshot prev = MakeClothSnapshot(tris, x, base.structure);
  ClothSnapshot next = MakeClothSnapshot(tris, x, base.structure);
  FillSnapshot(x, v, normals, 0, 0.0, kFrameS, &prev);
  FillSnapshot(x, v, normals, 1, 0.0, kFrameS, &next);
  ProxySpec ref_spec = base;
  ref_spec.snapshot_mode = SnapshotMode::kNewest;
  const ProxyModel ref_model = CompileProxyModel(device, ref_spec);
  ProxyState ref_state = MakeProxyState(ref_model);
  std::vector<ProxyModel> models;
  std::vector<ProxyState> states;
  for (SnapshotMode m : kModes) {
    ProxySpec s = base;
    s.snapshot_mode = m;
    models.push_back(CompileProxyModel(device, s));
    states.push_back(MakeProxyState(models.back()));
  }
  std::vector<ExternalForce> external(512);
  std::vector<ExternalForce> discard(512);
  // The modes' snapshots carry the frame's motion as velocities, as the server publishes them
  // (sim_loop/frame_motion.h): (x - x at the last publication) / the time between.
  std::vector<Vec3> x_published = x;
  std::vector<Vec3> v_published(x.size(), Vec3::Zero());
  SideTracker trackers[4];
  ClothView views[4];
  Vec3 last_force[4];
  Vec3 last_ref = Vec3::Zero();
  uint64_t frame = 1;
  double last_publish_t = 0.0;
  int64_t next_frame_tick = 0;
  const size_t n = args.quick ? std::min<size_t>(samples.size(), 3000) : samples.size();
  for (size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) * kTickS;
    // The exact cloth of this tick (the sim stepped 1 ms with the reference's reaction).
    if (!swing && i > 0) {
      const int32_t k = ref_state.reaction.DrainInto(external);
      StepFrame(model, std::span<const ExternalForce>(external.data(), k), kTickS, &state);
    }
    cloth_at(t);
    std::swap(ref_prev, ref_snap);
    FillSnapshot(x, v, normals, i + 1, t, kTickS, &ref_snap);
    // A 60 Hz frame publishes this cloth to the modes.
    if (static_cast<int64_t>(i) >= next_frame_tick) {
      std::swap(prev, next);
      const double dt = t - last_publish_t;
      for (size_t p = 0; p < x.size(); ++p) {
        v_published[p] = dt > 0 ? Vec3((x[p] - x_published[p]) / dt) : Vec3(Vec3::Zero());
      }
      x_published = x;
      FillSnapshot(x, v_published, normals, ++frame, t, dt > 0 ? dt : kFrameS, &next);
      last_publish_t = t;
      next_frame_tick = static_cast<int64_t>(std::llround((frame - 1) * kFrameS / kTickS));
    }
    const double since = t - last_publish_t;
    const DeviceSample sample{samples[i].p_D, samples[i].v_D};
    const ProxyTickResult ref = ProxyTick(ref_model, ref_snap, i > 0 ? &ref_prev : nullptr, 0.0,
                                          sample, kTickS, &ref_state);
    if (i > 0)
      res.reference_max_jump_N =
          std::max(res.reference_max_jump_N, (ref.force_D_N - last_ref).norm());
    last_ref = ref.force_D_N;
    for (int m = 0; m < 4; ++m) {
      const auto t0 = std::chrono::steady_clock::now();
      const ProxyTickResult r =
          ProxyTick(models[m], next, &prev, since, sample, kTickS, &states[m]);
      const auto t1 = std::chrono::steady_clock::now();
      states[m].reaction.DrainInto(discard);  // one-way: the modes replay the reference's cloth
      ModeStats& ms = res.modes[m];
      ms.tick_us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
      ms.err2_sum += (r.force_D_N - ref.force_D_N).squaredNorm();
      ++ms.ticks;
      if (i > 0) ms.max_jump_N = std::max(ms.max_jump_N, (r.force_D_N - last_force[m]).norm());
      last_force[m] = r.force_D_N;
      const ClothView view =
          r.on_newest ? ClothView::Of(next) : ModeView(kModes[m], next, prev, since);
      if (trackers[m].Check(view, states[m].body)) {
        ++ms.pop_through;
      }
      views[m] = view;
    }
    // How deep each proxy reached into its cloth, measured after every mode's tick so that the
    // measurement's memory traffic does not land between two timed ticks.
    res.reference_max_penetration_m =
        std::max(res.reference_max_penetration_m,
                 Penetration(ClothView::Of(ref_snap), model.triangles.size(), ref_state.body.p_W_m,
                             device.radius_m));
    for (int m = 0; m < 4; ++m) {
      const double depth =
          Penetration(views[m], model.triangles.size(), states[m].body.p_W_m, device.radius_m);
      ModeStats& ms = res.modes[m];
      ms.max_penetration_m = std::max(ms.max_penetration_m, depth);
      if (depth > kDeepFraction * device.radius_m) ++ms.deep_ticks;
    }
  }
  for (int m = 0; m < 4; ++m) {
    res.modes[m].overflow_ticks = states[m].counters.overflow_ticks;
    res.modes[m].catches = states[m].counters.catches;
  }
  res.sim_healthy = swing || state.counters.nan_events == 0;
  return res;
}

// The pointer traces: the bundled recordings (or generated ones when a file is missing).
std::vector<std::pair<std::string, std::vector<TraceSample>>> LoadTraces() {
  std::vector<std::pair<std::string, std::vector<TraceSample>>> traces;
  for (const std::string& name : BundledTraceNames()) {
    const std::string path = "recordings/" + name + ".trace";
    if (std::filesystem::exists(path)) {
      traces.emplace_back(name, ReadTrace(path).samples);
    } else {
      traces.emplace_back(name + "(generated)", GenerateTrace(name, kDefaultTraceSeed).samples);
    }
  }
  return traces;
}

std::vector<TraceSample> StillPointer(const Vec3& p_D, double seconds) {
  std::vector<TraceSample> s;
  for (int i = 0; i < static_cast<int>(seconds / kTickS); ++i) {
    s.push_back(TraceSample{i * kTickS, p_D, Vec3::Zero(), 0});
  }
  return s;
}

int Run(const Args& args) {
  std::vector<RunResult> runs;
  // The bundled traces on the real cloth, coupled with the reference.
  for (const auto& [name, samples] : LoadTraces()) {
    spdlog::info("bench haptic: {} on the sim curtain", name);
    runs.push_back(RunOne(name, samples, "sim", args));
  }
  // Swinging cloth: the pointer resting against the curtain, and poke-and-hold.
  const double swing_s = args.quick ? 3.0 : 8.0;
  runs.push_back(
      RunOne("rest_swing", StillPointer(Vec3(0.0, -0.02, 0.002), swing_s), "swing", args));
  runs.push_back(RunOne("poke_hold_swing", GenerateTrace("poke_hold", kDefaultTraceSeed).samples,
                        "swing", args));

  // Per-mode aggregates: all runs, and the swinging-cloth runs alone.
  ModeStats all[4];
  ModeStats swing[4];
  for (const RunResult& r : runs) {
    for (int m = 0; m < 4; ++m) {
      all[m].Add(r.modes[m]);
      if (r.source == "swing") swing[m].Add(r.modes[m]);
    }
  }

  // Markdown and CSV tables.
  std::string md = fmt::format(
      "| trace | cloth | mode | force_rms_error_N | max_force_jump_N | pop_through | "
      "max_penetration_um | deep_ticks | tick_us_median | tick_us_max | overflow_ticks | catches "
      "|\n|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  std::string csv =
      "trace,cloth,mode,force_rms_error_N,max_force_jump_N,pop_through,max_penetration_um,"
      "deep_ticks,tick_us_median,tick_us_max,overflow_ticks,catches,reference_max_jump_N,"
      "reference_max_penetration_um,sim_healthy\n";
  for (const RunResult& r : runs) {
    for (int m = 0; m < 4; ++m) {
      const ModeStats& s = r.modes[m];
      const std::string cloth = r.source + (r.sim_healthy ? "" : " (sim went non-finite)");
      md += fmt::format(
          "| {} | {} | {} | {:.4f} | {:.4f} | {} | {:.3f} | {} | {:.2f} | {:.1f} | {} | {} |\n",
          r.trace, cloth, SnapshotModeName(kModes[m]), s.rms(), s.max_jump_N, s.pop_through,
          1e6 * s.max_penetration_m, s.deep_ticks, s.median_us(), s.max_us(), s.overflow_ticks,
          s.catches);
      csv +=
          fmt::format("{},{},{},{:.6f},{:.6f},{},{:.6f},{},{:.3f},{:.3f},{},{},{:.6f},{:.6f},{}\n",
                      r.trace, r.source, SnapshotModeName(kModes[m]), s.rms(), s.max_jump_N,
                      s.pop_through, 1e6 * s.max_penetration_m, s.deep_ticks, s.median_us(),
                      s.max_us(), s.overflow_ticks, s.catches, r.reference_max_jump_N,
                      1e6 * r.reference_max_penetration_m, r.sim_healthy ? 1 : 0);
    }
  }
  md +=
      "\nPer mode over every trace (and, after the slash, over the swinging-cloth traces):\n\n"
      "| mode | force_rms_error_N | max_force_jump_N | pop_through | max_penetration_um | "
      "deep_ticks | tick_us_median | tick_us_max |\n|---|---|---|---|---|---|---|---|\n";
  // One mode's figures: forces [N], penetration [um], tick times [us].
  const auto mode_json = [](SnapshotMode mode, const ModeStats& s) {
    return Json{{"mode", SnapshotModeName(mode)},
                {"force_rms_error_N", RoundedJson(s.rms(), 6)},
                {"max_force_jump_N", RoundedJson(s.max_jump_N, 6)},
                {"pop_through", s.pop_through},
                {"max_penetration_um", RoundedJson(1e6 * s.max_penetration_m, 6)},
                {"deep_ticks", s.deep_ticks},
                {"tick_us_median", RoundedJson(s.median_us(), 3)},
                {"tick_us_max", RoundedJson(s.max_us(), 3)}};
  };
  Json modes = Json::array(), swing_modes = Json::array(), run_items = Json::array();
  for (int m = 0; m < 4; ++m) {
    modes.push_back(mode_json(kModes[m], all[m]));
    swing_modes.push_back(mode_json(kModes[m], swing[m]));
    md += fmt::format(
        "| {} | {:.4f} / {:.4f} | {:.4f} / {:.4f} | {} / {} | {:.3f} / {:.3f} | {} / {} | {:.2f} | "
        "{:.1f} |\n",
        SnapshotModeName(kModes[m]), all[m].rms(), swing[m].rms(), all[m].max_jump_N,
        swing[m].max_jump_N, all[m].pop_through, swing[m].pop_through,
        1e6 * all[m].max_penetration_m, 1e6 * swing[m].max_penetration_m, all[m].deep_ticks,
        swing[m].deep_ticks, all[m].median_us(), all[m].max_us());
  }
  for (const RunResult& r : runs) {
    Json run_modes = Json::array();
    for (int m = 0; m < 4; ++m) run_modes.push_back(mode_json(kModes[m], r.modes[m]));
    run_items.push_back(
        Json{{"trace", r.trace},
             {"cloth", r.source},
             {"sim_healthy", r.sim_healthy},
             {"reference_max_jump_N", RoundedJson(r.reference_max_jump_N, 6)},
             {"reference_max_penetration_um", RoundedJson(1e6 * r.reference_max_penetration_m, 6)},
             {"modes", run_modes}});
  }
  const std::string json = JsonText(Json{
      {"grid", args.grid}, {"modes", modes}, {"swing_modes", swing_modes}, {"runs", run_items}});

  std::fputs(md.c_str(), stdout);
  auto write = [](const std::string& path, const std::string& text) {
    if (path.empty()) return;
    std::ofstream out(path);
    out << text;
    if (!out) throw std::runtime_error("cannot write " + path);
  };
  write(args.json_path, json);
  write(args.csv_path, csv);
  write(args.md_path, md);
  return 0;
}

const bool kRegistered = app::RegisterCommand(app::CommandEntry{
    "bench", "haptic",
    "compare the proxy's snapshot modes on pointer traces against a 1 kHz reference cloth",
    [](CLI::App& cmd) -> app::CommandRun {
      auto args = std::make_shared<Args>();
      cmd.add_option("--json", args->json_path, "write per-mode results as JSON to this file");
      cmd.add_option("--csv", args->csv_path, "write the per-trace table as CSV to this file");
      cmd.add_option("--md", args->md_path, "write the tables as Markdown to this file");
      cmd.add_flag("--quick", args->quick, "at most 3 s of each trace");
      cmd.add_option("--grid", args->grid, "particles per side of the curtain (default 64)")
          ->check(CLI::Range(8, 256));
      return [args] { return Run(*args); };
    }});

}  // namespace
}  // namespace felt::bench::bench_haptic
