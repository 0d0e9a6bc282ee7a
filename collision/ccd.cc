#include "collision/ccd_cubic.h"
// The implementations of collision/ccd_proximity.h and ccd_cubic.h (one file: collision/ keeps
// eight .cc files, one unity batch; collision/spatial_hash.cc uses kInf, which only
// collision/bvh.cc defines, and builds only while both share a batch).

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "collision/ccd_proximity.h"

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

}  // namespace felt
