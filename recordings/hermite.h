#pragma once
// C1 piecewise-cubic Hermite interpolation of sampled 3-D motion, used to resample recordings to
// the 1 kHz haptic tick with velocity from the interpolant's derivative.
//
// On a segment [t0, t1] with h = t1 - t0 and s = (t - t0) / h the cubic Hermite form is
//   p(t) = h00(s) p0 + h10(s) h m0 + h01(s) p1 + h11(s) h m1,
//   h00 = 2s^3 - 3s^2 + 1, h10 = s^3 - 2s^2 + s, h01 = -2s^3 + 3s^2, h11 = s^3 - s^2
// (de Boor, "A Practical Guide to Splines", rev. ed. 2001, ch. IV, "Piecewise cubic Hermite
// interpolation"; Fritsch & Carlson, SIAM J. Numer. Anal. 17(2), 1980, §2). Neighbouring
// segments share the knot value and tangent, so the curve is C1 whatever the tangents are.

#include <span>
#include <vector>

#include "collision/mesh.h"

namespace felt {

/// Position [m] and velocity [m/s] of a curve at one time.
struct CurvePoint {
  Vec3 p = Vec3::Zero();  ///< position [m]
  Vec3 v = Vec3::Zero();  ///< velocity, dp/dt [m/s]
};

/// The cubic Hermite segment from (t0, p0, m0) to (t1, p1, m1) evaluated at t (t0 < t1; t may lie
/// outside [t0, t1], which extrapolates the cubic). Tangents m in m/s. Real-time safe.
CurvePoint HermiteSegment(double t0, const Vec3& p0, const Vec3& m0, double t1, const Vec3& p1,
                          const Vec3& m1, double t);

/// Knot tangents [m/s] for samples p [m] at strictly increasing times t [s] (equal sizes): the
/// derivative at t_k of the parabola through the knots k-1, k, k+1 ("Bessel" tangents, de Boor
/// 2001 ch. IV, "Bessel interpolation"; for uniform spacing the Catmull-Rom tangent (p_{k+1} -
/// p_{k-1}) / 2h). At the ends the parabola through the first (last) three knots is differentiated
/// at the end knot. Two knots give the chord slope, one knot gives zero. Exact when the samples lie
/// on a quadratic, which makes the interpolant third-order accurate on smooth motion even with
/// non-uniform spacing. Throws std::invalid_argument on size mismatch or non-increasing times.
std::vector<Vec3> BesselTangents(std::span<const double> t, std::span<const Vec3> p);

/// A piecewise-cubic Hermite curve through knots (t_k, p_k) with tangents m_k.
class HermiteCurve {
 public:
  /// Knot times [s] strictly increasing, positions [m], tangents [m/s], all the same size >= 1.
  /// Throws std::invalid_argument otherwise.
  HermiteCurve(std::vector<double> t, std::vector<Vec3> p, std::vector<Vec3> m);

  /// Position and velocity at t [s]; t is clamped to [t.front(), t.back()]. Finds the segment by
  /// binary search. Real-time safe.
  CurvePoint Evaluate(double t) const;

  /// The knot times [s].
  const std::vector<double>& knots() const { return t_; }

 private:
  std::vector<double> t_;
  std::vector<Vec3> p_;
  std::vector<Vec3> m_;
};

}  // namespace felt
