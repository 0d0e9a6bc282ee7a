// `felt run --scene FILE [--duration S] [--fast] [--json FILE] [--count-intersections]`: runs a
// scene's cloth headless at its frame rate (60 Hz by default) for a few seconds and prints frame
// statistics (with --count-intersections also self_intersections_max, the exact count of
// intersecting non-adjacent triangle pairs at the end of the worst frame). `make run` calls it
// until the server exists.
//
// Each frame steps the nominal 1 / frame_rate_hz, so a run's physics is deterministic; in real
// time the frames run in rt/loop_runner.h's RunLoop (absolute deadlines, overruns counted, missed
// periods skipped instead of bunching frames up). --fast never sleeps.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/command.h"
#include "base/json.h"
#include "base/report.h"
#include "collision/self_intersection.h"
#include "rt/loop_runner.h"
#include "scene/scene_file.h"
#include "server/server_spec.h"
#include "sim_loop/cloth.h"
#include "sim_loop/cloth_scene.h"
#include "sim_loop/integrator_names.h"

namespace felt::app::cmd_run {
namespace {

constexpr double kMaxDuration_s = 86400.0;  // one day of frames: the per-frame samples stay small

struct RunArgs {
  std::string scene;
  std::optional<double> duration_s;
  std::string json;
  bool fast = false;
  bool count_intersections = false;
};

// What a run measured.
struct RunStats {
  int64_t frames = 0;
  int64_t substeps = 0;
  double sim_time_s = 0.0;
  double wall_s = 0.0;
  std::vector<double> frame_ms;  // compute time of each frame
  double max_stretch = 1.0;      // over every frame
  double final_stretch = 1.0;
  double energy_start_J = 0.0;
  double energy_end_J = 0.0;
  double energy_min_J = 0.0;
  double energy_max_J = 0.0;
  int64_t overruns = 0;         // frames that ended after their deadline (real time only)
  int64_t skipped_periods = 0;  // periods skipped after overruns
  // Most intersecting non-adjacent triangle pairs at a frame's end (exact test), -1: not counted.
  int64_t self_intersections_max = -1;
};

// The nearest-rank percentile of the frame times [ms] (p in [0, 100]); 0 when no frame ran, as
// this command has always printed.
double FrameMsPercentile(const RunStats& stats, double p) {
  return stats.frame_ms.empty() ? 0.0 : report::Percentile(stats.frame_ms, p);
}

// Steps `model` for `frames` frames of nominal length, in real time unless `fast`.
// With count_intersections, every frame's end is checked by the exact O(T^2) triangle test
// (collision/self_intersection.h) after the frame's timing, unless the sim counts them itself
// ([self_collision] count_intersections).
RunStats RunFrames(const ClothModel& model, int64_t frames, bool fast, bool count_intersections,
                   ClothState* state) {
  RunStats stats;
  const bool count_here = count_intersections && !model.self_collision_count_intersections;
  if (count_here) stats.self_intersections_max = CountSelfIntersections(state->x, model.triangles);
  stats.frame_ms.reserve(static_cast<size_t>(frames));
  const double frame_dt_s = 1.0 / model.frame_rate_hz;
  const int64_t period_ns = std::max<int64_t>(1, std::llround(frame_dt_s * 1e9));
  const std::span<const ExternalForce> no_external;

  stats.energy_start_J = TotalEnergy(model, *state);
  stats.energy_min_J = stats.energy_max_J = stats.energy_start_J;
  stats.max_stretch = stats.final_stretch = MaxStretch(model, *state);

  // One frame: step (timed alone), then the frame's statistics.
  const auto frame = [&] {
    const int64_t begin_ns = MonotonicNowNs();
    const FrameResult result = StepFrame(model, no_external, frame_dt_s, state);
    stats.frame_ms.push_back(static_cast<double>(MonotonicNowNs() - begin_ns) * 1e-6);
    if (count_here) {
      stats.self_intersections_max =
          std::max(stats.self_intersections_max, CountSelfIntersections(state->x, model.triangles));
    }
    stats.substeps += result.substeps;
    stats.sim_time_s += result.dt_s;
    stats.final_stretch = MaxStretch(model, *state);
    stats.max_stretch = std::max(stats.max_stretch, stats.final_stretch);
    stats.energy_end_J = TotalEnergy(model, *state);
    stats.energy_min_J = std::min(stats.energy_min_J, stats.energy_end_J);
    stats.energy_max_J = std::max(stats.energy_max_J, stats.energy_end_J);
    ++stats.frames;
  };

  const int64_t start_ns = MonotonicNowNs();
  if (fast) {
    while (stats.frames < frames) frame();
  } else {
    // Real time: the loop runner every loop thread uses (absolute deadlines, overruns counted,
    // missed periods skipped), stopped after the last frame.
    std::atomic<bool> done{false};
    LoopRunOptions loop;
    loop.period_ns = period_ns;
    loop.stop = &done;
    LoopStats loop_stats(period_ns);
    RunLoop(loop, &loop_stats, [&](const TickInfo&) {
      frame();
      if (stats.frames >= frames) done.store(true, std::memory_order_relaxed);
    });
    LoopStatsSnapshot snapshot;
    loop_stats.Snapshot(&snapshot);
    stats.overruns = static_cast<int64_t>(snapshot.overruns);
    stats.skipped_periods = static_cast<int64_t>(snapshot.skipped_periods);
  }
  stats.wall_s = static_cast<double>(MonotonicNowNs() - start_ns) * 1e-9;
  if (!count_here) stats.self_intersections_max = state->counters.self_intersections_max;
  return stats;
}

void PrintStats(const SceneInfo& info, const std::string& file, const ClothModel& model,
                const ClothState& state, const RunStats& stats, bool fast) {
  std::printf("felt run: %s (%s)\n", info.name.c_str(), file.c_str());
  if (!info.description.empty()) std::printf("  %s\n", info.description.c_str());
  std::printf("  %d x %d particles, %zu springs, %zu pinned particles, %zu obstacles\n",
              model.width, model.height, model.springs.size(), model.pinned.size(),
              model.obstacles.size());
  std::printf("  %s, %d substeps per frame (%s), %s Hz, %s\n",
              std::string(ToName(model.integrator)).c_str(), model.substeps,
              model.auto_substeps ? "auto" : "fixed",
              FormatSceneNumber(model.frame_rate_hz).c_str(),
              fast ? "as fast as possible (--fast)" : "real time");
  std::printf("frames             %lld (%.3f s simulated in %.3f s wall)\n",
              static_cast<long long>(stats.frames), stats.sim_time_s, stats.wall_s);
  std::printf("substeps           %lld\n", static_cast<long long>(stats.substeps));
  std::printf("frame compute ms   p50 %.3f  p99 %.3f  max %.3f\n", FrameMsPercentile(stats, 50),
              FrameMsPercentile(stats, 99), FrameMsPercentile(stats, 100));
  std::printf("max stretch        %.4f (at the end %.4f)\n", stats.max_stretch,
              stats.final_stretch);
  std::printf("energy J           start %.6g  end %.6g  min %.6g  max %.6g\n", stats.energy_start_J,
              stats.energy_end_J, stats.energy_min_J, stats.energy_max_J);
  std::printf("nan events         %llu\n",
              static_cast<unsigned long long>(state.counters.nan_events));
  std::printf("clamped frames     %llu\n",
              static_cast<unsigned long long>(state.counters.clamped_frames));
  if (model.integrator == IntegratorKind::kImplicitEuler) {
    std::printf("cg not converged   %llu\n",
                static_cast<unsigned long long>(state.counters.cg_not_converged));
  }
  if (!model.limit_families.empty()) {
    // The finishing worklist (provot.finish): a substep that ran out of its budget was undone,
    // which is when max stretch can exceed the limit.
    const ClothCounters& c = state.counters;
    std::printf(
        "stretch limiter    worklist: %llu pairs found over the limit, %llu projections, %llu "
        "substeps out of budget (undone)\n",
        static_cast<unsigned long long>(c.limiter_initial),
        static_cast<unsigned long long>(c.limiter_projections),
        static_cast<unsigned long long>(c.limiter_unconverged));
  }
  if (model.self_collision_enabled) {
    const ClothCounters& c = state.counters;
    std::printf(
        "self-collision     %s, thickness %s m: %llu proximity pairs, %llu impulses, %llu "
        "CCD hits, %llu impact zones, %llu frozen / %llu unresolved substeps\n",
        std::string(SelfCullingMethodName(model.self_collision.method)).c_str(),
        FormatSceneNumber(model.self_collision.thickness_m).c_str(),
        static_cast<unsigned long long>(c.self_proximity_pairs),
        static_cast<unsigned long long>(c.self_impulses),
        static_cast<unsigned long long>(c.self_ccd_hits),
        static_cast<unsigned long long>(c.self_impact_zones),
        static_cast<unsigned long long>(c.self_frozen_substeps),
        static_cast<unsigned long long>(c.self_unresolved_substeps));
  }
  if (stats.self_intersections_max >= 0) {
    std::printf("self intersections max %lld (exact test, end of every frame)\n",
                static_cast<long long>(stats.self_intersections_max));
  }
  if (!fast) {
    std::printf("overruns           %lld (%lld periods skipped)\n",
                static_cast<long long>(stats.overruns),
                static_cast<long long>(stats.skipped_periods));
  }
  std::fflush(stdout);
}

void WriteJson(std::ofstream& out, const std::string& json_path, const SceneInfo& info,
               const std::string& file, const ClothModel& model, const ClothState& state,
               const RunStats& stats, bool fast) {
  const Json frame_ms{{"p50", FrameMsPercentile(stats, 50)},
                      {"p99", FrameMsPercentile(stats, 99)},
                      {"max", FrameMsPercentile(stats, 100)}};
  const Json energy_J{{"start", stats.energy_start_J},
                      {"end", stats.energy_end_J},
                      {"min", stats.energy_min_J},
                      {"max", stats.energy_max_J}};
  out << JsonText(Json{
      {"scene", info.name},
      {"file", file},
      {"width", model.width},
      {"height", model.height},
      {"integrator", ToName(model.integrator)},
      {"substeps_per_frame", model.substeps},
      {"auto_substeps", model.auto_substeps},
      {"frame_rate_hz", model.frame_rate_hz},
      {"realtime", !fast},
      {"frames", stats.frames},
      {"substeps", stats.substeps},
      {"sim_time_s", stats.sim_time_s},
      {"wall_s", stats.wall_s},
      {"frame_ms", frame_ms},
      {"max_stretch", stats.max_stretch},
      {"final_stretch", stats.final_stretch},
      {"energy_J", energy_J},
      {"nan_events", state.counters.nan_events},
      {"clamped_frames", state.counters.clamped_frames},
      {"cg_not_converged", state.counters.cg_not_converged},
      {"limiter_finish", !model.limit_families.empty()},
      {"limiter_initial", state.counters.limiter_initial},
      {"limiter_projections", state.counters.limiter_projections},
      {"limiter_unconverged", state.counters.limiter_unconverged},
      {"overruns", stats.overruns},
      {"skipped_periods", stats.skipped_periods},
      {"self_collision", model.self_collision_enabled},
      {"self_proximity_pairs", state.counters.self_proximity_pairs},
      {"self_impulses", state.counters.self_impulses},
      {"self_ccd_hits", state.counters.self_ccd_hits},
      {"self_impact_zones", state.counters.self_impact_zones},
      {"self_unresolved_substeps", state.counters.self_unresolved_substeps},
      {"self_intersections_max",
       stats.self_intersections_max >= 0 ? Json(stats.self_intersections_max) : Json(nullptr)}});
  out.flush();
  if (!out) throw std::runtime_error("--json " + json_path + ": write failed");
}

CommandRun SetupRun(CLI::App& cmd) {
  auto args = std::make_shared<RunArgs>();
  cmd.add_option("--scene", args->scene, "scene file (TOML, see docs/scenes.md)")->required();
  cmd.add_option("--duration", args->duration_s,
                 "seconds of simulated time (default: the scene's [scene] duration_s, else 5)");
  cmd.add_flag("--fast", args->fast, "run as fast as possible instead of in real time");
  cmd.add_option("--json", args->json, "also write the statistics to this JSON file");
  cmd.add_flag("--count-intersections", args->count_intersections,
               "check every frame's end for intersecting non-adjacent triangle pairs with the "
               "exact O(T^2) test and report self_intersections_max (slow on large cloths)");
  return [args]() {
    // Everything is read and validated before anything starts: a bad scene throws (exit 2).
    const SceneDocument doc = LoadSceneDocument(args->scene);
    const SceneInfo info = ParseSceneInfo(doc);
    const SimSpec spec = CheckWholeScene(doc).sim;  // the sections run does not use checked too
    const double duration_s = args->duration_s.value_or(info.duration_s);
    if (!(duration_s > 0.0 && duration_s <= kMaxDuration_s)) {
      throw std::invalid_argument("--duration must be in (0, " + FormatSceneNumber(kMaxDuration_s) +
                                  "] s, got " + FormatSceneNumber(duration_s));
    }
    std::optional<ClothModel> model;
    try {
      model.emplace(BuildClothModel(spec));
    } catch (const std::invalid_argument& error) {
      throw SceneError(doc.source_name + ": " + error.what());
    }
    std::ofstream json;
    if (!args->json.empty()) {
      json.open(args->json);
      if (!json) {
        throw std::runtime_error("--json " + args->json +
                                 ": cannot open for writing: " + std::strerror(errno));
      }
    }

    // Run and report.
    ClothState state = MakeClothState(*model);
    const int64_t frames =
        std::max<int64_t>(1, std::llround(duration_s * spec.integration.frame_rate_hz));
    const RunStats stats = RunFrames(*model, frames, args->fast, args->count_intersections, &state);
    PrintStats(info, doc.source_name, *model, state, stats, args->fast);
    if (json.is_open()) {
      WriteJson(json, args->json, info, doc.source_name, *model, state, stats, args->fast);
    }
    return 0;
  };
}

const bool kRegistered = RegisterCommand(
    {"", "run", "run a scene headless in real time and print frame statistics", SetupRun});

}  // namespace
}  // namespace felt::app::cmd_run
