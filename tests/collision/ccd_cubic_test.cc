// The coplanarity cubic: its Bernstein form against the triple product evaluated in extended
// precision and against the power-basis derivation; candidate intervals around known roots
// (simple, near 0 and 1, at 0 and 1, double, nearly double, triple; quadratic, linear, constant
// and identically zero polynomials); and every exact sign change of the coplanarity of sampled
// random motions lies in an interval.
#include "collision/ccd_cubic.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "collision/self_predicates.h"

namespace felt {
namespace {

using Ld3 = Eigen::Matrix<long double, 3, 1>;

// P(t) in long double from the end values (64-bit significand: far below the error bound).
long double TripleAt(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1, const Vec3& c0,
                     const Vec3& c1, long double t) {
  const auto lerp = [t](const Vec3& x0, const Vec3& x1) -> Ld3 {
    return (1.0L - t) * x0.cast<long double>() + t * x1.cast<long double>();
  };
  return lerp(a0, a1).cross(lerp(b0, b1)).dot(lerp(c0, c1));
}

TEST(CcdCubicTest, BernsteinFormMatchesTripleProductWithinItsBound) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int k = 0; k < 2000; ++k) {
    const double scale = std::pow(10.0, (k % 7) - 3);
    const auto r = [&]() -> Vec3 { return Vec3(g(rng), g(rng), g(rng)) * scale; };
    const Vec3 a0 = r(), a1 = r(), b0 = r(), b1 = r(), c0 = r(), c1 = r();
    const CoplanarityCubic cubic = MakeCoplanarityCubic(a0, a1, b0, b1, c0, c1);
    for (double t : {0.0, 0.1, 0.37, 0.5, 0.999, 1.0}) {
      const long double exact = TripleAt(a0, a1, b0, b1, c0, c1, t);
      const double value = EvaluateCoplanarity(cubic, t).value;
      ASSERT_LE(std::abs(static_cast<long double>(value) - exact), cubic.error_bound)
          << k << " " << t;
    }
    // The power basis from the direct expansion of (A0 + t dA) x (B0 + t dB) . (C0 + t dC).
    const Vec3 da = a1 - a0, db = b1 - b0, dc = c1 - c0;
    const std::array<double, 4> direct = {
        a0.cross(b0).dot(c0), a0.cross(b0).dot(dc) + (a0.cross(db) + da.cross(b0)).dot(c0),
        (a0.cross(db) + da.cross(b0)).dot(dc) + da.cross(db).dot(c0), da.cross(db).dot(dc)};
    const std::array<double, 4> power = PowerCoefficients(cubic.bernstein);
    for (int i = 0; i < 4; ++i) ASSERT_NEAR(power[i], direct[i], 1e3 * cubic.error_bound) << k;
  }
}

// A cubic with the given power coefficients and error bound.
CoplanarityCubic FromPower(double k0, double k1, double k2, double k3, double error_bound) {
  // Inverse of PowerCoefficients: b0 = k0, b1 = k0 + k1/3, b2 = k0 + 2k1/3 + k2/3,
  // b3 = k0 + k1 + k2 + k3.
  CoplanarityCubic c;
  c.bernstein = {k0, k0 + k1 / 3.0, k0 + 2.0 * k1 / 3.0 + k2 / 3.0, k0 + k1 + k2 + k3};
  c.error_bound = error_bound;
  return c;
}

// The cubic s (t - r0)(t - r1)(t - r2).
CoplanarityCubic FromRoots(double r0, double r1, double r2, double s, double error_bound) {
  return FromPower(-s * r0 * r1 * r2, s * (r0 * r1 + r0 * r2 + r1 * r2), -s * (r0 + r1 + r2), s,
                   error_bound);
}

bool Covers(const CoplanarTimes& times, double t) {
  for (int i = 0; i < times.count; ++i) {
    if (times.intervals[i].begin <= t && t <= times.intervals[i].end) return true;
  }
  return false;
}

double Width(const CoplanarTimes& times, double t) {
  for (int i = 0; i < times.count; ++i) {
    if (times.intervals[i].begin <= t && t <= times.intervals[i].end) {
      return times.intervals[i].end - times.intervals[i].begin;
    }
  }
  return -1.0;
}

TEST(CcdCubicTest, IntervalsHoldKnownRoots) {
  const double e = 1e-14;
  // Three simple roots, narrow intervals around each.
  CoplanarTimes times = CoplanarCandidateTimes(FromRoots(0.2, 0.5, 0.8, 10.0, e));
  ASSERT_EQ(times.count, 3);
  for (double r : {0.2, 0.5, 0.8}) {
    EXPECT_TRUE(Covers(times, r)) << r;
    EXPECT_LT(Width(times, r), 1e-13) << r;
  }
  // Roots near and at the ends.
  for (double r : {1e-12, 0.0, 1.0 - 1e-12, 1.0}) {
    times = CoplanarCandidateTimes(FromRoots(r, -3.0, 5.0, 1.0, e));
    EXPECT_TRUE(Covers(times, r)) << r;
    EXPECT_LT(Width(times, r), 1e-13) << r;
  }
  // No root in [0, 1]: nothing (the convex hull test or the pieces).
  EXPECT_EQ(CoplanarCandidateTimes(FromRoots(-0.5, 1.5, 2.0, 1.0, e)).count, 0);
  EXPECT_EQ(CoplanarCandidateTimes(FromRoots(-0.5, -1.5, 3.0, 1.0, e)).count, 0);
  // A double root (a touch) and a nearly double one (two roots 2e-9 apart, or none).
  times = CoplanarCandidateTimes(FromRoots(0.3, 0.3, 2.0, 1.0, e));
  EXPECT_TRUE(Covers(times, 0.3));
  EXPECT_LT(Width(times, 0.3), 1e-6);
  times = CoplanarCandidateTimes(FromRoots(0.3 - 1e-9, 0.3 + 1e-9, 2.0, 1.0, e));
  EXPECT_TRUE(Covers(times, 0.3 - 1e-9));
  EXPECT_TRUE(Covers(times, 0.3 + 1e-9));
  // (t - 0.3)^2 + 1e-16 has no real root but is within the error bound of one: covered.
  times = CoplanarCandidateTimes(FromPower(0.09 + 1e-16, -0.6, 1.0, 0.0, e));
  EXPECT_TRUE(Covers(times, 0.3));
  // A triple root.
  times = CoplanarCandidateTimes(FromRoots(0.5, 0.5, 0.5, 1.0, e));
  EXPECT_TRUE(Covers(times, 0.5));
  EXPECT_LT(Width(times, 0.5), 1e-3);
  // Leading coefficients zero: quadratic, linear, constant.
  times = CoplanarCandidateTimes(FromPower(0.06, -0.5, 1.0, 0.0, e));  // (t - 0.2)(t - 0.3)
  EXPECT_TRUE(Covers(times, 0.2));
  EXPECT_TRUE(Covers(times, 0.3));
  EXPECT_EQ(times.count, 2);
  times = CoplanarCandidateTimes(FromPower(-0.7, 1.0, 0.0, 0.0, e));
  EXPECT_TRUE(Covers(times, 0.7));
  EXPECT_EQ(times.count, 1);
  EXPECT_EQ(CoplanarCandidateTimes(FromPower(1e-12, 0.0, 0.0, 0.0, e)).count, 0);
  // Zero up to rounding (coplanar motion): all of [0, 1].
  times = CoplanarCandidateTimes(FromPower(1e-15, -2e-15, 0.0, 1e-15, e));
  ASSERT_EQ(times.count, 1);
  EXPECT_EQ(times.intervals[0].begin, 0.0);
  EXPECT_EQ(times.intervals[0].end, 1.0);
  times = CoplanarCandidateTimes(CoplanarityCubic{});  // exactly zero, zero bound
  ASSERT_EQ(times.count, 1);
  EXPECT_EQ(times.intervals[0].end - times.intervals[0].begin, 1.0);
}

TEST(CcdCubicTest, RandomCubicsRootsAreCovered) {
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> u(-0.2, 1.2);
  for (int k = 0; k < 20000; ++k) {
    // Roots anywhere around [0, 1], sometimes clustered.
    double r0 = u(rng), r1 = u(rng), r2 = u(rng);
    if (k % 4 == 1) r1 = r0 + 1e-7 * u(rng);
    if (k % 8 == 2) r2 = r1 = r0;
    const CoplanarityCubic cubic = FromRoots(r0, r1, r2, k % 2 ? 1.0 : -3.0, 1e-14);
    const CoplanarTimes times = CoplanarCandidateTimes(cubic);
    for (double r : {r0, r1, r2}) {
      // The coefficients were rounded: a root is that of a nearby polynomial, within about
      // sqrt(1e-16) for a double root. Require the interval to come within that of it.
      if (r < 0.0 || r > 1.0) continue;
      bool near = Covers(times, r);
      for (int i = 0; i < times.count && !near; ++i) {
        near = std::abs(times.intervals[i].begin - r) < 1e-7 ||
               std::abs(times.intervals[i].end - r) < 1e-7;
      }
      ASSERT_TRUE(near) << k << " root " << r;
    }
    // Intervals increase and are disjoint.
    for (int i = 0; i < times.count; ++i) {
      ASSERT_LE(times.intervals[i].begin, times.intervals[i].end);
      if (i > 0) {
        ASSERT_LT(times.intervals[i - 1].end, times.intervals[i].begin);
      }
    }
  }
}

// Dyadic inputs (multiples of 2^-20 in [-1, 1]) and sample times k / 2^12: the sampled positions
// x0 + t (x1 - x0) are then exact, so Orient3D gives the exact sign of the exact P at each
// sample, and a sign change between two samples proves an exact root between them.
double Dyadic(double v) { return std::ldexp(std::round(std::ldexp(v, 20)), -20); }

TEST(CcdCubicTest, EveryExactSignChangeOfSampledMotionIsCovered) {
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  const auto point = [&] { return Vec3(Dyadic(u(rng)), Dyadic(u(rng)), Dyadic(u(rng))); };
  const int samples = 1 << 12;
  int changes = 0;
  for (int k = 0; k < 400; ++k) {
    std::array<Vec3, 4> x0, x1;  // vertex, a, b, c
    for (int i = 0; i < 4; ++i) {
      x0[i] = point();
      x1[i] = point();
    }
    if (k % 4 == 1) {  // nearly coplanar motion: flatten z to a few ulps of the grid
      for (int i = 0; i < 4; ++i) x0[i].z() = x1[i].z() = Dyadic(1e-6 * (i % 2));
    }
    const CoplanarityCubic cubic = MakeCoplanarityCubic(
        x0[2] - x0[1], x1[2] - x1[1], x0[3] - x0[1], x1[3] - x1[1], x0[0] - x0[1], x1[0] - x1[1]);
    const CoplanarTimes times = CoplanarCandidateTimes(cubic);
    int previous = 0;
    for (int s = 0; s <= samples; ++s) {
      const double t = std::ldexp(s, -12);
      std::array<Vec3, 4> p;
      for (int i = 0; i < 4; ++i) p[i] = x0[i] + t * (x1[i] - x0[i]);
      const int sign = Orient3D(p[1], p[2], p[3], p[0]);
      if (sign == 0) {
        ASSERT_TRUE(Covers(times, t)) << k << " t " << t;
      }
      if (s > 0 && sign * previous < 0) {
        ++changes;
        bool overlaps = false;
        const double t_prev = std::ldexp(s - 1, -12);
        for (int i = 0; i < times.count; ++i) {
          overlaps |= times.intervals[i].begin <= t && times.intervals[i].end >= t_prev;
        }
        ASSERT_TRUE(overlaps) << k << " in [" << t_prev << ", " << t << "]";
      }
      previous = sign;
    }
  }
  EXPECT_GT(changes, 100);
}

}  // namespace
}  // namespace felt
