// `felt bench self-collision [--quick] [--case fold_drop|curtain] [--grids 32,64,128] [--frames N]
// [--detect-grid G] [--detect-frames N] [--out DIR] [--json F]`: the cost and the result of the
// self-collision response (issue 22; collision/self_response.h) on the fold-drop hard case
// (scenes/self_fold_drop.toml) resized to grid x grid particles over a 0.3 m square, or with
// --case curtain on the haptic curtain (scenes/curtain.toml) at each grid: per culling
// method and size, the detection's and the response's wall time per frame (median, p99), the
// frame time with and without self-collision, the collisions the culled detection missed against
// the all-pairs continuous reference (AllPairsCcd) on the same frames' motion, the pairs,
// impulses and impact zones, and the most intersecting non-adjacent triangle pairs at the end of
// a frame by the exact test (every frame up to 64 x 64, every 10th frame above: the test is
// O(T^2)); plus a detection row on a detect-grid x detect-grid cloth (150: 44402 triangles, issue
// 22's 4 ms target). Writes <out>/self_collision.{md,csv} and the JSON.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <memory>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "app/command.h"
#include "base/gnuplot.h"
#include "base/json.h"
#include "bench/bench_util.h"
#include "collision/ccd_all_pairs.h"
#include "collision/self_intersection.h"
#include "scene/scene_file.h"
#include "sim_loop/cloth.h"
#include "sim_loop/cloth_internal.h"
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
  // "fold_drop" (the scene above on a 0.3 m square) or "curtain" (scenes/curtain.toml, the
  // haptic curtain, at each grid over its own 0.496 m square, hanging from its two top corners
  // and released from rest: issue 22's "64 x 64 curtain with self-collision on").
  std::string case_name = "fold_drop";
  int32_t detect_grid = 150;   // the ~45k-triangle detection row (0: none)
  int32_t detect_frames = 60;  // its frames
  // The response's pass and padding settings, the shipped defaults unless given.
  int32_t passes_per_frame = SelfCollisionSettings{}.passes_per_frame;
  double broad_inflation = SelfCollisionSettings{}.broad_inflation;
  double max_pass_motion = SelfCollisionSettings{}.max_pass_motion;
  int32_t min_passes_per_frame = SelfCollisionSettings{}.min_passes_per_frame;
  double slow_pass_motion = SelfCollisionSettings{}.slow_pass_motion;
  double hand_pass_motion = SelfCollisionSettings{}.hand_pass_motion;
  std::string methods = "spatial_hash,bvh,bvox_aabb,apccd,bvh_cones";  // response rows' methods
  std::string detect_methods = "bvh_cones";  // culling methods of the detection row
  bool reference = true;  // compare with AllPairsCcd (off: for profiling the response alone)
  bool plot = true;       // gnuplot on gnuplot_script: <out>/self_collision.png
  std::string gnuplot_script = "bench/self_collision.gp";
};

struct Row {
  std::string method;             // a culling method's name, or "off"
  std::string kind = "response";  // "response" (32, 64, ...) or "detection" (--detect-grid)
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
  // Detection (broad phase, box filter, continuous pair tests) per frame: every pass and round,
  // and the first CCD detection of each pass alone (SelfCollisionStats::detect_s).
  double detect_ms_median = 0.0;
  double detect_ms_p99 = 0.0;
  double first_detect_ms_median = 0.0;
  double passes_per_frame = 0.0;
  double broad_phases_per_frame = 0.0;
  double broad_reuses_per_frame = 0.0;   // detections that skipped the broad phase (APCCD)
  double broad_updates_per_frame = 0.0;  // bvh_cones, apccd: broad phases carried over
  double narrow_tests_per_frame = 0.0;
  // The first CCD detection of each checked frame against AllPairsCcd on the same motion.
  int32_t reference_frames = 0;
  int64_t reference_hits = 0;       // pairs the reference reported, summed over those frames
  int64_t missed_vs_reference = 0;  // of those, not found by the culled detection
  int64_t extra_vs_reference = 0;   // found by the culled detection, not by the reference
  std::vector<double> frame_ms;     // each frame's wall time, ms (the plot over the animation)
  std::vector<double> detect_ms;    // each frame's detection time, ms (empty for "off")
};

// Compares the culled first CCD detection of the response's last pass with AllPairsCcd on the
// same motion (x_before -> first_pass_end, same options; box prefilter on: same result, faster).
void CompareWithReference(const ClothModel& model, const SelfCollisionResponse& response,
                          Row* row) {
  if (response.first_pass_end().empty()) return;
  AllPairsCcdOptions options = response.CcdPassOptions();
  options.box_prefilter = true;
  const std::vector<CcdPairHit> ref =
      AllPairsCcd(response.x_before(), response.first_pass_end(), model.triangles, options);
  const auto key = [](const CcdPairHit& h) {
    return std::tuple(static_cast<int>(h.kind), h.first, h.second);
  };
  std::vector<std::tuple<int, int32_t, int32_t>> found, expected;
  for (const CcdPairHit& h : response.first_pass_hits()) found.push_back(key(h));
  for (const CcdPairHit& h : ref) expected.push_back(key(h));
  std::sort(found.begin(), found.end());
  std::sort(expected.begin(), expected.end());
  std::vector<std::tuple<int, int32_t, int32_t>> diff;
  std::set_difference(expected.begin(), expected.end(), found.begin(), found.end(),
                      std::back_inserter(diff));
  row->missed_vs_reference += static_cast<int64_t>(diff.size());
  diff.clear();
  std::set_difference(found.begin(), found.end(), expected.begin(), expected.end(),
                      std::back_inserter(diff));
  row->extra_vs_reference += static_cast<int64_t>(diff.size());
  row->reference_hits += static_cast<int64_t>(expected.size());
  ++row->reference_frames;
}

// The case's scene on a grid x grid cloth: the fold drop over a 0.3 m square, or the curtain
// resized as `felt bench cloth` does (bench/bench_util.h ResizedCurtain); thickness min(2 mm,
// spacing / 4), the scene's other [self_collision] settings or the defaults.
SimSpec SelfBenchSpec(const Args& args, int32_t grid, const std::string& method) {
  SimSpec spec;
  if (args.case_name == "curtain") {
    spec = ResizedCurtain(args.scene, grid);
  } else {
    spec = ParseSimSpec(LoadSceneDocument(args.scene));
    ClothSpec& c = spec.cloth;
    const double particles_before = static_cast<double>(c.width) * c.height;
    c.width = grid;
    c.height = grid;
    c.spacing_m = 0.3 / (grid - 1);
    c.drag_N_s_per_m *= particles_before / (static_cast<double>(grid) * grid);
    c.mass_kg = 0.17 * 0.3 * 0.3;  // 0.17 kg/m^2
    c.origin_m = Vec3(-0.15, 0.016 + 0.3 * 0.955336, 0.0);
  }
  const ClothSpec& c = spec.cloth;
  if (method == "off") {
    spec.self_collision.reset();
  } else {
    if (!spec.self_collision) spec.self_collision.emplace();
    spec.self_collision->method = *SelfCullingMethodFromName(method);
    spec.self_collision->thickness_m = std::min(0.002, c.spacing_m / 4);
  }
  return spec;
}

// count_every: the exact intersection count every that many frames (and the last);
// reference_every: the all-pairs comparison every that many frames (0: never).
Row RunSelfBench(const Args& args, int32_t grid, const std::string& method, int32_t frames,
                 int32_t count_every, int32_t reference_every) {
  const SimSpec spec = SelfBenchSpec(args, grid, method);
  ClothModel model = BuildClothModel(spec);
  model.self_collision.passes_per_frame = args.passes_per_frame;
  model.self_collision.broad_inflation = args.broad_inflation;
  model.self_collision.max_pass_motion = args.max_pass_motion;
  model.self_collision.min_passes_per_frame = args.min_passes_per_frame;
  model.self_collision.slow_pass_motion = args.slow_pass_motion;
  model.self_collision.hand_pass_motion = args.hand_pass_motion;
  ClothState state = MakeClothState(model);
  SelfCollisionResponse* response =
      state.scratch->self_collision ? &*state.scratch->self_collision : nullptr;
  if (response && reference_every > 0) response->KeepFirstPass(true);
  Row row;
  row.method = method;
  row.grid = grid;
  row.triangles = static_cast<int64_t>(model.triangles.size());
  row.thickness_m = spec.self_collision ? spec.self_collision->thickness_m : 0.0;
  row.substeps = model.substeps;
  std::vector<double> per_substep_ms, frame_ms, detect_ms, first_detect_ms;
  double pairs = 0, impulses = 0, zones = 0, broads = 0, reuses = 0, updates = 0, narrows = 0;
  for (int32_t f = 0; f < frames; ++f) {
    const SelfCollisionStats before = response ? response->totals() : SelfCollisionStats{};
    const double t0 = WallMs();
    const FrameResult r = StepFrame(model, {}, kSelfBenchFrame_s, &state);
    frame_ms.push_back(WallMs() - t0);
    per_substep_ms.push_back(1e3 * r.self_collision_s / std::max(1, r.substeps));
    pairs += static_cast<double>(r.self_proximity_pairs);
    impulses += static_cast<double>(r.self_impulses);
    zones += static_cast<double>(r.self_impact_zones);
    if (response) {
      const SelfCollisionStats& after = response->totals();
      detect_ms.push_back(1e3 * (after.detect_s - before.detect_s));
      first_detect_ms.push_back(1e3 * (after.first_detect_s - before.first_detect_s));
      broads += after.broad_phases - before.broad_phases;
      reuses += after.broad_reuses - before.broad_reuses;
      updates += after.broad_updates - before.broad_updates;
      narrows += static_cast<double>(after.narrow_tests - before.narrow_tests);
    }
    const bool last = f + 1 == frames;
    if (response && reference_every > 0 && ((f + 1) % reference_every == 0 || last)) {
      CompareWithReference(model, *response, &row);
    }
    if ((f + 1) % count_every == 0 || last) {
      row.intersections_max =
          std::max(row.intersections_max, CountSelfIntersections(state.x, model.triangles));
      ++row.frames_counted;
    }
  }
  if (response) {
    row.detect_ms_median = Median(detect_ms);
    row.detect_ms_p99 = Percentile(detect_ms, 99);
    row.first_detect_ms_median = Median(first_detect_ms);
    row.broad_phases_per_frame = broads / frames;
    row.broad_reuses_per_frame = reuses / frames;
    row.broad_updates_per_frame = updates / frames;
    row.narrow_tests_per_frame = narrows / frames;
    row.passes_per_frame = static_cast<double>(response->totals().passes) / frames;
  }
  row.response_ms_median = Median(per_substep_ms);
  row.response_ms_p99 = Percentile(per_substep_ms, 99);
  row.frame_ms_median = Median(frame_ms);
  row.frame_ms = frame_ms;
  row.detect_ms = detect_ms;
  row.pairs_per_frame = pairs / frames;
  row.impulses_per_frame = impulses / frames;
  row.zones_per_frame = zones / frames;
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

// "off" then each culling method of the comma-separated `text` (option `option`, for the error).
std::vector<std::string> ParseSelfMethods(const std::string& text, const std::string& option) {
  std::vector<std::string> methods = {"off"};
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    if (!SelfCullingMethodFromName(item)) {
      throw std::invalid_argument(option + ": unknown culling method '" + item + "'");
    }
    methods.push_back(item);
  }
  return methods;
}

// The scene a case reads unless --scene names another.
std::string DefaultSelfScene(const std::string& case_name) {
  return case_name == "curtain" ? "scenes/curtain.toml" : "scenes/self_fold_drop.toml";
}

std::string SelfCommand(const Args& args) {
  std::string cmd = "felt bench self-collision";
  if (args.quick) cmd += " --quick";
  if (args.grids != "32,64,128") cmd += " --grids " + args.grids;
  if (args.frames != 90) cmd += " --frames " + std::to_string(args.frames);
  if (args.case_name != "fold_drop") cmd += " --case " + args.case_name;
  if (args.scene != DefaultSelfScene(args.case_name)) cmd += " --scene " + args.scene;
  if (args.out != "bench/results") cmd += " --out " + args.out;
  if (args.detect_grid != 150) cmd += " --detect-grid " + std::to_string(args.detect_grid);
  if (args.detect_frames != 60) cmd += " --detect-frames " + std::to_string(args.detect_frames);
  const Args defaults;
  if (args.passes_per_frame != defaults.passes_per_frame) {
    cmd += " --passes-per-frame " + std::to_string(args.passes_per_frame);
  }
  if (args.broad_inflation != defaults.broad_inflation)
    cmd += " --broad-inflation " + Sig(args.broad_inflation, 3);
  if (args.max_pass_motion != defaults.max_pass_motion)
    cmd += " --max-pass-motion " + Sig(args.max_pass_motion, 3);
  if (args.min_passes_per_frame != defaults.min_passes_per_frame) {
    cmd += " --min-passes-per-frame " + std::to_string(args.min_passes_per_frame);
  }
  if (args.slow_pass_motion != defaults.slow_pass_motion)
    cmd += " --slow-pass-motion " + Sig(args.slow_pass_motion, 3);
  if (args.hand_pass_motion != defaults.hand_pass_motion)
    cmd += " --hand-pass-motion " + Sig(args.hand_pass_motion, 3);
  if (args.methods != "spatial_hash,bvh,bvox_aabb,apccd,bvh_cones")
    cmd += " --methods " + args.methods;
  if (args.detect_methods != "bvh_cones") cmd += " --detect-methods " + args.detect_methods;
  if (!args.reference) cmd += " --no-reference";
  if (!args.json.empty()) cmd += " --json " + args.json;
  return cmd;
}

int Run(Args args) {
  if (args.quick) {
    args.grids = "16";
    args.frames = 20;
    args.detect_grid = 0;
  }
  const MachineInfo machine = ReadMachineInfo();
  const std::string cmd = SelfCommand(args);
  std::printf("%s\nload average %s\n", cmd.c_str(), machine.load_average.c_str());
  std::vector<Row> rows;
  const auto run = [&](int32_t grid, const std::string& method, int32_t frames, int32_t every,
                       int32_t reference_every, const char* kind) {
    // Timed without the all-pairs reference, whose O(T^2) sweeps between frames would evict
    // the response's data from the caches (at 64 x 64 it added about 0.3 ms of detection per
    // frame); the reference then runs on a second, identical run (the step is deterministic).
    Row r = RunSelfBench(args, grid, method, frames, every, 0);
    if (reference_every > 0 && method != "off") {
      const Row ref = RunSelfBench(args, grid, method, frames, every, reference_every);
      if (ref.impulses_per_frame != r.impulses_per_frame) {
        std::fprintf(stderr, "warning: %s %d: the reference run's impulses differ\n",
                     method.c_str(), grid);
      }
      r.missed_vs_reference = ref.missed_vs_reference;
      r.reference_hits = ref.reference_hits;
      r.reference_frames = ref.reference_frames;
    }
    r.kind = kind;
    std::printf(
        "%-9s %-13s %4d: detect %.3f ms/frame (first %.3f), frame %.2f ms, intersections %lld, "
        "missed %lld of %lld (%d frames)\n",
        kind, method.c_str(), grid, r.detect_ms_median, r.first_detect_ms_median, r.frame_ms_median,
        static_cast<long long>(r.intersections_max), static_cast<long long>(r.missed_vs_reference),
        static_cast<long long>(r.reference_hits), r.reference_frames);
    std::fflush(stdout);
    rows.push_back(r);
  };
  const std::vector<std::string> methods = ParseSelfMethods(args.methods, "--methods");
  for (const int32_t grid : ParseSelfGrids(args.grids)) {
    for (const std::string& method : methods) {
      const int32_t every = grid <= 64 ? 1 : 10;
      run(grid, method, args.frames, every, args.reference ? every : 0, "response");
    }
  }
  if (args.detect_grid > 0) {
    // The ~45k-triangle cloth (002's sizes) for the detection target (--detect-methods), the
    // exact count every 10th frame, the reference every 20th.
    for (const std::string& method : ParseSelfMethods(args.detect_methods, "--detect-methods")) {
      run(args.detect_grid, method, args.detect_frames, 10, args.reference ? 20 : 0, "detection");
    }
  }
  const std::string load_end = LoadAverage();
  const std::vector<std::string> header = {"kind",
                                           "method",
                                           "grid",
                                           "triangles",
                                           "thickness_mm",
                                           "substeps",
                                           "passes_per_frame",
                                           "detect_ms_median",
                                           "detect_ms_p99",
                                           "first_detect_ms_median",
                                           "response_ms_per_frame_median",
                                           "frame_ms_median",
                                           "frame_ratio_vs_off",
                                           "intersections_max",
                                           "frames_counted",
                                           "missed_vs_reference",
                                           "reference_hits",
                                           "reference_frames",
                                           "broad_phases_per_frame",
                                           "broad_reuses_per_frame",
                                           "broad_updates_per_frame",
                                           "narrow_tests_per_frame",
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
    const double response_ms = r.response_ms_median * r.substeps;
    table.push_back({r.kind,
                     r.method,
                     std::to_string(r.grid),
                     std::to_string(r.triangles),
                     on ? Sig(1e3 * r.thickness_m, 3) : "-",
                     std::to_string(r.substeps),
                     on ? Sig(r.passes_per_frame, 3) : "-",
                     on ? Sig(r.detect_ms_median, 3) : "-",
                     on ? Sig(r.detect_ms_p99, 3) : "-",
                     on ? Sig(r.first_detect_ms_median, 3) : "-",
                     on ? Sig(response_ms, 3) : "-",
                     Sig(r.frame_ms_median, 3),
                     Sig(r.frame_ms_median / off_ms, 3),
                     std::to_string(r.intersections_max),
                     std::to_string(r.frames_counted),
                     on ? std::to_string(r.missed_vs_reference) : "-",
                     on ? std::to_string(r.reference_hits) : "-",
                     on ? std::to_string(r.reference_frames) : "-",
                     on ? Sig(r.broad_phases_per_frame, 3) : "-",
                     on ? Sig(r.broad_reuses_per_frame, 3) : "-",
                     on ? Sig(r.broad_updates_per_frame, 3) : "-",
                     on ? Sig(r.narrow_tests_per_frame, 4) : "-",
                     on ? Sig(r.pairs_per_frame, 4) : "-",
                     on ? Sig(r.impulses_per_frame, 4) : "-",
                     on ? Sig(r.zones_per_frame, 3) : "-",
                     std::to_string(r.frozen_substeps),
                     std::to_string(r.unresolved_substeps),
                     std::to_string(r.overflows)});
    Json item{{"kind", r.kind},
              {"method", r.method},
              {"case", args.case_name},
              {"grid", r.grid},
              {"triangles", r.triangles},
              {"thickness_m", r.thickness_m},
              {"substeps", r.substeps},
              {"frame_ms_median", r.frame_ms_median},
              {"frame_ratio_vs_off", r.frame_ms_median / off_ms},
              {"intersections_end_of_frame", r.intersections_max},
              {"frames_counted", r.frames_counted},
              {"proximity_pairs_per_frame", r.pairs_per_frame},
              {"impulses_per_frame", r.impulses_per_frame},
              {"impact_zones_per_frame", r.zones_per_frame},
              {"frozen_substeps", r.frozen_substeps},
              {"unresolved_substeps", r.unresolved_substeps},
              {"overflows", r.overflows}};
    if (on) {
      item["passes_per_frame"] = r.passes_per_frame;
      item["detect_ms_median"] = r.detect_ms_median;
      item["detect_ms_p99"] = r.detect_ms_p99;
      item["first_detect_ms_median"] = r.first_detect_ms_median;
      item["response_ms_per_frame_median"] = response_ms;
      item["missed_vs_reference"] = r.missed_vs_reference;
      item["extra_vs_reference"] = r.extra_vs_reference;
      item["reference_hits"] = r.reference_hits;
      item["reference_frames"] = r.reference_frames;
      item["broad_phases_per_frame"] = r.broad_phases_per_frame;
      item["broad_reuses_per_frame"] = r.broad_reuses_per_frame;
      item["broad_updates_per_frame"] = r.broad_updates_per_frame;
      item["narrow_tests_per_frame"] = r.narrow_tests_per_frame;
    } else {
      // No detection without [self_collision]: the fields are there, null.
      item["detect_ms_median"] = nullptr;
      item["missed_vs_reference"] = nullptr;
    }
    items.push_back(item);
  }
  std::vector<bool> right(header.size(), true);
  right[0] = false;
  const std::string md_table = MarkdownTable(header, right, table);
  std::printf("\n%s", md_table.c_str());
  std::string md =
      ReportHeader("Self-collision response (`felt bench self-collision`)", cmd, machine, load_end);
  const std::string case_text =
      args.case_name == "curtain"
          ? "Case `curtain`: " + args.scene +
                " resized to grid x grid particles over its own 0.496 m square (as `felt bench "
                "cloth`), hanging from its two top corners and released from rest in its plane "
                "(it stays in that plane, swinging and crumpling there below its top edge), "
          : "Case `fold_drop`: " + args.scene +
                " resized to grid x grid particles over a 0.3 m square (0.17 kg/m^2, leaning 0.3 "
                "rad, released 1.6 cm above the floor; it piles up in folds), ";
  md +=
      case_text + std::to_string(args.frames) +
      " frames of 1/60 s (`response` rows; the `detection` rows, the ~45k-triangle cloth of "
      "issue 22's 4 ms detection target, " +
      std::to_string(args.detect_frames) +
      " frames), thickness min(2 mm, spacing / 4). `off` is the same scene without "
      "[self_collision]. Self-collision passes per frame, each over the motion of "
      "ceil(substeps / passes) substeps or fewer (a pass moves the fastest particle at most "
      "max_pass_motion thicknesses with --max-pass-motion; the scenes' default, and this "
      "bench's, is no cap), or up to ceil(substeps / min_passes_per_frame) substeps in a frame "
      "after one without contact, while the fastest particle moves at most slow_pass_motion "
      "thicknesses per pass (defaults 2 and 4; with a hand, which these cases do not have, "
      "hand_pass_motion, measured): `passes_per_frame`, the mean. "
      "`detect_ms`: wall "
      "time per frame in detection (broad phases, box filter, continuous pair tests of every "
      "CCD and impact-zone round; SelfCollisionStats::detect_s), median and p99 over frames; "
      "`first_detect_ms`: the first CCD detection alone (all candidates). "
      "`response_ms_per_frame`: the whole response per frame (median of the frame's response "
      "time / substeps, times the substeps). `intersections_max`: the most intersecting "
      "non-adjacent triangle pairs at the end of a counted frame, exact test "
      "(collision/self_intersection.h); `frames_counted` frames were checked (all up to 64 x 64, "
      "every 10th above). `missed_vs_reference`: colliding pairs that AllPairsCcd (no culling) "
      "reports on the motion of the first CCD detection of a checked frame and the culled "
      "detection did not, summed over `reference_frames` frames (every frame up to 64 x 64, every "
      "10th above, every 20th in the detection rows), out of `reference_hits`, counted on a "
      "second run of the same (deterministic) frames so that the reference's sweeps stay out of "
      "the timed run's caches. One timed run; medians.\n\n" +
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
  // The cost of every frame over the animation (002's figures): one CSV row per run and frame,
  // then the plot of it.
  std::string host = machine.cpu_model;
  std::replace(host.begin(), host.end(), ',', ' ');
  std::string frames_csv = "kind,method,grid,frame,frame_ms,detect_ms,case,host\n";
  for (const Row& r : rows) {
    for (size_t f = 0; f < r.frame_ms.size(); ++f) {
      frames_csv += r.kind + "," + r.method + "," + std::to_string(r.grid) + "," +
                    std::to_string(f) + "," + Sig(r.frame_ms[f], 4) + "," +
                    (f < r.detect_ms.size() ? Sig(r.detect_ms[f], 4) : std::string("NaN")) + "," +
                    args.case_name + "," + host + "\n";
    }
  }
  const std::string frames_path = args.out + "/self_collision_frames.csv";
  WriteTextFile(frames_path, frames_csv);
  std::printf("wrote %s\n", frames_path.c_str());
  if (args.plot) {
    const std::string png = args.out + "/self_collision.png";
    const std::string command =
        "gnuplot -e \"csv='" + frames_path + "'; png='" + png + "'\" " + args.gnuplot_script;
    if (report::RunGnuplot("felt bench self-collision", command, png) ==
        report::GnuplotOutcome::kFailed) {
      return 1;
    }
  }
  return 0;
}

app::CommandRun SelfSetup(CLI::App& cmd) {
  auto args = std::make_shared<Args>();
  cmd.add_option("--grids", args->grids, "comma-separated grid sizes")->capture_default_str();
  cmd.add_option("--frames", args->frames, "frames per run")->check(CLI::Range(1, 100000));
  cmd.add_option("--case", args->case_name,
                 "fold_drop (the fold-drop scene on a 0.3 m square) or curtain (the haptic "
                 "curtain hanging from its top corners)")
      ->check(CLI::IsMember({"fold_drop", "curtain"}))
      ->capture_default_str();
  auto* scene = cmd.add_option("--scene", args->scene,
                               "the case's scene (default scenes/self_fold_drop.toml, or "
                               "scenes/curtain.toml with --case curtain)");
  cmd.add_option("--out", args->out, "folder for self_collision.{md,csv}")->capture_default_str();
  cmd.add_option("--json", args->json, "JSON output file (default <out>/self_collision.json)");
  cmd.add_option("--detect-grid", args->detect_grid,
                 "grid of the ~45k-triangle detection row (0: none)")
      ->capture_default_str();
  cmd.add_option("--detect-frames", args->detect_frames, "frames of the detection row")
      ->check(CLI::Range(1, 100000));
  cmd.add_option("--passes-per-frame", args->passes_per_frame,
                 "self-collision passes per frame (SelfCollisionSettings::passes_per_frame)")
      ->check(CLI::Range(1, 1000));
  cmd.add_option("--max-pass-motion", args->max_pass_motion,
                 "cap on a pass's motion, in thicknesses at the fastest particle (0: none)")
      ->check(CLI::Range(0.0, 1000.0));
  cmd.add_option(
         "--min-passes-per-frame", args->min_passes_per_frame,
         "fewest passes of a quiet, slow frame (SelfCollisionSettings::min_passes_per_frame;"
         " >= --passes-per-frame: off)")
      ->check(CLI::Range(1, 1000));
  cmd.add_option("--slow-pass-motion", args->slow_pass_motion,
                 "a quiet frame's longer passes move the fastest particle at most this many "
                 "thicknesses (0: off)")
      ->check(CLI::Range(0.0, 1000.0));
  cmd.add_option("--hand-pass-motion", args->hand_pass_motion,
                 "with a hand on a quiet cloth, a pass moves the fastest particle at most this "
                 "many thicknesses (0: the count's passes; the bench's cases have no hand)")
      ->check(CLI::Range(0.0, 1000.0));
  cmd.add_option("--broad-inflation", args->broad_inflation,
                 "extra broad-phase padding, in thicknesses (0: a broad phase every pass)")
      ->check(CLI::Range(0.0, 100.0));
  cmd.add_option("--methods", args->methods, "culling methods of the response rows")
      ->capture_default_str();
  cmd.add_option("--detect-methods", args->detect_methods, "culling methods of the detection row")
      ->capture_default_str();
  cmd.add_flag("!--no-reference", args->reference,
               "skip the all-pairs reference (profiling; missed_vs_reference is not measured)");
  cmd.add_flag("!--no-plot", args->plot, "do not run gnuplot (the frames' CSV is still written)");
  cmd.add_option("--gnuplot-script", args->gnuplot_script, "the plot's gnuplot script")
      ->capture_default_str();
  cmd.add_flag("--quick", args->quick, "grid 16, 20 frames (seconds; for CI): not a result");
  return [args, scene]() {
    if (scene->count() == 0) args->scene = DefaultSelfScene(args->case_name);
    return Run(*args);
  };
}

const bool kRegistered = app::RegisterCommand(
    {"bench", "self-collision",
     "self-collision response cost and intersections per culling method and size (issue 22)",
     SelfSetup});

}  // namespace
}  // namespace felt::bench::bench_self_collision
