// Forces of the mass-spring cloth (001_0f9f1b7fedff7723.txt §2, §6.1): gravity, viscous drag,
// springs with a dashpot along each spring, external point forces; and the energy diagnostics.

#include <algorithm>
#include <cassert>
#include <cmath>

#include "sim_loop/cloth.h"
#include "sim_loop/cloth_internal.h"

namespace felt {
namespace {

// Springs shorter than this have no usable direction and exert no force.
constexpr double kMinSpringLength_m = 1e-12;
// The flat kernels read a std::vector<Vec3> as 3 n packed doubles.
static_assert(sizeof(Vec3) == 3 * sizeof(double));

}  // namespace

void AddSpringForces(const ClothModel& model, std::span<const Vec3> x, std::span<const Vec3> v,
                     std::span<Vec3> f) {
  assert(x.size() == v.size() && x.size() == f.size());
  // Flat loop over raw coordinates (a Vec3 is three packed doubles): no Eigen temporaries, and
  // restrict tells the compiler x, v and f do not alias, so it keeps the loads in registers.
  const double* __restrict xp = x.data()->data();
  const double* __restrict vp = v.data()->data();
  double* __restrict fp = f.data()->data();
  const Spring* __restrict springs = model.springs.data();
  const size_t count = model.springs.size();
  constexpr double kMinLength2 = kMinSpringLength_m * kMinSpringLength_m;
  for (size_t k = 0; k < count; ++k) {
    // Hooke plus dashpot along the unit direction u from i to j:
    // f_i = (k (l - L) + c (v_j - v_i) . u) u, f_j = -f_i (001 §2; 000 slide 5).
    const Spring& s = springs[k];
    const size_t i = 3 * static_cast<size_t>(s.i), j = 3 * static_cast<size_t>(s.j);
    const double dx = xp[j] - xp[i], dy = xp[j + 1] - xp[i + 1], dz = xp[j + 2] - xp[i + 2];
    const double len2 = dx * dx + dy * dy + dz * dz;
    if (!(len2 > kMinLength2)) continue;
    const double len = std::sqrt(len2);
    const double inv_len = 1.0 / len;
    const double rel_speed =
        ((vp[j] - vp[i]) * dx + (vp[j + 1] - vp[i + 1]) * dy + (vp[j + 2] - vp[i + 2]) * dz) *
        inv_len;
    // Force magnitude over length, so that force = scale * d.
    const double scale =
        (s.stiffness_N_per_m * (len - s.rest_length_m) + s.damping_N_s_per_m * rel_speed) *
        inv_len;
    const double fx = scale * dx, fy = scale * dy, fz = scale * dz;
    fp[i] += fx;
    fp[i + 1] += fy;
    fp[i + 2] += fz;
    fp[j] -= fx;
    fp[j + 1] -= fy;
    fp[j + 2] -= fz;
  }
}

void ComputeAccelerations(const ClothModel& model, std::span<const Vec3> x, std::span<const Vec3> v,
                          ClothState::Scratch* scratch, std::span<Vec3> a) {
  const int32_t n = model.num_particles();
  const double drag = model.spec.cloth.drag_N_s_per_m;
  Vec3* force = scratch->force_N.data();
  const Vec3* ext = scratch->external_N.data();
  // External forces and viscous drag F = -c v (001 §6.1).
  for (int32_t p = 0; p < n; ++p) force[p] = ext[p] - drag * v[p];
  AddSpringForces(model, x, v, scratch->force_N);
  // Haptic contact springs at these positions (sim_loop/cloth_coupling.h).
  AddCouplingForces(scratch->coupling, x, 1.0, force->data());
  // a = g + F / m for free particles; pinned particles (inv_mass 0) do not accelerate.
  const Vec3 g = model.spec.cloth.gravity_m_per_s2;
  const double* inv_mass = model.inv_mass_per_kg.data();
  for (int32_t p = 0; p < n; ++p) {
    a[p] = inv_mass[p] > 0.0 ? Vec3(g + inv_mass[p] * force[p]) : Vec3(Vec3::Zero());
  }
}

double MaxStretch(const ClothModel& model, const ClothState& state) {
  double worst = 1.0;
  bool any = false;
  for (const Spring& s : model.springs) {
    if (s.type != SpringType::kStructural) continue;
    const double ratio = (state.x[s.j] - state.x[s.i]).norm() / s.rest_length_m;
    worst = any ? std::max(worst, ratio) : ratio;
    any = true;
  }
  return any ? worst : 1.0;
}

double TotalEnergy(const ClothModel& model, const ClothState& state) {
  const Vec3& g = model.spec.cloth.gravity_m_per_s2;
  const double m = model.particle_mass_kg;
  double kinetic = 0.0, gravity = 0.0, elastic = 0.0;
  for (int32_t p = 0; p < model.num_particles(); ++p) {
    if (model.inv_mass_per_kg[p] > 0.0) kinetic += 0.5 * m * state.v[p].squaredNorm();
    // Potential of a uniform field: U = -m g . x.
    gravity -= m * g.dot(state.x[p]);
  }
  for (const Spring& s : model.springs) {
    const double stretch = (state.x[s.j] - state.x[s.i]).norm() - s.rest_length_m;
    elastic += 0.5 * s.stiffness_N_per_m * stretch * stretch;
  }
  return kinetic + gravity + elastic;
}

}  // namespace felt
