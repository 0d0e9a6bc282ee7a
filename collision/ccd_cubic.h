#pragma once
// The coplanarity cubic of continuous collision detection (issue 22): four points moving linearly
// over a step are coplanar exactly when a cubic polynomial in time vanishes (Provot, "Collision
// and self-collision handling in cloth model dedicated to design garments", Graphics Interface
// 1997; Bridson, Fedkiw & Anderson, "Robust treatment of collisions, contact and friction for
// cloth animation", SIGGRAPH 2002). Here the cubic is kept in Bernstein form on [0, 1] (as in
// Tang, Tong, Wang & Manocha, "Fast and exact continuous collision detection with Bernstein sign
// classification", SIGGRAPH Asia 2014) with a rigorous bound on its rounding error, and the times
// where it may vanish are returned as intervals that are guaranteed to contain every exact root.
// Pure functions, no allocation, no exceptions (real-time safe).

#include <array>
#include <cstdint>

#include "collision/mesh.h"

namespace felt {

/// P(t) = (A(t) x B(t)) . C(t) for three vectors moving linearly over t in [0, 1],
/// A(t) = (1 - t) A0 + t A1 (likewise B, C), in Bernstein form, with a bound on the rounding error
/// of EvaluateCoplanarity. For a vertex p and triangle (a, b, c): A = b - a, B = c - a, C = p - a
/// (P is six times the signed volume, > 0 when p lies on the side the normal (b-a) x (c-a) points
/// to); for edges (e0, e1) and (f0, f1): A = e1 - e0, B = f1 - f0, C = f0 - e0.
struct CoplanarityCubic {
  /// P(t) = sum_i bernstein[i] * C(3, i) (1 - t)^(3 - i) t^i, m^3.
  std::array<double, 4> bernstein = {};
  /// For every t in [0, 1], |EvaluateCoplanarity(t).value - exact P(t)| <= error_bound, where the
  /// exact P is that of the positions the differences were formed from, m^3.
  double error_bound = 0.0;
};

/// Builds the cubic from the three vectors at t = 0 (a0, b0, c0) and t = 1 (a1, b1, c1) [m]. Each
/// is assumed to be one rounded difference of two positions (relative error at most 2^-53 per
/// component). Since P is trilinear, its Bernstein coefficients are the averages of the triple
/// products with i factors taken at t = 1 (the blossom): b0 = [A0 B0 C0],
/// b1 = ([A1 B0 C0] + [A0 B1 C0] + [A0 B0 C1]) / 3, b2 = ([A0 B1 C1] + [A1 B0 C1] + [A1 B1 C0]) /
/// 3, b3 = [A1 B1 C1], with [X Y Z] = (X x Y) . Z. The error bound is 64 u M, u = 2^-53, M the
/// permanent of the componentwise maxima |A0|v|A1|, |B0|v|B1|, |C0|v|C1| (which bounds every triple
/// product's terms): about 11 u M from forming the coefficients and 12 u M from de Casteljau's
/// evaluation, with a margin (docs/self_collision.md). Real-time safe.
CoplanarityCubic MakeCoplanarityCubic(const Vec3& a0, const Vec3& a1, const Vec3& b0,
                                      const Vec3& b1, const Vec3& c0, const Vec3& c1);

/// A value of the cubic and its derivative.
struct CubicValue {
  double value = 0.0;  ///< P(t), m^3
  double slope = 0.0;  ///< dP/dt, m^3 per unit t
};

/// P(t) and P'(t) at t in [0, 1] by de Casteljau's algorithm (convex combinations: stable).
CubicValue EvaluateCoplanarity(const CoplanarityCubic& cubic, double t);

/// Power-basis coefficients (k0, k1, k2, k3), P(t) = k0 + k1 t + k2 t^2 + k3 t^3, of a cubic in
/// Bernstein form: k0 = b0, k1 = 3 (b1 - b0), k2 = 3 (b0 - 2 b1 + b2),
/// k3 = b3 - 3 b2 + 3 b1 - b0.
std::array<double, 4> PowerCoefficients(const std::array<double, 4>& bernstein);

/// A closed interval of times [begin, end] within [0, 1].
struct TimeInterval {
  double begin = 0.0;
  double end = 0.0;
};

/// The disjoint, increasing intervals of [0, 1] outside which the cubic certainly has no root.
struct CoplanarTimes {
  std::array<TimeInterval, 4> intervals;  ///< the first `count` are valid
  int32_t count = 0;
};

/// Every t in [0, 1] with exact P(t) = 0 lies in one of the returned intervals. Method: if the
/// Bernstein coefficients all exceed +error_bound (or all lie below -error_bound), no root (the
/// convex hull property). Otherwise [0, 1] is split at the derivative's roots (a quadratic, solved
/// by the cancellation-free formula, linear when its leading coefficient vanishes) and at the
/// inflection point, so that P is monotone on each piece; on each piece the set where
/// |P| <= error_bound is one interval, whose ends are found by Newton's method safeguarded by
/// bisection and rounded outward. Simple roots give intervals of width about
/// error_bound / |P'|, double roots about sqrt(error_bound / |P''|), and a polynomial that is zero
/// up to rounding (coplanar motion) gives [0, 1]. Real-time safe.
CoplanarTimes CoplanarCandidateTimes(const CoplanarityCubic& cubic);

}  // namespace felt
