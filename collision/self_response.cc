#include "collision/self_response.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "collision/ccd_proximity.h"
#include "collision/geometry.h"

namespace felt {
namespace {

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
  return std::nullopt;
}

std::string_view SelfCullingMethodName(SelfCullingMethod method) {
  return method == SelfCullingMethod::kBvh ? "bvh" : "spatial_hash";
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
  if (settings.max_zone_iterations < 1) {
    throw std::invalid_argument("self_collision.max_zone_iterations: < 1");
  }
  if (x.size() != inv_mass.size()) {
    throw std::invalid_argument("self-collision: positions and masses differ in size");
  }
  const int32_t n = static_cast<int32_t>(x.size());
  if (settings.method == SelfCullingMethod::kBvh) {
    bvh_.emplace(triangles, x);
  } else {
    hash_.emplace(triangles, x);
  }
  const size_t edges = Broad()->edges().size();
  // Colliding pairs per detection: a vertex touches a handful of faces in a fold; 8 per primitive
  // is far above what the hard scenes reach (an overflow is counted and handled by the fail-safe).
  hits_.reserve(8 * (static_cast<size_t>(n) + edges));
  for (std::vector<Vec3>* a : {&x_before_, &x_trial_, &vel_, &candidates_end_, &zone_mx_, &zone_mv_,
                               &zone_l_, &zone_pin_v_, &zone_omega_}) {
    a->assign(static_cast<size_t>(n), Vec3::Zero());
  }
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
  return &*hash_;
}

void SelfCollisionResponse::BeginStep(std::span<const Vec3> x) {
  std::copy(x.begin(), x.end(), x_before_.begin());
}

// The broad phase runs with the full thickness as padding, the narrow phase with the CCD
// thickness: the candidates then also hold every pair within the thickness at x1 (each box
// contains its primitive at x1 padded by h / 2), which the next substep's proximity pass reuses
// when it starts from x1 (Resolve).
int64_t SelfCollisionResponse::Detect(std::span<const Vec3> x1, SelfCollisionStats* stats) {
  SelfBroadPhase* broad = Broad();
  hits_.clear();
  const SelfBroadPhaseStats bs = broad->FindCandidates(x_before_, x1, settings_.thickness_m);
  candidates_end_valid_ = !bs.overflow;
  if (candidates_end_valid_) std::copy(x1.begin(), x1.end(), candidates_end_.begin());
  if (bs.overflow) {
    ++stats->overflows;
    return std::max<int64_t>(bs.vertex_triangle + bs.edge_edge, 1);  // unseen pairs: fail-safe
  }
  AllPairsCcdOptions options;
  options.ccd.thickness_m = settings_.thickness_m * settings_.ccd_thickness_fraction;
  const std::span<const MeshEdge> edges = broad->edges();
  int64_t hits = 0;
  for (const SelfCandidate& c : broad->candidates()) {
    CcdPairHit h;
    const bool hit = c.kind == CcdPairHit::Kind::kVertexTriangle
                         ? VertexTrianglePairHit(x_before_, x1, c.first, c.second,
                                                 triangles_[c.second], options, &h)
                         : EdgeEdgePairHit(x_before_, x1, c.first, edges[c.first], c.second,
                                           edges[c.second], options, &h);
    if (!hit) continue;
    ++hits;
    if (hits_.size() < hits_.capacity()) hits_.push_back(h);
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
  // The last detection's candidates cover every pair within the thickness at its end positions;
  // when this substep starts exactly there (the common case), no broad phase is needed.
  const bool reuse = candidates_end_valid_ &&
                     std::equal(x_before_.begin(), x_before_.end(), candidates_end_.begin());
  if (!reuse) {
    const SelfBroadPhaseStats bs = broad->FindCandidates(x_before_, x_before_, thick);
    if (bs.overflow) ++stats->overflows;
  }
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
  const size_t n = x_before_.size();
  const double inv_h = 1.0 / h_s;
  for (size_t p = 0; p < n; ++p) {
    vel_[p] = (x[p] - x_before_[p]) * inv_h;
    x_trial_[p] = x[p];
  }
  // 1. Proximity repulsion at x_before.
  Proximity(h_s, &stats);
  FlushTrial(h_s);
  // 2. CCD rounds: inelastic impulses with friction on every colliding pair, Gauss-Seidel in the
  // hits' order (deterministic), detection repeated while collisions remain.
  int64_t remaining = 0;
  for (int32_t round = 0; round <= settings_.iterations; ++round) {
    remaining = Detect(x_trial_, &stats);
    ++stats.ccd_rounds;
    if (round == 0) stats.ccd_hits = remaining;
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
      remaining = Detect(x_trial_, &stats);
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
          remaining = Detect(x_trial_, &stats);
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
        remaining = Detect(x_trial_, &stats);
        if (zone_list_.size() == before && round > 0) break;  // nothing more to freeze
      }
    }
  }
  stats.unresolved = remaining;
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
