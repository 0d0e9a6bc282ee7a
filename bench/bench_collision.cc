// `felt bench collision`: the repair and query costs of the collision structures in the layout of
// 001_0f9f1b7fedff7723.txt Tables 1-3 (§6.3), on a moving cloth (an analytic sagging sheet that
// swings about its top edge and deforms every frame), with a haptic pointer sweeping over it.
//
// Writes a Markdown report, a CSV and a JSON file (one record per structure and grid), and can run
// gnuplot on bench/collision.gp for the plot. Helpers (median, percentile) are local to this file.
#include <sched.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "app/command.h"
#include "base/json.h"
#include "base/report.h"
#include "collision/collision_structure.h"
#include "collision/mesh.h"
#include "rt/realtime.h"
#include "server/server_spec.h"

namespace felt::bench::bench_collision {
namespace {

using Clock = std::chrono::steady_clock;
constexpr double kPi = 3.14159265358979323846;
constexpr double kFrameDt = 1.0 / 60.0;   // sim frame, s
constexpr double kTickDt = 1.0 / 1000.0;  // haptic tick, s
constexpr double kProxyRadius = 0.005;    // m
constexpr double kInflation = 0.005;      // m, the inflated variants' margin
constexpr int64_t kWarmTicks = 2000;      // untimed ticks before a structure's timed ones

// The 1-, 5- and 15-minute load averages, from /proc/loadavg ("?" if unreadable).
std::string LoadAverage() {
  std::ifstream f("/proc/loadavg");
  double a = 0, b = 0, c = 0;
  if (!(f >> a >> b >> c)) return "?";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.2f %.2f %.2f", a, b, c);
  return buf;
}

// What the reports say about the run: the command line and the machine's load around it.
struct RunInfo {
  std::string cmd;
  std::string load_start;
  std::string load_end;
  std::string realtime = "off (--no-realtime)";  // RealtimeReport::Summary() of the query threads
  std::string dma_latency = "not requested";     // /dev/cpu_dma_latency held at 0?
};

double Us(Clock::duration d) { return std::chrono::duration<double, std::micro>(d).count(); }

// This thread's CPU time, us: unlike the wall clock it does not run while the thread is
// preempted (the benchmark machine is shared).
double ThreadCpuUs() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e6 + static_cast<double>(ts.tv_nsec) * 1e-3;
}

// Context switches of this thread so far (voluntary + involuntary).
long ContextSwitches() {
  rusage ru;
  getrusage(RUSAGE_THREAD, &ru);
  return ru.ru_nvcsw + ru.ru_nivcsw;
}

// Time the hypervisor gave this VM's CPUs to others ("steal", /proc/stat's eighth cpu field),
// in clock ticks summed over all CPUs; -1 if unreadable.
long long StealTicks() {
  std::ifstream f("/proc/stat");
  std::string cpu;
  long long v[8] = {};
  if (!(f >> cpu) || cpu != "cpu") return -1;
  for (long long& x : v) {
    if (!(f >> x)) return -1;
  }
  return v[7];
}

double Max(const std::vector<double>& v) {
  return v.empty() ? std::nan("") : *std::max_element(v.begin(), v.end());
}

double Mean(const std::vector<double>& v) {
  if (v.empty()) return std::nan("");
  double s = 0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}

// The analytic moving cloth: a 1 m x 1 m sheet pinned along its top edge (the x axis), swinging
// about it by up to 0.6 rad at 0.4 Hz, sagging in a belly whose depth breathes at 1.3 Hz, with a
// travelling ripple and a waist that narrows toward the free edge: every particle moves every
// frame, like a draped cloth in the wind. u across, v down from the top edge, t in seconds.
Vec3 SwingingCloth(double u, double v, double t) {
  const double theta = 0.6 * std::sin(2 * kPi * 0.4 * t);
  const Vec3 down(0.0, std::sin(theta), -std::cos(theta));
  const Vec3 normal(0.0, std::cos(theta), std::sin(theta));
  const double belly =
      0.08 * std::sin(kPi * u) * v * (1.0 + 0.3 * std::sin(2 * kPi * 1.3 * t + 4 * u));
  const double ripple = 0.01 * v * std::sin(2 * kPi * (1.5 * v - 0.7 * t) + 3 * u);
  const double waist = 1.0 - 0.08 * v * (1.0 + std::sin(2 * kPi * 0.5 * t));
  return Vec3(0.5 + (u - 0.5) * waist, 0.0, 0.0) + 0.97 * v * down + (belly + ripple) * normal;
}

void FillFrame(int32_t w, double t, std::vector<Vec3>* x) {
  x->resize(static_cast<size_t>(w) * w);
  for (int32_t r = 0; r < w; ++r)
    for (int32_t c = 0; c < w; ++c)
      (*x)[GridIndex(w, c, r)] = SwingingCloth(c / (w - 1.0), r / (w - 1.0), t);
}

// The pointer at time t: a Lissajous path over the cloth's surface, at a signed offset along the
// local normal that oscillates around the surface (so a good share of ticks touch it).
Vec3 Pointer(int32_t w, const std::vector<Vec3>& x, double t) {
  const double u = 0.5 + 0.35 * std::sin(2 * kPi * 0.31 * t);
  const double v = 0.5 + 0.35 * std::sin(2 * kPi * 0.23 * t + 1.0);
  // Bilinear surface point and normal from the grid cell.
  const double fc = u * (w - 1), fr = v * (w - 1);
  const int32_t c = std::min(w - 2, static_cast<int32_t>(fc));
  const int32_t r = std::min(w - 2, static_cast<int32_t>(fr));
  const double a = fc - c, b = fr - r;
  const Vec3& p00 = x[GridIndex(w, c, r)];
  const Vec3& p10 = x[GridIndex(w, c + 1, r)];
  const Vec3& p01 = x[GridIndex(w, c, r + 1)];
  const Vec3& p11 = x[GridIndex(w, c + 1, r + 1)];
  const Vec3 p = (1 - a) * (1 - b) * p00 + a * (1 - b) * p10 + (1 - a) * b * p01 + a * b * p11;
  const Vec3 n = (p10 - p00).cross(p01 - p00).normalized();
  const double offset = 0.012 * std::sin(2 * kPi * 0.9 * t) - 0.002;
  return p + offset * n;
}

// A cycle of precomputed frames, played forward then backward so motion never jumps.
struct FrameCycle {
  int32_t w = 0;
  std::vector<std::vector<Vec3>> frames;
  const std::vector<Vec3>& At(int64_t k) const {
    const int64_t n = static_cast<int64_t>(frames.size());
    if (n == 1) return frames[0];
    const int64_t period = 2 * (n - 1);
    const int64_t m = k % period;
    return frames[static_cast<size_t>(m < n ? m : period - m)];
  }
};

FrameCycle MakeCycle(int32_t w, int32_t num_frames) {
  FrameCycle cyc;
  cyc.w = w;
  cyc.frames.resize(static_cast<size_t>(num_frames));
  for (int32_t k = 0; k < num_frames; ++k) FillFrame(w, 0.25 + k * kFrameDt, &cyc.frames[k]);
  return cyc;
}

struct Record {
  std::string structure;
  int32_t grid = 0;
  int32_t triangles = 0;
  double repair_ms_median = std::nan("");
  double repair_ms_max = std::nan("");
  double repair_cpu_ms_median = std::nan("");
  double node_updates = std::nan("");  // mean per repair
  double nodes = std::nan("");
  int64_t repairs = 0;
  double query_us_median = std::nan("");
  double query_us_p99 = std::nan("");
  double query_us_max = std::nan("");
  double query_us_max_unpreempted = std::nan("");
  double preempted_fraction = std::nan("");
  double query_us_max_rerun = std::nan("");
  double query_us_p999 = std::nan("");
  double query_cpu_us_median = std::nan("");
  double query_cpu_us_max = std::nan("");
  double query_contact_us_mean = std::nan("");
  double query_free_us_mean = std::nan("");
  double query_contact_us_median = std::nan("");
  double query_free_us_median = std::nan("");
  double contact_fraction = std::nan("");
  int64_t queries = 0;
  double within_us_median = std::nan("");
  double within_us_max = std::nan("");
  // Evidence about the slow ticks (query phase): an empty steady_clock pair timed just before
  // each query (the same interruptions hit it), the ticks over 20 us, how many of those saw no
  // context switch of this thread (getrusage RUSAGE_THREAD), and the machine's steal time.
  double empty_us_max = std::nan("");
  double empty_us_p999 = std::nan("");
  int64_t slow_ticks = 0;
  int64_t slow_ticks_no_switch = 0;
  double steal_ms = std::nan("");
  bool realtime = false;  // the query phase ran under SCHED_FIFO
};

struct Settings {
  std::vector<int32_t> grids;
  int64_t ticks = 100000;        // haptic ticks per structure and grid
  int32_t max_repairs = 300;     // repairs timed per configuration (at most)
  double repair_budget_s = 0.4;  // stop repeating after this (with at least min_repairs)
  int32_t min_repairs = 15;
  double naive_budget_tests = 6e7;  // triangle tests the naive reference may spend per grid
  bool realtime = true;             // time the query phase under the haptic thread's settings
  RealtimeSettings rt;              // those settings (HapticSpec's defaults, pinned to a CPU)
  int64_t warm_ticks = kWarmTicks;  // untimed ticks before the timed ones
  double busy_ms_per_rest = 10.0;   // under SCHED_FIFO: sleep rest_ms after this much work
  double rest_ms = 1.0;
};

std::vector<CollisionStructureSpec> RepairSpecs() {
  std::vector<CollisionStructureSpec> specs;
  for (BvhRepair m :
       {BvhRepair::kBottomUp, BvhRepair::kBottomUpQueue, BvhRepair::kTopDown, BvhRepair::kRebuild})
    for (double d : {0.0, kInflation})
      for (int32_t arity : {2, 4})
        for (BoundingVolume v : {BoundingVolume::kSphere, BoundingVolume::kAabb}) {
          if (m == BvhRepair::kRebuild && d > 0.0) continue;  // a rebuild refits everything anyway
          specs.push_back({CollisionStructureSpec::Kind::kBvh, {v, arity, m, d}, {}});
        }
  specs.push_back({CollisionStructureSpec::Kind::kSpatialHash, {}, {}});
  return specs;
}

std::vector<CollisionStructureSpec> QuerySpecs() {
  std::vector<CollisionStructureSpec> specs;
  specs.push_back({CollisionStructureSpec::Kind::kNaive, {}, {}});
  specs.push_back({CollisionStructureSpec::Kind::kSpatialHash, {}, {}});
  for (double d : {0.0, kInflation})
    for (int32_t arity : {2, 4})
      for (BoundingVolume v : {BoundingVolume::kSphere, BoundingVolume::kAabb})
        specs.push_back(
            {CollisionStructureSpec::Kind::kBvh, {v, arity, BvhRepair::kBottomUp, d}, {}});
  return specs;
}

// Repair cost: one repair per sim frame over the moving cloth.
void BenchRepair(const Settings& s, const FrameCycle& cyc,
                 const std::shared_ptr<const std::vector<Triangle>>& tris,
                 const CollisionStructureSpec& spec, Record* rec) {
  CollisionStructure st = MakeCollisionStructure(spec, tris, cyc.At(0));
  std::vector<double> ms, cpu_ms, updates;
  ms.reserve(static_cast<size_t>(s.max_repairs));
  const auto start = Clock::now();
  for (int64_t k = 1; k <= s.max_repairs; ++k) {
    const std::vector<Vec3>& x = cyc.At(k);
    const double c0 = ThreadCpuUs();
    const auto t0 = Clock::now();
    const RepairStats rs = Repair(st, x);
    const auto t1 = Clock::now();
    const double c1 = ThreadCpuUs();
    ms.push_back(Us(t1 - t0) / 1000.0);
    cpu_ms.push_back((c1 - c0) / 1000.0);
    updates.push_back(spec.kind == CollisionStructureSpec::Kind::kSpatialHash ? rs.entries
                                                                              : rs.node_updates);
    if (k >= s.min_repairs &&
        std::chrono::duration<double>(Clock::now() - start).count() > s.repair_budget_s) {
      break;
    }
  }
  rec->repair_ms_median = report::Median(ms);
  rec->repair_ms_max = Max(ms);
  rec->repair_cpu_ms_median = report::Median(cpu_ms);
  rec->node_updates = Mean(updates);
  rec->repairs = static_cast<int64_t>(ms.size());
  if (const Bvh* b = std::get_if<Bvh>(&st)) rec->nodes = b->num_nodes();
}

// Query cost per haptic tick: the proxy's sweep from last tick's pointer to this tick's, and the
// within-reach query at the new position, with the structure repaired every sim frame.
void BenchQuery(const Settings& s, const FrameCycle& cyc,
                const std::shared_ptr<const std::vector<Triangle>>& tris,
                const CollisionStructureSpec& spec, Record* rec, double* sink) {
  CollisionStructure st = MakeCollisionStructure(spec, tris, cyc.At(0));
  // The 256 x 256 cloth gets a fifth of the ticks, to keep the whole run within minutes.
  int64_t ticks = cyc.w > 128 ? s.ticks / 5 : s.ticks;
  if (spec.kind == CollisionStructureSpec::Kind::kNaive) {
    ticks = std::min<int64_t>(
        ticks, std::max<int64_t>(200, static_cast<int64_t>(s.naive_budget_tests /
                                                           static_cast<double>(tris->size()))));
  }
  std::vector<double> all, cpu, contact, free, within, unpreempted;
  all.reserve(static_cast<size_t>(ticks));
  cpu.reserve(static_cast<size_t>(ticks));
  within.reserve(static_cast<size_t>(ticks));
  std::vector<PointContact> buf(256);
  std::vector<double> empty;
  empty.reserve(static_cast<size_t>(ticks));
  int64_t frame = -1;
  Vec3 prev = Vec3::Zero();
  // Warm-up: untimed ticks over the first frames, so the structure's arrays, the positions and
  // the code are in cache and (with mlockall) every page is resident before the timed ticks.
  for (int64_t k = 0; k < std::min(ticks, s.warm_ticks); ++k) {
    const double t = static_cast<double>(k) * kTickDt;
    const std::vector<Vec3>& x = cyc.At(static_cast<int64_t>(t / kFrameDt));
    if (k % 17 == 0) Repair(st, x);
    const Vec3 p = Pointer(cyc.w, x, t);
    if (k == 0) prev = p;
    *sink += SweepSphere(st, x, prev, p, kProxyRadius).toi +
             TrianglesWithin(st, x, p, 2 * kProxyRadius, buf).found;
    prev = p;
  }
  // Under SCHED_FIFO the loop rests rest_ms after every busy_ms_per_rest of work (outside the
  // timed regions): a back-to-back real-time loop would otherwise hit the kernel's real-time
  // throttling (95% of each second) and starve the CPU's other threads; the haptic thread in
  // production is busy a few us per 1 ms tick.
  const double rest_after_us = s.busy_ms_per_rest * 1000.0;
  const timespec rest{0, static_cast<long>(s.rest_ms * 1e6)};
  auto busy_since = Clock::now();
  const long long steal0 = StealTicks();
  long switches = ContextSwitches();
  for (int64_t k = 0; k < ticks; ++k) {
    if (rec->realtime && Us(Clock::now() - busy_since) > rest_after_us) {
      nanosleep(&rest, nullptr);
      busy_since = Clock::now();
      switches = ContextSwitches();
    }
    const double t = static_cast<double>(k) * kTickDt;
    const int64_t f = static_cast<int64_t>(t / kFrameDt);
    const std::vector<Vec3>& x = cyc.At(f);
    if (f != frame) {
      Repair(st, x);
      frame = f;
    }
    const Vec3 p = Pointer(cyc.w, x, t);
    if (k == 0) prev = p;
    // Wall time: steady_clock immediately around the query. Thread CPU time: read just outside
    // the wall pair, so it also holds one steady_clock read (tens of ns) but no preemption.
    const auto e0 = Clock::now();
    const auto e1 = Clock::now();
    const double c0 = ThreadCpuUs();
    const auto t0 = Clock::now();
    const SweepHit hit = SweepSphere(st, x, prev, p, kProxyRadius);
    const auto t1 = Clock::now();
    const double c1 = ThreadCpuUs();
    cpu.push_back(c1 - c0);
    const WithinResult wr = TrianglesWithin(st, x, p, 2 * kProxyRadius, buf);
    const auto t2 = Clock::now();
    const double us = Us(t1 - t0);
    all.push_back(us);
    (hit.hit ? contact : free).push_back(us);
    within.push_back(Us(t2 - t1));
    // Ticks during which the thread was not switched out (checked outside the timed region).
    empty.push_back(Us(e1 - e0));
    const long now_switches = ContextSwitches();
    if (now_switches == switches) unpreempted.push_back(us);
    if (us > 20.0) {
      ++rec->slow_ticks;
      if (now_switches == switches) ++rec->slow_ticks_no_switch;
    }
    switches = now_switches;
    *sink += hit.toi + wr.found;
    prev = p;
  }
  const long long steal1 = StealTicks();
  if (steal0 >= 0 && steal1 >= 0) {
    rec->steal_ms =
        1000.0 * static_cast<double>(steal1 - steal0) / static_cast<double>(sysconf(_SC_CLK_TCK));
  }
  rec->empty_us_max = Max(empty);
  rec->empty_us_p999 = report::Percentile(empty, 99.9);
  rec->queries = ticks;
  rec->query_us_median = report::Median(all);
  rec->query_us_p99 = report::Percentile(all, 99);
  rec->query_us_max = Max(all);
  rec->query_us_p999 = report::Percentile(all, 99.9);
  rec->query_cpu_us_median = report::Median(cpu);
  rec->query_cpu_us_max = Max(cpu);
  rec->query_us_max_unpreempted = Max(unpreempted);
  // Worst case without the machine's noise: re-run the 100 slowest ticks 5 times each (with the
  // structure repaired to their frame) and keep each one's fastest time; the worst of those and
  // of every other tick's time is the query's own worst case.
  std::vector<int64_t> idx(static_cast<size_t>(ticks));
  for (int64_t k = 0; k < ticks; ++k) idx[static_cast<size_t>(k)] = k;
  const size_t top = std::min<size_t>(100, idx.size());
  std::partial_sort(idx.begin(), idx.begin() + static_cast<std::ptrdiff_t>(top), idx.end(),
                    [&](int64_t a, int64_t b) { return all[a] > all[b]; });
  double worst = top < idx.size() ? all[static_cast<size_t>(idx[top])] : 0.0;
  for (size_t i = 0; i < top; ++i) {
    const int64_t k = idx[i];
    const double t = static_cast<double>(k) * kTickDt;
    const int64_t f = static_cast<int64_t>(t / kFrameDt);
    const std::vector<Vec3>& x = cyc.At(f);
    Repair(st, x);
    const Vec3 p = Pointer(cyc.w, x, t);
    const Vec3 q = k == 0 ? p
                          : Pointer(cyc.w, cyc.At(static_cast<int64_t>((t - kTickDt) / kFrameDt)),
                                    t - kTickDt);
    double best = all[static_cast<size_t>(k)];
    for (int rep = 0; rep < 5; ++rep) {
      const auto t0 = Clock::now();
      const SweepHit hit = SweepSphere(st, x, q, p, kProxyRadius);
      const auto t1 = Clock::now();
      best = std::min(best, Us(t1 - t0));
      *sink += hit.toi;
    }
    worst = std::max(worst, best);
  }
  rec->query_us_max_rerun = worst;
  rec->preempted_fraction =
      1.0 - static_cast<double>(unpreempted.size()) / static_cast<double>(ticks);
  rec->query_contact_us_mean = Mean(contact);
  rec->query_free_us_mean = Mean(free);
  rec->query_contact_us_median = report::Median(contact);
  rec->query_free_us_median = report::Median(free);
  rec->contact_fraction = static_cast<double>(contact.size()) / static_cast<double>(ticks);
  rec->within_us_median = report::Median(within);
  rec->within_us_max = Max(within);
}

std::string Num(double v, int prec = 3) {
  if (std::isnan(v)) return "NaN";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", prec, v);
  return buf;
}

std::string Cell(double v, int prec = 3) { return std::isnan(v) ? "-" : Num(v, prec); }

void WriteCsv(const std::string& path, const std::vector<Record>& recs) {
  std::ofstream f(path);
  if (!f) throw std::runtime_error("cannot write " + path);
  f << "structure,grid,triangles,repair_ms_median,repair_ms_max,repair_cpu_ms_median,"
       "node_updates,nodes,repairs,query_us_median,query_us_p99,query_us_max,"
       "query_us_max_unpreempted,preempted_fraction,query_us_max_rerun,query_contact_us_mean,"
       "query_free_us_mean,"
       "contact_fraction,queries,within_us_median,within_us_max,query_us_p999,query_cpu_us_median,"
       "query_cpu_us_max,empty_us_max,empty_us_p999,slow_ticks,slow_ticks_no_switch,steal_ms,"
       "realtime\n";
  for (const Record& r : recs) {
    f << r.structure << ',' << r.grid << ',' << r.triangles << ',' << Num(r.repair_ms_median, 5)
      << ',' << Num(r.repair_ms_max, 5) << ',' << Num(r.repair_cpu_ms_median, 5) << ','
      << Num(r.node_updates, 1) << ',' << Num(r.nodes, 0) << ',' << r.repairs << ','
      << Num(r.query_us_median) << ',' << Num(r.query_us_p99) << ',' << Num(r.query_us_max) << ','
      << Num(r.query_us_max_unpreempted) << ',' << Num(r.preempted_fraction) << ','
      << Num(r.query_us_max_rerun) << ',' << Num(r.query_contact_us_mean) << ','
      << Num(r.query_free_us_mean) << ',' << Num(r.contact_fraction) << ',' << r.queries << ','
      << Num(r.within_us_median) << ',' << Num(r.within_us_max) << ',' << Num(r.query_us_p999)
      << ',' << Num(r.query_cpu_us_median) << ',' << Num(r.query_cpu_us_max) << ','
      << Num(r.empty_us_max) << ',' << Num(r.empty_us_p999) << ',' << r.slow_ticks << ','
      << r.slow_ticks_no_switch << ',' << Num(r.steal_ms, 1) << ',' << (r.realtime ? 1 : 0) << '\n';
  }
}

void WriteJson(const std::string& path, const std::vector<Record>& recs, const RunInfo& info) {
  Json records = Json::array();
  for (const Record& r : recs) {
    records.push_back(Json{{"structure", r.structure},
                           {"grid", r.grid},
                           {"triangles", r.triangles},
                           {"repair_ms_median", RoundedJson(r.repair_ms_median, 5)},
                           {"repair_ms_max", RoundedJson(r.repair_ms_max, 5)},
                           {"repair_cpu_ms_median", RoundedJson(r.repair_cpu_ms_median, 5)},
                           {"node_updates", RoundedJson(r.node_updates, 1)},
                           {"nodes", RoundedJson(r.nodes, 0)},
                           {"repairs", r.repairs},
                           {"query_us_median", RoundedJson(r.query_us_median, 3)},
                           {"query_us_p99", RoundedJson(r.query_us_p99, 3)},
                           {"query_us_max", RoundedJson(r.query_us_max, 3)},
                           {"query_us_max_unpreempted", RoundedJson(r.query_us_max_unpreempted, 3)},
                           {"preempted_fraction", RoundedJson(r.preempted_fraction, 4)},
                           {"query_us_max_rerun", RoundedJson(r.query_us_max_rerun, 3)},
                           {"query_contact_us_mean", RoundedJson(r.query_contact_us_mean, 3)},
                           {"query_free_us_mean", RoundedJson(r.query_free_us_mean, 3)},
                           {"contact_fraction", RoundedJson(r.contact_fraction, 3)},
                           {"queries", r.queries},
                           {"within_us_median", RoundedJson(r.within_us_median, 3)},
                           {"within_us_max", RoundedJson(r.within_us_max, 3)},
                           {"query_us_p999", RoundedJson(r.query_us_p999, 3)},
                           {"query_cpu_us_median", RoundedJson(r.query_cpu_us_median, 3)},
                           {"query_cpu_us_max", RoundedJson(r.query_cpu_us_max, 3)},
                           {"empty_us_max", RoundedJson(r.empty_us_max, 3)},
                           {"empty_us_p999", RoundedJson(r.empty_us_p999, 3)},
                           {"slow_ticks", r.slow_ticks},
                           {"slow_ticks_no_switch", r.slow_ticks_no_switch},
                           {"steal_ms", RoundedJson(r.steal_ms, 1)},
                           {"realtime", r.realtime}});
  }
  report::WriteTextFile(path, JsonText(Json{{"command", info.cmd},
                                            {"load_average_start", info.load_start},
                                            {"load_average_end", info.load_end},
                                            {"query_realtime", info.realtime},
                                            {"cpu_dma_latency_zero", info.dma_latency},
                                            {"cloth", "analytic swinging sagging sheet"},
                                            {"proxy_radius_m", kProxyRadius},
                                            {"inflation_m", kInflation},
                                            {"records", records}}));
}

const Record* Find(const std::vector<Record>& recs, const std::string& name, int32_t grid) {
  for (const Record& r : recs) {
    if (r.structure == name && r.grid == grid) return &r;
  }
  return nullptr;
}

double Get(const std::vector<Record>& recs, const std::string& name, int32_t grid,
           double Record::*field) {
  const Record* r = Find(recs, name, grid);
  return r ? r->*field : std::nan("");
}

void WriteMarkdown(const std::string& path, const std::vector<Record>& recs,
                   const std::vector<int32_t>& grids, const RunInfo& info) {
  std::ofstream f(path);
  if (!f) throw std::runtime_error("cannot write " + path);
  // 001's own figures (ms on its hardware), by triangle count.
  const std::map<int32_t, std::vector<double>> t1 = {{162, {0.116, 0.153, 0.141}},
                                                     {722, {0.652, 0.922, 0.799}},
                                                     {1682, {1.722, 2.2277, 1.99}},
                                                     {3042, {2.871, 3.914, 3.346}},
                                                     {4802, {4.537, 5.4, 5.15}}};
  const std::map<int32_t, std::vector<double>> t2 = {
      {162, {263, 0.307, 323, 0.408, 190, 0.285, 247, 0.378, 1.368}},
      {722, {1191, 1.759, 1443, 2.429, 832, 1.1531, 1063, 2.257, 6.071}},
      {1682, {2506, 4.680, 3355, 7.429, 1887, 4.442, 2675, 7.216, 13.185}},
      {3042, {3185, 7.211, 5341, 13.569, 3162, 6.360, 3865, 11.205, 23.760}},
      {4802, {6433, 13.650, 9401, 22.686, 4284, 12.907, 6727, 20.729, 39.998}}};
  f << "# Collision structures: repair and query costs (`felt bench collision`)\n\n"
    << "Produced by `" << info.cmd << "` (Release build); load average (1, 5, 15 min) "
    << info.load_start << " at the start and " << info.load_end
    << " at the end. Layout after 001_0f9f1b7fedff7723.txt "
    << "§6.3 Tables 1-3; 001's own figures, measured on its 2007-era hardware with its own "
    << "cloth, are shown next to ours in *italics*. Cloth: an analytic 1 m x 1 m sheet pinned "
    << "along its top edge, swinging about it (0.6 rad, 0.4 Hz) with a breathing belly, a "
    << "travelling ripple and a narrowing waist, so every particle moves every 60 Hz frame (the "
    << "real sim was not used: see README-collision.md). Times are medians over repeated "
    << "repairs (one per frame) and over haptic ticks (1 kHz).\n\n";

  // The two targets, for the recommended structure (AABB quad tree, flat bottom-up).
  {
    const std::string best = "bvh-aabb-4-bottomup";
    const Record* r50 = Find(recs, best, 50);
    const Record* r128 = Find(recs, best, 128);
    f << "## Targets (" << best << ")\n\n"
      << "| target | measured | met? |\n|---|---|---|\n";
    if (r50) {
      f << "| repair of the 4802-triangle cloth <= 0.05 ms median | wall median "
        << Num(r50->repair_ms_median, 4) << " ms, thread-CPU median "
        << Num(r50->repair_cpu_ms_median, 4) << " ms (" << r50->repairs << " repairs) | "
        << (r50->repair_ms_median <= 0.05 ? "yes" : "no") << " |\n";
    }
    if (r128) {
      f << "| query on 128 x 128 (32,258 triangles) <= 2 us median | wall median "
        << Num(r128->query_us_median, 2) << " us over " << r128->queries << " queries | "
        << (r128->query_us_median <= 2.0 ? "yes" : "no") << " |\n"
        << "| ... <= 20 us worst case | wall max " << Num(r128->query_us_max, 1)
        << " us; wall p99.9 " << Num(r128->query_us_p999, 2) << " us; thread-CPU max "
        << Num(r128->query_cpu_us_max, 1) << " us; ticks with a context switch "
        << Num(100 * r128->preempted_fraction, 2)
        << "%; slowest 100 re-run: " << Num(r128->query_us_max_rerun, 1) << " us; "
        << r128->slow_ticks << " ticks over 20 us, " << r128->slow_ticks_no_switch
        << " of them with no context switch; an empty clock pair timed just before each query: "
           "max "
        << Num(r128->empty_us_max, 1) << " us, p99.9 " << Num(r128->empty_us_p999, 2)
        << " us; steal " << Num(r128->steal_ms, 1) << " ms during the phase; "
        << (r128->realtime ? "SCHED_FIFO" : "no real-time scheduling") << " | "
        << (r128->query_us_max <= 20.0 ? "yes" : "wall max no") << " |\n";
    }
    f << "\nWall times are steady_clock around each call; thread-CPU times are "
         "CLOCK_THREAD_CPUTIME_ID read just outside the wall pair (so they exclude time the "
         "thread was preempted, and include one steady_clock read). Query phase real-time "
         "settings (the haptic thread's, HapticSpec defaults, on a thread of its own): "
      << info.realtime
      << "; /dev/cpu_dma_latency held at 0 during the query phases: " << info.dma_latency
      << ". Before the timed ticks, " << kWarmTicks
      << " untimed ticks warm the structure, the positions and the code; under SCHED_FIFO the "
         "loop rests 1 ms after every 10 ms of work, outside the timed regions (kernel "
         "real-time throttling).\n\n";
  }

  f << "## Table 1: bottom-up array repair vs top-down repair (ms per repair)\n\n"
    << "Sphere volumes, exact refit. `array` = 001 §6.3's array-based bottom-up repair (arity "
    << "2) as written, with its parent queue (`bvh-sphere-2-queue`); `flat` = the same "
    << "repair as one pass over the leaves and one over the internal nodes "
    << "(`bvh-sphere-2-bottomup`); `binary`/`quad` = recursive top-down repair of the "
    << "arity-2/4 tree.\n\n"
    << "| triangles | array | flat | binary | quad | *001 array* | *001 binary* | *001 quad* |\n"
    << "|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  for (int32_t g : grids) {
    const int32_t n = 2 * (g - 1) * (g - 1);
    const auto it = t1.find(n);
    f << "| " << n << " | "
      << Cell(Get(recs, "bvh-sphere-2-queue", g, &Record::repair_ms_median), 4) << " | "
      << Cell(Get(recs, "bvh-sphere-2-bottomup", g, &Record::repair_ms_median), 4) << " | "
      << Cell(Get(recs, "bvh-sphere-2-topdown", g, &Record::repair_ms_median), 4) << " | "
      << Cell(Get(recs, "bvh-sphere-4-topdown", g, &Record::repair_ms_median), 4);
    for (int k = 0; k < 3; ++k)
      f << " | " << (it != t1.end() ? "*" + Num(it->second[k], 3) + "*" : "-");
    f << " |\n";
  }

  const auto table2 = [&](const std::string& title, const std::string& suffix) {
    f << "\n## " << title << "\n\n"
      << "| triangles | bin sphere #upd | ms | bin AABB #upd | ms | quad sphere #upd | ms | quad "
         "AABB #upd | ms | OSH ms |\n"
      << "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for (int32_t g : grids) {
      const int32_t n = 2 * (g - 1) * (g - 1);
      f << "| " << n;
      for (const char* cfg : {"sphere-2", "aabb-2", "sphere-4", "aabb-4"}) {
        const std::string name = std::string("bvh-") + cfg + suffix;
        f << " | " << Cell(Get(recs, name, g, &Record::node_updates), 0) << " | "
          << Cell(Get(recs, name, g, &Record::repair_ms_median), 4);
      }
      f << " | " << Cell(Get(recs, "osh", g, &Record::repair_ms_median), 4) << " |\n";
      const auto it = t2.find(n);
      if (it != t2.end() && suffix == "-bottomup") {
        f << "| *001* ";
        for (double v : it->second) f << " | *" << v << "*";
        f << " |\n";
      }
    }
  };
  table2("Table 2: repair (flat bottom-up, exact refit): mean node updates and median ms (wall)",
         "-bottomup");
  table2("Table 2a: 001 §6.3's bottom-up array repair with its parent queue, exact refit",
         "-queue");
  table2("Table 2b: the same with inflated volumes (d = 5 mm)", "-bottomup-d5mm");
  table2("Table 2c: top-down recursive repair", "-topdown");
  table2("Table 2d: full rebuild every frame (median split + refit)", "-rebuild");
  f << "\nOSH: a full rehash of every triangle (Teschner 2003, triangles only as in 001 §6.3); "
       "its '#upd' is not applicable.\n";

  f << "\n## Table 3: swept-sphere query per haptic tick (us), contact (CD) and no contact "
       "(NCD)\n\n"
    << "Mean us per query in ticks where the sweep found a contact (CD) and where it did not "
       "(NCD); then the median and worst case over all ticks. Proxy radius 5 mm. *001* reports "
       "ms for 126, 576 and 3042 triangles: *ref 0.103/0.084, 0.752/0.735, 2.782/2.745; OSH "
       "0.025/0.009, 0.024/0.013, 0.026/0.009; sphere-2 0.026/0.010, 0.029/0.012, 0.031/0.013; "
       "sphere-4 0.026/0.010, 0.028/0.012, 0.029/0.013; AABB-2 0.023/0.009, 0.025/0.009, "
       "0.027/0.010; AABB-4 0.024/0.008, 0.025/0.013, 0.027/0.011 ms (CD/NCD)*.\n\n"
    << "| triangles | structure | CD | NCD | median | p99 | p99.9 | max (wall) | max (CPU) | max "
       "(re-run) | contact ticks | queries | within-query median | within max |\n"
    << "|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  for (int32_t g : grids) {
    for (const Record& r : recs) {
      if (r.grid != g || std::isnan(r.query_us_median)) continue;
      f << "| " << r.triangles << " | " << r.structure << " | " << Cell(r.query_contact_us_mean, 2)
        << " | " << Cell(r.query_free_us_mean, 2) << " | " << Cell(r.query_us_median, 2) << " | "
        << Cell(r.query_us_p99, 2) << " | " << Cell(r.query_us_p999, 2) << " | "
        << Cell(r.query_us_max, 1) << " | " << Cell(r.query_cpu_us_max, 1) << " | "
        << Cell(r.query_us_max_rerun, 1) << " | " << Cell(100 * r.contact_fraction, 0) << "% | "
        << r.queries << " | " << Cell(r.within_us_median, 2) << " | " << Cell(r.within_us_max, 1)
        << " |\n";
    }
  }
}

std::vector<int32_t> ParseGrids(const std::string& s) {
  std::vector<int32_t> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    const int32_t g = std::stoi(item);
    if (g < 2) throw std::invalid_argument("--grids: every grid must be >= 2, got " + item);
    out.push_back(g);
  }
  if (out.empty()) throw std::invalid_argument("--grids: empty list");
  return out;
}

struct Options {
  std::string json = "bench/results/collision.json";
  std::string csv = "bench/results/collision.csv";
  std::string md = "bench/results/collision.md";
  std::string grids;
  bool quick = false;
  bool plot = false;
  bool no_realtime = false;
  int priority = HapticSpec{}.haptic_realtime.fifo_priority;
  int cpu = -2;             // -2: pin to the CPU the command starts on; -1: no pinning
  bool json_given = false;  // set from the parser: echoed in the reports' command line
  bool csv_given = false;
  bool md_given = false;
};

int Run(const Options& o) {
  Settings s;
  s.grids =
      ParseGrids(!o.grids.empty() ? o.grids : (o.quick ? "10,20,30" : "10,20,30,40,50,64,128,256"));
  if (o.quick) {
    s.ticks = 3000;
    s.max_repairs = 20;
    s.min_repairs = 5;
    s.repair_budget_s = 0.05;
    s.naive_budget_tests = 2e6;
  }
  // The query phase runs under the haptic thread's real-time settings (HapticSpec's defaults:
  // SCHED_FIFO, mlockall, minimal timer slack), pinned to one CPU, with /dev/cpu_dma_latency
  // held at 0 as the server does (only during the query phases, so the repair timings keep their
  // conditions; mlockall, process-wide, stays once granted); refusals log a warning and the
  // phase runs without them.
  s.realtime = !o.no_realtime;
  s.rt = HapticSpec{}.haptic_realtime;
  s.rt.fifo_priority = o.priority;
  s.rt.spin_us = 0;  // no deadlines here
  s.rt.cpu = o.cpu == -2 ? sched_getcpu() : o.cpu;
  RunInfo info;
  info.load_start = LoadAverage();
  std::string& cmd = info.cmd;
  cmd = "felt bench collision";
  if (o.quick) cmd += " --quick";
  if (!o.grids.empty()) cmd += " --grids " + o.grids;
  if (o.json_given) cmd += " --json " + o.json;
  if (o.csv_given) cmd += " --csv " + o.csv;
  if (o.md_given) cmd += " --md " + o.md;
  if (o.plot) cmd += " --plot";
  if (o.no_realtime) cmd += " --no-realtime";
  if (o.priority != HapticSpec{}.haptic_realtime.fifo_priority)
    cmd += " --priority " + std::to_string(o.priority);
  if (o.cpu != -2) cmd += " --cpu " + std::to_string(o.cpu);
  double sink = 0;
  std::vector<Record> recs;
  for (int32_t g : s.grids) {
    const auto tris = std::make_shared<const std::vector<Triangle>>(MakeGridTriangles(g, g));
    const int64_t verts = int64_t{g} * g;
    const int32_t frames =
        static_cast<int32_t>(std::clamp<int64_t>(2000000 / verts, 24, o.quick ? 40 : 240));
    const FrameCycle cyc = MakeCycle(g, frames);
    std::map<std::string, Record> by_name;
    const auto rec_for = [&](const CollisionStructureSpec& spec) -> Record& {
      Record& r = by_name[CollisionStructureName(spec)];
      r.structure = CollisionStructureName(spec);
      r.grid = g;
      r.triangles = static_cast<int32_t>(tris->size());
      return r;
    };
    for (const CollisionStructureSpec& spec : RepairSpecs()) {
      BenchRepair(s, cyc, tris, spec, &rec_for(spec));
    }
    // The query phase on a thread of its own, under the real-time settings (the main thread,
    // which times the repairs, stays a normal thread).
    std::exception_ptr failure;
    std::thread query_thread([&] {
      try {
        bool fifo = false;
        std::unique_ptr<CpuDmaLatencyHold> dma;
        if (s.realtime) {
          dma = std::make_unique<CpuDmaLatencyHold>();
          info.dma_latency = dma->held() ? "yes" : "refused (" + dma->error() + ")";
          const RealtimeReport report = ApplyRealtime(s.rt);
          fifo = report.fifo_granted;
          info.realtime = report.Summary() + " (priority " + std::to_string(s.rt.fifo_priority) +
                          ", cpu " + std::to_string(s.rt.cpu) + ")";
        }
        for (const CollisionStructureSpec& spec : QuerySpecs()) {
          Record& r = rec_for(spec);
          r.realtime = fifo;
          BenchQuery(s, cyc, tris, spec, &r, &sink);
        }
      } catch (...) {
        failure = std::current_exception();
      }
    });
    query_thread.join();
    if (failure) std::rethrow_exception(failure);
    for (const CollisionStructureSpec& spec : RepairSpecs()) {
      const Record& r = by_name[CollisionStructureName(spec)];
      std::printf(
          "grid %3d  %-26s repair %8.4f ms (cpu %8.4f)  updates %8.0f  query %6.3f us (max %7.1f, "
          "rerun %6.1f)\n",
          g, r.structure.c_str(), r.repair_ms_median, r.repair_cpu_ms_median, r.node_updates,
          r.query_us_median, r.query_us_max, r.query_us_max_rerun);
    }
    const Record& naive = by_name["naive"];
    std::printf("grid %3d  %-26s query %7.3f us (max %7.1f), %lld queries\n", g, "naive",
                naive.query_us_median, naive.query_us_max, static_cast<long long>(naive.queries));
    std::fflush(stdout);
    // Keep the naive reference first, then the order of RepairSpecs.
    recs.push_back(naive);
    for (const CollisionStructureSpec& spec : RepairSpecs()) {
      recs.push_back(by_name[CollisionStructureName(spec)]);
    }
  }
  info.load_end = LoadAverage();
  if (!o.json.empty()) WriteJson(o.json, recs, info);
  if (!o.csv.empty()) WriteCsv(o.csv, recs);
  if (!o.md.empty()) WriteMarkdown(o.md, recs, s.grids, info);
  std::printf("wrote %s %s %s (checksum %g)\n", o.json.c_str(), o.csv.c_str(), o.md.c_str(), sink);
  if (o.plot) {
    const std::string png = o.csv.substr(0, o.csv.rfind('.')) + ".png";
    const std::string gp =
        "gnuplot -e \"csv='" + o.csv + "'; png='" + png + "'\" bench/collision.gp";
    if (std::system(gp.c_str()) != 0) {
      std::fprintf(stderr, "felt bench collision: gnuplot failed: %s\n", gp.c_str());
      return 1;
    }
    std::printf("wrote %s\n", png.c_str());
  }
  return 0;
}

const bool kRegistered = felt::app::RegisterCommand({
    "bench",
    "collision",
    "BVH repair, spatial hashing and proxy query costs on a moving cloth (001 Tables 1-3)",
    [](CLI::App& cmd) -> felt::app::CommandRun {
      auto o = std::make_shared<Options>();
      CLI::Option* json = cmd.add_option("--json", o->json, "JSON output file");
      CLI::Option* csv = cmd.add_option("--csv", o->csv, "CSV output file");
      CLI::Option* md = cmd.add_option("--md", o->md, "Markdown report file");
      json->capture_default_str();
      csv->capture_default_str();
      md->capture_default_str();
      cmd.add_option("--grids", o->grids,
                     "comma-separated grid sizes (particles per side); default "
                     "10,20,30,40,50,64,128,256, or 10,20,30 with --quick");
      cmd.add_flag("--quick", o->quick, "small grids, few repeats (seconds; for CI)");
      cmd.add_flag("--no-realtime", o->no_realtime,
                   "time the queries on a normal thread (default: the haptic thread's SCHED_FIFO, "
                   "mlockall, CPU pinning and cpu_dma_latency settings)");
      cmd.add_option("--priority", o->priority, "SCHED_FIFO priority of the query phase (80)")
          ->check(CLI::Range(1, 99));
      cmd.add_option("--cpu", o->cpu,
                     "pin the query phase to this CPU (default: the CPU the command starts on; "
                     "-1: no pinning)")
          ->check(CLI::Range(-1, 4095));
      cmd.add_flag("--plot", o->plot,
                   "run gnuplot on bench/collision.gp to write the PNG next to the CSV");
      return [o, json, csv, md] {
        o->json_given = json->count() > 0;
        o->csv_given = csv->count() > 0;
        o->md_given = md->count() > 0;
        return Run(*o);
      };
    },
});

}  // namespace
}  // namespace felt::bench::bench_collision
