#include "recordings/hermite.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace felt {
namespace {

// A random cubic per axis: p(t) = c0 + c1 t + c2 t^2 + c3 t^3.
struct Cubic {
  Vec3 c[4];
  Vec3 P(double t) const { return c[0] + t * (c[1] + t * (c[2] + t * c[3])); }
  Vec3 V(double t) const { return c[1] + t * (2.0 * c[2] + 3.0 * t * c[3]); }
};

Cubic RandomCubic(std::mt19937_64* rng, bool quadratic) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Cubic q;
  for (Vec3& c : q.c) c = Vec3(u(*rng), u(*rng), u(*rng));
  if (quadratic) q.c[3].setZero();
  return q;
}

TEST(HermiteTest, SegmentIsExactOnCubicsWithExactTangents) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 2000; ++trial) {
    const Cubic q = RandomCubic(&rng, false);
    const double t0 = -1.0 + 2.0 * u(rng);
    const double t1 = t0 + 0.001 + u(rng);
    for (int i = 0; i <= 10; ++i) {
      const double t = t0 + (t1 - t0) * i / 10.0;
      const CurvePoint c = HermiteSegment(t0, q.P(t0), q.V(t0), t1, q.P(t1), q.V(t1), t);
      ASSERT_LT((c.p - q.P(t)).norm(), 1e-12) << trial;
      ASSERT_LT((c.v - q.V(t)).norm(), 1e-9 * (1.0 + q.V(t).norm())) << trial;
    }
  }
}

TEST(HermiteTest, BesselTangentsAreExactOnQuadraticsWithNonUniformTimes) {
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 500; ++trial) {
    const Cubic q = RandomCubic(&rng, true);
    const int n = 3 + trial % 20;
    std::vector<double> t(n);
    std::vector<Vec3> p(n);
    double time = u(rng);
    for (int k = 0; k < n; ++k) {
      t[k] = time;
      p[k] = q.P(time);
      time += 0.001 + 0.1 * u(rng) * u(rng);  // steps vary by up to 100x
    }
    const std::vector<Vec3> m = BesselTangents(t, p);
    for (int k = 0; k < n; ++k) ASSERT_LT((m[k] - q.V(t[k])).norm(), 1e-8) << trial << " " << k;
    // So the whole interpolant reproduces the quadratic, position and velocity.
    const HermiteCurve curve(t, p, m);
    for (int i = 0; i <= 100; ++i) {
      const double s = t.front() + (t.back() - t.front()) * i / 100.0;
      const CurvePoint c = curve.Evaluate(s);
      ASSERT_LT((c.p - q.P(s)).norm(), 1e-10);
      ASSERT_LT((c.v - q.V(s)).norm(), 1e-7);
    }
  }
}

TEST(HermiteTest, CurveIsC1AtEveryKnot) {
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const int n = 200;
  std::vector<double> t(n);
  std::vector<Vec3> p(n);
  double time = 0.0;
  for (int k = 0; k < n; ++k) {
    t[k] = time;
    p[k] = Vec3(u(rng), u(rng), u(rng)) * 0.05;  // rough data: continuity must not depend on it
    time += 0.002 + 0.05 * (u(rng) + 1.0);
  }
  const std::vector<Vec3> m = BesselTangents(t, p);
  const HermiteCurve curve(t, p, m);
  for (int k = 1; k + 1 < n; ++k) {
    // The left segment at its end and the right segment at its start agree in value and slope.
    const CurvePoint left = HermiteSegment(t[k - 1], p[k - 1], m[k - 1], t[k], p[k], m[k], t[k]);
    const CurvePoint right = HermiteSegment(t[k], p[k], m[k], t[k + 1], p[k + 1], m[k + 1], t[k]);
    ASSERT_LT((left.p - right.p).norm(), 1e-12);
    ASSERT_LT((left.v - right.v).norm(), 1e-9 * (1.0 + m[k].norm()));
    ASSERT_LT((left.p - p[k]).norm(), 1e-12);  // interpolates
    // And numerically: one-sided difference quotients on both sides approach the same slope.
    const double eps = 1e-8;
    const Vec3 slope_left = (curve.Evaluate(t[k]).p - curve.Evaluate(t[k] - eps).p) / eps;
    const Vec3 slope_right = (curve.Evaluate(t[k] + eps).p - curve.Evaluate(t[k]).p) / eps;
    ASSERT_LT((slope_left - slope_right).norm(), 1e-3 * (1.0 + m[k].norm())) << k;
  }
}

TEST(HermiteTest, InterpolationErrorShrinksAtThirdOrder) {
  // Sample a smooth motion at spacing h and 2h; the max position error ratio approaches 2^3 = 8
  // for Bessel tangents (de Boor 2001 ch. IV: O(h^3)).
  const auto max_error = [](double h) {
    std::vector<double> t;
    std::vector<Vec3> p;
    for (double s = 0.0; s <= 2.0 + 1e-12; s += h) {
      t.push_back(s);
      p.emplace_back(std::sin(3.0 * s), std::cos(2.0 * s), std::exp(-s));
    }
    const HermiteCurve curve(t, p, BesselTangents(t, p));
    double err = 0.0;
    for (int i = 0; i <= 4000; ++i) {
      const double s = t.back() * i / 4000.0;
      err = std::max(
          err,
          (curve.Evaluate(s).p - Vec3(std::sin(3.0 * s), std::cos(2.0 * s), std::exp(-s))).norm());
    }
    return err;
  };
  const double e1 = max_error(0.04);
  const double e2 = max_error(0.02);
  EXPECT_GT(e1 / e2, 6.0);
  EXPECT_LT(e1 / e2, 10.0);
}

TEST(HermiteTest, EdgeCasesAndErrors) {
  const std::vector<double> t1 = {0.5};
  const std::vector<Vec3> p1 = {Vec3(1, 2, 3)};
  EXPECT_EQ(BesselTangents(t1, p1)[0], Vec3::Zero());
  const std::vector<double> t2 = {0.0, 2.0};
  const std::vector<Vec3> p2 = {Vec3(0, 0, 0), Vec3(2, 4, 6)};
  EXPECT_EQ(BesselTangents(t2, p2)[1], Vec3(1, 2, 3));
  const std::vector<double> bad_t = {0.0, 0.0};
  EXPECT_THROW(BesselTangents(bad_t, p2), std::invalid_argument);
  EXPECT_THROW(BesselTangents(t1, p2), std::invalid_argument);
  EXPECT_THROW(HermiteCurve({0.0, 0.0}, p2, p2), std::invalid_argument);
  const HermiteCurve curve(t2, p2, BesselTangents(t2, p2));
  EXPECT_EQ(curve.Evaluate(-1.0).p, Vec3(0, 0, 0));  // clamped
  EXPECT_EQ(curve.Evaluate(5.0).p, Vec3(2, 4, 6));
  EXPECT_LT((curve.Evaluate(1.0).p - Vec3(1, 2, 3)).norm(), 1e-15);
}

}  // namespace
}  // namespace felt
