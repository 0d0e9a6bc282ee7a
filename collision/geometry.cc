#include "collision/geometry.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace felt {
namespace {

// Entry time t >= 0 of the ray p0 + t d into the sphere |x - center| <= r, for a ray that starts
// outside it; returns +inf if it never enters (Ericson §5.3.2, the smaller root of the quadratic).
double RaySphereEntry(const Vec3& p0, const Vec3& d, const Vec3& center, double r) {
  const Vec3 m = p0 - center;
  const double b = m.dot(d);
  const double c = m.squaredNorm() - r * r;
  const double a = d.squaredNorm();
  if (c <= 0.0 || b >= 0.0 || a <= 0.0) return std::numeric_limits<double>::infinity();
  const double disc = b * b - a * c;
  if (disc < 0.0) return std::numeric_limits<double>::infinity();
  // Grazes (see RayCylinderEntry) are not contacts.
  const double closest = (m - (b / a) * d).norm();
  if (!(r - closest > kGrazeDepth * r)) return std::numeric_limits<double>::infinity();
  return (-b - std::sqrt(disc)) / a;
}

// Entry time t >= 0 of the ray into the finite cylinder of radius r around segment [e0, e1]
// (its side only; the end caps lie inside the vertex spheres), or +inf (Ericson §5.3.7, with the
// components perpendicular to the axis).
double RayCylinderEntry(const Vec3& p0, const Vec3& d, const Vec3& e0, const Vec3& e1, double r,
                        Vec3* normal) {
  const double inf = std::numeric_limits<double>::infinity();
  const Vec3 e = e1 - e0;
  const double ee = e.squaredNorm();
  if (ee <= 0.0) return inf;
  const Vec3 m = p0 - e0;
  const double md = m.dot(e);
  const double nd = d.dot(e);
  const Vec3 m_perp = m - (md / ee) * e;
  const Vec3 d_perp = d - (nd / ee) * e;
  const double a = d_perp.squaredNorm();
  const double b = m_perp.dot(d_perp);
  const double c = m_perp.squaredNorm() - r * r;
  // Starting inside the infinite cylinder or moving parallel to it: entry is through a cap.
  if (c <= 0.0 || a <= 0.0 || b >= 0.0) return inf;
  const double disc = b * b - a * c;
  if (disc < 0.0) return inf;
  // A graze (the line passes at most kGrazeDepth r inside the cylinder) is not a contact: its
  // root is ill-conditioned (an error of order sqrt(eps) tilts the normal) and it cannot tunnel.
  const double closest = (m_perp - (b / a) * d_perp).norm();
  if (!(r - closest > kGrazeDepth * r)) return inf;
  const double t = (-b - std::sqrt(disc)) / a;
  // Keep it only where the entry point projects inside the segment.
  const double s = (md + t * nd) / ee;
  if (s < 0.0 || s > 1.0) return inf;
  const Vec3 radial = m_perp + t * d_perp;
  const double len = radial.norm();
  if (!(len > 0.0)) return inf;
  *normal = radial / len;
  return t;
}

/// The triangle point `point` (world, m) with its barycentric weights of (a, b, c), and its
/// squared distance |p - point|^2 (m^2) to the query point p (world, m).
TrianglePoint TriangleAt(const Vec3& p, const Vec3& point, const Vec3& barycentric) {
  TrianglePoint out;
  out.point = point;
  out.barycentric = barycentric;
  out.distance_sq = (p - point).squaredNorm();
  return out;
}

}  // namespace

SegmentPoint ClosestPointOnSegment(const Vec3& p, const Vec3& a, const Vec3& b) {
  // Ericson §5.1.2: project onto the line and clamp the parameter to [0, 1].
  const Vec3 ab = b - a;
  const double len_sq = ab.squaredNorm();
  if (!(len_sq > 0.0)) return {a, 0.0};
  const double s = std::clamp((p - a).dot(ab) / len_sq, 0.0, 1.0);
  return {a + s * ab, s};
}

bool IsDegenerateTriangle(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a;
  const Vec3 ac = c - a;
  const double n_sq = ab.cross(ac).squaredNorm();
  return !(n_sq > kDegenerateSin2 * ab.squaredNorm() * ac.squaredNorm());
}

TrianglePoint ClosestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  TrianglePoint out;
  // Degenerate triangles: the nearest point of the three edges (each a robust segment query).
  if (IsDegenerateTriangle(a, b, c)) {
    const std::array<const Vec3*, 3> v = {&a, &b, &c};
    double best = std::numeric_limits<double>::infinity();
    for (int i = 0; i < 3; ++i) {
      const int j = (i + 1) % 3;
      const SegmentPoint sp = ClosestPointOnSegment(p, *v[i], *v[j]);
      const double dsq = (p - sp.point).squaredNorm();
      if (dsq < best) {
        best = dsq;
        out.point = sp.point;
        out.barycentric.setZero();
        out.barycentric[i] = 1.0 - sp.s;
        out.barycentric[j] = sp.s;
        out.distance_sq = dsq;
      }
    }
    return out;
  }

  // Ericson §5.1.5: classify p against the Voronoi regions of vertices, edges and the face,
  // using only dot products of the edge vectors with the vectors to p.
  const Vec3 ab = b - a;
  const Vec3 ac = c - a;
  const Vec3 ap = p - a;
  const double d1 = ab.dot(ap);
  const double d2 = ac.dot(ap);
  // Vertex region of a.
  if (d1 <= 0.0 && d2 <= 0.0) return TriangleAt(p, a, Vec3(1, 0, 0));
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp);
  const double d4 = ac.dot(bp);
  // Vertex region of b.
  if (d3 >= 0.0 && d4 <= d3) return TriangleAt(p, b, Vec3(0, 1, 0));
  // Edge region of ab.
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double v = d1 / (d1 - d3);
    return TriangleAt(p, a + v * ab, Vec3(1.0 - v, v, 0.0));
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp);
  const double d6 = ac.dot(cp);
  // Vertex region of c.
  if (d6 >= 0.0 && d5 <= d6) return TriangleAt(p, c, Vec3(0, 0, 1));
  // Edge region of ac.
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double w = d2 / (d2 - d6);
    return TriangleAt(p, a + w * ac, Vec3(1.0 - w, 0.0, w));
  }
  // Edge region of bc.
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return TriangleAt(p, b + w * (c - b), Vec3(0.0, 1.0 - w, w));
  }
  // Face region: barycentrics from the signed sub-areas.
  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom;
  const double w = vc * denom;
  return TriangleAt(p, a + v * ab + w * ac, Vec3(1.0 - v - w, v, w));
}

SweepContact SweepSphereTriangle(const Vec3& p0, const Vec3& p1, double r, const Vec3& a,
                                 const Vec3& b, const Vec3& c) {
  SweepContact out;
  const Vec3 d = p1 - p0;
  const double d_len = d.norm();
  const double approach = -kApproachCos * d_len;
  const bool degenerate = IsDegenerateTriangle(a, b, c);
  const Vec3 face_n = degenerate ? Vec3::Zero() : Vec3((b - a).cross(c - a).normalized());

  // Already overlapping at t = 0: a contact only if the sphere moves toward the triangle.
  const TrianglePoint start = ClosestPointOnTriangle(p0, a, b, c);
  if (start.distance_sq <= r * r) {
    const Vec3 diff = p0 - start.point;
    const double dist = diff.norm();
    Vec3 n;
    if (dist > 0.0) {
      n = diff / dist;
    } else if (!degenerate) {
      n = face_n.dot(d) <= 0.0 ? face_n : Vec3(-face_n);
    } else if (d_len > 0.0) {
      n = -d / d_len;
    } else {
      return out;
    }
    if (n.dot(d) < approach) {
      out.hit = true;
      out.toi = 0.0;
      out.point = start.point;
      out.normal = n;
      out.barycentric = start.barycentric;
    }
    return out;
  }

  double best_t = std::numeric_limits<double>::infinity();
  Vec3 best_n = Vec3::Zero();
  const auto consider = [&](double t, const Vec3& n) {
    if (t >= 0.0 && t <= 1.0 && t < best_t && n.dot(d) < 0.0) {
      best_t = t;
      best_n = n;
    }
  };

  // Faces offset by +-r along the normal, on the side p0 starts from (Ericson §5.3.6).
  if (!degenerate) {
    const double s0 = (p0 - a).dot(face_n);
    const double dn = d.dot(face_n);
    const double sigma = s0 > 0.0 ? 1.0 : (s0 < 0.0 ? -1.0 : (dn > 0.0 ? -1.0 : 1.0));
    if (sigma * dn < 0.0) {
      const double t = (sigma * r - s0) / dn;
      if (t >= 0.0 && t <= 1.0) {
        // The entry point must project inside the triangle (edge-function signs, Ericson §3.4).
        const Vec3 y = p0 + t * d - (s0 + t * dn) * face_n;
        const bool inside = (b - a).cross(y - a).dot(face_n) >= 0.0 &&
                            (c - b).cross(y - b).dot(face_n) >= 0.0 &&
                            (a - c).cross(y - c).dot(face_n) >= 0.0;
        if (inside && sigma * dn < approach) consider(t, sigma * face_n);
      }
    }
  }

  // Edge cylinders and vertex spheres: the rest of the Minkowski sum's boundary.
  const std::array<const Vec3*, 3> v = {&a, &b, &c};
  for (int i = 0; i < 3; ++i) {
    Vec3 n;
    const double t_cyl = RayCylinderEntry(p0, d, *v[i], *v[(i + 1) % 3], r, &n);
    if (t_cyl < best_t) consider(t_cyl, n);
    const double t_sph = RaySphereEntry(p0, d, *v[i], r);
    if (t_sph < best_t) {
      const Vec3 radial = p0 + t_sph * d - *v[i];
      const double len = radial.norm();
      if (len > 0.0) consider(t_sph, radial / len);
    }
  }
  if (!(best_t <= 1.0)) return out;

  // The touched point and its barycentrics: the closest point at the time of impact.
  const TrianglePoint at = ClosestPointOnTriangle(p0 + best_t * d, a, b, c);
  out.hit = true;
  out.toi = best_t;
  out.point = at.point;
  out.normal = best_n;
  out.barycentric = at.barycentric;
  return out;
}

SweepContact MovingTriangleSphereContact(const Vec3& c0, const Vec3& c1, double r, const Vec3& a0,
                                         const Vec3& b0, const Vec3& c0v, const Vec3& a1,
                                         const Vec3& b1, const Vec3& c1v,
                                         const MovingContactOptions& options) {
  SweepContact out;
  // Velocities per unit t, relative to the sphere's centre.
  const Vec3 dc = c1 - c0;
  const std::array<Vec3, 3> rel = {(a1 - a0) - dc, (b1 - b0) - dc, (c1v - c0v) - dc};
  const double lipschitz = std::max({rel[0].norm(), rel[1].norm(), rel[2].norm()});

  double t = 0.0;
  for (int32_t iter = 0; iter <= options.max_iterations; ++iter) {
    // Closest point of the triangle at time t.
    const Vec3 centre = c0 + t * dc;
    const Vec3 a = a0 + t * (a1 - a0);
    const Vec3 b = b0 + t * (b1 - b0);
    const Vec3 c = c0v + t * (c1v - c0v);
    const TrianglePoint cp = ClosestPointOnTriangle(centre, a, b, c);
    const double dist = std::sqrt(cp.distance_sq);
    const double gap = dist - r;
    const bool give_up = iter == options.max_iterations;
    if (gap <= options.tolerance_m || give_up) {
      // The touched point's velocity relative to the centre, by the same barycentric weights.
      const Vec3 w =
          cp.barycentric[0] * rel[0] + cp.barycentric[1] * rel[1] + cp.barycentric[2] * rel[2];
      Vec3 n;
      if (dist > 0.0) {
        n = (centre - cp.point) / dist;
      } else if (!IsDegenerateTriangle(a, b, c)) {
        const Vec3 face_n = (b - a).cross(c - a).normalized();
        n = face_n.dot(w) >= 0.0 ? face_n : Vec3(-face_n);
      } else if (w.norm() > 0.0) {
        n = w.normalized();
      } else {
        return out;
      }
      // At t = 0 an overlap counts only if the triangle approaches the sphere.
      if (t == 0.0 && !(n.dot(w) > kApproachCos * lipschitz)) return out;
      out.hit = true;
      out.toi = t;
      out.point = cp.point;
      out.normal = n;
      out.barycentric = cp.barycentric;
      return out;
    }
    // Advance by the gap over the largest relative speed: no contact can happen before.
    if (!(lipschitz > 0.0)) return out;
    t += gap / lipschitz;
    if (t > 1.0) return out;
  }
  return out;
}

}  // namespace felt
