#include "proxy/proxy.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <span>

#include "collision/geometry.h"
#include "proxy/obstacle_sweep.h"

namespace felt {
namespace {

// An orthonormal frame of a triangle (e1 along ab, n the face normal); ok = false if degenerate.
struct TriFrame {
  Vec3 e1 = Vec3::UnitX();
  Vec3 e2 = Vec3::UnitY();
  Vec3 n = Vec3::UnitZ();
  bool ok = false;
};

TriFrame FrameOf(const Vec3& a, const Vec3& b, const Vec3& c) {
  TriFrame f;
  const Vec3 ab = b - a;
  const Vec3 nn = ab.cross(c - a);
  const double lab = ab.norm();
  const double ln = nn.norm();
  if (lab <= 0.0 || ln <= 0.0 || IsDegenerateTriangle(a, b, c)) return f;
  f.e1 = ab / lab;
  f.n = nn / ln;
  f.e2 = f.n.cross(f.e1);
  f.ok = true;
  return f;
}

// World offset -> triangle frame, and back (a degenerate frame keeps world coordinates: the
// proxy then only translates with its contact point).
Vec3 ToLocal(const TriFrame& f, const Vec3& d) {
  return f.ok ? Vec3(f.e1.dot(d), f.e2.dot(d), f.n.dot(d)) : d;
}
Vec3 FromLocal(const TriFrame& f, const Vec3& l) {
  return f.ok ? Vec3(l(0) * f.e1 + l(1) * f.e2 + l(2) * f.n) : l;
}

const LocalTriangle* FindLocal(const LocalCloth& cloth, int32_t triangle) {
  for (const LocalTriangle& t : cloth.triangles()) {
    if (t.triangle == triangle) return &t;
  }
  return nullptr;
}

// The contact's barycentric point on a triangle with corners a, b, c, m.
Vec3 ContactPointOn(const ProxyContact& contact, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3& w = contact.barycentric;
  return w(0) * a + w(1) * b + w(2) * c;
}

// The proxy centre a contact anchors on a triangle with corners a, b, c: the contact's
// barycentric point plus its offset in the triangle's frame (the carry's rule).
Vec3 AnchoredAt(const ProxyContact& contact, const Vec3& a, const Vec3& b, const Vec3& c) {
  return ContactPointOn(contact, a, b, c) + FromLocal(FrameOf(a, b, c), contact.local_m);
}

// The constraint a contact puts on the proxy centre: n . x >= n . point + r (Ruspini 1997 §3: the
// plane tangent to the configuration-space obstacle, i.e. the cloth grown by the radius).
ConstraintPlane PlaneOf(const ProxyContact& c, double r) {
  return ConstraintPlane{c.normal_W, c.normal_W.dot(c.point_W_m) + r, c.triangle};
}

// One pass of the god-object update: its result before the contacts' local frames are filled.
struct Pass {
  Vec3 p = Vec3::Zero();
  int32_t n = 0;
  std::array<ProxyContact, kMaxConstraintPlanes> contacts;
  int32_t iterations = 0;
  bool converged = true;
  bool feasible = true;
};

// The first contact on the cloth (not an obstacle), or -1.
int32_t FirstClothContact(const GodObject& body) {
  for (int32_t i = 0; i < body.num_contacts; ++i) {
    if (!IsObstacleContactId(body.contacts[i].triangle)) return i;
  }
  return -1;
}

// Re-evaluates remembered contacts at the proxy's (carried) position on this tick's cloth: a
// contact stays a constraint while its triangle is gathered (or its obstacle declared) and still
// touches the sphere; its plane becomes the exact tangent plane at the current closest point.
int32_t SeedContacts(const LocalCloth& cloth, std::span<const ObstacleSpec> obstacles,
                     const GodObject& body, double r,
                     std::array<ProxyContact, kMaxConstraintPlanes>* out) {
  int32_t n = 0;
  const double touch = r * (1.0 + 1e-6) + 1e-12;
  for (int32_t i = 0; i < body.num_contacts; ++i) {
    const ProxyContact& old = body.contacts[i];
    if (IsObstacleContactId(old.triangle)) {
      // An obstacle: its closest point and outward normal now (the obstacle does not move).
      const int32_t k = ObstacleIndexOf(old.triangle);
      if (k >= static_cast<int32_t>(obstacles.size())) continue;
      const ObstaclePoint op = ClosestObstaclePoint(obstacles[k], body.p_W_m);
      if (op.distance_m > touch) continue;
      ProxyContact c = old;
      c.point_W_m = op.point_W_m;
      c.normal_W = op.normal_W;
      (*out)[n++] = c;
      continue;
    }
    Vec3 a, b, c3;
    if (!cloth.Corners(old.triangle, &a, &b, &c3)) continue;
    const TrianglePoint cp = ClosestPointOnTriangle(body.p_W_m, a, b, c3);
    if (cp.distance_sq > touch * touch) continue;
    const double dist = std::sqrt(cp.distance_sq);
    ProxyContact c = old;
    c.point_W_m = cp.point;
    c.barycentric = cp.barycentric;
    // The normal faces the proxy; a centre exactly on the cloth keeps the side it had.
    c.normal_W = dist > 1e-12 * (1.0 + r) ? Vec3((body.p_W_m - cp.point) / dist) : old.normal_W;
    (*out)[n++] = c;
  }
  return n;
}

// Ruspini 1997 §3: from `start`, sweep toward the closest point to `goal` on the free side of the
// active planes; at each first contact add its plane (at most three) and solve again; drop planes
// the solution leaves (the goal moved to their free side). Bounded by max_iterations.
Pass RunPass(const LocalCloth& cloth, std::span<const ObstacleSpec> obstacles, const Vec3& start,
             std::span<const ProxyContact> seeds, const Vec3& goal, double r,
             int32_t max_iterations) {
  Pass pass;
  pass.p = start;
  for (const ProxyContact& s : seeds) pass.contacts[pass.n++] = s;
  const double tiny = 1e-12 * (1.0 + start.cwiseAbs().maxCoeff() + goal.cwiseAbs().maxCoeff());
  pass.converged = false;
  for (int32_t it = 0; it < max_iterations; ++it) {
    // The closest feasible point to the goal over the active planes.
    std::array<ConstraintPlane, kMaxConstraintPlanes> planes;
    for (int32_t i = 0; i < pass.n; ++i) planes[i] = PlaneOf(pass.contacts[i], r);
    const PlaneSolveResult sol =
        SolveClosestFeasible(goal, std::span<const ConstraintPlane>(planes.data(), pass.n));
    if (!sol.feasible) {
      // Pinched: no point satisfies every plane; the proxy stays where it is (never crosses).
      pass.feasible = false;
      pass.converged = true;
      break;
    }
    // Release the planes the solution does not press on.
    int32_t kept = 0;
    for (int32_t i = 0; i < pass.n; ++i) {
      if (sol.active_mask & (1u << i)) pass.contacts[kept++] = pass.contacts[i];
    }
    pass.n = kept;
    const Vec3 target = sol.point;
    if ((target - pass.p).squaredNorm() <= tiny * tiny) {
      pass.converged = true;
      break;
    }
    // Sweep toward it: free motion ends the pass; a contact adds its plane and repeats.
    ++pass.iterations;
    SweepHit hit = cloth.Sweep(pass.p, target, r);
    // The obstacles are constraint sources beside the triangles: the earlier contact wins (ties:
    // the cloth, which lies on top of an obstacle it rests on). Ericson §5.5.7.
    if (!obstacles.empty()) {
      int32_t k = -1;
      const SweepContact oc = SweepSphereObstacles(pass.p, target, r, obstacles, &k);
      if (oc.hit && (!hit.hit || oc.toi < hit.toi)) {
        hit = SweepHit{true, oc.toi, ObstacleContactId(k), oc.point, oc.normal, Vec3::Zero()};
      }
    }
    if (!hit.hit) {
      pass.p = target;
      pass.converged = true;
      break;
    }
    pass.p = pass.p + hit.toi * (target - pass.p);
    ProxyContact c;
    c.triangle = hit.triangle;
    c.barycentric = hit.barycentric;
    c.point_W_m = hit.point_m;
    c.normal_W = hit.normal;
    // A triangle already active gets its plane updated; otherwise it is added (three at most:
    // a fourth plane means the proxy is boxed in, and it stays where the sweep stopped it).
    int32_t slot = -1;
    for (int32_t i = 0; i < pass.n; ++i) {
      if (pass.contacts[i].triangle == c.triangle) slot = i;
    }
    if (slot < 0 && pass.n == kMaxConstraintPlanes) {
      pass.converged = true;
      break;
    }
    if (slot < 0) slot = pass.n++;
    pass.contacts[slot] = c;
  }
  return pass;
}

// The interpolated vertex normal at a contact (Morgenbesser & Srinivasan 1996: Phong-style normal
// interpolation), turned to the proxy's side; the contact normal where the cloth has none.
Vec3 ShadingNormal(const ClothView& view, const ProxyContact& c) {
  if (IsObstacleContactId(c.triangle)) return c.normal_W;  // an obstacle is not shaded
  const Triangle& tri = (*view.to->triangles)[c.triangle];
  Vec3 n = c.barycentric(0) * view.Normal(tri[0]) + c.barycentric(1) * view.Normal(tri[1]) +
           c.barycentric(2) * view.Normal(tri[2]);
  const double len = n.norm();
  if (!(len > 1e-9)) return c.normal_W;
  n /= len;
  return n.dot(c.normal_W) < 0.0 ? Vec3(-n) : n;
}

// Splits the force on the cloth over the contacts by their normals (the planes' multipliers:
// F = sum f_i n_i, f_i >= 0), the remainder going to the first cloth contact so the total is
// exact. The shares of obstacle contacts are computed alike and then not applied (the static
// obstacle takes them).
void SplitOverContacts(const GodObject& body, const Vec3& force_on_cloth_W,
                       std::array<Vec3, kMaxConstraintPlanes>* parts) {
  const int32_t n = body.num_contacts;
  for (auto& p : *parts) p.setZero();
  if (n <= 0) return;
  const int32_t first = std::max(0, FirstClothContact(body));
  if (n == 1) {
    (*parts)[0] = force_on_cloth_W;
    return;
  }
  Eigen::Matrix3d gram = Eigen::Matrix3d::Identity();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  for (int32_t a = 0; a < n; ++a) {
    rhs(a) = body.contacts[a].normal_W.dot(force_on_cloth_W);
    for (int32_t b = 0; b < n; ++b) {
      gram(a, b) = body.contacts[a].normal_W.dot(body.contacts[b].normal_W);
    }
  }
  Eigen::Vector3d f = Eigen::Vector3d::Zero();
  const double det = gram.determinant();
  if (std::abs(det) > 1e-9) f = gram.inverse() * rhs;
  Vec3 assigned = Vec3::Zero();
  for (int32_t a = 0; a < n; ++a) {
    // The cloth is pushed along -n_i: keep only shares of that sign.
    const double fa = std::min(0.0, f(a));
    (*parts)[a] = fa * body.contacts[a].normal_W;
    assigned += (*parts)[a];
  }
  (*parts)[first] += force_on_cloth_W - assigned;
}

// How far the hand presses the cloth itself: the part of goal - proxy [m, world] the cloth's
// contacts take, limited to how far the proxy could follow a yielding cloth before an obstacle
// stops it. The coupling spring (and the reaction) must not give the cloth more: the energy
// 1/2 k depth^2 the sim's sphere stores is released into the cloth when the cloth slips away
// from under it, while the real proxy would drop onto the obstacle instead.
struct ClothPress {
  double full_m = 0.0;   ///< the cloth contacts' share of |goal - proxy|, m
  double depth_m = 0.0;  ///< full_m limited by the obstacles, m
};

ClothPress PressOnCloth(const GodObject& body, const Vec3& goal, double r,
                        std::span<const ObstacleSpec> obstacles) {
  ClothPress out;
  Vec3 push = goal - body.p_W_m;
  // With an obstacle among the contacts only the cloth contacts' share presses the cloth: the
  // split of goal - proxy over the contacts by their planes' multipliers (Ruspini, Kolarov &
  // Khatib 1997 §3: F = sum f_i n_i; SplitOverContacts), obstacle shares left out.
  bool with_obstacle = false;
  for (int32_t i = 0; i < body.num_contacts; ++i) {
    with_obstacle = with_obstacle || IsObstacleContactId(body.contacts[i].triangle);
  }
  if (with_obstacle) {
    std::array<Vec3, kMaxConstraintPlanes> parts;
    SplitOverContacts(body, push, &parts);
    push.setZero();
    for (int32_t i = 0; i < body.num_contacts; ++i) {
      if (!IsObstacleContactId(body.contacts[i].triangle)) push += parts[i];
    }
  }
  out.full_m = push.norm();
  out.depth_m = out.full_m;
  // The room to follow the cloth: the first obstacle contact of the proxy sphere swept along the
  // push (exact sphere-obstacle sweep, Ericson 2005 §5.5.7; a proxy resting on an obstacle slides
  // along it freely). A proxy pressing a cloth that lies on a table follows it only the cloth's
  // margin down; one rounding the cloth's edge just above the table, hardly at all.
  if (!obstacles.empty() && out.full_m > 0.0) {
    int32_t k = -1;
    const SweepContact oc = SweepSphereObstacles(body.p_W_m, body.p_W_m + push, r, obstacles, &k);
    if (oc.hit) out.depth_m = oc.toi * out.full_m;
  }
  return out;
}

// What one body did in a tick.
struct BodyTick {
  GodObjectStep step;
  bool overflow = false;
  bool caught = false;
};

// The constraint a remembered cloth contact puts on the proxy (Ruspini 1997 §3's tangent plane of
// the radius-grown cloth at the closest point), evaluated for a proxy centre at p on the cloth
// `now`, the contact's point, weights and normal refreshed. The normal points from the closest
// point to p; a triangle whose interior has moved past p (p on the other side of its face than the
// contact's local_m says) gets the face normal of the contact's side instead, so it pushes the
// proxy back to that side.
ConstraintPlane ContactPlaneAt(const ClothView& now, const Vec3& p, double r, ProxyContact* c) {
  Vec3 a, b, cc;
  now.Corners(c->triangle, &a, &b, &cc);
  const TrianglePoint cp = ClosestPointOnTriangle(p, a, b, cc);
  const TriFrame f = FrameOf(a, b, cc);
  const Vec3 d = p - cp.point;
  const double dist = std::sqrt(cp.distance_sq);
  const double side = c->local_m(2) >= 0.0 ? 1.0 : -1.0;
  if (f.ok && cp.barycentric.minCoeff() > 1e-9 && side * f.n.dot(d) < 0.0) {
    c->normal_W = side * f.n;
  } else if (dist > 1e-12 * (1.0 + r)) {
    c->normal_W = d / dist;
  }
  c->point_W_m = cp.point;
  c->barycentric = cp.barycentric;
  return PlaneOf(*c, r);
}

// After the carry and the catch: the proxy goes to the point nearest its position on the free
// side of every cloth contact's plane, the planes taken at `p_eval` (the carried position, where
// the first contact holds the proxy exactly; ContactPlaneAt) except the first contact's when
// `first_plane` gives it. The carry follows the first contact only; the others move with the cloth
// too, and in a closing crease they move into the proxy: a flap folding onto a proxy in the fold
// squeezes it out along the fold, never through either face. Returns false, leaving the body as
// it was, when no point satisfies every plane (the fold is narrower than the proxy).
bool SettleOnContacts(const ClothView& now, const Vec3& p_eval, double r,
                      const ConstraintPlane* first_plane, GodObject* body) {
  std::array<ConstraintPlane, kMaxConstraintPlanes> planes;
  std::array<ProxyContact, kMaxConstraintPlanes> contacts = body->contacts;
  int32_t n = 0;
  for (int32_t i = 0; i < body->num_contacts; ++i) {
    if (IsObstacleContactId(contacts[i].triangle)) continue;  // static: the obstacle sweep's
    planes[n++] = (i == 0 && first_plane != nullptr) ? *first_plane
                                                     : ContactPlaneAt(now, p_eval, r, &contacts[i]);
  }
  if (n == 0) return true;
  const PlaneSolveResult sol =
      SolveClosestFeasible(body->p_W_m, std::span<const ConstraintPlane>(planes.data(), n));
  if (!sol.feasible) return false;
  body->p_W_m = sol.point;
  body->contacts = contacts;
  return true;
}

// A proxy the moving cloth caught rides the triangle that hit it (`caught`, placed at `p_ride`)
// and keeps the cloth contacts it was carried with to `p_carried` (three contacts at most):
// riding the caught face alone put it behind the face it was carried on when a crease closed on it
// (a pop-through in fast_swipe, mode extrapolate). Then SettleOnContacts, the caught plane being
// the tangent one at p_ride. If that finds no room the catch is refused and the proxy stays
// carried. Returns whether the catch was taken.
bool RideCaught(const ClothView& now, const Vec3& p_carried, const Vec3& p_ride,
                const ProxyContact& caught, double r, GodObject* body) {
  GodObject rider = *body;
  rider.p_W_m = p_ride;
  rider.num_contacts = 0;
  rider.contacts[rider.num_contacts++] = caught;
  for (int32_t i = 0; i < body->num_contacts && rider.num_contacts < kMaxConstraintPlanes; ++i) {
    const ProxyContact& k = body->contacts[i];
    if (IsObstacleContactId(k.triangle) || k.triangle == caught.triangle) continue;
    rider.contacts[rider.num_contacts++] = k;
  }
  // |p_ride - point| = r (the triangle's frame is rigid), so this plane passes through p_ride.
  const Vec3 off = p_ride - caught.point_W_m;
  const double len = off.norm();
  ProxyContact tangent = caught;
  if (len > 1e-12 * (1.0 + r)) tangent.normal_W = off / len;
  const ConstraintPlane caught_plane = PlaneOf(tangent, r);
  if (!SettleOnContacts(now, p_carried, r, &caught_plane, &rider)) return false;
  *body = rider;
  return true;
}

// The first contact of the carried proxy with a moving triangle (LocalCloth::SweepMoving), its
// toi a fraction of the piece [q0, q1] that covers the part [s0, s1] of the motion.
struct CarriedSweep {
  SweepHit hit;
  Vec3 q0 = Vec3::Zero();
  Vec3 q1 = Vec3::Zero();
  double s0 = 0.0;
  double s1 = 1.0;
};

// The carried proxy follows its anchor triangle, whose frame turns as it moves: a straight path
// p_prev -> p_carried cuts the arc, and the anchor's neighbours "caught" a proxy their common
// motion never brought closer (then on the wrong side of the anchor, after a large carry). So the
// path is cut into pieces of at most one radius (eight at most), each ending where the carry puts
// the proxy on the cloth part-way (the two cloths' corners blended), the triangles moving linearly
// over each piece's share of the motion.
CarriedSweep SweepCarriedPath(const LocalCloth& local, const ClothView& before,
                              const ClothView& now, const GodObject& body, const Vec3& p_prev,
                              const Vec3& p_carried, double r, std::span<const int32_t> skip) {
  const int32_t anchor = FirstClothContact(body);
  const double carry_m = (p_carried - p_prev).norm();
  const int32_t pieces =
      anchor < 0 ? 1 : std::clamp(static_cast<int32_t>(std::ceil(carry_m / r)), 1, 8);
  Vec3 a0, b0, c0, a1, b1, c1;  // the anchor's corners on both cloths
  if (pieces > 1) {
    before.Corners(body.contacts[anchor].triangle, &a0, &b0, &c0);
    now.Corners(body.contacts[anchor].triangle, &a1, &b1, &c1);
  }
  CarriedSweep out;
  out.q0 = p_prev;
  for (int32_t k = 0; k < pieces; ++k) {
    out.s0 = static_cast<double>(k) / pieces;
    out.s1 = static_cast<double>(k + 1) / pieces;
    const double s = out.s1;
    out.q1 = k + 1 < pieces ? AnchoredAt(body.contacts[anchor], a0 + s * (a1 - a0),
                                         b0 + s * (b1 - b0), c0 + s * (c1 - c0))
                            : p_carried;
    out.hit = local.SweepMoving(out.q0, out.q1, r, skip, out.s0, out.s1);
    if (out.hit.hit) return out;
    out.q0 = out.q1;
  }
  return out;
}

// Carry, gather, catch and update one body against one cloth for this tick.
BodyTick TickBody(const ClothSnapshot& query, double inflation_m, const ClothView& now,
                  const ClothView* before, const Vec3& goal, const GodObjectOptions& opts,
                  LocalCloth* local, GodObject* body) {
  BodyTick out;
  const double r = opts.radius_m;
  if (!body->placed) {
    body->p_W_m = goal;
    body->num_contacts = 0;
    body->placed = true;
    // A goal inside an obstacle: the proxy starts on its surface instead (in declaration order).
    for (const ObstacleSpec& o : opts.obstacles) {
      const ObstaclePoint op = ClosestObstaclePoint(o, body->p_W_m);
      if (op.distance_m < r) body->p_W_m = op.point_W_m + r * op.normal_W;
    }
  }
  // Carry a proxy in contact with its contact triangle to this tick's cloth.
  const Vec3 p_prev = body->p_W_m;
  if (before != nullptr) CarryGodObject(*before, now, body);
  const Vec3 p_carried = body->p_W_m;
  // Gather every triangle the proxy can meet this tick: all of this tick's motion stays within
  // 3 |p - goal| of the goal (the update only approaches its (sub)goal), the catch within
  // |goal - p_prev| + |p_carried - p_prev|.
  const double reach = std::max(3.0 * (p_carried - goal).norm(),
                                (goal - p_prev).norm() + (p_carried - p_prev).norm());
  out.overflow =
      !local->Gather(query, inflation_m, now, before, goal, reach + r * (1.0 + 1e-6) + 1e-9);
  // Catch: the cloth moving from the previous tick's shape to this one may sweep over the proxy
  // (which moves with its carry meanwhile); it then rides on the triangle that hit it.
  if (before != nullptr) {
    std::array<int32_t, kMaxConstraintPlanes> skip;  // the contacts touch from the start
    skip.fill(-1);
    for (int32_t i = 0; i < body->num_contacts; ++i) skip[i] = body->contacts[i].triangle;
    const CarriedSweep cs =
        SweepCarriedPath(*local, *before, now, *body, p_prev, p_carried, r, skip);
    if (cs.hit.hit) {
      const SweepHit& hit = cs.hit;
      const LocalTriangle* t = FindLocal(*local, hit.triangle);
      const double s = cs.s0 + hit.toi * (cs.s1 - cs.s0);
      const TriFrame f0 = FrameOf(t->a0 + s * (t->a - t->a0), t->b0 + s * (t->b - t->b0),
                                  t->c0 + s * (t->c - t->c0));
      const Vec3 p_toi = cs.q0 + hit.toi * (cs.q1 - cs.q0);
      const Vec3 local_off = ToLocal(f0, p_toi - hit.point_m);
      const TriFrame f1 = FrameOf(t->a, t->b, t->c);
      const Vec3& w = hit.barycentric;
      const Vec3 point = w(0) * t->a + w(1) * t->b + w(2) * t->c;
      const Vec3 p_ride = point + FromLocal(f1, local_off);
      ProxyContact c;
      c.triangle = hit.triangle;
      c.barycentric = w;
      c.point_W_m = point;
      c.normal_W = f1.ok ? Vec3(f1.n * (local_off(2) >= 0.0 ? 1.0 : -1.0)) : hit.normal;
      c.local_m = local_off;
      out.caught = RideCaught(now, p_carried, p_ride, c, r, body);
    }
  }
  if (!out.caught) SettleOnContacts(now, p_carried, r, nullptr, body);
  // The static obstacles stop the carry and the catch: the cloth may press the proxy toward an
  // obstacle, but the proxy never enters one (it stays at the first contact on its way).
  if (!opts.obstacles.empty()) {
    int32_t k = -1;
    const SweepContact oc = SweepSphereObstacles(p_prev, body->p_W_m, r, opts.obstacles, &k);
    if (oc.hit) body->p_W_m = p_prev + oc.toi * (body->p_W_m - p_prev);
  }
  out.step = UpdateGodObject(*local, now, goal, opts, body);
  return out;
}

// Spring-damper force on the device for a proxy at p (world), device frame, unclamped.
Vec3 CouplingForceD(const DeviceSpec& d, const Vec3& p_W, const Vec3& goal_W, const Vec3& v_proxy_W,
                    const Vec3& v_device_D) {
  const Eigen::Matrix3d& R = d.rotation_WD;
  const Vec3 spring = d.stiffness_N_per_m * (R.transpose() * (p_W - goal_W)) / d.scale;
  const Vec3 v_proxy_D = R.transpose() * v_proxy_W / d.scale;
  return spring + d.damping_N_s_per_m * (v_proxy_D - v_device_D);
}

}  // namespace

int32_t SideOfTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const TriFrame f = FrameOf(a, b, c);
  if (!f.ok) return 0;
  const TrianglePoint cp = ClosestPointOnTriangle(p, a, b, c);
  const double s = f.n.dot(p - cp.point);
  return s > 0.0 ? 1 : (s < 0.0 ? -1 : 0);
}

void CarryGodObject(const ClothView& /*before*/, const ClothView& now, GodObject* body) {
  const int32_t first = FirstClothContact(*body);
  if (first < 0) return;
  // The first cloth contact anchors the proxy: same barycentric point, same offset in the
  // triangle's frame (which holds the side and the radius), on the new cloth.
  const ProxyContact& c = body->contacts[first];
  Vec3 a, b, cc;
  now.Corners(c.triangle, &a, &b, &cc);
  body->p_W_m = AnchoredAt(c, a, b, cc);
}

GodObjectStep UpdateGodObject(const LocalCloth& cloth, const ClothView& view, const Vec3& goal_W,
                              const GodObjectOptions& options, GodObject* body) {
  GodObjectStep step;
  const double r = options.radius_m;
  const Vec3 p_old = body->p_W_m;
  std::array<ProxyContact, kMaxConstraintPlanes> seeds;
  const std::span<const ObstacleSpec> obstacles = options.obstacles;
  const int32_t num_seeds = SeedContacts(cloth, obstacles, *body, r, &seeds);
  const std::span<const ProxyContact> seed_span(seeds.data(), num_seeds);

  // Pass 1: the plain god-object update toward the goal.
  Pass pass = RunPass(cloth, obstacles, p_old, seed_span, goal_W, r, options.max_iterations);
  step.iterations += pass.iterations;
  step.converged = step.converged && pass.converged;
  step.feasible = step.feasible && pass.feasible;
  Pass surface = pass;  // the contacts the force comes from

  // Pass 2, force shading (Ruspini 1997 §5 after Morgenbesser & Srinivasan 1996): the goal
  // projected onto the planes through the proxy with the interpolated normals is the sub-goal of
  // a second update from the same start.
  Vec3 goal = goal_W;
  if (options.force_shading && pass.n > 0) {
    std::array<ConstraintPlane, kMaxConstraintPlanes> shaded;
    for (int32_t i = 0; i < pass.n; ++i) {
      const Vec3 ns = ShadingNormal(view, pass.contacts[i]);
      shaded[i] = ConstraintPlane{ns, ns.dot(pass.p), pass.contacts[i].triangle};
    }
    const PlaneSolveResult sub =
        SolveClosestFeasible(goal_W, std::span<const ConstraintPlane>(shaded.data(), pass.n));
    if (sub.feasible) goal = sub.point;
    pass = RunPass(cloth, obstacles, p_old, seed_span, goal, r, options.max_iterations);
    step.iterations += pass.iterations;
    step.converged = step.converged && pass.converged;
    step.feasible = step.feasible && pass.feasible;
    if (pass.n > 0) surface = pass;
  }

  // Friction (Ruspini 1997 §4; Salisbury et al. 1995's cone): a proxy that was and stays in
  // contact sticks while the goal is inside the cone around the normal (the static cone when
  // stuck, the dynamic one while slipping), else it trails the frictionless point at the edge of
  // the dynamic cone.
  bool slipping = false;
  if (options.friction_static > 0.0 && num_seeds > 0 && pass.n > 0) {
    Vec3 n = Vec3::Zero();
    for (int32_t i = 0; i < pass.n; ++i) n += pass.contacts[i].normal_W;
    n.normalize();
    const Vec3 p_free = pass.p;
    const double depth = n.dot(p_free - goal_W);
    Vec3 t = p_old - p_free;
    t -= n * n.dot(t);
    const double tl = t.norm();
    if (depth > 0.0 && tl > 0.0) {
      const double mu_d = std::min(options.friction_dynamic, options.friction_static);
      const double mu_hold = body->slipping ? mu_d : options.friction_static;
      slipping = tl > mu_hold * depth;
      const Vec3 target = slipping ? Vec3(p_free + t * (mu_d * depth / tl)) : Vec3(p_free + t);
      pass = RunPass(cloth, obstacles, p_old, seed_span, target, r, options.max_iterations);
      step.iterations += pass.iterations;
      step.converged = step.converged && pass.converged;
      step.feasible = step.feasible && pass.feasible;
      if (pass.n > 0) surface = pass;
    }
  }
  body->slipping = slipping;

  // The new proxy, with its contacts' offsets in their triangles' frames (for the carry).
  body->p_W_m = pass.p;
  body->num_contacts = surface.n;
  for (int32_t i = 0; i < surface.n; ++i) {
    ProxyContact c = surface.contacts[i];
    Vec3 a, b, c3;
    const TriFrame f = cloth.Corners(c.triangle, &a, &b, &c3) ? FrameOf(a, b, c3) : TriFrame{};
    c.local_m = ToLocal(f, pass.p - c.point_W_m);
    body->contacts[i] = c;
  }
  return step;
}

ProxyState MakeProxyState(const ProxySpec& proxy) { return ProxyState(proxy.candidate_capacity); }

ProxyTickResult ProxyTick(const DeviceSpec& device, const ProxySpec& proxy,
                          const ClothSnapshot& newest, const ClothSnapshot* previous,
                          double since_newest_s, const DeviceSample& sample, double tick_dt_s,
                          ProxyState* state) {
  ProxyTickResult out;
  ProxyCounters& counters = state->counters;
  ++counters.ticks;
  const Vec3 goal = DeviceToWorld(device, sample.p_D_m);
  out.goal_W_m = goal;

  // Which snapshots this tick has; a previous one of another cloth is ignored.
  const ClothSnapshot* prev = previous;
  if (prev != nullptr && (prev == &newest || prev->x.size() != newest.x.size())) prev = nullptr;
  SnapshotMode mode = proxy.snapshot_mode;
  if (prev == nullptr) mode = SnapshotMode::kNewest;
  const bool arrived = !state->have_frame || newest.frame != state->newest_frame;
  const bool first = !state->have_frame;
  if (arrived) {
    if (!first) ++counters.new_snapshots;
    state->newest_frame = newest.frame;
    state->have_frame = true;
    state->pair_displacement_m = prev != nullptr ? MaxDisplacement(*prev, newest) : 0.0;
  }
  const double frame_dt = newest.frame_dt_s;
  const double alpha = frame_dt > 0.0 ? std::clamp(since_newest_s / frame_dt, 0.0, 1.0) : 1.0;
  const double tau = std::max(0.0, since_newest_s);
  const double disp = state->pair_displacement_m;

  GodObjectOptions opts;
  opts.radius_m = device.radius_m;
  opts.max_iterations = proxy.max_iterations;
  opts.force_shading = proxy.force_shading;
  opts.friction_static = proxy.friction_static;
  opts.friction_dynamic = proxy.friction_dynamic;
  opts.obstacles = proxy.obstacles;

  // The cloth of this tick and of the previous tick, by mode.
  ClothView now = ClothView::Of(newest);
  ClothView before_view = now;
  bool moved = arrived && !first && prev != nullptr;
  double inflation = 0.0;
  switch (mode) {
    case SnapshotMode::kNewest:
    case SnapshotMode::kBlendForces:
      if (moved) {
        before_view = ClothView::Of(*prev);
        inflation = disp;
      }
      break;
    case SnapshotMode::kInterpolate: {
      // One frame late: the cloth runs from the previous snapshot to the newest over the frame.
      now = ClothView{prev, &newest, alpha, 0.0};
      const double alpha_before = arrived ? 0.0 : state->last_alpha;
      before_view = ClothView{prev, &newest, alpha_before, 0.0};
      moved = !first && alpha_before != alpha;
      inflation = (1.0 - std::min(alpha, alpha_before)) * disp;
      break;
    }
    case SnapshotMode::kExtrapolate: {
      now = ClothView{&newest, &newest, 0.0, tau};
      double before_extent = state->last_tau_s * newest.max_speed_m_per_s;
      if (arrived) {
        before_view = ClothView{prev, prev, 0.0, state->last_tau_s};
        before_extent = disp + state->last_tau_s * prev->max_speed_m_per_s;
      } else {
        before_view = ClothView{&newest, &newest, 0.0, state->last_tau_s};
      }
      moved = !first && (arrived || state->last_tau_s != tau);
      inflation = std::max(tau * newest.max_speed_m_per_s, before_extent);
      break;
    }
  }

  // A previous tick that fell back to its newest snapshot (below) left the proxy on that cloth:
  // the one now called prev after an arrival.
  const bool interpolated =
      mode == SnapshotMode::kInterpolate || mode == SnapshotMode::kExtrapolate;
  if (interpolated && state->last_on_newest && !first) {
    before_view = arrived ? ClothView::Of(*prev) : ClothView::Of(newest);
    moved = true;
    inflation = std::max(inflation, arrived ? disp : 0.0);
  }

  // Mode (b): the proxy on the previous cloth is the one that was on the newest last frame.
  if (mode == SnapshotMode::kBlendForces && arrived) state->body_prev = state->body;
  const GodObject body_before = state->body;
  BodyTick main = TickBody(newest, inflation, now, moved ? &before_view : nullptr, goal, opts,
                           &state->local, &state->body);
  // Modes (c), (d): after a gather overflow the sweeps query the newest snapshot's structure at
  // its own positions (LocalCloth::Sweep) while the carry and the gathered triangles used the
  // interpolated or extrapolated cloth, so the proxy could be solved against two cloths at once.
  // Such a tick runs again wholly on the newest snapshot (mode (a) for one tick), from the
  // previous tick's cloth; every vertex of both stays within `inflation` of it.
  bool on_newest = false;
  if (interpolated && main.overflow) {
    state->body = body_before;
    now = ClothView::Of(newest);
    main = TickBody(newest, inflation, now, first ? nullptr : &before_view, goal, opts,
                    &state->local, &state->body);
    on_newest = true;
  }
  out.on_newest = on_newest;
  Vec3 proxy_W = state->body.p_W_m;
  out.iterations = main.step.iterations;
  out.overflow = main.overflow;
  out.caught = main.caught;
  bool converged = main.step.converged;
  bool feasible = main.step.feasible;

  // Forces: spring-damper on the device, per proxy; mode (b) blends the two by alpha.
  const double inv_dt = tick_dt_s > 0.0 ? 1.0 / tick_dt_s : 0.0;
  Vec3 f_main_D =
      CouplingForceD(device, state->body.p_W_m, goal,
                     (state->body.p_W_m - state->last_proxy_W_m) * inv_dt, sample.v_D_m_per_s);
  Vec3 f_prev_D = Vec3::Zero();
  double w_main = 1.0;
  double w_prev = 0.0;
  if (mode == SnapshotMode::kBlendForces) {
    const ClothView prev_view = ClothView::Of(*prev);
    const BodyTick other =
        TickBody(*prev, 0.0, prev_view, nullptr, goal, opts, &state->local, &state->body_prev);
    out.iterations += other.step.iterations;
    out.overflow = out.overflow || other.overflow;
    converged = converged && other.step.converged;
    feasible = feasible && other.step.feasible;
    w_main = alpha;
    w_prev = 1.0 - alpha;
    proxy_W = w_prev * state->body_prev.p_W_m + w_main * state->body.p_W_m;
    f_prev_D = CouplingForceD(device, state->body_prev.p_W_m, goal,
                              (state->body_prev.p_W_m - state->last_proxy_W_m) * inv_dt,
                              sample.v_D_m_per_s);
  }
  Vec3 force_D = w_main * f_main_D + w_prev * f_prev_D;

  // Clamp to the device's maximum, direction kept.
  double clamp = 1.0;
  const double mag = force_D.norm();
  if (mag > device.max_force_N) {
    clamp = device.max_force_N / mag;
    out.clamped = true;
    ++counters.clamped_ticks;
  }
  force_D *= clamp;
  const Eigen::Matrix3d& R = device.rotation_WD;
  out.force_D_N = force_D;
  out.force_W_N = R * force_D / device.scale;

  // Two-way coupling: each proxy's share of -F_W goes to the cloth at its contacts.
  const std::vector<Triangle>& tris = *newest.triangles;
  // Each gets only what the cloth itself takes before an obstacle does (PressOnCloth), as the
  // contact spring below.
  const ClothPress press = PressOnCloth(state->body, goal, opts.radius_m, opts.obstacles);
  auto add_reaction = [&](const GodObject& body, const ClothPress& p, const Vec3& f_D,
                          double weight) {
    if (body.num_contacts <= 0 || weight <= 0.0) return;
    Vec3 on_cloth_W = -(R * (weight * clamp * f_D)) / device.scale;
    if (p.depth_m < p.full_m) on_cloth_W *= p.depth_m / p.full_m;
    std::array<Vec3, kMaxConstraintPlanes> parts;
    SplitOverContacts(body, on_cloth_W, &parts);
    for (int32_t i = 0; i < body.num_contacts; ++i) {
      const ProxyContact& c = body.contacts[i];
      if (IsObstacleContactId(c.triangle)) continue;  // the static obstacle takes its share
      state->reaction.AddForce(c.triangle, tris[c.triangle], c.barycentric, parts[i], tick_dt_s);
    }
  };
  add_reaction(state->body, press, f_main_D, w_main);
  if (mode == SnapshotMode::kBlendForces) {
    add_reaction(state->body_prev,
                 PressOnCloth(state->body_prev, goal, opts.radius_m, opts.obstacles), f_prev_D,
                 w_prev);
  }
  state->reaction.AddTime(tick_dt_s);
  // The contact of this tick as a spring the sim evaluates at its substep rate (virtual coupling,
  // Colgate, Stanley & Brown 1995). The device spring F_D = k (proxy_D - device_D) is, in the
  // world, F_W = (k / scale^2) (proxy_W - goal_W) (proxy_spec.h). The sim presses a sphere onto the
  // nearest point of the cloth around the contact triangle, re-found at every force evaluation, so
  // the force is a potential's gradient however the contact wanders between triangles (tying it to
  // this tick's one triangle made a press next to a vertex cycle at 20 Hz; docs/proxy.md).
  // Obstacle contacts (negative ids) put nothing on the cloth: the spring is the first cloth one.
  const int32_t spring_contact = FirstClothContact(state->body);
  const double spring_k_W = device.stiffness_N_per_m / (device.scale * device.scale);
  const double spring_max_W = device.max_force_N / device.scale;
  if (spring_contact >= 0) {
    const ProxyContact& c = state->body.contacts[spring_contact];
    // The sim's sphere: centred on the proxy, its radius grown by how far the hand presses the
    // cloth itself (PressOnCloth: |proxy - goal| without obstacles; along the contact normal for a
    // frictionless contact), so at rest its penetration is that depth. Both are continuous in time
    // (a sphere at the goal itself, deep behind the cloth in a fast swipe, found its nearest point
    // sideways; one tied to the contact normal moved whenever the contact hopped between
    // triangles).
    const Vec3& proxy_c = state->body.p_W_m;
    const double reach_m = opts.radius_m + press.depth_m;
    state->reaction.SetContactSpring(c.triangle, c.barycentric, c.normal_W,
                                     proxy_c - reach_m * c.normal_W, spring_k_W, spring_max_W,
                                     reach_m);
    state->hand_seed = c;
  } else if (state->hand_seed.triangle >= 0 && !first) {
    // Free: the hand is still there for the cloth. The haptic side's cloth is a snapshot (or an
    // interpolated or extrapolated one) while the sim's is the real one; a proxy that lost contact
    // with the one may still be pressing on the other. Without a spring the sim's cloth sprang
    // back freely into the hand, and mode extrapolate fell into a limit cycle (contact lost each
    // frame the sim's cloth was pushed away, regained when it sprang back;
    // bench/results/compare_poke_hold.md). So while the free proxy (at the goal) is within three
    // radii of its last contact point, on the side it touched (the newest snapshot's cloth there),
    // the sim keeps the proxy sphere there: a unilateral spring that pushes only if the cloth
    // enters it, continuous with the contact's (whose sphere's far side also lies r beyond the
    // goal). The frame's averaged impulses then give way to it (ReactionAccumulator::DrainInto).
    const ProxyContact& c = state->hand_seed;
    Vec3 a, b, cc;
    ClothView::Of(newest).Corners(c.triangle, &a, &b, &cc);
    const Vec3 d = goal - ContactPointOn(c, a, b, cc);
    if (d.norm() < 3.0 * opts.radius_m && d.dot(c.normal_W) >= 0.0) {
      state->reaction.SetContactSpring(c.triangle, c.barycentric, c.normal_W,
                                       goal - opts.radius_m * c.normal_W, spring_k_W, spring_max_W,
                                       opts.radius_m);
    } else {
      state->hand_seed.triangle = -1;
      state->reaction.ClearContactSpring();
    }
  } else {
    state->reaction.ClearContactSpring();
  }

  // Book-keeping for the next tick.
  out.proxy_W_m = proxy_W;
  out.num_contacts = state->body.num_contacts;
  if (out.overflow) ++counters.overflow_ticks;
  if (out.caught) ++counters.catches;
  if (!converged) ++counters.unconverged_ticks;
  if (!feasible) ++counters.infeasible_ticks;
  state->last_alpha = alpha;
  state->last_tau_s = tau;
  state->last_on_newest = on_newest;
  state->last_proxy_W_m = mode == SnapshotMode::kBlendForces ? proxy_W : state->body.p_W_m;
  return out;
}

}  // namespace felt
