#include "collision/self_response.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "collision/ccd_proximity.h"
#include "collision/geometry.h"

namespace felt {
namespace {

// bvh_cones: the pass's broad phase (on its motion) also serves the proximity pass while the
// last pass's repulsion moved at most 1 / kConeShareMovedDen of the vertices; otherwise the
// proximity pass gets its own on the static x_before and the first CCD detection another on its
// motion. Measured on `felt bench self-collision` (docs/self_collision.md, "One broad phase per
// pass"): sharing always halved the broad phases at 32 x 32 (frame 3.2 -> 2.1 times the frame
// without), but at 64 x 64, where the pile's repulsion moves thousands of vertices, the carried
// over broad phase was nearly a full one and the certificate over the motion culled fewer close
// pairs (proximity pairs 6.8k -> 12.2k per frame): 5.4 times against 4.6 unshared.
constexpr int64_t kConeShareMovedDen = 16;
// bvh_cones: a detection runs a full broad phase instead of carrying the last one over when more
// than 1 / kConeUpdateMovedDen of the vertices moved since (the traversal would be nearly
// full, and the carried-over list must also be filtered).
constexpr int64_t kConeUpdateMovedDen = 4;
// apccd: when some vertices left the last broad phase's boxes, at most 1 / kDanglingDen of them,
// only theirs are made again and the tree traversed again where they are (APCCD's dangling
// vertices and triangles, 004_aff31237b107e6f0.txt; SelfBvh::UpdateCandidates); more, and a full
// broad phase runs (the cones' threshold, for the same reason).
constexpr int64_t kDanglingDen = 4;

// Distances below this [m] give no usable direction between closest points: the face normal (or
// the edges' cross product) is used instead.
constexpr double kSelfResponseTinyDistance_m = 1e-12;

// A unit vector normal to both edge directions, or zero when they are parallel.
Vec3 SelfResponseEdgeNormal(const Vec3& a, const Vec3& b) {
  const Vec3 c = a.cross(b);
  const double len = c.norm();
  return len > 1e-20 ? Vec3(c / len) : Vec3(Vec3::Zero());
}

// True when the boxes of points a (na of them) and b (nb) at one time are more than `gap` [m]
// apart on some axis: the primitives are then more than gap apart (a cheap rejection before the
// closest points; the candidates come from swept boxes, many of which are far apart at x_before).
bool SelfResponseBoxesApart(const Vec3* const* a, int na, const Vec3* const* b, int nb,
                            double gap) {
  for (int k = 0; k < 3; ++k) {
    double alo = (*a[0])[k], ahi = alo, blo = (*b[0])[k], bhi = blo;
    for (int i = 1; i < na; ++i) {
      alo = std::min(alo, (*a[i])[k]);
      ahi = std::max(ahi, (*a[i])[k]);
    }
    for (int i = 1; i < nb; ++i) {
      blo = std::min(blo, (*b[i])[k]);
      bhi = std::max(bhi, (*b[i])[k]);
    }
    if (blo - ahi > gap || alo - bhi > gap) return true;
  }
  return false;
}

}  // namespace

std::optional<SelfCullingMethod> SelfCullingMethodFromName(std::string_view name) {
  if (name == "spatial_hash") return SelfCullingMethod::kSpatialHash;
  if (name == "bvh") return SelfCullingMethod::kBvh;
  if (name == "bvh_cones") return SelfCullingMethod::kBvhCones;
  if (name == "bvox_aabb") return SelfCullingMethod::kBvox;
  if (name == "apccd") return SelfCullingMethod::kApccd;
  return std::nullopt;
}

std::string_view SelfCullingMethodName(SelfCullingMethod method) {
  switch (method) {
    case SelfCullingMethod::kBvh:
      return "bvh";
    case SelfCullingMethod::kBvhCones:
      return "bvh_cones";
    case SelfCullingMethod::kBvox:
      return "bvox_aabb";
    case SelfCullingMethod::kApccd:
      return "apccd";
    case SelfCullingMethod::kSpatialHash:
      break;
  }
  return "spatial_hash";
}

SelfCollisionResponse::SelfCollisionResponse(std::span<const Triangle> triangles,
                                             std::span<const Vec3> x,
                                             std::span<const double> inv_mass,
                                             const SelfCollisionSettings& settings)
    : settings_(settings),
      triangles_(triangles.begin(), triangles.end()),
      inv_mass_(inv_mass.begin(), inv_mass.end()) {
  if (!(settings.thickness_m > 0.0) || !std::isfinite(settings.thickness_m)) {
    throw std::invalid_argument("self_collision.thickness_m: must be > 0");
  }
  if (settings.iterations < 0) throw std::invalid_argument("self_collision.iterations: < 0");
  if (!(settings.friction >= 0.0)) throw std::invalid_argument("self_collision.friction: < 0");
  if (!(settings.repulsion_stiffness_N_per_m >= 0.0)) {
    throw std::invalid_argument("self_collision.repulsion_stiffness_N_per_m: < 0");
  }
  if (!(settings.ccd_thickness_fraction > 0.0 && settings.ccd_thickness_fraction <= 1.0)) {
    throw std::invalid_argument("self-collision: ccd_thickness_fraction must be in (0, 1]");
  }
  if (settings.passes_per_frame < 1) {
    throw std::invalid_argument("self_collision.passes_per_frame: < 1");
  }
  if (settings.min_passes_per_frame < 1) {
    throw std::invalid_argument("self_collision.min_passes_per_frame: < 1");
  }
  if (!(settings.slow_pass_motion >= 0.0) || !std::isfinite(settings.slow_pass_motion)) {
    throw std::invalid_argument("self_collision.slow_pass_motion: must be >= 0");
  }
  if (!(settings.hand_pass_motion >= 0.0) || !std::isfinite(settings.hand_pass_motion)) {
    throw std::invalid_argument("self_collision.hand_pass_motion: must be >= 0");
  }
  if (!(settings.max_pass_motion >= 0.0) || !std::isfinite(settings.max_pass_motion)) {
    throw std::invalid_argument("self_collision.max_pass_motion: must be >= 0");
  }
  if (settings.max_zone_iterations < 1) {
    throw std::invalid_argument("self_collision.max_zone_iterations: < 1");
  }
  if (x.size() != inv_mass.size()) {
    throw std::invalid_argument("self-collision: positions and masses differ in size");
  }
  const int32_t n = static_cast<int32_t>(x.size());
  if (settings.method == SelfCullingMethod::kBvh || settings.method == SelfCullingMethod::kApccd) {
    bvh_.emplace(triangles, x);
    apccd_ = settings.method == SelfCullingMethod::kApccd;
  } else if (settings.method == SelfCullingMethod::kBvhCones) {
    SelfBroadPhaseOptions options;
    options.normal_cones = true;
    bvh_.emplace(triangles, x, options);
    cones_ = true;
  } else if (settings.method == SelfCullingMethod::kBvox) {
    bvox_.emplace(triangles, x);
  } else {
    hash_.emplace(triangles, x);
  }
  const size_t edges = Broad()->edges().size();
  // Colliding pairs per detection: a vertex touches a handful of faces in a fold; 8 per primitive
  // is far above what the hard scenes reach (an overflow is counted and handled by the fail-safe).
  hits_.reserve(8 * (static_cast<size_t>(n) + edges));
  for (std::vector<Vec3>* a :
       {&x_before_, &x_trial_, &vel_, &broad_lo_, &broad_hi_, &ccd_lo_, &ccd_hi_, &zone_mx_,
        &zone_mv_, &zone_l_, &zone_pin_v_, &zone_omega_}) {
    a->assign(static_cast<size_t>(n), Vec3::Zero());
  }
  cand_hit_.assign(static_cast<size_t>(Broad()->max_candidates()), 0);
  moved_.assign(static_cast<size_t>(n), 0);
  dangling_.assign(static_cast<size_t>(n), 0);
  moved_list_.reserve(static_cast<size_t>(n));
  if (!(settings.broad_inflation >= 0.0) || !std::isfinite(settings.broad_inflation)) {
    throw std::invalid_argument("self_collision.broad_inflation: must be >= 0");
  }
  // The broad phase pads by the half thickness plus the inflation (the 1e-5 as in
  // self_broadphase.cc). A position may lie this far outside the last sweep's boxes and its
  // candidates still cover a test at distance d: a box padded by d / 2 (1 + 1e-5) around it
  // stays inside the broad phase's padded box (10 % kept back for rounding).
  const double h = settings.thickness_m;
  broad_pad_m_ = 0.5 * h * (1.0 + 2.0 * settings.broad_inflation) * (1.0 + 1e-5);
  ccd_margin_m_ = 0.9 * (broad_pad_m_ - 0.5 * h * settings.ccd_thickness_fraction * (1.0 + 1e-5));
  prox_margin_m_ = 0.9 * (broad_pad_m_ - 0.5 * h * (1.0 + 1e-5));
  dirty_.assign(static_cast<size_t>(n), 0);
  dirty_list_.reserve(static_cast<size_t>(n));
  parent_.resize(static_cast<size_t>(n));
  in_zone_.assign(static_cast<size_t>(n), 0);
  zone_list_.reserve(static_cast<size_t>(n));
  zone_mass_.assign(static_cast<size_t>(n), 0.0);
  zone_inertia_.assign(static_cast<size_t>(n), Eigen::Matrix3d::Zero());
  zone_pins_.assign(static_cast<size_t>(n), 0);
  zone_stamp_.assign(static_cast<size_t>(n), 0);
  double mass = 0.0;
  int32_t free = 0;
  for (double im : inv_mass_) {
    if (im > 0.0) {
      mass += 1.0 / im;
      ++free;
    }
  }
  particle_mass_kg_ = free > 0 ? mass / free : 1.0;
}

SelfBroadPhase* SelfCollisionResponse::Broad() {
  if (bvh_) return &*bvh_;
  if (bvox_) return &*bvox_;
  return &*hash_;
}

const SelfBroadPhase* SelfCollisionResponse::Broad() const {
  if (bvh_) return &*bvh_;
  if (bvox_) return &*bvox_;
  return &*hash_;
}

void SelfCollisionResponse::BeginStep(std::span<const Vec3> x) {
  std::copy(x.begin(), x.end(), x_before_.begin());
}

void SelfCollisionResponse::KeepFirstPass(bool on) {
  keep_first_pass_ = on;
  if (on) {
    first_end_.assign(x_before_.size(), Vec3::Zero());
    first_hits_.reserve(hits_.capacity());
  } else {
    first_end_.clear();
  }
  first_hits_.clear();
}

AllPairsCcdOptions SelfCollisionResponse::CcdPassOptions() const {
  AllPairsCcdOptions options;
  options.ccd.thickness_m = settings_.thickness_m * settings_.ccd_thickness_fraction;
  return options;
}

// Vertex p's swept box x_before -> x1, padded as the broad phase pads for the CCD thickness.
void SelfCollisionResponse::SetCcdBox(int32_t p, std::span<const Vec3> x1) {
  const double pad = 0.5 * settings_.thickness_m * settings_.ccd_thickness_fraction * (1.0 + 1e-5);
  ccd_lo_[p] = x_before_[p].cwiseMin(x1[p]).array() - pad;
  ccd_hi_[p] = x_before_[p].cwiseMax(x1[p]).array() + pad;
}

namespace {
// True when the boxes [alo, ahi] and [blo, bhi] share a point (closed).
bool SelfResponseBoxesMeet(const Vec3& alo, const Vec3& ahi, const Vec3& blo, const Vec3& bhi) {
  return alo.x() <= bhi.x() && blo.x() <= ahi.x() && alo.y() <= bhi.y() && blo.y() <= ahi.y() &&
         alo.z() <= bhi.z() && blo.z() <= ahi.z();
}
}  // namespace

// One candidate's continuous test over x_before -> x1. The candidates come from boxes padded by
// the full thickness; a pair whose boxes padded by the CCD's thickness (ccd_lo_, ccd_hi_) do not
// meet cannot be reported by the test (the broad phase's own argument), so it is skipped first.
bool SelfCollisionResponse::NarrowTest(int32_t candidate, std::span<const Vec3> x1,
                                       const AllPairsCcdOptions& options, CcdPairHit* hit) {
  const SelfBroadPhase* broad = Broad();
  const SelfCandidate& c = broad->candidates()[candidate];
  if (c.kind == CcdPairHit::Kind::kVertexTriangle) {
    const Triangle& t = triangles_[c.second];
    const Vec3 lo = ccd_lo_[t[0]].cwiseMin(ccd_lo_[t[1]]).cwiseMin(ccd_lo_[t[2]]);
    const Vec3 hi = ccd_hi_[t[0]].cwiseMax(ccd_hi_[t[1]]).cwiseMax(ccd_hi_[t[2]]);
    if (!SelfResponseBoxesMeet(ccd_lo_[c.first], ccd_hi_[c.first], lo, hi)) return false;
    return VertexTrianglePairHit(x_before_, x1, c.first, c.second, t, options, hit);
  }
  const MeshEdge& e = broad->edges()[c.first];
  const MeshEdge& f = broad->edges()[c.second];
  if (!SelfResponseBoxesMeet(
          ccd_lo_[e[0]].cwiseMin(ccd_lo_[e[1]]), ccd_hi_[e[0]].cwiseMax(ccd_hi_[e[1]]),
          ccd_lo_[f[0]].cwiseMin(ccd_lo_[f[1]]), ccd_hi_[f[0]].cwiseMax(ccd_hi_[f[1]]))) {
    return false;
  }
  return EdgeEdgePairHit(x_before_, x1, c.first, e, c.second, f, options, hit);
}

// The broad phase on x_before_ -> x1 with boxes padded by broad_pad_m_ (FindCandidates pads by
// half its thickness argument, times 1 + 1e-5); remembers each vertex's sweep.
void SelfCollisionResponse::RunBroadPhase(std::span<const Vec3> x1, SelfCollisionStats* stats) {
  narrow_valid_ = false;
  const SelfBroadPhaseStats bs =
      Broad()->FindCandidates(x_before_, x1, 2.0 * broad_pad_m_ / (1.0 + 1e-5));
  ++stats->broad_phases;
  broad_valid_ = !bs.overflow;
  if (bs.overflow) ++stats->overflows;
  const int32_t n = static_cast<int32_t>(x_before_.size());
  for (int32_t p = 0; p < n; ++p) {
    broad_lo_[p] = x_before_[p].cwiseMin(x1[p]);
    broad_hi_[p] = x_before_[p].cwiseMax(x1[p]);
  }
}

// The broad phase for x_before_ -> x1 when the last one no longer covers it: some vertex lies
// more than margin_m [m] outside its sweep there (WithinBroadBoxes). With apccd (the fixed tree),
// when those dangling vertices are few (kDanglingDen), only their boxes are made again and the
// tree is traversed again where they are (SelfBvh::UpdateCandidates): every other vertex's box
// still holds its sweep padded for the test (the reuse argument of DetectAll), so the candidates
// among the triangles none of whose vertices dangles still cover their pairs, and each pair with a
// dangling triangle is found again against the boxes the tree holds. Otherwise a full broad phase.
void SelfCollisionResponse::RefreshBroadPhase(std::span<const Vec3> x1, double margin_m,
                                              SelfCollisionStats* stats) {
  const int32_t n = static_cast<int32_t>(x_before_.size());
  if (apccd_ && broad_valid_) {
    int64_t count = 0;
    for (int32_t p = 0; p < n; ++p) {
      const bool out =
          !(WithinBroadBoxes(p, x_before_[p], margin_m) && WithinBroadBoxes(p, x1[p], margin_m));
      dangling_[p] = out ? 1 : 0;
      count += out ? 1 : 0;
    }
    if (count * kDanglingDen <= n) {
      narrow_valid_ = false;
      const SelfBroadPhaseStats bs =
          bvh_->UpdateCandidates(x_before_, x1, 2.0 * broad_pad_m_ / (1.0 + 1e-5), 0.0, dangling_);
      ++stats->broad_updates;
      broad_valid_ = !bs.overflow;
      if (bs.overflow) ++stats->overflows;
      for (int32_t p = 0; p < n; ++p) {
        if (!dangling_[p]) continue;
        broad_lo_[p] = x_before_[p].cwiseMin(x1[p]);
        broad_hi_[p] = x_before_[p].cwiseMax(x1[p]);
      }
      return;
    }
  }
  RunBroadPhase(x1, stats);
}

// True when q lies within margin_m [m] of vertex p's box in the last broad phase.
bool SelfCollisionResponse::WithinBroadBoxes(int32_t p, const Vec3& q, double margin_m) const {
  return (q.array() >= broad_lo_[p].array() - margin_m).all() &&
         (q.array() <= broad_hi_[p].array() + margin_m).all();
}

// Every candidate's continuous test over x_before_ -> x1. The candidates of the last broad phase
// are reused when every vertex's sweep lies within the CCD's margin of its boxes there (APCCD's
// skipped broad phase); otherwise the broad phase runs first.
int64_t SelfCollisionResponse::DetectAll(std::span<const Vec3> x1, SelfCollisionStats* stats) {
  SelfBroadPhase* broad = Broad();
  hits_.clear();
  for (int32_t p : moved_list_) moved_[p] = 0;
  moved_list_.clear();
  const int32_t n = static_cast<int32_t>(x_before_.size());
  const AllPairsCcdOptions options = CcdPassOptions();
  bool reuse = broad_valid_;
  for (int32_t p = 0; reuse && p < n; ++p) {
    reuse = WithinBroadBoxes(p, x_before_[p], ccd_margin_m_) &&
            WithinBroadBoxes(p, x1[p], ccd_margin_m_);
  }
  if (reuse) {
    ++stats->broad_reuses;
  } else {
    RefreshBroadPhase(x1, ccd_margin_m_, stats);
  }
  narrow_valid_ = false;
  if (!broad_valid_) {
    // Overflow: unseen pairs, the fail-safe's last resort.
    return std::max<int64_t>(static_cast<int64_t>(broad->candidates().size()), 1);
  }
  for (int32_t p = 0; p < n; ++p) SetCcdBox(p, x1);
  const int32_t count = static_cast<int32_t>(broad->candidates().size());
  int64_t hits = 0;
  for (int32_t i = 0; i < count; ++i) TestCandidate(i, x1, options, stats, &hits);
  narrow_valid_ = true;
  if (static_cast<size_t>(hits) > hits_.size()) ++stats->overflows;
  return hits;
}

// The narrow test of candidate i on x_before_ -> x1: its result kept for the next round, a hit
// counted in *hits and kept while hits_ has room (DetectAll and Detect count the overflow).
void SelfCollisionResponse::TestCandidate(int32_t i, std::span<const Vec3> x1,
                                          const AllPairsCcdOptions& options,
                                          SelfCollisionStats* stats, int64_t* hits) {
  CcdPairHit h;
  ++stats->narrow_tests;
  const bool hit = NarrowTest(i, x1, options, &h);
  cand_hit_[i] = hit ? 1 : 0;
  if (!hit) return;
  ++*hits;
  if (hits_.size() < hits_.capacity()) hits_.push_back(h);
}

// True when the candidates and narrow results of the last detection still cover x_trial_: every
// vertex moved since then ends within the CCD's margin of its boxes (x_before_ is unchanged
// within a pass, and was within it at that detection).
bool SelfCollisionResponse::CanDetectIncrementally() const {
  if (cones_ || !narrow_valid_ || !broad_valid_) return false;
  for (int32_t p : moved_list_) {
    if (!WithinBroadBoxes(p, x_trial_[p], ccd_margin_m_)) return false;
  }
  return true;
}

// Detection of the motion x_before -> x1 (x1 is x_trial_). After a first detection of all
// candidates, a round only re-tests the candidates that have a vertex moved since the last
// detection, or that collided then (a pair whose four trajectories did not change has the same
// result), as long as the moved vertices stay within the CCD's margin of the broad phase's
// boxes; otherwise every candidate is tested again (DetectAll). Hits in candidate order.
int64_t SelfCollisionResponse::Detect(std::span<const Vec3> x1, SelfCollisionStats* stats) {
  if (cones_) return DetectCones(x1, stats);
  if (!CanDetectIncrementally()) return DetectAll(x1, stats);
  ++stats->incremental_detections;
  const SelfBroadPhase* broad = Broad();
  hits_.clear();
  for (int32_t p : moved_list_) SetCcdBox(p, x1);
  const AllPairsCcdOptions options = CcdPassOptions();
  const std::span<const SelfCandidate> cands = broad->candidates();
  const std::span<const MeshEdge> edges = broad->edges();
  const int32_t count = static_cast<int32_t>(cands.size());
  int64_t hits = 0;
  for (int32_t i = 0; i < count; ++i) {
    const SelfCandidate& c = cands[i];
    bool retest = cand_hit_[i] != 0;
    if (!retest) {
      if (c.kind == CcdPairHit::Kind::kVertexTriangle) {
        const Triangle& t = triangles_[c.second];
        retest = (moved_[c.first] | moved_[t[0]] | moved_[t[1]] | moved_[t[2]]) != 0;
      } else {
        const MeshEdge& e = edges[c.first];
        const MeshEdge& f = edges[c.second];
        retest = (moved_[e[0]] | moved_[e[1]] | moved_[f[0]] | moved_[f[1]]) != 0;
      }
    }
    if (retest) TestCandidate(i, x1, options, stats, &hits);
  }
  for (int32_t p : moved_list_) moved_[p] = 0;
  moved_list_.clear();
  if (static_cast<size_t>(hits) > hits_.size()) ++stats->overflows;
  return hits;
}

void SelfCollisionResponse::ClearMoved() {
  for (int32_t p : moved_list_) moved_[p] = 0;
  moved_list_.clear();
}

// bvh_cones' detection of x_before_ -> x1 (x1 is x_trial_). The pass's broad phase (Proximity)
// is carried over to this motion: SelfBvh::UpdateCandidates keeps the candidates of triangles
// none of whose vertices moved since the last detection and traverses again where one did. A
// kept candidate's four trajectories did not change, so its last result stands: only the new
// candidates are tested, and the kept ones that collided (to give their hits again); the first
// detection after the broad phase tests all. A full broad phase runs again (on this motion,
// same padding) after an overflow or when more than a quarter of the vertices moved. Every
// candidate is first filtered by the CCD thickness's boxes (NarrowTest). Hits in candidate
// order.
int64_t SelfCollisionResponse::DetectCones(std::span<const Vec3> x1, SelfCollisionStats* stats) {
  SelfBvh* bvh = &*bvh_;
  hits_.clear();
  const AllPairsCcdOptions options = CcdPassOptions();
  const int32_t n = static_cast<int32_t>(x_before_.size());
  const double thick = options.ccd.thickness_m;
  const double start_thick = share_ ? settings_.thickness_m : 0.0;
  int32_t first_new = 0;  // candidates [first_new, end) have no narrow result
  if (!cone_valid_ || kConeUpdateMovedDen * std::ssize(moved_list_) > n) {
    // A full broad phase on this motion.
    const SelfBroadPhaseStats bs = bvh->FindCandidates(x_before_, x1, thick, start_thick);
    ++stats->broad_phases;
    cone_valid_ = !bs.overflow;
    ClearMoved();
    if (bs.overflow) {
      ++stats->overflows;
      return std::max<int64_t>(static_cast<int64_t>(bvh->candidates().size()), 1);
    }
    cone_fresh_ = true;
  } else if (!moved_list_.empty()) {
    const SelfBroadPhaseStats bs = bvh->UpdateCandidates(x_before_, x1, thick, start_thick, moved_);
    ++stats->broad_updates;
    if (bs.overflow) {
      cone_valid_ = false;
      ClearMoved();
      ++stats->overflows;
      return std::max<int64_t>(static_cast<int64_t>(bvh->candidates().size()), 1);
    }
    // The kept candidates' results follow them (kept_from is increasing and never below i).
    const std::span<const int32_t> kept_from = bvh->kept_from();
    first_new = static_cast<int32_t>(kept_from.size());
    for (int32_t i = 0; i < first_new; ++i) cand_hit_[i] = cand_hit_[kept_from[i]];
  } else {
    first_new = static_cast<int32_t>(bvh->candidates().size());  // nothing moved
  }
  if (cone_fresh_) {
    for (int32_t p = 0; p < n; ++p) SetCcdBox(p, x1);
    first_new = 0;
    cone_fresh_ = false;
  } else {
    for (int32_t p : moved_list_) SetCcdBox(p, x1);
  }
  ClearMoved();
  const int32_t count = static_cast<int32_t>(bvh->candidates().size());
  int64_t hits = 0;
  for (int32_t i = 0; i < count; ++i) {
    if (i >= first_new || cand_hit_[i] != 0) TestCandidate(i, x1, options, stats, &hits);
  }
  if (static_cast<size_t>(hits) > hits_.size()) ++stats->overflows;
  return hits;
}

void SelfCollisionResponse::SetVelocity(int32_t p, const Vec3& vel) {
  vel_[p] = vel;
  if (!dirty_[p]) {
    dirty_[p] = 1;
    dirty_list_.push_back(p);
  }
}

void SelfCollisionResponse::FlushTrial(double h_s) {
  for (int32_t p : dirty_list_) {
    x_trial_[p] = x_before_[p] + h_s * vel_[p];
    dirty_[p] = 0;
    if (!moved_[p]) {
      moved_[p] = 1;
      moved_list_.push_back(p);
    }
  }
  dirty_list_.clear();
}

// Changes the relative velocity sum_i w_i vel_i of the four vertices by dv (a vector, m/s) with
// the least kinetic energy: impulse j = dv / sum_i w_i^2 / m_i, vel_i += w_i j / m_i (Bridson et
// al. 2002 §7.1's weighted impulse, with per-vertex masses; a pinned vertex has 1/m = 0).
bool SelfCollisionResponse::ApplyPairImpulse(const std::array<int32_t, 4>& vid,
                                             const std::array<double, 4>& w, const Vec3& dv) {
  double denom = 0.0;
  for (int i = 0; i < 4; ++i) denom += w[i] * w[i] * inv_mass_[vid[i]];
  if (!(denom > 0.0)) return false;
  const Vec3 j = dv / denom;
  for (int i = 0; i < 4; ++i) {
    const double im = inv_mass_[vid[i]];
    if (im == 0.0 || w[i] == 0.0) continue;
    SetVelocity(vid[i], vel_[vid[i]] + (w[i] * im) * j);
  }
  return true;
}

// The velocity change of one pair: remove the approach speed -v_N along n (inelastic), add
// extra_normal [m/s] (the repulsion spring), and reduce the tangential relative velocity by at most
// mu times the normal change (Coulomb friction, Bridson §7.3). Returns the normal change.
namespace {
Vec3 SelfResponsePairDelta(const Vec3& v_rel, const Vec3& n, double extra_normal, double mu,
                           double* dv_normal) {
  const double vn = v_rel.dot(n);
  const double inelastic = vn < 0.0 ? -vn : 0.0;
  const double dvn = inelastic + extra_normal;
  *dv_normal = dvn;
  Vec3 delta = dvn * n;
  if (mu > 0.0 && dvn > 0.0) {
    const Vec3 vt = v_rel - vn * n;
    const double vt_len = vt.norm();
    if (vt_len > 0.0) delta -= std::min(1.0, mu * dvn / vt_len) * vt;
  }
  return delta;
}
}  // namespace

void SelfCollisionResponse::Proximity(double h_s, SelfCollisionStats* stats) {
  SelfBroadPhase* broad = Broad();
  const double thick = settings_.thickness_m;
  // The last broad phase's candidates cover every pair within the thickness at positions within
  // prox_margin_m_ of its boxes; when this pass starts there (the common case: the last pass
  // ended inside its sweep), no broad phase is needed. Otherwise one on the static positions.
  bool reuse = broad_valid_;
  const int32_t num = static_cast<int32_t>(x_before_.size());
  for (int32_t p = 0; reuse && p < num; ++p) {
    reuse = WithinBroadBoxes(p, x_before_[p], prox_margin_m_);
  }
  if (cones_) {
    // Cone-culled candidates hold for their own motion only. Shared: one broad phase on the
    // pass's motion x_before -> x (x_trial_ before any impulse), boxes padded for the CCD's
    // thickness around the sweep and for the full thickness around x_before; a patch certified
    // over the motion is certified at x_before too, so it serves this pass (at x_before) and,
    // carried over to the motion the repulsion leaves (DetectCones), the first CCD detection.
    // Not shared (the last pass's repulsion moved many vertices): one on the static x_before.
    const auto start = std::chrono::steady_clock::now();
    ClearMoved();
    share_ = kConeShareMovedDen * prox_moved_ <= std::ssize(x_before_);
    const SelfBroadPhaseStats bs =
        share_ ? bvh_->FindCandidates(x_before_, x_trial_, CcdPassOptions().ccd.thickness_m, thick)
               : broad->FindCandidates(x_before_, x_before_, thick);
    ++stats->broad_phases;
    if (bs.overflow) ++stats->overflows;
    broad_valid_ = false;
    cone_valid_ = !bs.overflow && share_;
    cone_fresh_ = true;
    stats->detect_s +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  } else if (!reuse) {
    const auto start = std::chrono::steady_clock::now();
    RefreshBroadPhase(x_before_, prox_margin_m_, stats);
    stats->detect_s +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  narrow_valid_ = false;  // these candidates carry no narrow results
  const std::span<const MeshEdge> edges = broad->edges();
  const double k_over_m = settings_.repulsion_stiffness_N_per_m / particle_mass_kg_;
  for (const SelfCandidate& c : broad->candidates()) {
    std::array<int32_t, 4> vid;
    std::array<double, 4> w;
    Vec3 n;
    double d;
    if (c.kind == CcdPairHit::Kind::kVertexTriangle) {
      const Triangle& t = triangles_[c.second];
      vid = {c.first, t[0], t[1], t[2]};
      const Vec3& p = x_before_[c.first];
      const Vec3* pv[1] = {&p};
      const Vec3* tv[3] = {&x_before_[t[0]], &x_before_[t[1]], &x_before_[t[2]]};
      if (SelfResponseBoxesApart(pv, 1, tv, 3, thick)) continue;
      const TrianglePoint tp =
          ClosestPointOnTriangle(p, x_before_[t[0]], x_before_[t[1]], x_before_[t[2]]);
      if (tp.distance_sq >= thick * thick) continue;
      d = std::sqrt(tp.distance_sq);
      w = {1.0, -tp.barycentric[0], -tp.barycentric[1], -tp.barycentric[2]};
      if (d > kSelfResponseTinyDistance_m) {
        n = (p - tp.point) / d;
      } else {
        n = SelfResponseEdgeNormal(x_before_[t[1]] - x_before_[t[0]],
                                   x_before_[t[2]] - x_before_[t[0]]);
      }
    } else {
      const MeshEdge& e = edges[c.first];
      const MeshEdge& f = edges[c.second];
      vid = {e[0], e[1], f[0], f[1]};
      const Vec3* ev[2] = {&x_before_[e[0]], &x_before_[e[1]]};
      const Vec3* fv[2] = {&x_before_[f[0]], &x_before_[f[1]]};
      if (SelfResponseBoxesApart(ev, 2, fv, 2, thick)) continue;
      const SegmentsClosest sc = ClosestPointsOfSegments(x_before_[e[0]], x_before_[e[1]],
                                                         x_before_[f[0]], x_before_[f[1]]);
      if (sc.distance_sq >= thick * thick) continue;
      d = std::sqrt(sc.distance_sq);
      w = {1.0 - sc.s, sc.s, -(1.0 - sc.u), -sc.u};
      if (d > kSelfResponseTinyDistance_m) {
        n = (sc.point_a - sc.point_b) / d;
      } else {
        n = SelfResponseEdgeNormal(x_before_[e[1]] - x_before_[e[0]],
                                   x_before_[f[1]] - x_before_[f[0]]);
      }
    }
    ++stats->proximity_pairs;
    Vec3 v_rel = Vec3::Zero();
    for (int i = 0; i < 4; ++i) v_rel += w[i] * vel_[vid[i]];
    if (n.isZero()) {
      // Touching with no direction: push against the relative velocity.
      const double len = v_rel.norm();
      if (!(len > 0.0)) continue;
      n = -v_rel / len;
    }
    // Bridson §7.2: the repulsion spring's impulse h k d / m, limited so that the normal speed it
    // leaves does not exceed 0.1 d / h (d = thickness - distance, the overlap).
    const double overlap = thick - d;
    const double vn = v_rel.dot(n);
    const double vn_after = std::max(vn, 0.0);
    const double cap = 0.1 * overlap / h_s - vn_after;
    const double spring = cap > 0.0 ? std::min(h_s * k_over_m * overlap, cap) : 0.0;
    double dvn = 0.0;
    const Vec3 delta = SelfResponsePairDelta(v_rel, n, spring, settings_.friction, &dvn);
    if (dvn > 0.0 && ApplyPairImpulse(vid, w, delta)) ++stats->proximity_impulses;
  }
}

int32_t SelfCollisionResponse::Find(int32_t p) {
  while (parent_[p] != p) {
    parent_[p] = parent_[parent_[p]];  // path halving
    p = parent_[p];
  }
  return p;
}

void SelfCollisionResponse::Union(int32_t a, int32_t b) {
  for (int32_t p : {a, b}) {
    if (!in_zone_[p]) {
      in_zone_[p] = 1;
      parent_[p] = p;
      zone_list_.push_back(p);
    }
  }
  const int32_t ra = Find(a);
  const int32_t rb = Find(b);
  if (ra == rb) return;
  // The smaller index is the root: the zones do not depend on the order of the unions.
  if (ra < rb) {
    parent_[rb] = ra;
  } else {
    parent_[ra] = rb;
  }
}

// Every zone's free vertices get the zone's rigid velocity (Provot 1997; Bridson §7.4): the
// mass-weighted mean velocity v_cm plus w x (x - x_cm), with w = I^-1 L from the zone's angular
// momentum L and inertia tensor I about its centre of mass, at x_before (directions of I with a
// near-zero moment get no spin: a zone on a line). A zone holding pinned vertices (infinite mass)
// moves with their mean velocity.
void SelfCollisionResponse::RigidZones(double h_s, SelfCollisionStats* stats) {
  ++stamp_;
  int64_t zones = 0;
  for (int32_t p : zone_list_) {
    const int32_t r = Find(p);
    if (zone_stamp_[r] != stamp_) {
      zone_stamp_[r] = stamp_;
      zone_mass_[r] = 0.0;
      zone_mx_[r].setZero();
      zone_mv_[r].setZero();
      zone_l_[r].setZero();
      zone_pin_v_[r].setZero();
      zone_inertia_[r].setZero();
      zone_pins_[r] = 0;
      ++zones;
    }
    const double im = inv_mass_[p];
    if (im == 0.0) {
      ++zone_pins_[r];
      zone_pin_v_[r] += vel_[p];
      continue;
    }
    const double m = 1.0 / im;
    zone_mass_[r] += m;
    zone_mx_[r] += m * x_before_[p];
    zone_mv_[r] += m * vel_[p];
  }
  stats->impact_zones = zones;
  stats->zone_vertices = static_cast<int64_t>(zone_list_.size());
  for (int32_t p : zone_list_) {
    const int32_t r = Find(p);
    const double im = inv_mass_[p];
    if (im == 0.0 || zone_pins_[r] > 0) continue;
    const double m = 1.0 / im;
    const Vec3 rp = x_before_[p] - zone_mx_[r] / zone_mass_[r];
    const Vec3 vp = vel_[p] - zone_mv_[r] / zone_mass_[r];
    zone_l_[r] += m * rp.cross(vp);
    zone_inertia_[r] += m * (rp.squaredNorm() * Eigen::Matrix3d::Identity() - rp * rp.transpose());
  }
  ++stamp_;
  for (int32_t p : zone_list_) {
    const int32_t r = Find(p);
    if (zone_stamp_[r] == stamp_) continue;
    zone_stamp_[r] = stamp_;
    zone_omega_[r].setZero();
    if (zone_pins_[r] > 0) continue;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(zone_inertia_[r]);
    const Eigen::Vector3d lambda = eig.eigenvalues();
    const double floor = 1e-12 * std::max(lambda.maxCoeff(), 0.0);
    for (int k = 0; k < 3; ++k) {
      if (lambda[k] > floor && lambda[k] > 0.0) {
        const Vec3 u = eig.eigenvectors().col(k);
        zone_omega_[r] += (u.dot(zone_l_[r]) / lambda[k]) * u;
      }
    }
  }
  for (int32_t p : zone_list_) {
    if (inv_mass_[p] == 0.0) continue;
    const int32_t r = Find(p);
    if (zone_pins_[r] > 0) {
      SetVelocity(p, zone_pin_v_[r] / zone_pins_[r]);
    } else {
      const Vec3 x_cm = zone_mx_[r] / zone_mass_[r];
      SetVelocity(p, zone_mv_[r] / zone_mass_[r] + zone_omega_[r].cross(x_before_[p] - x_cm));
    }
  }
  FlushTrial(h_s);
}

SelfCollisionStats SelfCollisionResponse::Resolve(double h_s, std::span<Vec3> x,
                                                  std::span<Vec3> v) {
  SelfCollisionStats stats;
  stats.passes = 1;
  const size_t n = x_before_.size();
  const double inv_h = 1.0 / h_s;
  for (size_t p = 0; p < n; ++p) {
    vel_[p] = (x[p] - x_before_[p]) * inv_h;
    x_trial_[p] = x[p];
  }
  // 1. Proximity repulsion at x_before.
  Proximity(h_s, &stats);
  FlushTrial(h_s);
  prox_moved_ = static_cast<int64_t>(moved_list_.size());
  // Every detection is timed (stats.detect_s).
  const auto detect = [&]() {
    const auto start = std::chrono::steady_clock::now();
    const int64_t found = Detect(x_trial_, &stats);
    const double s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    stats.detect_s += s;
    return std::pair<int64_t, double>(found, s);
  };
  // 2. CCD rounds: inelastic impulses with friction on every colliding pair, Gauss-Seidel in the
  // hits' order (deterministic), detection repeated while collisions remain.
  int64_t remaining = 0;
  for (int32_t round = 0; round <= settings_.iterations; ++round) {
    const auto [found, seconds] = detect();
    remaining = found;
    ++stats.ccd_rounds;
    if (round == 0) {
      stats.ccd_hits = remaining;
      stats.first_detect_s = seconds;
      if (keep_first_pass_) {
        std::copy(x_trial_.begin(), x_trial_.end(), first_end_.begin());
        first_hits_.assign(hits_.begin(), hits_.end());  // capacity reserved: no allocation
      }
    }
    if (remaining == 0 || round == settings_.iterations) break;
    for (const CcdPairHit& hit : hits_) {
      Vec3 v_rel = Vec3::Zero();
      for (int i = 0; i < 4; ++i) v_rel += hit.weights[i] * vel_[hit.vertices[i]];
      double dvn = 0.0;
      const Vec3 delta = SelfResponsePairDelta(v_rel, hit.normal, 0.0, settings_.friction, &dvn);
      if (dvn > 0.0 && ApplyPairImpulse(hit.vertices, hit.weights, delta)) {
        ++stats.ccd_impulses;
      }
    }
    FlushTrial(h_s);
  }
  // 3. Fail-safe: rigid impact zones, merged until no collision remains.
  if (remaining > 0 && settings_.fail_safe) {
    for (int32_t p : zone_list_) in_zone_[p] = 0;
    zone_list_.clear();
    bool overflowed = false;
    while (remaining > 0 && stats.zone_rounds < settings_.max_zone_iterations) {
      if (hits_.size() < static_cast<size_t>(remaining)) overflowed = true;
      if (overflowed) break;
      for (const CcdPairHit& hit : hits_) {
        for (int i = 1; i < 4; ++i) Union(hit.vertices[0], hit.vertices[i]);
      }
      RigidZones(h_s, &stats);
      ++stats.zone_rounds;
      remaining = detect().first;
    }
    if (remaining > 0) {
      // The zones did not settle (or a buffer overflowed): the free vertices of every zone keep
      // their start positions, the zones still growing by the collisions that remain; with
      // incomplete hits, every free vertex stays.
      stats.frozen = true;
      for (size_t round = 0; remaining > 0 && round <= n; ++round) {
        if (overflowed || hits_.size() < static_cast<size_t>(remaining)) {
          for (size_t p = 0; p < n; ++p) {
            if (inv_mass_[p] > 0.0) SetVelocity(static_cast<int32_t>(p), Vec3::Zero());
          }
          FlushTrial(h_s);
          remaining = detect().first;
          break;
        }
        const size_t before = zone_list_.size();
        for (const CcdPairHit& hit : hits_) {
          for (int i = 1; i < 4; ++i) Union(hit.vertices[0], hit.vertices[i]);
        }
        for (int32_t p : zone_list_) {
          if (inv_mass_[p] > 0.0) SetVelocity(p, Vec3::Zero());
        }
        FlushTrial(h_s);
        remaining = detect().first;
        if (zone_list_.size() == before && round > 0) break;  // nothing more to freeze
      }
    }
  }
  stats.unresolved = remaining;
  totals_.proximity_pairs += stats.proximity_pairs;
  totals_.proximity_impulses += stats.proximity_impulses;
  totals_.ccd_hits += stats.ccd_hits;
  totals_.ccd_impulses += stats.ccd_impulses;
  totals_.ccd_rounds += stats.ccd_rounds;
  totals_.zone_rounds += stats.zone_rounds;
  totals_.impact_zones += stats.impact_zones;
  totals_.zone_vertices += stats.zone_vertices;
  totals_.frozen = totals_.frozen || stats.frozen;
  totals_.unresolved += stats.unresolved;
  totals_.overflows += stats.overflows;
  totals_.broad_phases += stats.broad_phases;
  totals_.broad_reuses += stats.broad_reuses;
  totals_.broad_updates += stats.broad_updates;
  totals_.incremental_detections += stats.incremental_detections;
  totals_.narrow_tests += stats.narrow_tests;
  totals_.detect_s += stats.detect_s;
  totals_.first_detect_s += stats.first_detect_s;
  totals_.passes += stats.passes;
  // The corrected motion, as Provot's constraints apply theirs: x += dx, v += dx / h.
  for (size_t p = 0; p < n; ++p) {
    if (inv_mass_[p] == 0.0) continue;
    const Vec3 dx = x_trial_[p] - x[p];
    if (dx.isZero()) continue;
    x[p] = x_trial_[p];
    v[p] += dx * inv_h;
  }
  return stats;
}

}  // namespace felt
