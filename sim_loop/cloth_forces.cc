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

}  // namespace

void AddSpringForces(const ClothModel& model, std::span<const Vec3> x, std::span<const Vec3> v,
                     std::span<Vec3> f) {
  assert(x.size() == v.size() && x.size() == f.size());
  const Vec3* xp = x.data();
  const Vec3* vp = v.data();
  Vec3* fp = f.data();
  for (const Spring& s : model.springs) {
    // Hooke plus dashpot along the unit direction u from i to j:
    // f_i = (k (l - L) + c (v_j - v_i) . u) u, f_j = -f_i (001 §2; 000 slide 5).
    const Vec3 d = xp[s.j] - xp[s.i];
    const double len2 = d.squaredNorm();
    if (!(len2 > kMinSpringLength_m * kMinSpringLength_m)) continue;
    const double len = std::sqrt(len2);
    const Vec3 u = d / len;
    const double rel_speed = (vp[s.j] - vp[s.i]).dot(u);
    const Vec3 force =
        (s.stiffness_N_per_m * (len - s.rest_length_m) + s.damping_N_s_per_m * rel_speed) * u;
    fp[s.i] += force;
    fp[s.j] -= force;
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
