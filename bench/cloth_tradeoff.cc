#include "bench/cloth_tradeoff.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <set>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "base/gnuplot.h"
#include "bench/bench_util.h"
#include "bench/bullet_peer.h"
#include "sim_loop/cloth.h"

namespace felt::bench {

// ---------------------------------------------------------------------------------------------
// The judgement (pure).

std::vector<CostStretch> FeltFront(std::span<const CostStretch> points) {
  std::vector<CostStretch> sorted;
  for (const CostStretch& p : points) {
    if (std::isfinite(p.cost_ms) && std::isfinite(p.stretch)) sorted.push_back(p);
  }
  // Cheapest first, the least stretched first among equal costs; keep each point that stretches
  // strictly less than every cheaper one.
  std::sort(sorted.begin(), sorted.end(), [](const CostStretch& a, const CostStretch& b) {
    return a.cost_ms != b.cost_ms ? a.cost_ms < b.cost_ms : a.stretch < b.stretch;
  });
  std::vector<CostStretch> front;
  for (const CostStretch& p : sorted) {
    if (front.empty() || p.stretch < front.back().stretch) front.push_back(p);
  }
  return front;
}

const char* BelowByName(BelowBy by) {
  switch (by) {
    case BelowBy::kMeasured:
      return "measured";
    case BelowBy::kInterpolated:
      return "interpolated";
    case BelowBy::kNo:
      return "no";
  }
  return "no";
}

BelowVerdict JudgeBelow(std::span<const CostStretch> front, CostStretch bullet) {
  BelowVerdict v;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  v.felt_stretch = nan;
  v.felt_cost_at_stretch_ms = nan;
  // Speed at equal stretch: the cheapest front point at most as stretched.
  for (const CostStretch& p : front) {
    if (p.stretch <= bullet.stretch) {
      v.felt_cost_at_stretch_ms = p.cost_ms;
      break;
    }
  }
  // The costliest front point not costlier than the Bullet point: the least stretched of them.
  size_t below = front.size();
  for (size_t i = 0; i < front.size() && front[i].cost_ms <= bullet.cost_ms; ++i) below = i;
  if (below == front.size()) return v;  // Felt has no point this cheap
  v.felt_stretch = front[below].stretch;
  if (front[below].stretch <= bullet.stretch) {
    v.by = BelowBy::kMeasured;
    return v;
  }
  // Between it and the next front point, on a line in (log10 cost, stretch).
  if (below + 1 < front.size()) {
    const CostStretch& a = front[below];
    const CostStretch& b = front[below + 1];
    const double t = (std::log10(bullet.cost_ms) - std::log10(a.cost_ms)) /
                     (std::log10(b.cost_ms) - std::log10(a.cost_ms));
    v.felt_stretch = a.stretch + t * (b.stretch - a.stretch);
    if (v.felt_stretch <= bullet.stretch) v.by = BelowBy::kInterpolated;
  }
  return v;
}

bool BulletPointJudged(int32_t grid, double release_stretch, double settled_stretch) {
  const double side = grid - 1;
  return std::isfinite(release_stretch) && std::isfinite(settled_stretch) &&
         release_stretch <= side && settled_stretch <= side;
}

std::vector<FeltSetting> FeltSettings(const TradeoffOptions& options, int32_t scene_sweeps) {
  std::vector<FeltSetting> settings;
  std::set<std::tuple<int32_t, int32_t, double, bool>> seen;
  const auto add = [&](const char* curve, int32_t substeps, int32_t sweeps, double limit,
                       bool alone = false) {
    if (seen.insert({substeps, sweeps, limit, alone}).second) {
      settings.push_back({curve, substeps, sweeps, limit, alone});
    }
  };
  for (const int32_t n : options.substeps) add("felt_substeps", n, scene_sweeps, 0.0);
  std::vector<int32_t> sweeps = options.sweeps;
  if (std::find(sweeps.begin(), sweeps.end(), scene_sweeps) == sweeps.end()) {
    sweeps.push_back(scene_sweeps);
    std::sort(sweeps.begin(), sweeps.end());
  }
  for (const int32_t k : sweeps) add("felt_sweeps", 0, k, 0.0);
  for (const int32_t n : options.small_steps) add("felt_small_steps", n, 1, 0.0);
  for (const double e : options.limits) add("felt_limit", 0, scene_sweeps, e);
  for (const int32_t k : options.sweeps_alone) add("felt_sweeps_alone", 0, k, 0.0, true);
  return settings;
}

// ---------------------------------------------------------------------------------------------
// The run.

namespace {

constexpr double kRatioTarget = 0.3;  // Felt's 64 x 64 frame / Bullet's 10-iteration step
constexpr int32_t kRatioGrid = 64;
constexpr int32_t kRatioIterations = 10;

// The curves, in plot order: id and title.
struct CurveInfo {
  const char* id;
  const char* title;
};
constexpr CurveInfo kCurves[] = {
    {"felt_substeps", "Felt: substeps swept, the scene's Provot sweeps"},
    {"felt_sweeps", "Felt: Provot sweeps swept, auto substeps"},
    {"felt_small_steps", "Felt: small steps (substeps swept, 1 sweep)"},
    {"felt_limit", "Felt: tighter Provot limit (auto substeps, the scene's sweeps)"},
    {"felt_sweeps_alone",
     "Felt: Provot sweeps alone, swept (no finishing worklist, no headroom; auto substeps)"},
    {"bullet_bending", "Bullet: piterations swept, bending links (kLST 1)"},
    {"bullet_links", "Bullet: piterations swept, no bending links"},
};

const char* CurveTitle(const std::string& id) {
  for (const CurveInfo& c : kCurves) {
    if (id == c.id) return c.title;
  }
  return "?";
}

// One point: a setting on a grid, with what it measured.
struct Point {
  std::string peer;   // "felt" or "bullet"
  std::string curve;  // kCurves id
  int32_t grid = 0;
  std::string keys;             // Felt: the scene keys overridden; Bullet: its settings
  int32_t substeps = 0;         // Felt: resolved substeps per frame
  int32_t iterations = 0;       // Felt: Provot sweeps per substep; Bullet: piterations
  bool shipped = false;         // Felt: the scene's own settings
  int64_t links = 0;            // Bullet: links solved
  std::vector<double> wall_ms;  // the timed (settled) frames
  std::vector<double> cpu_ms;
  double release = 1.0;  // max stretch over every frame
  double settled = 1.0;  // over the timed frames
  uint64_t nan_events = 0;
  int32_t frames_run = 0;
  std::string status = "ok";  // ok, over budget, not run, non-finite, nan events
  double projected_s = std::numeric_limits<double>::quiet_NaN();  // over budget: projected time
  double probe_ms = std::numeric_limits<double>::quiet_NaN();  // over budget: median frame so far
  bool judged = false;
  BelowVerdict release_verdict;
  BelowVerdict settled_verdict;

  double wall_median() const { return Median(wall_ms); }
  double cpu_median() const { return Median(cpu_ms); }
  CostStretch release_point() const { return {wall_median(), release}; }
  CostStretch settled_point() const { return {wall_median(), settled}; }
};

// Steps `step` settle + timed frames, timing each; measures `stretch` after each. Stops when the
// projected run time exceeds the budget (status "over budget") or the stretch is not finite.
template <typename Step, typename Stretch>
void RunFrames(const TradeoffOptions& o, Step&& step, Stretch&& stretch, Point* p) {
  const int32_t total = o.settle_frames + o.frames;
  std::vector<double> all_ms;
  all_ms.reserve(static_cast<size_t>(total));
  p->wall_ms.reserve(static_cast<size_t>(o.frames));
  p->cpu_ms.reserve(static_cast<size_t>(o.frames));
  const double start_ms = WallMs();
  for (int32_t f = 0; f < total; ++f) {
    const double cpu0 = ThreadCpuMs();
    const double wall0 = WallMs();
    step();
    const double wall1 = WallMs();
    const double cpu1 = ThreadCpuMs();
    all_ms.push_back(wall1 - wall0);
    if (f >= o.settle_frames) {
      p->wall_ms.push_back(wall1 - wall0);
      p->cpu_ms.push_back(cpu1 - cpu0);
    }
    p->frames_run = f + 1;
    const double s = stretch();
    if (!std::isfinite(s)) {
      p->release = p->settled = std::numeric_limits<double>::quiet_NaN();
      p->status = "non-finite";
      return;
    }
    p->release = std::max(p->release, s);
    if (f >= o.settle_frames) p->settled = std::max(p->settled, s);
    // The budget, from the third frame on: time so far + the rest at the median so far.
    if (f + 1 >= 3 && f + 1 < total) {
      const double projected_s =
          (WallMs() - start_ms) / 1000.0 + (total - f - 1) * Median(all_ms) / 1000.0;
      if (projected_s > o.point_budget_s) {
        p->status = "over budget";
        p->projected_s = projected_s;
        p->probe_ms = Median(all_ms);
        return;
      }
    }
  }
}

// Appends "; " (unless `text` is empty), then `part`. (Appending piece by piece also keeps GCC 12's
// false -Wstringop-overflow on `const char* + std::string&&` away; it broke a unity batch.)
void AppendPart(const std::string& part, std::string* text) {
  if (!text->empty()) text->append("; ");
  text->append(part);
}

std::string FeltKeys(const FeltSetting& s) {
  std::string keys;
  if (s.substeps > 0) AppendPart("integration.substeps=" + std::to_string(s.substeps), &keys);
  if (s.sweeps > 0) AppendPart("provot.iterations=" + std::to_string(s.sweeps), &keys);
  if (s.max_elongation > 0.0) {
    AppendPart("provot.max_elongation=" + Sig(s.max_elongation, 6), &keys);
  }
  if (s.sweeps_alone) AppendPart("provot.finish=false; provot.sweep_headroom=0", &keys);
  return keys.empty() ? "(the scene's own)" : keys;
}

Point RunFelt(const TradeoffOptions& o, int32_t grid, const FeltSetting& setting,
              int32_t scene_sweeps) {
  SimSpec spec = ResizedCurtain(o.scene, grid);
  if (setting.substeps > 0) spec.integration.substeps = setting.substeps;
  if (setting.sweeps > 0) spec.provot.iterations = setting.sweeps;
  if (setting.max_elongation > 0.0) spec.provot.max_elongation = setting.max_elongation;
  if (setting.sweeps_alone) {
    spec.provot.finish = false;
    spec.provot.sweep_headroom = 0.0;
  }
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  Point p;
  p.peer = "felt";
  p.curve = setting.curve;
  p.grid = grid;
  p.keys = FeltKeys(setting);
  p.substeps = model.substeps;
  p.iterations = model.provot_iterations;
  p.shipped = setting.substeps == 0 && setting.max_elongation == 0.0 && !setting.sweeps_alone &&
              (setting.sweeps == 0 || setting.sweeps == scene_sweeps);
  if (p.shipped)
    p.keys =
        "(the scene's own: auto substeps; provot.iterations=" + std::to_string(scene_sweeps) + ")";
  const double frame_dt_s = 1.0 / spec.integration.frame_rate_hz;
  const std::span<const ExternalForce> none;
  RunFrames(
      o, [&] { StepFrame(model, none, frame_dt_s, &state); },
      [&] { return MaxStretch(model, state); }, &p);
  p.nan_events = state.counters.nan_events;
  if (p.status == "ok" && p.nan_events > 0) p.status = "nan events";
  return p;
}

std::string BulletKeys(bool bending, int32_t iterations) {
  return "m_cfg.piterations=" + std::to_string(iterations) +
         (bending ? "; bending links kLST=1" : "; no bending links");
}

Point RunBullet(const TradeoffOptions& o, int32_t grid, bool bending, int32_t iterations) {
  const SimSpec spec = ResizedCurtain(o.scene, grid);
  const BulletCurtainSpec bspec = BulletCurtainFromSim(spec, iterations, bending);
  BulletCurtain curtain(bspec);
  Point p;
  p.peer = "bullet";
  p.curve = bending ? "bullet_bending" : "bullet_links";
  p.grid = grid;
  p.keys = BulletKeys(bending, iterations);
  p.iterations = iterations;
  p.links = curtain.links();
  RunFrames(
      o, [&] { curtain.StepFrame(); }, [&] { return curtain.MaxStructuralStretch(); }, &p);
  return p;
}

void PrintPoint(const Point& p) {
  std::printf("grid %4d  %-16s %-58s %9.4f ms (cpu %9.4f)  release %9.4f  settled %9.4f  %s",
              p.grid, p.curve.c_str(), p.keys.c_str(), p.wall_median(), p.cpu_median(), p.release,
              p.settled, p.status.c_str());
  if (p.status == "over budget") {
    std::printf(" (%.1f ms/frame over %d frames, %.0f s projected)", p.probe_ms, p.frames_run,
                p.projected_s);
  }
  std::printf("\n");
  std::fflush(stdout);
}

// The judgement of every Bullet point of `grid` against Felt's fronts of that grid.
void Judge(int32_t grid, std::vector<Point>* points) {
  std::vector<CostStretch> release, settled;
  for (const Point& p : *points) {
    if (p.grid != grid || p.peer != "felt") continue;
    if (p.status != "ok") continue;
    release.push_back(p.release_point());
    settled.push_back(p.settled_point());
  }
  const std::vector<CostStretch> release_front = FeltFront(release);
  const std::vector<CostStretch> settled_front = FeltFront(settled);
  for (Point& p : *points) {
    if (p.grid != grid) continue;
    if (p.peer == "felt") {
      p.judged = p.status == "ok";
      continue;
    }
    p.judged = p.status == "ok" && BulletPointJudged(grid, p.release, p.settled);
    if (!p.judged) continue;
    p.release_verdict = JudgeBelow(release_front, p.release_point());
    p.settled_verdict = JudgeBelow(settled_front, p.settled_point());
  }
}

// The two targets here, judged from the points.
struct Targets {
  std::string ratio_text;  // one line per Bullet curve
  bool ratio_measured = false;
  bool ratio_met = true;
  std::string below_text;
  bool below_measured = false;
  bool below_met = true;
  Json json;
};

const Point* Find(const std::vector<Point>& points, int32_t grid, const std::string& curve,
                  int32_t iterations) {
  for (const Point& p : points) {
    if (p.grid == grid && p.curve == curve && p.iterations == iterations && p.status == "ok") {
      return &p;
    }
  }
  return nullptr;
}

Targets JudgeTargets(const std::vector<Point>& points, const TradeoffOptions& o) {
  Targets t;
  t.json = Json::object();
  // 1. Felt's shipped 64 x 64 frame <= 0.3 x Bullet's 10-iteration step, in this run.
  const Point* felt = nullptr;
  for (const Point& p : points) {
    if (p.grid == kRatioGrid && p.shipped && p.status == "ok") felt = &p;
  }
  Json ratio = Json::array();
  for (const char* curve : {"bullet_bending", "bullet_links"}) {
    const Point* bullet = Find(points, kRatioGrid, curve, kRatioIterations);
    std::string line = "- vs " + std::string(CurveTitle(curve)) + ", " +
                       std::to_string(kRatioIterations) + " iterations: ";
    if (felt == nullptr || bullet == nullptr) {
      line += "not measured (";
      line += felt == nullptr ? "no shipped Felt point at 64 x 64" : "";
      line += felt == nullptr && bullet == nullptr ? "; " : "";
      line += bullet == nullptr ? "no completed Bullet point at 64 x 64 with 10 iterations" : "";
      line += ")";
      ratio.push_back(Json{{"bullet_curve", curve}, {"measured", false}});
    } else {
      const double r = felt->wall_median() / bullet->wall_median();
      const double r_cpu = felt->cpu_median() / bullet->cpu_median();
      const bool met = r <= kRatioTarget;
      t.ratio_measured = true;
      t.ratio_met = t.ratio_met && met;
      line += "Felt " + Fixed(felt->wall_median(), 3) + " ms / Bullet " +
              Fixed(bullet->wall_median(), 3) + " ms = **" + Fixed(r, 3) + "** (cpu " +
              Fixed(r_cpu, 3) + "): " + (met ? "**met**" : "**missed**");
      ratio.push_back(Json{{"bullet_curve", curve},
                           {"measured", true},
                           {"felt_ms", felt->wall_median()},
                           {"bullet_ms", bullet->wall_median()},
                           {"ratio", r},
                           {"ratio_cpu", r_cpu},
                           {"met", met}});
    }
    t.ratio_text += line + "\n";
  }
  if (!t.ratio_measured) t.ratio_met = false;
  t.json["ratio_target"] = kRatioTarget;
  t.json["ratio"] = ratio;
  t.json["ratio_met"] = t.ratio_measured && t.ratio_met;

  // 2. Felt's curve below every judged Bullet point, release and settled.
  int judged = 0, met_release = 0, met_settled = 0;
  std::string misses;
  for (const Point& p : points) {
    if (p.peer != "bullet" || !p.judged) continue;
    ++judged;
    const bool r = p.release_verdict.by != BelowBy::kNo;
    const bool s = p.settled_verdict.by != BelowBy::kNo;
    met_release += r ? 1 : 0;
    met_settled += s ? 1 : 0;
    if (!r || !s) {
      const auto front = [](const BelowVerdict& v) {
        return std::isfinite(v.felt_stretch) ? Sig(v.felt_stretch, 4)
                                             : std::string("no Felt point this cheap");
      };
      misses += "  - grid " + std::to_string(p.grid) + ", " + p.curve + ", piterations " +
                std::to_string(p.iterations) + " (" + Fixed(p.wall_median(), 4) + " ms, release " +
                Sig(p.release, 4) + ", settled " + Sig(p.settled, 4) + "): missed on " +
                (!r && !s ? "both"
                 : !r     ? "release"
                          : "settled") +
                "; Felt's front at that cost: release " + front(p.release_verdict) + ", settled " +
                front(p.settled_verdict) + "\n";
    }
  }
  t.below_measured = judged > 0;
  t.below_met = t.below_measured && met_release == judged && met_settled == judged;
  if (!t.below_measured) {
    t.below_text = "- not measured (no judged Bullet point" +
                   std::string(o.bullet ? "" : ": --no-bullet") + ")\n";
  } else {
    t.below_text = "- " + std::to_string(judged) + " judged Bullet points; Felt below on release " +
                   std::to_string(met_release) + ", on settled " + std::to_string(met_settled) +
                   ": " + (t.below_met ? "**met**" : "**missed**") + "\n" + misses;
  }
  t.json["below_judged_points"] = judged;
  t.json["below_met_release"] = met_release;
  t.json["below_met_settled"] = met_settled;
  t.json["below_met"] = t.below_met;
  return t;
}

std::string VerdictCell(const Point& p, const BelowVerdict& v) {
  if (p.peer != "bullet") return "-";
  if (!p.judged) return "not judged";
  std::string cell = BelowByName(v.by);
  cell += std::isfinite(v.felt_stretch) ? " (Felt " + Fixed(v.felt_stretch, 4) + ")"
                                        : " (no Felt point this cheap)";
  return cell;
}

std::string EqualStretchCell(const Point& p) {
  if (p.peer != "bullet" || !p.judged) return "-";
  const double c = p.release_verdict.felt_cost_at_stretch_ms;
  if (!std::isfinite(c)) return "none";
  return Fixed(c, 3) + " ms (" + Sig(p.wall_median() / c, 3) + "x)";
}

std::string StatusCell(const Point& p) {
  if (p.status == "over budget") {
    return "over budget: " + Sig(p.probe_ms, 3) + " ms/frame over " + std::to_string(p.frames_run) +
           " frames, " + Sig(p.projected_s, 3) + " s projected";
  }
  if (p.status == "nan events") return "nan events: " + std::to_string(p.nan_events);
  if (p.peer == "bullet" && p.status == "ok" && !p.judged) return "came apart (not judged)";
  return p.status;
}

std::vector<std::string> MdRow(const Point& p) {
  const bool ran = p.status == "ok" || p.status == "nan events";
  return {"`" + p.curve + "`" + std::string(p.shipped ? " **(shipped)**" : ""),
          p.keys,
          p.peer == "felt" ? std::to_string(p.substeps) : "1",
          std::to_string(p.iterations),
          p.peer == "bullet" ? std::to_string(p.links) : "-",
          ran ? Fixed(p.wall_median(), 4) : "-",
          ran ? Fixed(p.cpu_median(), 4) : "-",
          ran ? Sig(p.release, 5) : "-",
          ran ? Sig(p.settled, 5) : "-",
          StatusCell(p),
          VerdictCell(p, p.release_verdict),
          VerdictCell(p, p.settled_verdict),
          EqualStretchCell(p)};
}

std::vector<std::string> CsvRow(const Point& p, const std::string& host) {
  const auto num = [](double v) { return std::isfinite(v) ? Sig(v, 8) : std::string("NaN"); };
  const bool ran = p.status == "ok" || p.status == "nan events";
  const bool bullet_judged = p.peer == "bullet" && p.judged;
  return {p.curve,
          std::to_string(p.grid),
          p.peer,
          p.keys,
          p.shipped ? "1" : "0",
          p.peer == "felt" ? std::to_string(p.substeps) : "1",
          std::to_string(p.iterations),
          std::to_string(p.links),
          std::to_string(p.frames_run),
          ran ? num(p.wall_median()) : "NaN",
          ran ? num(Percentile(p.wall_ms, 99)) : "NaN",
          ran ? num(p.cpu_median()) : "NaN",
          ran ? num(p.release) : "NaN",
          ran ? num(p.settled) : "NaN",
          std::to_string(p.nan_events),
          p.status,
          p.judged ? "1" : "0",
          bullet_judged ? BelowByName(p.release_verdict.by) : "",
          bullet_judged ? BelowByName(p.settled_verdict.by) : "",
          bullet_judged ? num(p.release_verdict.felt_cost_at_stretch_ms) : "NaN",
          host};
}

Json PointJson(const Point& p) {
  Json j{{"curve", p.curve},
         {"grid", p.grid},
         {"peer", p.peer},
         {"setting", p.keys},
         {"shipped", p.shipped},
         {"substeps", p.substeps},
         {"iterations", p.iterations},
         {"links", p.links},
         {"frames_run", p.frames_run},
         {"status", p.status},
         {"frame_ms_median", p.wall_median()},
         {"frame_ms_p99", Percentile(p.wall_ms, 99)},
         {"cpu_ms_median", p.cpu_median()},
         {"release_max_stretch", p.release},
         {"settled_max_stretch", p.settled},
         {"nan_events", static_cast<int64_t>(p.nan_events)},
         {"judged", p.judged}};
  if (p.status == "over budget") {
    j["probe_ms"] = p.probe_ms;
    j["projected_s"] = p.projected_s;
  }
  if (p.peer == "bullet" && p.judged) {
    j["release_below"] = BelowByName(p.release_verdict.by);
    j["release_felt_stretch"] = p.release_verdict.felt_stretch;
    j["settled_below"] = BelowByName(p.settled_verdict.by);
    j["settled_felt_stretch"] = p.settled_verdict.felt_stretch;
    j["felt_ms_at_release_stretch"] = p.release_verdict.felt_cost_at_stretch_ms;
  }
  return j;
}

// How the Bullet curtain was set up, from the spec it was given (the same for every grid but the
// grid, its spacing and its particle mass).
std::string BulletSetupText(const TradeoffOptions& o, int32_t grid) {
  const BulletCurtainSpec b = BulletCurtainFromSim(ResizedCurtain(o.scene, grid), 1, true);
  return "Bullet " + BulletVersionText() +
         " (Debian libbullet-dev), btSoftBody in a btSoftRigidDynamicsWorld "
         "(btSoftBodyRigidBodyCollisionConfiguration, btCollisionDispatcher, btDbvtBroadphase, "
         "btSequentialImpulseConstraintSolver, btDefaultSoftBodySolver) holding nothing else; one "
         "frame is `stepSimulation(1/60, 1, 1/60)`, checked to take exactly one internal step. "
         "The curtain: `btSoftBodyHelpers::CreatePatch` over the same four corners, N x N nodes "
         "(node index row * N + col, as Felt's), structural links and one diagonal link per cell "
         "(`gendiags = true`; Bullet's patch has no second diagonal, Felt has both), default "
         "material kLST = 1; the two top corners fixed (mass 0); every other node the mass of a "
         "Felt particle (0.1 kg / N^2, " +
         Sig(b.particle_mass_kg, 4) + " kg at " + std::to_string(grid) + " x " +
         std::to_string(grid) +
         "); gravity (0, -9.81, 0) m/s^2 in the soft body world "
         "info (Bullet's default is -10); Felt's drag as Bullet's velocity damping kDP = 1 - "
         "exp(-(c / m) dt) = " +
         Sig(b.velocity_damping, 4) +
         " (c / m the same at every grid); collision margin = the particle spacing; deactivation "
         "disabled. Default Positions solver preset; `m_cfg.piterations` swept as listed, "
         "`viterations` 0 (the Positions preset has no velocity solver to iterate), `diterations` "
         "0, `citerations` 4 (no clusters). Curve `bullet_bending`: plus "
         "`generateBendingConstraints(2, m)` with a second material of kLST = 1 (the stiffest: in "
         "a trial run at 64 x 64, not part of this table, it gave less stretch at equal cost than "
         "the 0.4 of Bullet's cloth demo); "
         "curve `bullet_links`: without. Bullet's stretch: the largest length / rest length over "
         "the structural links (grid neighbours along a row or a column), computed in double "
         "from its float nodes.";
}

// The plot: gnuplot if installed, else the command to run.
void Plot(const TradeoffOptions& o, const std::string& csv, const std::vector<int32_t>& grids) {
  const std::string png = o.out + "/cloth_tradeoff.png";
  std::string grid_words;
  for (const int32_t g : grids) {
    if (!grid_words.empty()) grid_words += ' ';
    grid_words += std::to_string(g);
  }
  const std::string command = "gnuplot -e \"csv='" + csv + "'; png='" + png + "'; grids='" +
                              grid_words + "'\" " + o.gnuplot_script;
  if (report::RunGnuplot("felt bench cloth --tradeoff", command, png) ==
      report::GnuplotOutcome::kFailed) {
    throw std::runtime_error("gnuplot failed: " + command);
  }
}

}  // namespace

int RunClothTradeoff(const TradeoffOptions& o) {
  // Every input is checked before anything runs.
  if (o.grids.empty()) throw std::invalid_argument("no grid to run");
  for (const int32_t g : o.grids) {
    if (g < 2) throw std::invalid_argument("grids must be >= 2, got " + std::to_string(g));
  }
  if (o.frames < 1) throw std::invalid_argument("--frames must be >= 1");
  if (o.settle_frames < 0) throw std::invalid_argument("--settle-frames must be >= 0");
  if (!(o.point_budget_s > 0.0)) throw std::invalid_argument("--point-budget-s must be > 0");
  for (const std::vector<int32_t>* list :
       {&o.substeps, &o.sweeps, &o.small_steps, &o.bullet_iterations}) {
    for (const int32_t n : *list) {
      if (n < 1) throw std::invalid_argument("substep, sweep and iteration counts must be >= 1");
    }
  }
  for (const double e : o.limits) {
    if (!(e > 0.0)) throw std::invalid_argument("Provot limits must be > 0");
  }
  const int32_t scene_sweeps = ResizedCurtain(o.scene, o.grids.front()).provot.iterations;
  const std::vector<FeltSetting> felt_settings = FeltSettings(o, scene_sweeps);
  const bool bullet = o.bullet && BulletAvailable();
  std::string bullet_note;
  if (!o.bullet) {
    bullet_note = "Bullet rows skipped: --no-bullet.";
  } else if (!BulletAvailable()) {
    bullet_note = "Bullet rows skipped: " + BulletMissingReason() + ".";
  }

  const MachineInfo machine = ReadMachineInfo();
  std::printf("%s\nload average %s\n", o.command.c_str(), machine.load_average.c_str());
  if (!bullet_note.empty()) std::printf("%s\n", bullet_note.c_str());
  std::fflush(stdout);

  // Every grid: Felt's settings, then Bullet's curves, each iteration count until one is over
  // budget.
  std::vector<Point> points;
  for (const int32_t grid : o.grids) {
    for (const FeltSetting& s : felt_settings) {
      points.push_back(RunFelt(o, grid, s, scene_sweeps));
      PrintPoint(points.back());
    }
    if (bullet) {
      for (const bool bending : {true, false}) {
        bool over = false;
        for (const int32_t it : o.bullet_iterations) {
          if (over) {
            Point p;
            p.peer = "bullet";
            p.curve = bending ? "bullet_bending" : "bullet_links";
            p.grid = grid;
            p.keys = BulletKeys(bending, it);
            p.iterations = it;
            p.status = "not run";
            points.push_back(p);
            continue;
          }
          points.push_back(RunBullet(o, grid, bending, it));
          PrintPoint(points.back());
          over = points.back().status == "over budget";
        }
      }
    }
    Judge(grid, &points);
  }
  const std::string load_end = LoadAverage();
  const Targets targets = JudgeTargets(points, o);
  std::printf("targets:\n%s%s", targets.ratio_text.c_str(), targets.below_text.c_str());

  // Markdown.
  std::string md = ReportHeader("Cloth speed against stretch (`felt bench cloth --tradeoff`)",
                                o.command, machine, load_end);
  const double load1_start = std::atof(machine.load_average.c_str());
  const double load1_end = std::atof(load_end.c_str());
  if (load1_start > 1.0 || load1_end > 1.0) {
    md += "**Shared machine:** the 1-minute load average was above 1 during this run (" +
          machine.load_average + " at the start, " + load_end +
          " at the end): other processes took CPU time, which the wall-clock medians include and "
          "the cpu columns do not.\n\n";
  }
  md += "The default curtain (" + o.scene +
        ") resized to each grid over the same 0.496 m square (bench/bench_util.h ResizedCurtain), "
        "released from rest, pinned at its two top corners, 1/60 s frames: " +
        std::to_string(o.settle_frames) + " frames settle, then " + std::to_string(o.frames) +
        " frames are timed one by one. `frame ms` is the median wall time of one frame over the "
        "timed frames (Felt: StepFrame; Bullet: stepSimulation), `cpu ms` the same in this "
        "thread's CPU time. `release stretch`: the largest structural length / rest length "
        "after any frame, the release transient included; `settled stretch`: the same over the "
        "timed frames only (as `felt bench cloth` defines them). A point whose projected run time "
        "(frames so far at their median cost) exceeds " +
        Sig(o.point_budget_s, 3) +
        " s is stopped and listed as over budget with the cost it showed; a Bullet curve runs no "
        "higher iteration count after one is over budget.\n\n";
  md +=
      "**Felt's settings** are scene keys (docs/scenes.md) over the scene's own: "
      "`integration.substeps` swept with the scene's Provot sweeps, `provot.iterations` swept "
      "with auto substeps (the scene's own count is the shipped setting), and small steps "
      "(substeps swept with `provot.iterations=1`), and a tighter Provot limit "
      "(`provot.max_elongation` below the scene's 0.10, auto substeps, the scene's sweeps: "
      "Felt's stretch sits near 1 + its limit), and Provot's sweeps alone, swept "
      "(`provot.finish=false; provot.sweep_headroom=0`: no finishing worklist; the "
      "multiresolution families in the first sweep only, as shipped; auto substeps); everything "
      "else as the scene (leapfrog Verlet, Provot with long "
      "range attachments and "
      "multiresolution families). Substep counts under the auto count give up part of the "
      "margin auto keeps below the integrator's stable step (`integration.auto_safety`); they "
      "are measured as they run. A Felt point with NaN events (a frame restored its last good "
      "state) is shown but is not on Felt's curve.\n\n";
  if (bullet) {
    md += "**Bullet's setup:** " + BulletSetupText(o, o.grids.front()) +
          " A Bullet point whose cloth came apart (a structural link longer than the curtain's "
          "side, grid - 1 rest lengths, or not finite) is shown but not judged.\n\n";
  } else {
    md += "**" + bullet_note + "**\n\n";
  }
  md +=
      "**Felt below Bullet** (the issue's plot target): on each grid, Felt's curve is the "
      "lower-left front of its points (those no other Felt point beats on both cost and "
      "stretch). A Bullet point (cost c, stretch s) is met `measured` when some measured Felt "
      "point costs <= c with stretch <= s; else `interpolated` when the straight line between "
      "the two front points around c, in (log10 cost, stretch), is at or under s at c; else "
      "`no` (also when every Felt point costs more than c). Judged on the wall-clock medians, "
      "separately for the release and the settled stretch; the target is met when every "
      "judged Bullet point is met on both. `Felt ms at this stretch` is the cheapest Felt "
      "front point whose release stretch is at most the Bullet point's, and how many times "
      "cheaper than Bullet it is.\n\n";
  md += "## Targets (issue 21)\n\n";
  md += "64 x 64 frame at most " + Sig(kRatioTarget, 2) +
        " times Bullet's 10-iteration step, measured in the same run (Felt's shipped setting, "
        "wall-clock medians):\n\n" +
        targets.ratio_text +
        "\nThe speed-against-stretch plot shows Felt's curve below Bullet's "
        "everywhere Bullet has a point:\n\n" +
        targets.below_text + "\n";
  md +=
      "Plot: `cloth_tradeoff.png` (bench/cloth_tradeoff.gp on cloth_tradeoff.csv): x = frame ms "
      "(wall median, log), y = max stretch - 1 (log, so that Felt's 1.1 and Bullet's 20 both "
      "show; the dashed line is the 1.10 target), one curve per method, one column per grid, "
      "release stretch above, settled below.\n\n";
  const std::vector<std::string> header = {"curve",
                                           "setting",
                                           "substeps",
                                           "sweeps / iterations",
                                           "links",
                                           "frame ms",
                                           "cpu ms",
                                           "release stretch",
                                           "settled stretch",
                                           "status",
                                           "Felt below (release)",
                                           "Felt below (settled)",
                                           "Felt ms at this stretch"};
  const std::vector<bool> right = {false, false, true,  true,  true,  true, true,
                                   true,  true,  false, false, false, false};
  md += "Curves:\n\n";
  for (const CurveInfo& c : kCurves) md += "- `" + std::string(c.id) + "`: " + c.title + "\n";
  md += "\n";
  for (const int32_t grid : o.grids) {
    std::vector<std::vector<std::string>> rows;
    for (const Point& p : points) {
      if (p.grid == grid) rows.push_back(MdRow(p));
    }
    md += "## " + std::to_string(grid) + " x " + std::to_string(grid) + "\n\n" +
          MarkdownTable(header, right, rows) + "\n";
  }
  WriteTextFile(o.out + "/cloth_tradeoff.md", md);

  // CSV.
  std::vector<std::vector<std::string>> csv_rows;
  for (const Point& p : points) csv_rows.push_back(CsvRow(p, machine.cpu_model));
  const std::string csv = o.out + "/cloth_tradeoff.csv";
  WriteTextFile(csv, CsvTable({"curve",
                               "grid",
                               "peer",
                               "setting",
                               "shipped",
                               "substeps",
                               "sweeps_or_iterations",
                               "links",
                               "frames_run",
                               "frame_ms_median",
                               "frame_ms_p99",
                               "cpu_ms_median",
                               "release_max_stretch",
                               "settled_max_stretch",
                               "nan_events",
                               "status",
                               "judged",
                               "release_below",
                               "settled_below",
                               "felt_ms_at_release_stretch",
                               "host"},
                              csv_rows));

  // JSON.
  Json top{{"command", o.command}};
  AppendMachineJson(machine, load_end, &top);
  top["settle_frames"] = o.settle_frames;
  top["frames"] = o.frames;
  top["point_budget_s"] = o.point_budget_s;
  top["bullet"] = Json{{"available", BulletAvailable()},
                       {"run", bullet},
                       {"version", BulletVersionText()},
                       {"note", bullet_note}};
  Json items = Json::array();
  for (const Point& p : points) items.push_back(PointJson(p));
  top["points"] = items;
  top["targets"] = targets.json;
  const std::string json_path = o.json.empty() ? o.out + "/cloth_tradeoff.json" : o.json;
  WriteTextFile(json_path, JsonText(top));
  std::printf("wrote %s/cloth_tradeoff.md, %s, %s\n", o.out.c_str(), csv.c_str(),
              json_path.c_str());
  if (o.plot) Plot(o, csv, o.grids);
  return 0;
}

}  // namespace felt::bench
