#pragma once
// `felt bench cloth --tradeoff` (issue 21): frame cost against max structural stretch for each
// method and setting of Felt's solver that the scene keys express, and for Bullet's btSoftBody
// (bench/bullet_peer.h) with its iterations swept, on the default curtain resized to each grid
// (ResizedCurtain). Writes <out>/cloth_tradeoff.{md,csv,json} and, with gnuplot,
// <out>/cloth_tradeoff.png (bench/cloth_tradeoff.gp). Not real-time safe.
//
// A point: one setting on one grid. The curtain is released from rest and stepped
// `settle_frames` + `frames` frames of 1/60 s; every frame is timed (wall clock and this thread's
// CPU time), the frame cost is the median over the last `frames` (the settled cloth), as in
// `felt bench cloth`. Release stretch: the largest structural length / rest length after any
// frame (the release transient included); settled stretch: the same over the last `frames` only.
//
// "Felt below Bullet" (JudgeBelow): Felt's curve on a grid is the lower-left front of its judged
// points (FeltFront). A Bullet point (c, s) is below-met when a measured Felt point costs <= c
// with stretch <= s ("measured"), or else when the straight line between the two front points
// around c, in (log10 cost, stretch), passes at or under s at c ("interpolated"); "no" when
// neither, including when every Felt point costs more than c. The target holds when every
// judged Bullet point of every grid is met, for the release and the settled stretch alike.

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "base/json.h"
#include "sim_loop/cloth_spec.h"

namespace felt::bench {

/// A point on the speed-against-stretch axes.
struct CostStretch {
  double cost_ms = 0.0;  ///< frame cost, ms
  double stretch = 1.0;  ///< max structural length / rest length
};

/// The points of `points` that no other point beats on both axes (cost <= and stretch <=, one of
/// them strictly), sorted by cost ascending (so stretch descending). Points with a non-finite
/// coordinate are left out.
std::vector<CostStretch> FeltFront(std::span<const CostStretch> points);

/// How a Bullet point is judged against Felt's front.
enum class BelowBy {
  kMeasured,      ///< a measured Felt point is at most as costly and at most as stretched
  kInterpolated,  ///< the front's interpolation at the Bullet point's cost is at most as stretched
  kNo,            ///< neither (or Felt has no point as cheap)
};

/// "measured", "interpolated" or "no".
const char* BelowByName(BelowBy by);

/// The judgement of one Bullet point against Felt's front (file comment).
struct BelowVerdict {
  BelowBy by = BelowBy::kNo;
  /// Felt's front at the Bullet point's cost: the measured stretch of the costliest front point
  /// not costlier (kMeasured), the interpolated stretch (kInterpolated), NaN when Felt has no
  /// point as cheap.
  double felt_stretch = 0.0;
  /// The cheapest Felt front point with stretch <= the Bullet point's, ms (NaN when none): speed at
  /// equal stretch.
  double felt_cost_at_stretch_ms = 0.0;
};

/// Judges `bullet` against `front` (FeltFront's output: sorted by cost, stretch descending).
BelowVerdict JudgeBelow(std::span<const CostStretch> front, CostStretch bullet);

/// Whether a Bullet point counts in the judgement: finite, and no structural link longer than the
/// whole side of the curtain (stretch <= grid - 1: a cloth that came apart is not on the curve).
bool BulletPointJudged(int32_t grid, double release_stretch, double settled_stretch);

/// One Felt setting: the scene keys it overrides (0 keeps the scene's own value).
struct FeltSetting {
  std::string curve;            ///< curve id, e.g. "felt_substeps"
  int32_t substeps = 0;         ///< integration.substeps; 0 = the scene's ("auto")
  int32_t sweeps = 0;           ///< provot.iterations; 0 = the scene's
  double max_elongation = 0.0;  ///< provot.max_elongation; 0 = the scene's
  /// provot.finish = false and provot.sweep_headroom = 0: Provot's sweeps alone, without the
  /// finishing worklist (the limiter before issue 21's worklist)
  bool sweeps_alone = false;
};

/// What `felt bench cloth --tradeoff` runs and where it writes (bench/bench_cloth.cc parses it).
struct TradeoffOptions {
  std::vector<int32_t> grids = {32, 64, 128};
  std::string scene = "scenes/curtain.toml";
  std::string out = "bench/results";
  std::string json;  ///< "" = <out>/cloth_tradeoff.json
  int32_t settle_frames = 120;
  int32_t frames = 120;
  /// A point whose projected run time (frames run so far, their median cost) exceeds this is
  /// stopped and reported over budget; a Bullet curve runs no more iterations after one is.
  double point_budget_s = 45.0;
  std::vector<int32_t> substeps = {3, 6, 12, 24, 48};         ///< with the scene's sweeps
  std::vector<int32_t> sweeps = {1, 3, 10, 40};               ///< with auto substeps
  std::vector<int32_t> small_steps = {3, 6, 12, 24, 48, 96};  ///< substeps with 1 sweep
  /// Provot's limit, with auto substeps and the scene's sweeps (Felt's stretch sits near 1 + the
  /// limit, so only a tighter limit reaches below it).
  std::vector<double> limits = {0.05, 0.02, 0.01};
  /// Provot's sweeps alone (no finishing worklist, no headroom), with auto substeps.
  std::vector<int32_t> sweeps_alone = {1, 3, 10};
  std::vector<int32_t> bullet_iterations = {1, 2, 5, 10, 20, 50, 100, 300};
  bool bullet = true;  ///< false: --no-bullet
  std::string gnuplot_script = "bench/cloth_tradeoff.gp";
  bool plot = true;
  std::string command;  ///< the command line, for the report's header
};

/// The Felt settings of `options` on a scene whose own sweeps are `scene_sweeps`, in run order:
/// the substep sweep (scene sweeps), the Provot sweep (auto substeps; the scene's own count
/// always among them: the shipped setting), the small steps (1 sweep), the tighter limits (auto
/// substeps, scene sweeps), the sweeps alone (auto substeps, FeltSetting::sweeps_alone).
/// Duplicates are dropped.
std::vector<FeltSetting> FeltSettings(const TradeoffOptions& options, int32_t scene_sweeps);

/// Runs the benchmark and writes its files (file comment). Returns 0; throws
/// std::invalid_argument for bad options, SceneError for a bad scene.
int RunClothTradeoff(const TradeoffOptions& options);

}  // namespace felt::bench
