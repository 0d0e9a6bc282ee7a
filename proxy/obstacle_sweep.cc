#include "proxy/obstacle_sweep.h"

#include <algorithm>
#include <cmath>
#include <variant>

#include "sim_loop/cloth.h"

namespace felt {
namespace {

// Whether p lies in the closed box [lo, hi].
bool InBox(const Vec3& p, const Vec3& lo, const Vec3& hi) {
  return (p.array() >= lo.array()).all() && (p.array() <= hi.array()).all();
}

// Keeps the earlier of two entry times (call with the test's result already computed: an
// argument's evaluation order is unspecified).
void KeepEarlier(bool hit, double t, bool* any, double* best) {
  if (hit && (!*any || t < *best)) {
    *any = true;
    *best = t;
  }
}

// First entry of the segment into a box grown by r (a rounded box), p0 outside it: the union of
// the three face slabs (the box grown by r along one axis) and the twelve edge capsules of radius
// r (their end balls are the rounded corners). Ericson §5.5.7.
bool SegmentEntersRoundedBox(const Vec3& p0, const Vec3& p1, const Vec3& lo, const Vec3& hi,
                             double r, double* t) {
  // Cull by the grown box, which holds the rounded box.
  const Vec3 grow = Vec3::Constant(r);
  double t_grown = 0.0;
  if (!InBox(p0, lo - grow, hi + grow) && !SegmentEntersBox(p0, p1, lo - grow, hi + grow, &t_grown))
    return false;
  bool any = false;
  double best = 1.0;
  double ti = 0.0;
  // The face slabs.
  for (int axis = 0; axis < 3; ++axis) {
    Vec3 g = Vec3::Zero();
    g(axis) = r;
    const bool hit = SegmentEntersBox(p0, p1, lo - g, hi + g, &ti);
    KeepEarlier(hit, ti, &any, &best);
  }
  // The edges: along `axis`, at each of the four (lo|hi, lo|hi) of the other two axes.
  for (int axis = 0; axis < 3; ++axis) {
    const int j = (axis + 1) % 3;
    const int k = (axis + 2) % 3;
    for (int corner = 0; corner < 4; ++corner) {
      Vec3 a = lo;
      a(j) = (corner & 1) != 0 ? hi(j) : lo(j);
      a(k) = (corner & 2) != 0 ? hi(k) : lo(k);
      Vec3 b = a;
      b(axis) = hi(axis);
      const bool hit = SegmentEntersCapsule(p0, p1, a, b, r, &ti);
      KeepEarlier(hit, ti, &any, &best);
    }
  }
  if (any) *t = best;
  return any;
}

}  // namespace

ObstaclePoint ClosestObstaclePoint(const ObstacleSpec& obstacle, const Vec3& p_W) {
  ObstaclePoint out;
  Vec3 normal = Vec3::UnitY();
  out.distance_m = ObstacleDistance(obstacle, p_W, &normal);
  out.normal_W = normal;
  // Every shape's distance is measured along its normal: the surface point is p - d n.
  out.point_W_m = p_W - out.distance_m * normal;
  return out;
}

bool SegmentEntersBall(const Vec3& p0, const Vec3& p1, const Vec3& c, double R, double* t) {
  // Ericson §5.3.2: |m + t d|^2 = R^2 with m = p0 - c; the smaller root is the entry.
  const Vec3 d = p1 - p0;
  const Vec3 m = p0 - c;
  const double a = d.squaredNorm();
  const double b = m.dot(d);
  const double cc = m.squaredNorm() - R * R;
  if (cc <= 0.0 || a <= 0.0 || b >= 0.0) return false;  // inside, still, or moving away
  const double disc = b * b - a * cc;
  if (disc < 0.0) return false;
  const double root = (-b - std::sqrt(disc)) / a;
  if (root > 1.0) return false;
  *t = std::max(0.0, root);
  return true;
}

bool SegmentEntersCapsule(const Vec3& p0, const Vec3& p1, const Vec3& a, const Vec3& b, double R,
                          double* t) {
  // Starting inside the capsule is no entry.
  if ((p0 - ClosestPointOnSegment(p0, a, b).point).squaredNorm() <= R * R) return false;
  bool any = false;
  double best = 1.0;
  double ti = 0.0;
  // The end balls (Ericson §5.3.2).
  bool hit = SegmentEntersBall(p0, p1, a, R, &ti);
  KeepEarlier(hit, ti, &any, &best);
  hit = SegmentEntersBall(p0, p1, b, R, &ti);
  KeepEarlier(hit, ti, &any, &best);
  // The side of the finite cylinder (Ericson §5.3.7): the components of m = p0 - a and of the
  // motion d orthogonal to the axis give |m_perp + t d_perp|^2 = R^2; an entry counts where its
  // axial parameter lies on [a, b] (an entry through an end disc is inside that end's ball).
  const Vec3 ab = b - a;
  const double L2 = ab.squaredNorm();
  if (L2 > 0.0) {
    const Vec3 d = p1 - p0;
    const Vec3 m = p0 - a;
    const Vec3 m_perp = m - (m.dot(ab) / L2) * ab;
    const Vec3 d_perp = d - (d.dot(ab) / L2) * ab;
    const double qa = d_perp.squaredNorm();
    const double qb = m_perp.dot(d_perp);
    const double qc = m_perp.squaredNorm() - R * R;
    if (qa > 0.0 && qc > 0.0 && qb < 0.0) {
      const double disc = qb * qb - qa * qc;
      if (disc >= 0.0) {
        const double root = (-qb - std::sqrt(disc)) / qa;
        const double s = (m + root * d).dot(ab) / L2;
        if (root >= 0.0 && root <= 1.0 && s >= 0.0 && s <= 1.0) {
          KeepEarlier(true, root, &any, &best);
        }
      }
    }
  }
  if (any) *t = best;
  return any;
}

bool SegmentEntersBox(const Vec3& p0, const Vec3& p1, const Vec3& lo, const Vec3& hi, double* t) {
  if (InBox(p0, lo, hi)) return false;
  // Ericson §5.3.3: intersect the parameter intervals of the three slabs.
  const Vec3 d = p1 - p0;
  double t_min = 0.0;
  double t_max = 1.0;
  for (int i = 0; i < 3; ++i) {
    if (d(i) == 0.0) {
      if (p0(i) < lo(i) || p0(i) > hi(i)) return false;
      continue;
    }
    double t1 = (lo(i) - p0(i)) / d(i);
    double t2 = (hi(i) - p0(i)) / d(i);
    if (t1 > t2) std::swap(t1, t2);
    t_min = std::max(t_min, t1);
    t_max = std::min(t_max, t2);
    if (t_min > t_max) return false;
  }
  *t = t_min;
  return true;
}

SweepContact SweepSphereObstacle(const Vec3& p0, const Vec3& p1, double r,
                                 const ObstacleSpec& obstacle) {
  SweepContact out;
  const Vec3 d = p1 - p0;
  const ObstaclePoint start = ClosestObstaclePoint(obstacle, p0);
  // Already touching: a contact now only if moving toward the obstacle (convexity: moving away or
  // along it, the distance never falls again on this motion). "Touching" includes a rounding
  // slack, so that a start the distance puts just outside but a piece's own test puts just inside
  // (|p - c| - h against p <= c + h) is not taken for a start inside that piece.
  const double slack = 1e-12 * (1.0 + r + p0.cwiseAbs().maxCoeff());
  if (start.distance_m <= r + slack) {
    if (start.normal_W.dot(d) < -kApproachCos * d.norm()) {
      out.hit = true;
      out.toi = 0.0;
      out.point = start.point_W_m;
      out.normal = start.normal_W;
    }
    return out;
  }
  // The motion's entry into the obstacle grown by r.
  bool hit = false;
  double t = 1.0;
  if (const auto* plane = std::get_if<PlaneSpec>(&obstacle.shape)) {
    // The plane moved by r along its normal: n . (p0 + t d - q) = r.
    const double dn = plane->normal.dot(d);
    if (dn < 0.0) {
      t = (start.distance_m - r) / -dn;
      hit = t <= 1.0;
    }
  } else if (const auto* sphere = std::get_if<SphereSpec>(&obstacle.shape)) {
    hit = SegmentEntersBall(p0, p1, sphere->center_m, sphere->radius_m + r, &t);
  } else if (const auto* box = std::get_if<BoxSpec>(&obstacle.shape)) {
    hit = SegmentEntersRoundedBox(p0, p1, box->min_m, box->max_m, r, &t);
  } else if (const auto* capsule = std::get_if<CapsuleSpec>(&obstacle.shape)) {
    hit = SegmentEntersCapsule(p0, p1, capsule->a_m, capsule->b_m, capsule->radius_m + r, &t);
  }
  if (!hit) return out;
  // The contact: the obstacle's nearest point to the centre at toi, and its outward normal.
  const ObstaclePoint at = ClosestObstaclePoint(obstacle, p0 + t * d);
  out.hit = true;
  out.toi = t;
  out.point = at.point_W_m;
  out.normal = at.normal_W;
  return out;
}

SweepContact SweepSphereObstacles(const Vec3& p0, const Vec3& p1, double r,
                                  std::span<const ObstacleSpec> obstacles, int32_t* index) {
  SweepContact best;
  for (size_t k = 0; k < obstacles.size(); ++k) {
    const SweepContact c = SweepSphereObstacle(p0, p1, r, obstacles[k]);
    if (c.hit && (!best.hit || c.toi < best.toi)) {
      best = c;
      *index = static_cast<int32_t>(k);
    }
  }
  return best;
}

}  // namespace felt
