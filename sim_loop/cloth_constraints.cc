// What is enforced after each substep: Provot's deformation constraints, the obstacles, the pins.

#include <algorithm>
#include <cmath>

#include "sim_loop/cloth.h"
#include "sim_loop/cloth_internal.h"

namespace felt {
namespace {

// The flat kernels read a std::vector<Vec3> as 3 n packed doubles.
static_assert(sizeof(Vec3) == 3 * sizeof(double));

// Provot stops sweeping once the worst excess in a sweep is below this fraction of the limit.
constexpr double kProvotConverged = 1e-3;
// Each violated constraint is shortened by this multiple of its excess, ending it up to 50 % of
// the excess below the limit: projected successive over-relaxation (Cryer 1971), as position-based
// solvers use it (Macklin, Mueller, Chentanez & Kim 2014, §4.2). Gauss-Seidel with plain
// projection (1.0) carries a correction only slowly down the chains of constraints that hold a
// hanging cloth; measured on the two-corner curtain (10 sweeps, first second after release), 1.5
// lowers the peak stretch from 1.154 to 1.131 at 32 x 32, from 1.169 to about 1.13 at 64 x 64, at
// the same cost. An inequality constraint left below its limit is inactive, so nothing is pushed.
constexpr double kProvotOverRelaxation = 1.5;
// Sphere-tracing steps along a substep's path before it is taken as a graze.
constexpr int kMaxMarchSteps = 48;

// Removes the velocity into the surface with normal `n` and applies Coulomb friction: the
// tangential speed drops by at most mu times the normal speed removed (sticking if it would
// reverse).
void ContactVelocity(const Vec3& n, double mu, Vec3* v) {
  const double vn = v->dot(n);
  if (vn >= 0.0) return;
  Vec3 vt = *v - vn * n;
  if (mu > 0.0) {
    const double vt_len = vt.norm();
    const double drop = -mu * vn;
    vt = vt_len <= drop ? Vec3(Vec3::Zero()) : Vec3(vt * (1.0 - drop / vt_len));
  }
  *v = vt;
}

// The first point of the segment a -> b whose distance to the obstacle is <= margin, by sphere
// tracing (every shape's distance is exact outside, so each step is safe). False if none.
bool FirstContact(const ObstacleSpec& o, const Vec3& a, const Vec3& b, Vec3* hit, Vec3* normal) {
  const Vec3 d = b - a;
  const double len = d.norm();
  if (!(len > 0.0)) return false;
  const Vec3 dir = d / len;
  double t = 0.0;
  for (int i = 0; i < kMaxMarchSteps && t <= len; ++i) {
    const Vec3 p = a + t * dir;
    const double gap = ObstacleDistance(o, p, normal) - o.margin_m;
    if (gap <= 1e-9) {
      *hit = p;
      return true;
    }
    t += gap;
  }
  return false;
}

}  // namespace

double ObstacleDistance(const ObstacleSpec& o, const Vec3& p, Vec3* normal) {
  if (const auto* plane = std::get_if<PlaneSpec>(&o.shape)) {
    *normal = plane->normal;
    return plane->normal.dot(p - plane->point_m);
  }
  if (const auto* sphere = std::get_if<SphereSpec>(&o.shape)) {
    const Vec3 d = p - sphere->center_m;
    const double len = d.norm();
    *normal = len > 0.0 ? Vec3(d / len) : Vec3(Vec3::UnitY());
    return len - sphere->radius_m;
  }
  if (const auto* box = std::get_if<BoxSpec>(&o.shape)) {
    // Exact box distance: q = |p - centre| - half extent per axis.
    const Vec3 centre = 0.5 * (box->min_m + box->max_m);
    const Vec3 half = 0.5 * (box->max_m - box->min_m);
    const Vec3 rel = p - centre;
    const Vec3 q = rel.cwiseAbs() - half;
    const Vec3 sign(rel.x() < 0.0 ? -1.0 : 1.0, rel.y() < 0.0 ? -1.0 : 1.0,
                    rel.z() < 0.0 ? -1.0 : 1.0);
    const Vec3 outside = q.cwiseMax(0.0);
    const double out_len = outside.norm();
    if (out_len > 0.0) {
      *normal = sign.cwiseProduct(outside) / out_len;
      return out_len;
    }
    // Inside: the nearest face.
    Eigen::Index axis = 0;
    const double depth = q.maxCoeff(&axis);
    *normal = Vec3::Zero();
    (*normal)[axis] = sign[axis];
    return depth;
  }
  const auto& capsule = std::get<CapsuleSpec>(o.shape);
  // Distance to the closest point of the segment a-b, less the radius.
  const Vec3 ab = capsule.b_m - capsule.a_m;
  const double ab2 = ab.squaredNorm();
  const double t = ab2 > 0.0 ? std::clamp((p - capsule.a_m).dot(ab) / ab2, 0.0, 1.0) : 0.0;
  const Vec3 d = p - (capsule.a_m + t * ab);
  const double len = d.norm();
  *normal = len > 0.0 ? Vec3(d / len) : Vec3(Vec3::UnitY());
  return len - capsule.radius_m;
}

void ApplyProvot(const ClothModel& model, double h_s, ClothState* state) {
  const double inv_h = 1.0 / h_s;
  const size_t n3 = 3 * static_cast<size_t>(model.num_particles());
  // Flat loops over raw coordinates (a Vec3 is three packed doubles), no Eigen temporaries. Only
  // positions move inside the loops; velocities follow once at the end (v += (x - x_before) / h,
  // the sum of every move / h), which halves the memory each projection touches.
  double* __restrict x = state->x.data()->data();
  double* __restrict v = state->v.data()->data();
  double* __restrict x_before = state->scratch->provot_x_before.data();
  std::copy(x, x + n3, x_before);
  // Long range attachments first: each free particle back into the ball around its pin (Kim,
  // Chentanez & Mueller 2012); the pin is kinematic, so only the particle moves.
  for (const PinAttachment& a : model.attachments) {
    const size_t p = 3 * static_cast<size_t>(a.particle), q = 3 * static_cast<size_t>(a.pin);
    const double dx = x[p] - x[q], dy = x[p + 1] - x[q + 1], dz = x[p + 2] - x[q + 2];
    const double len2 = dx * dx + dy * dy + dz * dz;
    if (len2 <= a.max_length_m * a.max_length_m) continue;
    const double len = std::sqrt(len2);
    const double scale = (len - a.max_length_m) / len;
    x[p] -= scale * dx;
    x[p + 1] -= scale * dy;
    x[p + 2] -= scale * dz;
  }
  // The constraints in sweep order: first those with a pinned end j (the free end i takes the
  // whole correction), then those with two free ends (halves); 16 bytes each.
  const ProvotPair* __restrict pairs = model.provot_pairs.data();
  const size_t pinned_count = static_cast<size_t>(model.provot_pinned_pairs);
  const size_t count = model.provot_pairs.size();
  constexpr double kLoose2 = (1.0 + kProvotConverged) * (1.0 + kProvotConverged);
  for (int32_t sweep = 0; sweep < model.spec.provot.iterations; ++sweep) {
    // Converged when no spring of this sweep was over its limit by more than kProvotConverged.
    bool loose = false;
    for (size_t k = 0; k < count; ++k) {
      // Provot 1995 (000_25210a744b053ca5.txt slides 9-10): a spring longer than its limit
      // (1 + tau_c) L is shortened back to it by moving its ends by their shares.
      const ProvotPair& c = pairs[k];
      const size_t i = 3 * static_cast<size_t>(c.i), j = 3 * static_cast<size_t>(c.j);
      const double dx = x[j] - x[i], dy = x[j + 1] - x[i + 1], dz = x[j + 2] - x[i + 2];
      const double len2 = dx * dx + dy * dy + dz * dz;
      const double max2 = c.max_length_m * c.max_length_m;
      if (len2 <= max2) continue;
      loose = loose || len2 > kLoose2 * max2;
      const double len = std::sqrt(len2);
      const double scale = kProvotOverRelaxation * (len - c.max_length_m) / len;
      // A pinned end j stays and the free end takes the whole correction; else halves.
      const bool pinned_j = k < pinned_count;
      const double a = pinned_j ? scale : 0.5 * scale;
      x[i] += a * dx;
      x[i + 1] += a * dy;
      x[i + 2] += a * dz;
      if (pinned_j) continue;
      x[j] -= a * dx;
      x[j + 1] -= a * dy;
      x[j + 2] -= a * dz;
    }
    if (!loose) break;
  }
  // Velocities follow the positions, v += dx / h, so (x, v) stay consistent.
  for (size_t k = 0; k < n3; ++k) v[k] += inv_h * (x[k] - x_before[k]);
}

void ApplyObstacles(const ClothModel& model, double h_s, ClothState* state) {
  const auto& obstacles = model.spec.cloth.obstacles;
  const Vec3* x_start = state->scratch->x_start.data();
  for (int32_t p = 0; p < model.num_particles(); ++p) {
    if (model.inv_mass_per_kg[p] == 0.0) continue;
    bool touched = false;
    for (const ObstacleSpec& o : obstacles) {
      Vec3& x = state->x[p];
      Vec3 normal;
      const double phi = ObstacleDistance(o, x, &normal);
      const Vec3 start = x_start[p];
      // The distance is 1-Lipschitz: a path that ends farther out than its length cannot have
      // touched the margin shell, the common case, decided without a second distance.
      const double path = (x - start).norm();
      if (phi - o.margin_m >= path) continue;
      Vec3 n_start, hit;
      const double phi_start = ObstacleDistance(o, start, &n_start);
      // Started clearly outside the shell (not resting on it): the first contact along the path
      // is where the particle meets the obstacle, so a fast particle cannot tunnel through a thin
      // one or exit on its far side.
      const bool start_clear = phi_start - o.margin_m > 1e-9;
      if (phi >= o.margin_m) {
        if (!start_clear || phi_start + phi - 2.0 * o.margin_m > path) continue;
        if (!FirstContact(o, start, x, &hit, &normal)) continue;
        x = hit;
      } else if (start_clear && FirstContact(o, start, x, &hit, &normal)) {
        x = hit;
      } else {
        // Resting on or starting inside the shell: out to the nearest surface plus margin.
        x += (o.margin_m - phi) * normal;
      }
      ContactVelocity(normal, o.friction, &state->v[p]);
      touched = true;
    }
    if (touched) SyncVerletHistory(model, p, h_s, state);
  }
}

void ApplyPins(const ClothModel& model, double t_s, ClothState* state) {
  const auto& pins = model.spec.cloth.pins;
  for (size_t k = 0; k < model.pinned.size(); ++k) {
    const int32_t p = model.pinned[k];
    if (model.pin_scripted[k]) {
      const PinMotionSpec& motion = pins[model.pin_spec[k]].motion;
      state->x[p] = model.rest_position_m[p] + PinOffset(motion, t_s);
      state->v[p] = PinVelocity(motion, t_s);
    } else {
      state->x[p] = model.rest_position_m[p];
      state->v[p].setZero();
    }
  }
}

}  // namespace felt
