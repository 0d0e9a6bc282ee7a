// The auto-substep bound (ClothModel::omega_max_rad_per_s and friends) against the true spectrum
// of the linearised cloth, and the auto step of every explicit integrator against its energy.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "sim_loop/cloth.h"
#include "sim_loop/integrator_names.h"
#include "tests/sim_loop/cloth_test_util.h"

namespace felt {
namespace {

using cloth_test::Corner;
using cloth_test::Curtain;
using cloth_test::HorizontalCurtain;

// Largest eigenvalues of M^-1 K and M^-1 D over the free particles at positions x: K the spring
// force Jacobian -df/dx, k (u u^T + (1 - L/l) (I - u u^T)) per spring, D the dashpots' c u u^T
// (uniform masses, so M^-1 K is symmetric). Dense: for small grids only.
struct Spectrum {
  double stiffness_per_s2;
  double damping_per_s;
};

Spectrum TrueSpectrum(const ClothModel& model, const std::vector<Vec3>& x) {
  const int32_t n = model.num_particles();
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(3 * n, 3 * n), D = K;
  const Eigen::Matrix3d eye = Eigen::Matrix3d::Identity();
  for (const Spring& s : model.springs) {
    const Vec3 d = x[s.j] - x[s.i];
    const double len = d.norm();
    const Vec3 u = d / len;
    const Eigen::Matrix3d uu = u * u.transpose();
    const Eigen::Matrix3d block =
        s.stiffness_N_per_m * (uu + (1.0 - s.rest_length_m / len) * (eye - uu));
    const Eigen::Matrix3d dash = s.damping_N_s_per_m * uu;
    for (auto [M, B] : {std::pair{&K, block}, std::pair{&D, dash}}) {
      M->block<3, 3>(3 * s.i, 3 * s.i) += B;
      M->block<3, 3>(3 * s.j, 3 * s.j) += B;
      M->block<3, 3>(3 * s.i, 3 * s.j) -= B;
      M->block<3, 3>(3 * s.j, 3 * s.i) -= B;
    }
  }
  // Pinned particles do not move: drop their rows and columns.
  std::vector<int> free;
  for (int32_t p = 0; p < n; ++p) {
    if (model.inv_mass_per_kg[p] > 0.0) {
      for (int r = 0; r < 3; ++r) free.push_back(3 * p + r);
    }
  }
  const auto largest = [&](const Eigen::MatrixXd& M) {
    Eigen::MatrixXd sub(free.size(), free.size());
    for (size_t a = 0; a < free.size(); ++a) {
      for (size_t b = 0; b < free.size(); ++b) sub(a, b) = M(free[a], free[b]);
    }
    return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(sub, Eigen::EigenvaluesOnly)
               .eigenvalues()
               .maxCoeff() /
           model.particle_mass_kg;
  };
  return {largest(K), largest(D)};
}

TEST(ClothBoundsTest, FrequencyBoundHoldsInEveryConfiguration) {
  // Grids with and without pins, odd shapes, non-default constants; configurations from rest to
  // rotated, stretched three times, compressed and crumpled at random.
  std::mt19937 rng(20261121);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  struct Case {
    int32_t width, height;
    bool pinned;
    double k_shear, k_bend;
  };
  for (const Case& c : {Case{5, 4, true, 0.5, 0.1}, Case{7, 7, false, 0.5, 0.1},
                        Case{6, 9, true, 3.0, 0.02}, Case{4, 6, false, 0.01, 2.0}}) {
    SimSpec spec = Curtain(6);
    spec.cloth.width = c.width;
    spec.cloth.height = c.height;
    if (!c.pinned) spec.cloth.pins.clear();
    spec.cloth.shear->stiffness_N_per_m = c.k_shear;
    spec.cloth.bend->stiffness_N_per_m = c.k_bend;
    spec.cloth.bend->damping_N_s_per_m = 3e-3;  // a different c/k from the other types
    const ClothModel model = BuildClothModel(spec);
    const double omega2 = model.omega_max_rad_per_s * model.omega_max_rad_per_s;
    const double gamma = model.gamma_max_per_s - model.drag_rate_per_s;
    for (int trial = 0; trial < 12; ++trial) {
      std::vector<Vec3> x = model.rest_position_m;
      const double stretch = trial < 4 ? 1.0 : trial < 8 ? 3.0 : 0.5;
      const Eigen::Matrix3d R =
          Eigen::AngleAxisd(3.0 * unit(rng), Vec3(unit(rng), unit(rng), unit(rng)).normalized())
              .toRotationMatrix();
      const double noise = trial == 0 ? 0.0 : trial % 4 == 3 ? 0.2 : 0.004;  // 0.2 m: crumpled
      for (Vec3& p : x) {
        p = R * (stretch * p) + noise * Vec3(unit(rng), unit(rng), unit(rng));
      }
      const Spectrum s = TrueSpectrum(model, x);
      EXPECT_LE(s.stiffness_per_s2, omega2 * (1.0 + 1e-9))
          << c.width << "x" << c.height << " trial " << trial;
      EXPECT_LE(s.damping_per_s, gamma * (1.0 + 1e-9))
          << c.width << "x" << c.height << " trial " << trial;
    }
  }
}

TEST(ClothBoundsTest, FrequencyBoundIsTheGridSymbolAndTight) {
  // The default springs (k = 1, 0.5, 0.1 N/m). In the cosines ca, cb of the wave vector the
  // symbol is 2 k_st (2 - ca - cb) + 4 k_sh (1 - ca cb) + 4 k_b (2 - ca^2 - cb^2) on [-1, 1]^2,
  // largest at ca = -1, cb = (4 k_sh - 2 k_st) / (8 k_b) = 0: 6 k_st + 4 k_sh + 4 k_b = 8.4 N/m
  // (the Gershgorin row bound used before was 2 sum k = 12.8 N/m).
  SimSpec spec = Curtain(12);
  spec.cloth.pins.clear();
  const ClothModel model = BuildClothModel(spec);
  const double omega2 = model.omega_max_rad_per_s * model.omega_max_rad_per_s;
  EXPECT_NEAR(omega2 * model.particle_mass_kg, 8.4, 8.4 * 0.005);
  EXPECT_GE(omega2 * model.particle_mass_kg, 8.4);  // an upper bound, never below the maximum
  // Not wastefully loose: at rest (no stiffness across the springs) a 12 x 12 grid already has
  // 0.70 of it, and stretched three times (across: k (1 - 1/3)) more than 0.8.
  const Spectrum rest = TrueSpectrum(model, model.rest_position_m);
  EXPECT_GT(rest.stiffness_per_s2, 0.65 * omega2);
  std::vector<Vec3> stretched = model.rest_position_m;
  for (Vec3& p : stretched) p *= 3.0;
  const Spectrum taut = TrueSpectrum(model, stretched);
  EXPECT_GT(taut.stiffness_per_s2, rest.stiffness_per_s2);
  EXPECT_GT(taut.stiffness_per_s2, 0.8 * omega2);
}

// Kinetic + gravity + spring energy never rises by more than `slack_J` over `frames` frames of
// `spec` at its auto substep count, and nothing goes non-finite.
void ExpectBoundedEnergy(const SimSpec& spec, int frames, double slack_J, const char* what) {
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  const double e0 = TotalEnergy(model, state);
  double e_max = e0;
  for (int f = 0; f < frames; ++f) {
    StepFrame(model, {}, 1.0 / 60.0, &state);
    e_max = std::max(e_max, TotalEnergy(model, state));
  }
  const std::string name = std::string(ToName(spec.integration.integrator)) + " " + what + " (" +
                           std::to_string(model.substeps) + " substeps)";
  EXPECT_EQ(state.counters.nan_events, 0u) << name;
  EXPECT_LT(e_max, e0 + slack_J) << name;
  EXPECT_LT(MaxStretch(model, state), spec.provot.enabled ? 1.11 : 100.0) << name;
}

TEST(ClothBoundsTest, AutoSubstepsKeepEveryExplicitIntegratorStable) {
  // Springs 30 times the default (k = 30 N/m structural), released horizontal from two corners,
  // with and without Provot. Drag 2e-3 N s/m per particle: explicit Euler has no stable step
  // without drag for the motion across stretched springs (their dashpots act along them only),
  // and needs thousands of substeps with little of it.
  for (const IntegratorName& entry : kIntegratorNames) {
    if (entry.kind == IntegratorKind::kImplicitEuler) continue;
    for (bool provot : {true, false}) {
      SimSpec spec = HorizontalCurtain(10);
      for (auto* s : {&spec.cloth.structural, &spec.cloth.shear, &spec.cloth.bend}) {
        (*s)->stiffness_N_per_m *= 30;
        (*s)->damping_N_s_per_m *= 30;
      }
      spec.cloth.drag_N_s_per_m = 2e-3;
      spec.provot.enabled = provot;
      spec.integration.integrator = entry.kind;
      // 1 % of M g L (0.1 kg x 9.81 m/s^2 x 0.5 m), the stability bench's criterion.
      ExpectBoundedEnergy(spec, 30, 0.01 * 0.49, provot ? "Provot on" : "Provot off");
    }
  }
}

TEST(ClothBoundsTest, ExplicitEulerRefusesAutoWhereDragCannotStabiliseIt) {
  // The stiff hard case (springs x 1000) with the default drag: explicit Euler's stable step for
  // the drag-damped motion across the springs is below 1e-7 s; auto says so instead of blowing up.
  SimSpec spec = HorizontalCurtain(8);
  for (auto* s : {&spec.cloth.structural, &spec.cloth.shear, &spec.cloth.bend}) {
    (*s)->stiffness_N_per_m *= 1000;
    (*s)->damping_N_s_per_m *= 1000;
  }
  spec.integration.integrator = IntegratorKind::kExplicitEuler;
  try {
    BuildClothModel(spec);
    ADD_FAILURE() << "expected a refusal";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("integration.substeps: auto needs", 0), 0u) << e.what();
  }
}

}  // namespace
}  // namespace felt
