#include "collision/ccd.h"
// The implementations of collision/ccd_proximity.h, ccd_cubic.h, ccd.h and ccd_all_pairs.h (one
// file: see docs/self_collision.md, "Build note").

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "base/check.h"
#include "collision/ccd_all_pairs.h"
#include "collision/ccd_cubic.h"
#include "collision/ccd_proximity.h"
#include "collision/geometry.h"

namespace felt {

// ----------------------------------------------------------------------------------------------
// collision/ccd_proximity.h
// ----------------------------------------------------------------------------------------------

namespace {

// Segments whose sin^2 of the angle between them is above this are "far from parallel": the
// stationary point's parameters then carry a relative error of about 1e-13 (machine epsilon over
// sin), and when it lies inside the square it is the answer without a look at the boundary.
constexpr double kWellConditionedSin2 = 1e-6;

SegmentsClosest SegmentsAt(const Vec3& p0, const Vec3& d1, const Vec3& q0, const Vec3& d2, double s,
                           double u) {
  SegmentsClosest out;
  out.s = s;
  out.u = u;
  out.point_a = p0 + s * d1;
  out.point_b = q0 + u * d2;
  out.distance_sq = (out.point_a - out.point_b).squaredNorm();
  return out;
}

}  // namespace

SegmentsClosest ClosestPointsOfSegments(const Vec3& p0, const Vec3& p1, const Vec3& q0,
                                        const Vec3& q1) {
  const Vec3 d1 = p1 - p0;
  const Vec3 d2 = q1 - q0;
  const Vec3 r = p0 - q0;
  const double a = d1.squaredNorm();
  const double e = d2.squaredNorm();
  // n = d1 x d2, |n|^2 = a e sin^2(angle): zero for parallel or zero-length segments. Formed from
  // the cross product rather than as a e - (d1.d2)^2, it keeps its relative accuracy (about
  // epsilon / sin, not epsilon / sin^2) for nearly parallel segments.
  const Vec3 n = d1.cross(d2);
  const double nn = n.squaredNorm();

  SegmentsClosest best;
  best.distance_sq = std::numeric_limits<double>::infinity();
  // The stationary point of the quadratic (Ericson §5.1.9: c + a s - b u = 0, f + b s - e u = 0
  // with b = d1.d2, c = d1.r, f = d2.r), its numerators rewritten by Lagrange's identity
  // (x × y).(z × w) = (x.z)(y.w) - (x.w)(y.z): s = n.(d2 × r) / |n|^2, u = n.(d1 × r) / |n|^2.
  // Kept (clamped into the square) as a candidate.
  if (a > 0.0 && e > 0.0 && nn > 0.0) {
    const double s = n.dot(d2.cross(r)) / nn;
    const double u = n.dot(d1.cross(r)) / nn;
    const bool inside = s >= 0.0 && s <= 1.0 && u >= 0.0 && u <= 1.0;
    best = SegmentsAt(p0, d1, q0, d2, std::clamp(s, 0.0, 1.0), std::clamp(u, 0.0, 1.0));
    if (inside && nn > kWellConditionedSin2 * a * e) return best;
  }
  // The square's four sides: each end point against the other segment.
  const auto consider = [&](double s, double u) {
    const SegmentsClosest cand = SegmentsAt(p0, d1, q0, d2, s, u);
    if (cand.distance_sq < best.distance_sq) best = cand;
  };
  consider(0.0, ClosestPointOnSegment(p0, q0, q1).s);
  consider(1.0, ClosestPointOnSegment(p1, q0, q1).s);
  consider(ClosestPointOnSegment(q0, p0, p1).s, 0.0);
  consider(ClosestPointOnSegment(q1, p0, p1).s, 1.0);
  return best;
}

// ----------------------------------------------------------------------------------------------
// collision/ccd_cubic.h
// ----------------------------------------------------------------------------------------------

namespace {

// Half an ulp of 1 (the unit roundoff of doubles).
constexpr double kCubicUnitRoundoff = 0x1p-53;
// error_bound = kCubicErrorFactor u M (see MakeCoplanarityCubic's comment).
constexpr double kCubicErrorFactor = 64.0;
// The ends of a band interval are located to this many units of t (a few ulps of 1).
constexpr double kCubicTimeTolerance = 1e-15;
// A Newton step this small leaves an error of about its square times |P'' / 2 P'|: the probes
// are tried (and the iteration continues if they do not bracket the crossing).
constexpr double kCubicNewtonConverged = 1e-8;

// The triple product [X Y Z] = (X x Y) . Z.
double Triple(const Vec3& x, const Vec3& y, const Vec3& z) { return x.cross(y).dot(z); }

// The permanent of the 3x3 matrix with rows x, y, z (all entries >= 0): the sum of the absolute
// values of the six terms of the determinant.
double Permanent(const Vec3& x, const Vec3& y, const Vec3& z) {
  return x[0] * (y[1] * z[2] + y[2] * z[1]) + x[1] * (y[2] * z[0] + y[0] * z[2]) +
         x[2] * (y[0] * z[1] + y[1] * z[0]);
}

// Roots in the open interval (0, 1) of qa t^2 + qb t + qc, appended to roots[*n].
void QuadraticRootsInUnit(double qa, double qb, double qc, double* roots, int* n) {
  const auto keep = [&](double t) {
    if (t > 0.0 && t < 1.0) roots[(*n)++] = t;
  };
  if (qa == 0.0) {
    if (qb != 0.0) keep(-qc / qb);
    return;
  }
  const double disc = qb * qb - 4.0 * qa * qc;
  if (disc < 0.0) return;  // a nearly double root is covered by the inflection split
  // Cancellation-free form (Press et al., Numerical Recipes, §5.6).
  const double q = -0.5 * (qb + std::copysign(std::sqrt(disc), qb));
  keep(q / qa);
  if (q != 0.0) keep(qc / q);
}

// The end, on the side where P is outside the band (sign(level) (P - level) > 0), of a bracket
// around the crossing of P = level between t_out (outside, P = f_out there) and t_in (not outside,
// P = f_in), P monotone between them: a first guess (`guess`, or where the chord crosses the
// level when it is NaN), then Newton steps kept inside the bracket (bisection otherwise); once a
// step is small enough for Newton's quadratic convergence to have reached the tolerance, probes a
// tolerance to each side of the estimate close the bracket (else the iteration goes on).
double BandEdge(const CoplanarityCubic& cubic, double t_out, double f_out, double t_in, double f_in,
                double level, double guess) {
  const double side = level >= 0.0 ? 1.0 : -1.0;
  const auto outside = [&](double v) { return side * (v - level) > 0.0; };
  double t = std::isnan(guess) ? t_out + (level - f_out) / (f_in - f_out) * (t_in - t_out) : guess;
  for (int iter = 0; iter < 64; ++iter) {
    double lo = std::min(t_out, t_in), hi = std::max(t_out, t_in);
    if (hi - lo <= 4.0 * kCubicTimeTolerance) break;
    if (!(t > lo && t < hi)) t = 0.5 * (lo + hi);  // bisection (also for a NaN guess)
    const CubicValue v = EvaluateCoplanarity(cubic, t);
    (outside(v.value) ? t_out : t_in) = t;
    const double step = (v.value - level) / v.slope;
    if (!(std::abs(step) <= kCubicNewtonConverged)) {
      t -= step;  // Newton (a NaN or out-of-bracket guess bisects next)
      continue;
    }
    // Converged: one probe on each side of the estimate.
    lo = std::min(t_out, t_in), hi = std::max(t_out, t_in);
    const double toward_in = t_in > t_out ? 1.0 : -1.0;
    const double a = std::clamp(t - step - toward_in * kCubicTimeTolerance, lo, hi);
    const double b = std::clamp(t - step + toward_in * kCubicTimeTolerance, lo, hi);
    if (outside(EvaluateCoplanarity(cubic, a).value)) t_out = a;
    if (!outside(EvaluateCoplanarity(cubic, b).value)) t_in = b;
    t = 0.5 * (t_out + t_in);
  }
  return t_out;
}

}  // namespace

CoplanarityCubic MakeCoplanarityCubic(const Vec3& a0, const Vec3& a1, const Vec3& b0,
                                      const Vec3& b1, const Vec3& c0, const Vec3& c1) {
  CoplanarityCubic cubic;
  // The blossom of the trilinear P (Tang et al. 2014: the Bernstein form of the coplanarity
  // polynomial): coefficient i averages the triple products with i factors taken at t = 1.
  cubic.bernstein[0] = Triple(a0, b0, c0);
  cubic.bernstein[1] = (Triple(a1, b0, c0) + Triple(a0, b1, c0) + Triple(a0, b0, c1)) / 3.0;
  cubic.bernstein[2] = (Triple(a0, b1, c1) + Triple(a1, b0, c1) + Triple(a1, b1, c0)) / 3.0;
  cubic.bernstein[3] = Triple(a1, b1, c1);
  // Rounding error bound (docs/self_collision.md, "Error bound"): every triple product of the
  // coefficients and every value of P on [0, 1] is a combination of terms bounded by M.
  const Vec3 abar = a0.cwiseAbs().cwiseMax(a1.cwiseAbs());
  const Vec3 bbar = b0.cwiseAbs().cwiseMax(b1.cwiseAbs());
  const Vec3 cbar = c0.cwiseAbs().cwiseMax(c1.cwiseAbs());
  cubic.error_bound = kCubicErrorFactor * kCubicUnitRoundoff * Permanent(abar, bbar, cbar);
  return cubic;
}

CubicValue EvaluateCoplanarity(const CoplanarityCubic& cubic, double t) {
  // de Casteljau: three levels of convex combinations; the last two points give the slope.
  const auto& b = cubic.bernstein;
  const double s = 1.0 - t;
  const double l0 = s * b[0] + t * b[1];
  const double l1 = s * b[1] + t * b[2];
  const double l2 = s * b[2] + t * b[3];
  const double m0 = s * l0 + t * l1;
  const double m1 = s * l1 + t * l2;
  return {s * m0 + t * m1, 3.0 * (m1 - m0)};
}

std::array<double, 4> PowerCoefficients(const std::array<double, 4>& b) {
  return {b[0], 3.0 * (b[1] - b[0]), 3.0 * (b[0] - 2.0 * b[1] + b[2]),
          b[3] - 3.0 * b[2] + 3.0 * b[1] - b[0]};
}

CoplanarTimes CoplanarCandidateTimes(const CoplanarityCubic& cubic) {
  CoplanarTimes out;
  const auto& b = cubic.bernstein;
  const double e = cubic.error_bound;
  // Bernstein sign classification: P lies in the convex hull of its coefficients.
  const double bmin = std::min(std::min(b[0], b[1]), std::min(b[2], b[3]));
  const double bmax = std::max(std::max(b[0], b[1]), std::max(b[2], b[3]));
  if (bmin > e || bmax < -e) return out;

  // Split [0, 1] where P' or P'' vanishes. P'(t) = 3 (d0 (1-t)^2 + 2 d1 t (1-t) + d2 t^2), whose
  // bracket is d0 + 2 (d1 - d0) t + (d0 - 2 d1 + d2) t^2; P'' is proportional to
  // (d1 - d0) (1 - t) + (d2 - d1) t.
  const double d0 = b[1] - b[0], d1 = b[2] - b[1], d2 = b[3] - b[2];
  std::array<double, 5> split;
  int n = 0;
  split[n++] = 0.0;
  QuadraticRootsInUnit(d0 - 2.0 * d1 + d2, 2.0 * (d1 - d0), d0, split.data(), &n);
  const double curvature_change = (d1 - d0) - (d2 - d1);
  if (curvature_change != 0.0) {
    const double inflection = (d1 - d0) / curvature_change;
    if (inflection > 0.0 && inflection < 1.0) split[n++] = inflection;
  }
  // Sort the (at most three) interior splits; insertion sort (std::sort on a fixed array trips
  // GCC 12's -Warray-bounds).
  for (int i = 2; i < n; ++i) {
    for (int j = i; j > 1 && split[j] < split[j - 1]; --j) std::swap(split[j], split[j - 1]);
  }
  split[n++] = 1.0;

  // On each monotone piece, the interval where |P| <= e.
  double f_left = EvaluateCoplanarity(cubic, 0.0).value;
  for (int i = 0; i + 1 < n; ++i) {
    const double l = split[i], r = split[i + 1];
    const double f_right = EvaluateCoplanarity(cubic, r).value;
    const double fl = f_left;
    f_left = f_right;
    if (!(r > l)) continue;
    if ((fl > e && f_right > e) || (fl < -e && f_right < -e)) continue;
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double begin =
        std::abs(fl) <= e ? l : BandEdge(cubic, l, fl, r, f_right, std::copysign(e, fl), nan);
    // Through the band (a simple root): the far edge lies about 2 e / |P'| beyond the near one.
    double guess = nan;
    if (std::abs(fl) > e && std::abs(f_right) > e) {
      const double slope = EvaluateCoplanarity(cubic, begin).slope;
      guess = begin + 2.0 * e / std::abs(slope);
    }
    const double end = std::abs(f_right) <= e
                           ? r
                           : BandEdge(cubic, r, f_right, l, fl, std::copysign(e, f_right), guess);
    // Merge with the previous interval when they touch (a band across a split point).
    if (out.count > 0 && begin <= out.intervals[out.count - 1].end) {
      out.intervals[out.count - 1].end = std::max(out.intervals[out.count - 1].end, end);
    } else {
      out.intervals[out.count++] = {begin, end};
    }
  }
  return out;
}

// ----------------------------------------------------------------------------------------------
// collision/ccd.h
// ----------------------------------------------------------------------------------------------

namespace {

// A direction shorter than this many ulps of the coordinates' magnitude is rounding noise.
constexpr double kCcdNoiseUlps = 64.0 * 0x1p-53;

CcdPoints PointsAt(const CcdPoints& x0, const CcdPoints& x1, double t) {
  CcdPoints p;
  for (int i = 0; i < 4; ++i) p[i] = LinearPointAt(x0[i], x1[i], t);
  return p;
}

// The magnitude below which a difference of these positions is rounding noise, m.
double NoiseLength(const CcdPoints& p) {
  double m = 0.0;
  for (const Vec3& v : p) m = std::max(m, v.cwiseAbs().maxCoeff());
  return kCcdNoiseUlps * m;
}

// Where a conservative advancement stopped.
struct Advanced {
  bool hit = false;
  bool capped = false;
  double t = 0.0;
};

// The earliest t in [begin, end] with distance_at(t) <= h (1 + slack), by conservative
// advancement (Mirtich, "Impulse-based dynamic simulation of rigid body systems", PhD thesis,
// 1996): the distance changes by at most `speed` per unit t, so it stays above h for
// (d - h) / speed after a time at distance d; the interval's end is always examined. A step
// landing a rounding error past a contact lands within rounding of it, far inside h.
template <class DistanceAt>
Advanced Advance(DistanceAt&& distance_at, double begin, double end, double speed, double h,
                 int32_t max_steps) {
  const double h_hit = h * (1.0 + kCcdDistanceSlack);
  double t = begin;
  for (int32_t step = 0;; ++step) {
    const double d = distance_at(t);
    if (d <= h_hit) return {true, false, t};
    if (!(speed > 0.0) || t >= end) return {false, false, t};
    if (step >= max_steps) return {true, true, t};
    const double next = t + (d - h) / speed;
    t = next < end ? next : end;
  }
}

// A unit direction for a contact without a face normal: `apart` (from the second primitive to
// the first) when longer than rounding noise, else against the relative velocity, else +z.
Vec3 FallbackNormal(const Vec3& apart, const Vec3& relative_velocity, double noise) {
  if (apart.norm() > noise) return apart.normalized();
  if (relative_velocity.norm() > 0.0) return -relative_velocity.normalized();
  return Vec3::UnitZ();
}

// Turns n toward the side the first primitive started on (`apart0`, its separation at t = 0 with
// the contact's weights), or against the relative velocity when it started in contact.
Vec3 Oriented(const Vec3& n, const Vec3& apart0, const Vec3& relative_velocity) {
  const double side = n.dot(apart0);
  if (side < 0.0 || (side == 0.0 && n.dot(relative_velocity) > 0.0)) return -n;
  return n;
}

// The vertex-triangle proximity at time t.
struct VertexTriangleState {
  CcdPoints p;
  TrianglePoint closest;
};

VertexTriangleState VertexTriangleAt(const CcdPoints& x0, const CcdPoints& x1, double t) {
  VertexTriangleState s;
  s.p = PointsAt(x0, x1, t);
  s.closest = ClosestPointOnTriangle(s.p[0], s.p[1], s.p[2], s.p[3]);
  return s;
}

// The hit record at an advancement's stop, with the normal of the file comment
// (`prefer_apart`: the minimal-separation variant's closest-point direction first).
VertexTriangleHit VertexTriangleHitAt(const CcdPoints& x0, const CcdPoints& x1, const Advanced& adv,
                                      bool prefer_apart) {
  const VertexTriangleState s = VertexTriangleAt(x0, x1, adv.t);
  const Vec3& w = s.closest.barycentric;
  VertexTriangleHit hit;
  hit.hit = true;
  hit.capped = adv.capped;
  hit.toi = adv.t;
  hit.distance_m = std::sqrt(s.closest.distance_sq);
  hit.barycentric = w;
  const auto velocity = [&](int i) -> Vec3 { return x1[i] - x0[i]; };
  const Vec3 relative_velocity =
      velocity(0) - (w[0] * velocity(1) + w[1] * velocity(2) + w[2] * velocity(3));
  const Vec3 apart0 = x0[0] - (w[0] * x0[1] + w[1] * x0[2] + w[2] * x0[3]);
  const Vec3 apart = s.p[0] - s.closest.point;
  const double noise = NoiseLength(s.p);
  Vec3 n;
  if (prefer_apart && apart.norm() > noise) {
    n = apart.normalized();
  } else if (!IsDegenerateTriangle(s.p[1], s.p[2], s.p[3])) {
    n = Oriented((s.p[2] - s.p[1]).cross(s.p[3] - s.p[1]).normalized(), apart0, relative_velocity);
  } else {
    n = Oriented(FallbackNormal(apart, relative_velocity, noise), apart0, relative_velocity);
  }
  hit.normal = n;
  return hit;
}

// The edge-edge proximity at time t.
struct EdgeEdgeState {
  CcdPoints p;
  SegmentsClosest closest;
};

EdgeEdgeState EdgeEdgeAt(const CcdPoints& x0, const CcdPoints& x1, double t) {
  EdgeEdgeState s;
  s.p = PointsAt(x0, x1, t);
  s.closest = ClosestPointsOfSegments(s.p[0], s.p[1], s.p[2], s.p[3]);
  return s;
}

EdgeEdgeHit EdgeEdgeHitAt(const CcdPoints& x0, const CcdPoints& x1, const Advanced& adv,
                          bool prefer_apart) {
  const EdgeEdgeState s = EdgeEdgeAt(x0, x1, adv.t);
  EdgeEdgeHit hit;
  hit.hit = true;
  hit.capped = adv.capped;
  hit.toi = adv.t;
  hit.distance_m = std::sqrt(s.closest.distance_sq);
  hit.s = s.closest.s;
  hit.u = s.closest.u;
  const auto at = [&](const CcdPoints& x, double s_e, double u_f) -> Vec3 {
    return (x[0] + s_e * (x[1] - x[0])) - (x[2] + u_f * (x[3] - x[2]));
  };
  CcdPoints v;
  for (int i = 0; i < 4; ++i) v[i] = x1[i] - x0[i];
  const Vec3 relative_velocity = at(v, hit.s, hit.u);
  const Vec3 apart0 = at(x0, hit.s, hit.u);
  const Vec3 apart = s.closest.point_a - s.closest.point_b;
  const double noise = NoiseLength(s.p);
  const Vec3 ea = s.p[1] - s.p[0];
  const Vec3 eb = s.p[3] - s.p[2];
  const Vec3 cross = ea.cross(eb);
  Vec3 n;
  if (prefer_apart && apart.norm() > noise) {
    n = apart.normalized();
  } else if (cross.squaredNorm() > kDegenerateSin2 * ea.squaredNorm() * eb.squaredNorm()) {
    n = Oriented(cross.normalized(), apart0, relative_velocity);
  } else {
    n = Oriented(FallbackNormal(apart, relative_velocity, noise), apart0, relative_velocity);
  }
  hit.normal = n;
  return hit;
}

void CheckOptions(const CcdOptions& options) {
  FELT_CHECK(options.thickness_m > 0.0);
  FELT_CHECK(options.max_steps >= 0);
}

}  // namespace

Vec3 LinearPointAt(const Vec3& a, const Vec3& b, double t) {
  return t < 0.5 ? Vec3(a + t * (b - a)) : Vec3(b - (1.0 - t) * (b - a));
}

double VertexTriangleRelativeSpeed(const CcdPoints& x0, const CcdPoints& x1) {
  const Vec3 v = x1[0] - x0[0];
  double speed = 0.0;
  for (int i = 1; i < 4; ++i) speed = std::max(speed, (v - (x1[i] - x0[i])).norm());
  return speed;
}

double EdgeEdgeRelativeSpeed(const CcdPoints& x0, const CcdPoints& x1) {
  double speed = 0.0;
  for (int i = 0; i < 2; ++i) {
    for (int j = 2; j < 4; ++j) {
      speed = std::max(speed, ((x1[i] - x0[i]) - (x1[j] - x0[j])).norm());
    }
  }
  return speed;
}

VertexTriangleHit VertexTriangleCcd(const CcdPoints& x0, const CcdPoints& x1,
                                    const CcdOptions& options) {
  CheckOptions(options);
  // Coplanarity of the vertex with the triangle: A = b - a, B = c - a, C = p - a (Provot 1997;
  // Bridson et al. 2002), then the times it may vanish.
  const CoplanarityCubic cubic = MakeCoplanarityCubic(x0[2] - x0[1], x1[2] - x1[1], x0[3] - x0[1],
                                                      x1[3] - x1[1], x0[0] - x0[1], x1[0] - x1[1]);
  const CoplanarTimes times = CoplanarCandidateTimes(cubic);
  if (times.count == 0) return {};
  // In each, the first time the vertex is within h of the triangle.
  const double speed = VertexTriangleRelativeSpeed(x0, x1);
  const auto distance_at = [&](double t) {
    return std::sqrt(VertexTriangleAt(x0, x1, t).closest.distance_sq);
  };
  for (int32_t i = 0; i < times.count; ++i) {
    const Advanced adv = Advance(distance_at, times.intervals[i].begin, times.intervals[i].end,
                                 speed, options.thickness_m, options.max_steps);
    if (adv.hit) return VertexTriangleHitAt(x0, x1, adv, /*prefer_apart=*/false);
  }
  return {};
}

EdgeEdgeHit EdgeEdgeCcd(const CcdPoints& x0, const CcdPoints& x1, const CcdOptions& options) {
  CheckOptions(options);
  // Coplanarity of the two edges: A = e1 - e0, B = f1 - f0, C = f0 - e0 (Bridson et al. 2002).
  const CoplanarityCubic cubic = MakeCoplanarityCubic(x0[1] - x0[0], x1[1] - x1[0], x0[3] - x0[2],
                                                      x1[3] - x1[2], x0[2] - x0[0], x1[2] - x1[0]);
  const CoplanarTimes times = CoplanarCandidateTimes(cubic);
  if (times.count == 0) return {};
  const double speed = EdgeEdgeRelativeSpeed(x0, x1);
  const auto distance_at = [&](double t) {
    return std::sqrt(EdgeEdgeAt(x0, x1, t).closest.distance_sq);
  };
  for (int32_t i = 0; i < times.count; ++i) {
    const Advanced adv = Advance(distance_at, times.intervals[i].begin, times.intervals[i].end,
                                 speed, options.thickness_m, options.max_steps);
    if (adv.hit) return EdgeEdgeHitAt(x0, x1, adv, /*prefer_apart=*/false);
  }
  return {};
}

VertexTriangleHit VertexTriangleSeparation(const CcdPoints& x0, const CcdPoints& x1,
                                           const CcdOptions& options) {
  CheckOptions(options);
  const auto distance_at = [&](double t) {
    return std::sqrt(VertexTriangleAt(x0, x1, t).closest.distance_sq);
  };
  const Advanced adv = Advance(distance_at, 0.0, 1.0, VertexTriangleRelativeSpeed(x0, x1),
                               options.thickness_m, options.max_steps);
  if (!adv.hit) return {};
  return VertexTriangleHitAt(x0, x1, adv, /*prefer_apart=*/true);
}

EdgeEdgeHit EdgeEdgeSeparation(const CcdPoints& x0, const CcdPoints& x1,
                               const CcdOptions& options) {
  CheckOptions(options);
  const auto distance_at = [&](double t) {
    return std::sqrt(EdgeEdgeAt(x0, x1, t).closest.distance_sq);
  };
  const Advanced adv = Advance(distance_at, 0.0, 1.0, EdgeEdgeRelativeSpeed(x0, x1),
                               options.thickness_m, options.max_steps);
  if (!adv.hit) return {};
  return EdgeEdgeHitAt(x0, x1, adv, /*prefer_apart=*/true);
}

// ----------------------------------------------------------------------------------------------
// collision/ccd_all_pairs.h
// ----------------------------------------------------------------------------------------------

namespace {

// The box around both positions of the given vertices, grown by `pad` [m].
struct SweptBox {
  Vec3 lo;
  Vec3 hi;
};

template <size_t N>
SweptBox BoxOf(std::span<const Vec3> x0, std::span<const Vec3> x1, const std::array<int32_t, N>& v,
               double pad) {
  SweptBox b{x0[v[0]], x0[v[0]]};
  for (int32_t i : v) {
    b.lo = b.lo.cwiseMin(x0[i]).cwiseMin(x1[i]);
    b.hi = b.hi.cwiseMax(x0[i]).cwiseMax(x1[i]);
  }
  b.lo.array() -= pad;
  b.hi.array() += pad;
  return b;
}

bool BoxesApart(const SweptBox& a, const SweptBox& b) {
  return (a.hi.array() < b.lo.array()).any() || (b.hi.array() < a.lo.array()).any();
}

CcdPoints Gather(std::span<const Vec3> x, const std::array<int32_t, 4>& v) {
  return {x[v[0]], x[v[1]], x[v[2]], x[v[3]]};
}

}  // namespace

std::vector<MeshEdge> MeshEdges(std::span<const Triangle> triangles) {
  std::vector<MeshEdge> edges;
  edges.reserve(3 * triangles.size());
  for (const Triangle& t : triangles) {
    for (int k = 0; k < 3; ++k) {
      const int32_t a = t[k], b = t[(k + 1) % 3];
      if (a != b) edges.push_back({std::min(a, b), std::max(a, b)});
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  return edges;
}

bool VertexTrianglePairHit(std::span<const Vec3> x0, std::span<const Vec3> x1, int32_t v,
                           int32_t ti, const Triangle& triangle, const AllPairsCcdOptions& options,
                           CcdPairHit* hit) {
  const std::array<int32_t, 4> ids = {v, triangle[0], triangle[1], triangle[2]};
  const CcdPoints p0 = Gather(x0, ids), p1 = Gather(x1, ids);
  const VertexTriangleHit r = options.minimal_separation
                                  ? VertexTriangleSeparation(p0, p1, options.ccd)
                                  : VertexTriangleCcd(p0, p1, options.ccd);
  if (!r.hit) return false;
  hit->kind = CcdPairHit::Kind::kVertexTriangle;
  hit->first = v;
  hit->second = ti;
  hit->vertices = ids;
  hit->capped = r.capped;
  hit->toi = r.toi;
  hit->distance_m = r.distance_m;
  hit->normal = r.normal;
  hit->weights = {1.0, -r.barycentric[0], -r.barycentric[1], -r.barycentric[2]};
  return true;
}

bool EdgeEdgePairHit(std::span<const Vec3> x0, std::span<const Vec3> x1, int32_t ei,
                     const MeshEdge& e, int32_t fi, const MeshEdge& f,
                     const AllPairsCcdOptions& options, CcdPairHit* hit) {
  const std::array<int32_t, 4> ids = {e[0], e[1], f[0], f[1]};
  const CcdPoints p0 = Gather(x0, ids), p1 = Gather(x1, ids);
  const EdgeEdgeHit r = options.minimal_separation ? EdgeEdgeSeparation(p0, p1, options.ccd)
                                                   : EdgeEdgeCcd(p0, p1, options.ccd);
  if (!r.hit) return false;
  hit->kind = CcdPairHit::Kind::kEdgeEdge;
  hit->first = ei;
  hit->second = fi;
  hit->vertices = ids;
  hit->capped = r.capped;
  hit->toi = r.toi;
  hit->distance_m = r.distance_m;
  hit->normal = r.normal;
  hit->weights = {1.0 - r.s, r.s, -(1.0 - r.u), -r.u};
  return true;
}

std::vector<CcdPairHit> AllPairsCcd(std::span<const Vec3> x0, std::span<const Vec3> x1,
                                    std::span<const Triangle> triangles,
                                    const AllPairsCcdOptions& options) {
  FELT_CHECK(x0.size() == x1.size());
  const int32_t nv = static_cast<int32_t>(x0.size());
  for (const Triangle& t : triangles) {
    for (int32_t v : t) FELT_CHECK(v >= 0 && v < nv);
  }
  // Half the thickness on each box: boxes more than h apart hold primitives more than h apart.
  const double pad = 0.5 * options.ccd.thickness_m;
  std::vector<CcdPairHit> hits;

  // Vertex-triangle pairs.
  std::vector<SweptBox> tri_boxes;
  if (options.box_prefilter) {
    for (const Triangle& t : triangles) tri_boxes.push_back(BoxOf<3>(x0, x1, t, pad));
  }
  for (int32_t v = 0; v < nv; ++v) {
    const SweptBox vbox = BoxOf<1>(x0, x1, std::array<int32_t, 1>{v}, pad);
    for (int32_t ti = 0; ti < static_cast<int32_t>(triangles.size()); ++ti) {
      const Triangle& t = triangles[ti];
      if (t[0] == v || t[1] == v || t[2] == v) continue;
      if (options.box_prefilter && BoxesApart(vbox, tri_boxes[ti])) continue;
      CcdPairHit h;
      if (VertexTrianglePairHit(x0, x1, v, ti, t, options, &h)) hits.push_back(h);
    }
  }

  // Edge-edge pairs.
  const std::vector<MeshEdge> edges = MeshEdges(triangles);
  std::vector<SweptBox> edge_boxes;
  if (options.box_prefilter) {
    for (const MeshEdge& e : edges) edge_boxes.push_back(BoxOf<2>(x0, x1, e, pad));
  }
  const int32_t ne = static_cast<int32_t>(edges.size());
  for (int32_t i = 0; i < ne; ++i) {
    for (int32_t j = i + 1; j < ne; ++j) {
      const MeshEdge& e = edges[i];
      const MeshEdge& f = edges[j];
      if (e[0] == f[0] || e[0] == f[1] || e[1] == f[0] || e[1] == f[1]) continue;
      if (options.box_prefilter && BoxesApart(edge_boxes[i], edge_boxes[j])) continue;
      CcdPairHit h;
      if (EdgeEdgePairHit(x0, x1, i, e, j, f, options, &h)) hits.push_back(h);
    }
  }
  return hits;
}

}  // namespace felt
