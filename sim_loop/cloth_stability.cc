// Stability limits of the integrators, found on the scalar test oscillator
// x'' = -omega^2 x - gamma x' that each mode of the linearised cloth obeys
// (critical stiffness: 000_25210a744b053ca5.txt slide 8; integrators: 001_0f9f1b7fedff7723.txt §3).

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

#include "sim_loop/cloth.h"

namespace felt {
namespace {

// One substep of `kind` on the scalar oscillator, with exactly the update formulas the cloth
// integrators use (sim_loop/cloth_integrators.cc). State (x, v, w): w is leapfrog's previous
// acceleration or basic Verlet's previous position, unused by the others.
Eigen::Vector3d ScalarStep(IntegratorKind kind, double h, double omega2, double gamma,
                           const Eigen::Vector3d& s) {
  const auto f = [&](double x, double v) { return -omega2 * x - gamma * v; };
  const double x = s[0], v = s[1], w = s[2];
  switch (kind) {
    case IntegratorKind::kExplicitEuler: {
      const double a = f(x, v);
      return {x + h * v, v + h * a, 0.0};
    }
    case IntegratorKind::kSymplecticEuler: {
      const double v1 = v + h * f(x, v);
      return {x + h * v1, v1, 0.0};
    }
    case IntegratorKind::kExplicitMidpoint: {
      const double a = f(x, v);
      const double xm = x + 0.5 * h * v, vm = v + 0.5 * h * a;
      return {x + h * vm, v + h * f(xm, vm), 0.0};
    }
    case IntegratorKind::kRk4: {
      const double k1x = v, k1v = f(x, v);
      const double k2x = v + 0.5 * h * k1v, k2v = f(x + 0.5 * h * k1x, v + 0.5 * h * k1v);
      const double k3x = v + 0.5 * h * k2v, k3v = f(x + 0.5 * h * k2x, v + 0.5 * h * k2v);
      const double k4x = v + h * k3v, k4v = f(x + h * k3x, v + h * k3v);
      return {x + h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x),
              v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v), 0.0};
    }
    case IntegratorKind::kVelocityVerlet: {
      const double a0 = f(x, v);
      const double x1 = x + h * v + 0.5 * h * h * a0;
      const double a1 = f(x1, v + h * a0);
      return {x1, v + 0.5 * h * (a0 + a1), 0.0};
    }
    case IntegratorKind::kLeapfrogVerlet: {
      const double a = f(x, v);
      const double v_half = v - 0.5 * h * w + h * a;
      return {x + h * v_half, v_half + 0.5 * h * a, a};
    }
    case IntegratorKind::kBasicVerlet: {
      const double a = f(x, v);
      const double x1 = 2 * x - w + h * h * a;
      return {x1, (x1 - x) / h + 0.5 * h * a, x};
    }
    case IntegratorKind::kImplicitEuler:
      break;
  }
  return s;
}

// Spectral radius of one substep's amplification matrix.
double SpectralRadius(IntegratorKind kind, double h, double omega2, double gamma) {
  Eigen::Matrix3d m;
  for (int c = 0; c < 3; ++c)
    m.col(c) = ScalarStep(kind, h, omega2, gamma, Eigen::Vector3d::Unit(c));
  return m.eigenvalues().cwiseAbs().maxCoeff();
}

}  // namespace

double StableStep(const ClothModel& model, IntegratorKind kind) {
  if (kind == IntegratorKind::kImplicitEuler) return std::numeric_limits<double>::infinity();
  const double omega_max = model.omega_max_rad_per_s;
  if (!(omega_max > 0.0)) return std::numeric_limits<double>::infinity();

  // The modes to check: frequencies up to omega_max, each with the least and the most damping a
  // mode of that frequency can have along the springs (drag plus c/k of the softest- or
  // hardest-damped spring type times omega^2), plus the damping bound at omega_max.
  struct Mode {
    double omega2, gamma;
  };
  std::vector<Mode> modes;
  constexpr int kSamples = 48;
  for (int i = 0; i < kSamples; ++i) {
    const double omega = omega_max * std::pow(1e-3, static_cast<double>(i) / (kSamples - 1));
    const double w2 = omega * omega;
    // No mode is damped faster than the bound on M^-1 D (gamma_max_per_s).
    const double cap = model.gamma_max_per_s;
    modes.push_back({w2, std::min(cap, model.drag_rate_per_s + model.damping_time_min_s * w2)});
    modes.push_back({w2, std::min(cap, model.drag_rate_per_s + model.damping_time_max_s * w2)});
  }
  modes.push_back({omega_max * omega_max, model.gamma_max_per_s});
  // Motion across stretched springs: no dashpot acts on it, only drag (ClothModel::
  // omega_transverse_rad_per_s). Without this, explicit Euler's auto step grew those modes.
  const double omega_t = std::min(model.omega_transverse_rad_per_s, omega_max);
  for (int i = 0; i < kSamples && omega_t > 0.0; ++i) {
    const double omega = omega_t * std::pow(1e-3, static_cast<double>(i) / (kSamples - 1));
    modes.push_back({omega * omega, model.drag_rate_per_s});
  }
  // Stable: no mode grows faster than kMaxGrowthPerSecond (rho^(1/h) <= e^rate). A tolerance in
  // time, not per step, so that rounding in the eigenvalues of neutral modes (|rho| = 1 up to
  // ~1e-10) does not count as growth, while a weakly unstable scheme (explicit Euler without
  // damping, rho = sqrt(1 + (w h)^2)) needs a step small enough to grow < 0.1 % per second.
  constexpr double kMaxGrowthPerSecond = 1e-3;
  const auto stable = [&](double h) {
    for (const Mode& m : modes) {
      const double rho = SpectralRadius(kind, h, m.omega2, m.gamma);
      if (!(std::log(rho) <= kMaxGrowthPerSecond * h)) return false;
    }
    return true;
  };

  // Walk down from a step every explicit method fails at until one is stable, then bisect.
  double hi = 8.0 / omega_max, lo = hi;
  while (!stable(lo)) {
    hi = lo;
    lo *= 0.8;
    if (lo < 1e-7 / omega_max) return 0.0;
  }
  if (lo == hi) return lo;
  for (int i = 0; i < 40; ++i) {
    const double mid = 0.5 * (lo + hi);
    (stable(mid) ? lo : hi) = mid;
  }
  return lo;
}

}  // namespace felt
