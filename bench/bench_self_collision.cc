// `felt bench self-collision [--quick] [--grids 32,64,128] [--frames N] [--out DIR] [--json F]`:
// the cost and the result of the self-collision response (issue 22; collision/self_response.h) on
// the fold-drop hard case (scenes/self_fold_drop.toml) resized to grid x grid particles over a
// 0.3 m square: per culling method and size, the response's wall time per substep (median over
// frames of the frame's response time / substeps, and p99), the frame time with and without
// self-collision, the pairs, impulses and impact zones, and the most intersecting non-adjacent
// triangle pairs at the end of a frame by the exact test (every frame up to 64 x 64, every 10th
// frame above: the test is O(T^2)). Writes <out>/self_collision.{md,csv} and the JSON.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "app/command.h"
#include "base/json.h"
#include "bench/bench_util.h"
#include "collision/self_intersection.h"
#include "scene/scene_file.h"
#include "sim_loop/cloth.h"
#include "sim_loop/cloth_scene.h"

namespace felt::bench::bench_self_collision {
namespace {

constexpr double kSelfBenchFrame_s = 1.0 / 60.0;

struct Args {
  bool quick = false;
  std::string grids = "32,64,128";
  int32_t frames = 90;
  std::string out = "bench/results";
  std::string json;
  std::string scene = "scenes/self_fold_drop.toml";
};

struct Row {
  std::string method;  // "spatial_hash", "bvh" or "off"
  int32_t grid = 0;
  int64_t triangles = 0;
  double thickness_m = 0.0;
  int32_t substeps = 0;
  double response_ms_median = 0.0;  // per substep
  double response_ms_p99 = 0.0;     // per substep
  double frame_ms_median = 0.0;
  int64_t intersections_max = 0;
  int32_t frames_counted = 0;
  double pairs_per_frame = 0.0;     // proximity pairs, mean
  double impulses_per_frame = 0.0;  // mean
  double zones_per_frame = 0.0;     // mean
  int64_t frozen_substeps = 0;
  int64_t unresolved_substeps = 0;
  int64_t overflows = 0;
};

// The fold-drop scene on a grid x grid cloth over a 0.3 m square; thickness min(2 mm, spacing/4).
SimSpec SelfBenchSpec(const std::string& scene, int32_t grid, const std::string& method) {
  SimSpec spec = ParseSimSpec(LoadSceneDocument(scene));
  ClothSpec& c = spec.cloth;
  const double particles_before = static_cast<double>(c.width) * c.height;
  c.width = grid;
  c.height = grid;
  c.spacing_m = 0.3 / (grid - 1);
  c.drag_N_s_per_m *= particles_before / (static_cast<double>(grid) * grid);
  c.mass_kg = 0.17 * 0.3 * 0.3;  // 0.17 kg/m^2
  c.origin_m = Vec3(-0.15, 0.016 + 0.3 * 0.955336, 0.0);
  if (method == "off") {
    spec.self_collision.reset();
  } else {
    if (!spec.self_collision) spec.self_collision.emplace();
    spec.self_collision->method = *SelfCullingMethodFromName(method);
    spec.self_collision->thickness_m = std::min(0.002, c.spacing_m / 4);
  }
  return spec;
}

Row RunSelfBench(const Args& args, int32_t grid, const std::string& method) {
  const SimSpec spec = SelfBenchSpec(args.scene, grid, method);
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  Row row;
  row.method = method;
  row.grid = grid;
  row.triangles = static_cast<int64_t>(model.triangles.size());
  row.thickness_m = spec.self_collision ? spec.self_collision->thickness_m : 0.0;
  row.substeps = model.substeps;
  const int32_t count_every = grid <= 64 ? 1 : 10;
  std::vector<double> per_substep_ms, frame_ms;
  double pairs = 0, impulses = 0, zones = 0;
  for (int32_t f = 0; f < args.frames; ++f) {
    const double t0 = WallMs();
    const FrameResult r = StepFrame(model, {}, kSelfBenchFrame_s, &state);
    frame_ms.push_back(WallMs() - t0);
    per_substep_ms.push_back(1e3 * r.self_collision_s / std::max(1, r.substeps));
    pairs += static_cast<double>(r.self_proximity_pairs);
    impulses += static_cast<double>(r.self_impulses);
    zones += static_cast<double>(r.self_impact_zones);
    if ((f + 1) % count_every == 0 || f + 1 == args.frames) {
      row.intersections_max =
          std::max(row.intersections_max, CountSelfIntersections(state.x, model.triangles));
      ++row.frames_counted;
    }
  }
  row.response_ms_median = Median(per_substep_ms);
  row.response_ms_p99 = Percentile(per_substep_ms, 99);
  row.frame_ms_median = Median(frame_ms);
  row.pairs_per_frame = pairs / args.frames;
  row.impulses_per_frame = impulses / args.frames;
  row.zones_per_frame = zones / args.frames;
  row.frozen_substeps = static_cast<int64_t>(state.counters.self_frozen_substeps);
  row.unresolved_substeps = static_cast<int64_t>(state.counters.self_unresolved_substeps);
  row.overflows = static_cast<int64_t>(state.counters.self_overflows);
  return row;
}

std::vector<int32_t> ParseSelfGrids(const std::string& text) {
  std::vector<int32_t> grids;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    const int32_t g = std::stoi(item);
    if (g < 4) throw std::invalid_argument("--grids: each size must be >= 4, got " + item);
    grids.push_back(g);
  }
  return grids;
}

std::string SelfCommand(const Args& args) {
  std::string cmd = "felt bench self-collision";
  if (args.quick) cmd += " --quick";
  if (args.grids != "32,64,128") cmd += " --grids " + args.grids;
  if (args.frames != 90) cmd += " --frames " + std::to_string(args.frames);
  if (args.scene != "scenes/self_fold_drop.toml") cmd += " --scene " + args.scene;
  if (args.out != "bench/results") cmd += " --out " + args.out;
  if (!args.json.empty()) cmd += " --json " + args.json;
  return cmd;
}

int Run(Args args) {
  if (args.quick) {
    args.grids = "16";
    args.frames = 20;
  }
  const MachineInfo machine = ReadMachineInfo();
  const std::string cmd = SelfCommand(args);
  std::printf("%s\nload average %s\n", cmd.c_str(), machine.load_average.c_str());
  std::vector<Row> rows;
  for (const int32_t grid : ParseSelfGrids(args.grids)) {
    for (const std::string method : {"off", "spatial_hash", "bvh"}) {
      const Row r = RunSelfBench(args, grid, method);
      std::printf(
          "%-13s %4d: response %.3f ms/substep (p99 %.3f), frame %.2f ms, "
          "intersections %lld\n",
          method.c_str(), grid, r.response_ms_median, r.response_ms_p99, r.frame_ms_median,
          static_cast<long long>(r.intersections_max));
      std::fflush(stdout);
      rows.push_back(r);
    }
  }
  const std::string load_end = LoadAverage();
  const std::vector<std::string> header = {"method",
                                           "grid",
                                           "triangles",
                                           "thickness_mm",
                                           "substeps",
                                           "response_ms_per_substep_median",
                                           "response_ms_per_substep_p99",
                                           "frame_ms_median",
                                           "frame_ratio_vs_off",
                                           "intersections_max",
                                           "frames_counted",
                                           "proximity_pairs_per_frame",
                                           "impulses_per_frame",
                                           "impact_zones_per_frame",
                                           "frozen_substeps",
                                           "unresolved_substeps",
                                           "overflows"};
  std::vector<std::vector<std::string>> table;
  Json items = Json::array();
  for (const Row& r : rows) {
    double off_ms = NAN;
    for (const Row& o : rows) {
      if (o.grid == r.grid && o.method == "off") off_ms = o.frame_ms_median;
    }
    const bool on = r.method != "off";
    table.push_back({r.method, std::to_string(r.grid), std::to_string(r.triangles),
                     on ? Sig(1e3 * r.thickness_m, 3) : "-", std::to_string(r.substeps),
                     on ? Sig(r.response_ms_median, 3) : "-", on ? Sig(r.response_ms_p99, 3) : "-",
                     Sig(r.frame_ms_median, 3), Sig(r.frame_ms_median / off_ms, 3),
                     std::to_string(r.intersections_max), std::to_string(r.frames_counted),
                     on ? Sig(r.pairs_per_frame, 4) : "-", on ? Sig(r.impulses_per_frame, 4) : "-",
                     on ? Sig(r.zones_per_frame, 3) : "-", std::to_string(r.frozen_substeps),
                     std::to_string(r.unresolved_substeps), std::to_string(r.overflows)});
    items.push_back(Json{{"method", r.method},
                         {"case", "fold_drop"},
                         {"grid", r.grid},
                         {"triangles", r.triangles},
                         {"thickness_m", r.thickness_m},
                         {"substeps", r.substeps},
                         {"response_ms_per_substep_median", r.response_ms_median},
                         {"response_ms_per_substep_p99", r.response_ms_p99},
                         {"frame_ms_median", r.frame_ms_median},
                         {"intersections_end_of_frame", r.intersections_max},
                         {"frames_counted", r.frames_counted},
                         {"proximity_pairs_per_frame", r.pairs_per_frame},
                         {"impulses_per_frame", r.impulses_per_frame},
                         {"impact_zones_per_frame", r.zones_per_frame},
                         {"frozen_substeps", r.frozen_substeps},
                         {"unresolved_substeps", r.unresolved_substeps},
                         {"overflows", r.overflows}});
  }
  std::vector<bool> right(header.size(), true);
  right[0] = false;
  const std::string md_table = MarkdownTable(header, right, table);
  std::printf("\n%s", md_table.c_str());
  std::string md =
      ReportHeader("Self-collision response (`felt bench self-collision`)", cmd, machine, load_end);
  md +=
      "Case: scenes/self_fold_drop.toml resized to grid x grid particles over a 0.3 m square "
      "(0.17 kg/m^2, leaning 0.3 rad, released 1.6 cm above the floor; it piles up in folds), " +
      std::to_string(args.frames) +
      " frames of 1/60 s, thickness min(2 mm, spacing / 4). `off` is the same scene without "
      "[self_collision]. The response time is wall time inside the response (proximity, CCD "
      "rounds, impact zones), per substep: the median and p99 over frames of the frame's "
      "total / its substeps. `intersections_max`: the most intersecting non-adjacent triangle "
      "pairs at the end of a counted frame, exact test (collision/self_intersection.h); "
      "frames_counted says how many frames were checked (all up to 64 x 64, every 10th "
      "above). One run; medians.\n\n" +
      md_table;
  WriteTextFile(args.out + "/self_collision.md", md);
  std::string csv = "# " + cmd + " | " + machine.date_utc + " | " + machine.cpu_model + "\n";
  csv += CsvTable(header, table);
  WriteTextFile(args.out + "/self_collision.csv", csv);
  Json top{{"command", cmd}};
  AppendMachineJson(machine, load_end, &top);
  top["rows"] = items;
  const std::string json_path = args.json.empty() ? args.out + "/self_collision.json" : args.json;
  WriteTextFile(json_path, JsonText(top));
  std::printf("wrote %s/self_collision.{md,csv}, %s\n", args.out.c_str(), json_path.c_str());
  return 0;
}

app::CommandRun SelfSetup(CLI::App& cmd) {
  auto args = std::make_shared<Args>();
  cmd.add_option("--grids", args->grids, "comma-separated grid sizes")->capture_default_str();
  cmd.add_option("--frames", args->frames, "frames per run")->check(CLI::Range(1, 100000));
  cmd.add_option("--scene", args->scene, "the fold-drop scene")->capture_default_str();
  cmd.add_option("--out", args->out, "folder for self_collision.{md,csv}")->capture_default_str();
  cmd.add_option("--json", args->json, "JSON output file (default <out>/self_collision.json)");
  cmd.add_flag("--quick", args->quick, "grid 16, 20 frames (seconds; for CI): not a result");
  return [args]() { return Run(*args); };
}

const bool kRegistered = app::RegisterCommand(
    {"bench", "self-collision",
     "self-collision response cost and intersections per culling method and size (issue 22)",
     SelfSetup});

}  // namespace
}  // namespace felt::bench::bench_self_collision
