#include "recordings/hermite.h"

#include <algorithm>
#include <stdexcept>

namespace felt {

CurvePoint HermiteSegment(double t0, const Vec3& p0, const Vec3& m0, double t1, const Vec3& p1,
                          const Vec3& m1, double t) {
  // Hermite basis and its s-derivative (de Boor 2001 ch. IV; Fritsch & Carlson 1980 §2).
  const double h = t1 - t0;
  const double s = (t - t0) / h;
  const double s2 = s * s;
  const double s3 = s2 * s;
  const double h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
  const double h10 = s3 - 2.0 * s2 + s;
  const double h01 = -2.0 * s3 + 3.0 * s2;
  const double h11 = s3 - s2;
  const double d00 = 6.0 * s2 - 6.0 * s;
  const double d10 = 3.0 * s2 - 4.0 * s + 1.0;
  const double d11 = 3.0 * s2 - 2.0 * s;
  CurvePoint out;
  out.p = h00 * p0 + (h10 * h) * m0 + h01 * p1 + (h11 * h) * m1;
  // d/dt = (1/h) d/ds; d01 = -d00.
  out.v = (d00 / h) * (p0 - p1) + d10 * m0 + d11 * m1;
  return out;
}

std::vector<Vec3> BesselTangents(std::span<const double> t, std::span<const Vec3> p) {
  if (t.size() != p.size()) throw std::invalid_argument("BesselTangents: t and p sizes differ");
  const size_t n = t.size();
  for (size_t k = 1; k < n; ++k) {
    if (!(t[k] > t[k - 1])) throw std::invalid_argument("BesselTangents: times must increase");
  }
  std::vector<Vec3> m(n, Vec3::Zero());
  if (n < 2) return m;
  if (n == 2) {
    m[0] = m[1] = (p[1] - p[0]) / (t[1] - t[0]);
    return m;
  }
  // Interior: derivative at t_k of the parabola through k-1, k, k+1 (de Boor 2001 ch. IV, Bessel):
  // m_k = (h_k d_{k-1} + h_{k-1} d_k) / (h_{k-1} + h_k), d_k = (p_{k+1} - p_k) / h_k.
  for (size_t k = 1; k + 1 < n; ++k) {
    const double h0 = t[k] - t[k - 1];
    const double h1 = t[k + 1] - t[k];
    const Vec3 d0 = (p[k] - p[k - 1]) / h0;
    const Vec3 d1 = (p[k + 1] - p[k]) / h1;
    m[k] = (h1 * d0 + h0 * d1) / (h0 + h1);
  }
  // Ends: the same parabola through the three end knots, differentiated at the end knot.
  {
    const double h0 = t[1] - t[0];
    const double h1 = t[2] - t[1];
    const Vec3 d0 = (p[1] - p[0]) / h0;
    const Vec3 d1 = (p[2] - p[1]) / h1;
    m[0] = ((2.0 * h0 + h1) * d0 - h0 * d1) / (h0 + h1);
  }
  {
    const double h0 = t[n - 2] - t[n - 3];
    const double h1 = t[n - 1] - t[n - 2];
    const Vec3 d0 = (p[n - 2] - p[n - 3]) / h0;
    const Vec3 d1 = (p[n - 1] - p[n - 2]) / h1;
    m[n - 1] = ((2.0 * h1 + h0) * d1 - h1 * d0) / (h0 + h1);
  }
  return m;
}

HermiteCurve::HermiteCurve(std::vector<double> t, std::vector<Vec3> p, std::vector<Vec3> m)
    : t_(std::move(t)), p_(std::move(p)), m_(std::move(m)) {
  if (t_.empty() || t_.size() != p_.size() || t_.size() != m_.size()) {
    throw std::invalid_argument("HermiteCurve: t, p and m need the same size >= 1");
  }
  for (size_t k = 1; k < t_.size(); ++k) {
    if (!(t_[k] > t_[k - 1])) throw std::invalid_argument("HermiteCurve: times must increase");
  }
}

CurvePoint HermiteCurve::Evaluate(double t) const {
  // One knot, or outside the knots: hold the end (value and tangent of the end knot).
  if (t_.size() == 1) return {p_[0], m_[0]};
  if (t <= t_.front()) return {p_.front(), m_.front()};
  if (t >= t_.back()) return {p_.back(), m_.back()};
  // Segment k with t_k <= t < t_{k+1}.
  const size_t k = static_cast<size_t>(std::upper_bound(t_.begin(), t_.end(), t) - t_.begin()) - 1;
  return HermiteSegment(t_[k], p_[k], m_[k], t_[k + 1], p_[k + 1], m_[k + 1], t);
}

}  // namespace felt
