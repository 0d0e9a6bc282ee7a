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

// The first contact of the proxy sphere (radius r, m) swept p -> target [m, world] against the
// gathered cloth and the obstacles: the obstacles are constraint sources beside the triangles, and
// the earlier contact wins (ties: the cloth, which lies on top of an obstacle it rests on).
// Ericson 2005 §5.5.7.
SweepHit FirstHitOnWay(const LocalCloth& cloth, std::span<const ObstacleSpec> obstacles,
                       const Vec3& p, const Vec3& target, double r) {
  SweepHit hit = cloth.Sweep(p, target, r);
  if (!obstacles.empty()) {
    int32_t k = -1;
    const SweepContact oc = SweepSphereObstacles(p, target, r, obstacles, &k);
    if (oc.hit && (!hit.hit || oc.toi < hit.toi)) {
      hit = SweepHit{true, oc.toi, ObstacleContactId(k), oc.point, oc.normal, Vec3::Zero()};
    }
  }
  return hit;
}

// Makes a sweep's hit a contact of the pass: a triangle already active gets its plane updated;
// otherwise it is added (three at most). Returns false when a fourth plane would be needed: the
// proxy is boxed in, and it stays where the sweep stopped it.
bool AddPassContact(const SweepHit& hit, Pass* pass) {
  ProxyContact c;
  c.triangle = hit.triangle;
  c.barycentric = hit.barycentric;
  c.point_W_m = hit.point_m;
  c.normal_W = hit.normal;
  int32_t slot = -1;
  for (int32_t i = 0; i < pass->n; ++i) {
    if (pass->contacts[i].triangle == c.triangle) slot = i;
  }
  if (slot < 0 && pass->n == kMaxConstraintPlanes) return false;
  if (slot < 0) slot = pass->n++;
  pass->contacts[slot] = c;
  return true;
}

// The closest point to `goal` [m, world] on the free side of the pass's active planes (radius r,
// m), releasing the planes it does not press on. Returns false when no point satisfies every plane.
bool SolveActivePlanes(const Vec3& goal, double r, Pass* pass, Vec3* target) {
  std::array<ConstraintPlane, kMaxConstraintPlanes> planes;
  for (int32_t i = 0; i < pass->n; ++i) planes[i] = PlaneOf(pass->contacts[i], r);
  const PlaneSolveResult sol =
      SolveClosestFeasible(goal, std::span<const ConstraintPlane>(planes.data(), pass->n));
  if (!sol.feasible) return false;
  int32_t kept = 0;
  for (int32_t i = 0; i < pass->n; ++i) {
    if (sol.active_mask & (1u << i)) pass->contacts[kept++] = pass->contacts[i];
  }
  pass->n = kept;
  *target = sol.point;
  return true;
}

// Ruspini 1997 §3: from `start`, sweep toward the closest point to `goal` on the free side of the
// active planes; at each first contact add its plane (at most three) and solve again; drop planes
// the solution leaves (the goal moved to their free side). Bounded by model.max_iterations.
Pass RunPass(const ProxyModel& model, const LocalCloth& cloth, const Vec3& start,
             std::span<const ProxyContact> seeds, const Vec3& goal) {
  const double r = model.radius_m;
  Pass pass;
  pass.p = start;
  for (const ProxyContact& s : seeds) pass.contacts[pass.n++] = s;
  const double tiny = 1e-12 * (1.0 + start.cwiseAbs().maxCoeff() + goal.cwiseAbs().maxCoeff());
  pass.converged = false;
  for (int32_t it = 0; it < model.max_iterations; ++it) {
    Vec3 target;
    if (!SolveActivePlanes(goal, r, &pass, &target)) {
      // Pinched: no point satisfies every plane; the proxy stays where it is (never crosses).
      pass.feasible = false;
      pass.converged = true;
      break;
    }
    if ((target - pass.p).squaredNorm() <= tiny * tiny) {
      pass.converged = true;
      break;
    }
    // Sweep toward it: free motion ends the pass; a contact adds its plane and repeats.
    ++pass.iterations;
    const SweepHit hit = FirstHitOnWay(cloth, model.obstacles, pass.p, target, r);
    if (!hit.hit) {
      pass.p = target;
      pass.converged = true;
      break;
    }
    pass.p = pass.p + hit.toi * (target - pass.p);
    if (!AddPassContact(hit, &pass)) {
      pass.converged = true;
      break;
    }
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

// A body not yet placed starts at the goal [m, world]; a goal inside an obstacle puts it on the
// obstacle's surface instead (in declaration order).
void PlaceAtGoal(const ProxyModel& model, const Vec3& goal, GodObject* body) {
  body->p_W_m = goal;
  body->num_contacts = 0;
  body->placed = true;
  for (const ObstacleSpec& o : model.obstacles) {
    const ObstaclePoint op = ClosestObstaclePoint(o, body->p_W_m);
    if (op.distance_m < model.radius_m) body->p_W_m = op.point_W_m + model.radius_m * op.normal_W;
  }
}

// Catch: the cloth moving from the previous tick's shape `before` to `now` may sweep over the
// proxy (which moves with its carry meanwhile, p_prev -> p_carried [m, world]); it then rides on
// the triangle that hit it (RideCaught). Returns whether it was caught.
bool CatchOnMovingCloth(const LocalCloth& local, const ClothView& before, const ClothView& now,
                        const Vec3& p_prev, const Vec3& p_carried, double r, GodObject* body) {
  std::array<int32_t, kMaxConstraintPlanes> skip;  // the contacts touch from the start
  skip.fill(-1);
  for (int32_t i = 0; i < body->num_contacts; ++i) skip[i] = body->contacts[i].triangle;
  const CarriedSweep cs = SweepCarriedPath(local, before, now, *body, p_prev, p_carried, r, skip);
  if (!cs.hit.hit) return false;
  const SweepHit& hit = cs.hit;
  const LocalTriangle* t = FindLocal(local, hit.triangle);
  const double s = cs.s0 + hit.toi * (cs.s1 - cs.s0);
  const TriFrame f0 =
      FrameOf(t->a0 + s * (t->a - t->a0), t->b0 + s * (t->b - t->b0), t->c0 + s * (t->c - t->c0));
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
  return RideCaught(now, p_carried, p_ride, c, r, body);
}

// Carry, gather, catch and update one body against one cloth for this tick.
BodyTick TickBody(const ProxyModel& model, const ClothSnapshot& query, double inflation_m,
                  double patch_offset_m, const ClothView& now, const ClothView* before,
                  const Vec3& goal, LocalCloth* local, GodObject* body) {
  BodyTick out;
  const double r = model.radius_m;
  if (!body->placed) PlaceAtGoal(model, goal, body);
  // Carry a proxy in contact with its contact triangle to this tick's cloth.
  const Vec3 p_prev = body->p_W_m;
  if (before != nullptr) CarryGodObject(*before, now, body);
  const Vec3 p_carried = body->p_W_m;
  // Gather every triangle the proxy can meet this tick: all of this tick's motion stays within
  // 3 |p - goal| of the goal (the update only approaches its (sub)goal), the catch within
  // |goal - p_prev| + |p_carried - p_prev|.
  const double reach = std::max(3.0 * (p_carried - goal).norm(),
                                (goal - p_prev).norm() + (p_carried - p_prev).norm());
  out.overflow = !local->Gather(query, inflation_m, now, before, goal,
                                reach + r * (1.0 + 1e-6) + 1e-9, patch_offset_m);
  if (before != nullptr) {
    out.caught = CatchOnMovingCloth(*local, *before, now, p_prev, p_carried, r, body);
  }
  if (!out.caught) SettleOnContacts(now, p_carried, r, nullptr, body);
  // The static obstacles stop the carry and the catch: the cloth may press the proxy toward an
  // obstacle, but the proxy never enters one (it stays at the first contact on its way).
  if (!model.obstacles.empty()) {
    int32_t k = -1;
    const SweepContact oc = SweepSphereObstacles(p_prev, body->p_W_m, r, model.obstacles, &k);
    if (oc.hit) body->p_W_m = p_prev + oc.toi * (body->p_W_m - p_prev);
  }
  out.step = UpdateGodObject(model, *local, now, goal, body);
  return out;
}

// Spring-damper force on the device for a proxy at p_W (world, m) moving at v_proxy_W [m/s,
// world], the device at goal_W moving at v_device_D [m/s, device frame]: device frame, N,
// unclamped.
Vec3 CouplingForceD(const ProxyModel& m, const Vec3& p_W, const Vec3& goal_W, const Vec3& v_proxy_W,
                    const Vec3& v_device_D) {
  const Eigen::Matrix3d& R = m.rotation_WD;
  const Vec3 spring = m.stiffness_N_per_m * (R.transpose() * (p_W - goal_W)) / m.scale;
  const Vec3 v_proxy_D = R.transpose() * v_proxy_W / m.scale;
  return spring + m.damping_N_s_per_m * (v_proxy_D - v_device_D);
}

// Adds a pass's counts to the update's.
void TallyPass(const Pass& pass, GodObjectStep* step) {
  step->iterations += pass.iterations;
  step->converged = step->converged && pass.converged;
  step->feasible = step->feasible && pass.feasible;
}

// Force shading's sub-goal (Ruspini 1997 §5 after Morgenbesser & Srinivasan 1996): goal_W [m,
// world] projected onto the planes through the proxy with the interpolated normals; goal_W itself
// when they admit no point.
Vec3 ShadedGoal(const ClothView& view, const Pass& pass, const Vec3& goal_W) {
  std::array<ConstraintPlane, kMaxConstraintPlanes> shaded;
  for (int32_t i = 0; i < pass.n; ++i) {
    const Vec3 ns = ShadingNormal(view, pass.contacts[i]);
    shaded[i] = ConstraintPlane{ns, ns.dot(pass.p), pass.contacts[i].triangle};
  }
  const PlaneSolveResult sub =
      SolveClosestFeasible(goal_W, std::span<const ConstraintPlane>(shaded.data(), pass.n));
  return sub.feasible ? sub.point : goal_W;
}

// Friction (Ruspini 1997 §4; Salisbury et al. 1995's cone): a proxy that was and stays in
// contact sticks while the goal is inside the cone around the normal (the static cone when
// stuck, the dynamic one while slipping), else it trails the frictionless point at the edge of
// the dynamic cone. Reruns the pass from p_old toward that point. Returns whether it slips.
bool ApplyFriction(const ProxyModel& model, const LocalCloth& cloth, const Vec3& goal_W,
                   const Vec3& p_old, std::span<const ProxyContact> seeds, bool was_slipping,
                   Pass* pass, Pass* surface, GodObjectStep* step) {
  if (!(model.friction_static > 0.0 && !seeds.empty() && pass->n > 0)) return false;
  Vec3 n = Vec3::Zero();
  for (int32_t i = 0; i < pass->n; ++i) n += pass->contacts[i].normal_W;
  n.normalize();
  const Vec3 p_free = pass->p;
  const double depth = n.dot(p_free - goal_W);
  Vec3 t = p_old - p_free;
  t -= n * n.dot(t);
  const double tl = t.norm();
  if (!(depth > 0.0 && tl > 0.0)) return false;
  const double mu_d = model.friction_dynamic;
  const double mu_hold = was_slipping ? mu_d : model.friction_static;
  const bool slipping = tl > mu_hold * depth;
  const Vec3 target = slipping ? Vec3(p_free + t * (mu_d * depth / tl)) : Vec3(p_free + t);
  *pass = RunPass(model, cloth, p_old, seeds, target);
  TallyPass(*pass, step);
  if (pass->n > 0) *surface = *pass;
  return slipping;
}

// The pass's proxy into the body, with the surface's contacts and their offsets in their
// triangles' frames (for the carry).
void StoreBody(const LocalCloth& cloth, const Pass& pass, const Pass& surface, GodObject* body) {
  body->p_W_m = pass.p;
  body->num_contacts = surface.n;
  for (int32_t i = 0; i < surface.n; ++i) {
    ProxyContact c = surface.contacts[i];
    Vec3 a, b, c3;
    const TriFrame f = cloth.Corners(c.triangle, &a, &b, &c3) ? FrameOf(a, b, c3) : TriFrame{};
    c.local_m = ToLocal(f, pass.p - c.point_W_m);
    body->contacts[i] = c;
  }
}

// Step 2's second half: the cloth of this tick and of the previous tick by the tick's mode
// (ClothView recipes over `newest` and cloth->prev), and how far both lie from `newest`.
void ViewsForMode(const ClothSnapshot& newest, const ProxyState& state, TickCloth* cloth) {
  const ClothSnapshot* prev = cloth->prev;
  const double disp = state.pair_displacement_m;
  const double alpha = cloth->alpha;
  const double tau = cloth->tau_s;
  cloth->now = ClothView::Of(newest);
  cloth->before = cloth->now;
  cloth->moved = cloth->arrived && !cloth->first && prev != nullptr;
  cloth->inflation_m = 0.0;
  switch (cloth->mode) {
    case SnapshotMode::kNewest:
    case SnapshotMode::kBlendForces:
      if (cloth->moved) {
        cloth->before = ClothView::Of(*prev);
        cloth->inflation_m = disp;
      }
      break;
    case SnapshotMode::kInterpolate: {
      // One frame late: the cloth runs from the previous snapshot to the newest over the frame.
      cloth->now = ClothView{prev, &newest, alpha, 0.0};
      const double alpha_before = cloth->arrived ? 0.0 : state.last_alpha;
      cloth->before = ClothView{prev, &newest, alpha_before, 0.0};
      cloth->moved = !cloth->first && alpha_before != alpha;
      cloth->inflation_m = (1.0 - std::min(alpha, alpha_before)) * disp;
      break;
    }
    case SnapshotMode::kExtrapolate:
    case SnapshotMode::kPatch: {
      cloth->now = ClothView{&newest, &newest, 0.0, tau};
      double before_extent = state.last_tau_s * newest.max_speed_m_per_s;
      if (cloth->arrived) {
        cloth->before = ClothView{prev, prev, 0.0, state.last_tau_s};
        before_extent = disp + state.last_tau_s * prev->max_speed_m_per_s;
      } else {
        cloth->before = ClothView{&newest, &newest, 0.0, state.last_tau_s};
      }
      cloth->moved = !cloth->first && (cloth->arrived || state.last_tau_s != tau);
      cloth->inflation_m = std::max(tau * newest.max_speed_m_per_s, before_extent);
      break;
    }
  }
}

// What the tick's proxies did, both together (mode b: the main one and the previous cloth's).
struct TickBodies {
  BodyTick main;           // the proxy on the tick's cloth
  BodyTick other;          // mode b: the proxy on the previous snapshot (else untouched)
  bool on_newest = false;  // modes c, d: the main proxy fell back to `newest` (overflow)
};

// Steps 3-5 for the main proxy: carry, catch and update on the tick's cloth. Modes (c), (d):
// after a gather overflow the sweeps query the newest snapshot's structure at its own positions
// (LocalCloth::Sweep) while the carry and the gathered triangles used the interpolated or
// extrapolated cloth, so the proxy could be solved against two cloths at once. Such a tick runs
// again wholly on the newest snapshot (mode (a) for one tick), from the previous tick's cloth;
// every vertex of both stays within `inflation` of it. Mode (b): the proxy on the previous
// cloth is the one that was on the newest last frame, and it is updated there too.
TickBodies MoveProxies(const ProxyModel& model, const ClothSnapshot& newest, const TickCloth& cloth,
                       const Vec3& goal, ProxyState* state) {
  TickBodies out;
  const bool blend = cloth.mode == SnapshotMode::kBlendForces;
  if (blend && cloth.arrived) state->body_prev = state->body;
  const GodObject body_before = state->body;
  out.main = TickBody(model, newest, cloth.inflation_m, cloth.patch_offset_m, cloth.now,
                      cloth.moved ? &cloth.before : nullptr, goal, &state->local, &state->body);
  if (cloth.interpolated && out.main.overflow) {
    state->body = body_before;
    out.main = TickBody(model, newest, std::max(cloth.inflation_m, cloth.patch_offset_m), 0.0,
                        ClothView::Of(newest), cloth.first ? nullptr : &cloth.before, goal,
                        &state->local, &state->body);
    out.on_newest = true;
  }
  if (blend) {
    out.other = TickBody(model, *cloth.prev, 0.0, 0.0, ClothView::Of(*cloth.prev), nullptr, goal,
                         &state->local, &state->body_prev);
  }
  return out;
}

// Step 6 before the clamp: each proxy's spring-damper on the device [N, device frame] and the
// weights that blend them (mode b: by alpha; else the main one alone), and the proxy reported.
struct TickForces {
  Vec3 main_D = Vec3::Zero();   // the main proxy's coupling force, device frame, N
  Vec3 prev_D = Vec3::Zero();   // mode b: the previous cloth's proxy's, device frame, N
  double w_main = 1.0;          // blend weight of main_D
  double w_prev = 0.0;          // blend weight of prev_D
  Vec3 proxy_W = Vec3::Zero();  // the proxy centre reported, world, m (mode b: blended)
};

TickForces CouplingForces(const ProxyModel& model, const TickCloth& cloth, const Vec3& goal,
                          const DeviceSample& sample, double tick_dt_s, const ProxyState& state) {
  TickForces f;
  const double inv_dt = tick_dt_s > 0.0 ? 1.0 / tick_dt_s : 0.0;
  f.main_D = CouplingForceD(model, state.body.p_W_m, goal,
                            (state.body.p_W_m - state.last_proxy_W_m) * inv_dt, sample.v_D_m_per_s);
  f.proxy_W = state.body.p_W_m;
  if (cloth.mode == SnapshotMode::kBlendForces) {
    f.w_main = cloth.alpha;
    f.w_prev = 1.0 - cloth.alpha;
    f.proxy_W = f.w_prev * state.body_prev.p_W_m + f.w_main * state.body.p_W_m;
    f.prev_D =
        CouplingForceD(model, state.body_prev.p_W_m, goal,
                       (state.body_prev.p_W_m - state.last_proxy_W_m) * inv_dt, sample.v_D_m_per_s);
  }
  return f;
}

// Two-way coupling for one proxy: its share `weight` of -F_W (F_D = f_D times the clamp factor
// `clamp`) goes to the cloth at its contacts, only what the cloth itself takes before an obstacle
// does (`press`), each share at its triangle (of `tris`) for tick_dt_s [s].
void AddReaction(const ProxyModel& model, const std::vector<Triangle>& tris, const GodObject& body,
                 const ClothPress& press, const Vec3& f_D, double weight, double clamp,
                 double tick_dt_s, ReactionAccumulator* reaction) {
  if (body.num_contacts <= 0 || weight <= 0.0) return;
  Vec3 on_cloth_W = -(model.rotation_WD * (weight * clamp * f_D)) / model.scale;
  if (press.depth_m < press.full_m) on_cloth_W *= press.depth_m / press.full_m;
  std::array<Vec3, kMaxConstraintPlanes> parts;
  SplitOverContacts(body, on_cloth_W, &parts);
  for (int32_t i = 0; i < body.num_contacts; ++i) {
    const ProxyContact& c = body.contacts[i];
    if (IsObstacleContactId(c.triangle)) continue;  // the static obstacle takes its share
    reaction->AddForce(c.triangle, tris[c.triangle], c.barycentric, parts[i], tick_dt_s);
  }
}

// Step 6's reaction: each proxy's share of -F_W to the cloth (mode b: both, by their weights),
// and the tick's time. Returns the main proxy's press on the cloth (for the hand's spring).
ClothPress AddReactions(const ProxyModel& model, const ClothSnapshot& newest, SnapshotMode mode,
                        const Vec3& goal, const TickForces& f, double clamp, double tick_dt_s,
                        ProxyState* state) {
  const std::vector<Triangle>& tris = *newest.triangles;
  const ClothPress press = PressOnCloth(state->body, goal, model.radius_m, model.obstacles);
  AddReaction(model, tris, state->body, press, f.main_D, f.w_main, clamp, tick_dt_s,
              &state->reaction);
  if (mode == SnapshotMode::kBlendForces) {
    AddReaction(model, tris, state->body_prev,
                PressOnCloth(state->body_prev, goal, model.radius_m, model.obstacles), f.prev_D,
                f.w_prev, clamp, tick_dt_s, &state->reaction);
  }
  state->reaction.AddTime(tick_dt_s);
  return press;
}

// The contact of this tick as a spring the sim evaluates at its substep rate (virtual coupling,
// Colgate, Stanley & Brown 1995). The device spring F_D = k (proxy_D - device_D) is, in the
// world, F_W = (k / scale^2) (proxy_W - goal_W) (proxy_spec.h). The sim presses a sphere onto the
// nearest point of the cloth around the contact triangle, re-found at every force evaluation, so
// the force is a potential's gradient however the contact wanders between triangles (tying it to
// this tick's one triangle made a press next to a vertex cycle at 20 Hz; docs/proxy.md).
// Obstacle contacts (negative ids) put nothing on the cloth: the spring is the first cloth one.
void SetHandSpring(const ProxyModel& model, const ClothSnapshot& newest, const Vec3& goal,
                   const Vec3& hand_velocity_W, const ClothPress& press, bool first,
                   ProxyState* state) {
  const int32_t spring_contact = FirstClothContact(state->body);
  const double spring_k_W = model.stiffness_W_N_per_m;
  const double spring_max_W = model.max_force_W_N;
  const double r = model.radius_m;
  if (spring_contact >= 0) {
    const ProxyContact& c = state->body.contacts[spring_contact];
    // The sim's sphere: centred on the proxy, its radius grown by how far the hand presses the
    // cloth itself (PressOnCloth: |proxy - goal| without obstacles; along the contact normal for a
    // frictionless contact), so at rest its penetration is that depth. Both are continuous in time
    // (a sphere at the goal itself, deep behind the cloth in a fast swipe, found its nearest point
    // sideways; one tied to the contact normal moved whenever the contact hopped between
    // triangles).
    const Vec3& proxy_c = state->body.p_W_m;
    const double reach_m = r + press.depth_m;
    state->reaction.SetContactSpring(c.triangle, c.barycentric, c.normal_W,
                                     proxy_c - reach_m * c.normal_W, spring_k_W, spring_max_W,
                                     reach_m, hand_velocity_W);
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
    if (d.norm() < 3.0 * r && d.dot(c.normal_W) >= 0.0) {
      state->reaction.SetContactSpring(c.triangle, c.barycentric, c.normal_W, goal - r * c.normal_W,
                                       spring_k_W, spring_max_W, r, hand_velocity_W);
    } else {
      state->hand_seed.triangle = -1;
      state->reaction.ClearContactSpring();
    }
  } else {
    state->reaction.ClearContactSpring();
  }
}

// The tick's result from its steps (`force` clamped, `f` before the clamp, `bodies` moved).
ProxyTickResult TickResult(const ProxyModel& model, const ProxyState& state,
                           const TickBodies& bodies, const TickForces& f, const ClampedForce& force,
                           const Vec3& goal) {
  ProxyTickResult out;
  out.force_D_N = force.force_D_N;
  out.force_W_N = model.rotation_WD * force.force_D_N / model.scale;
  out.proxy_W_m = f.proxy_W;
  out.goal_W_m = goal;
  out.num_contacts = state.body.num_contacts;
  out.iterations = bodies.main.step.iterations + bodies.other.step.iterations;
  out.clamped = force.clamped;
  out.overflow = bodies.main.overflow || bodies.other.overflow;
  out.caught = bodies.main.caught;
  out.on_newest = bodies.on_newest;
  return out;
}

// Book-keeping for the next tick: the counters and what the next tick's cloth choice and damping
// velocity need.
void RecordTick(const TickCloth& cloth, const TickBodies& bodies, const ProxyTickResult& out,
                ProxyState* state) {
  ProxyCounters& counters = state->counters;
  if (out.clamped) ++counters.clamped_ticks;
  if (out.overflow) ++counters.overflow_ticks;
  if (out.caught) ++counters.catches;
  if (!(bodies.main.step.converged && bodies.other.step.converged)) ++counters.unconverged_ticks;
  if (!(bodies.main.step.feasible && bodies.other.step.feasible)) ++counters.infeasible_ticks;
  state->last_alpha = cloth.alpha;
  state->last_tau_s = cloth.tau_s;
  state->last_on_newest = bodies.on_newest;
  state->last_proxy_W_m = out.proxy_W_m;
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

GodObjectStep UpdateGodObject(const ProxyModel& model, const LocalCloth& cloth,
                              const ClothView& view, const Vec3& goal_W, GodObject* body) {
  GodObjectStep step;
  const Vec3 p_old = body->p_W_m;
  std::array<ProxyContact, kMaxConstraintPlanes> seeds;
  const int32_t num_seeds = SeedContacts(cloth, model.obstacles, *body, model.radius_m, &seeds);
  const std::span<const ProxyContact> seed_span(seeds.data(), num_seeds);

  // Pass 1: the plain god-object update toward the goal.
  Pass pass = RunPass(model, cloth, p_old, seed_span, goal_W);
  TallyPass(pass, &step);
  Pass surface = pass;  // the contacts the force comes from

  // Pass 2, force shading (Ruspini 1997 §5 after Morgenbesser & Srinivasan 1996): the goal
  // projected onto the planes through the proxy with the interpolated normals is the sub-goal of
  // a second update from the same start.
  if (model.force_shading && pass.n > 0) {
    pass = RunPass(model, cloth, p_old, seed_span, ShadedGoal(view, pass, goal_W));
    TallyPass(pass, &step);
    if (pass.n > 0) surface = pass;
  }

  body->slipping =
      ApplyFriction(model, cloth, goal_W, p_old, seed_span, body->slipping, &pass, &surface, &step);
  StoreBody(cloth, pass, surface, body);
  return step;
}

ProxyState MakeProxyState(const ProxyModel& model) { return ProxyState(model.candidate_capacity); }

TickCloth ChooseTickCloth(const ProxyModel& model, const ClothSnapshot& newest,
                          const ClothSnapshot* previous, double since_newest_s, ProxyState* state,
                          const PatchOverlay* patch) {
  TickCloth cloth;
  // Which snapshots this tick has; a previous one of another cloth is ignored.
  const ClothSnapshot* prev = previous;
  if (prev != nullptr && (prev == &newest || prev->x.size() != newest.x.size())) prev = nullptr;
  cloth.prev = prev;
  cloth.mode = prev == nullptr ? SnapshotMode::kNewest : model.snapshot_mode;
  cloth.arrived = !state->have_frame || newest.frame != state->newest_frame;
  cloth.first = !state->have_frame;
  if (cloth.arrived) {
    if (!cloth.first) ++state->counters.new_snapshots;
    state->newest_frame = newest.frame;
    state->have_frame = true;
    // The publisher's own figure when prev is the snapshot just before (the same positions).
    const bool known = prev != nullptr && newest.displacement_from_previous_m >= 0.0 &&
                       prev->frame + 1 == newest.frame;
    state->pair_displacement_m = known             ? newest.displacement_from_previous_m
                                 : prev != nullptr ? MaxDisplacement(*prev, newest)
                                                   : 0.0;
  }
  const double frame_dt = newest.frame_dt_s;
  cloth.alpha = frame_dt > 0.0 ? std::clamp(since_newest_s / frame_dt, 0.0, 1.0) : 1.0;
  cloth.tau_s = std::max(0.0, since_newest_s);
  ViewsForMode(newest, *state, &cloth);
  // Mode patch: the local patch's particles in both cloths (extrapolated elsewhere).
  if (cloth.mode == SnapshotMode::kPatch && patch != nullptr && patch->patch != nullptr) {
    const ClothPatch& p = *patch->patch;
    cloth.now.patch_role = p.roles();
    cloth.now.patch_x = p.x();
    cloth.now.patch = &p;
    cloth.before.patch_role = p.roles();
    cloth.before.patch_x = p.x_before();
    cloth.before.patch = &p;
    cloth.moved = !cloth.first;
    // The gather enlarges its query by both bounds, or takes the windows' triangles at their own
    // positions when that overflows (LocalCloth::Gather).
    cloth.patch_offset_m = patch->offset_m;
  }
  // A previous tick that fell back to its newest snapshot (MoveProxies) left the proxy on that
  // cloth: the one now called prev after an arrival.
  cloth.interpolated = cloth.mode == SnapshotMode::kInterpolate ||
                      cloth.mode == SnapshotMode::kExtrapolate || cloth.mode == SnapshotMode::kPatch;
  if (cloth.interpolated && state->last_on_newest && !cloth.first) {
    cloth.before = cloth.arrived ? ClothView::Of(*prev) : ClothView::Of(newest);
    cloth.moved = true;
    cloth.inflation_m =
        std::max(cloth.inflation_m, cloth.arrived ? state->pair_displacement_m : 0.0);
  }
  return cloth;
}

ClampedForce ClampDeviceForce(const ProxyModel& model, const Vec3& force_D_N) {
  ClampedForce out;
  const double mag = force_D_N.norm();
  if (mag > model.max_force_N) {
    out.factor = model.max_force_N / mag;
    out.clamped = true;
  }
  out.force_D_N = force_D_N * out.factor;
  return out;
}

ProxyTickResult ProxyTick(const ProxyModel& model, const ClothSnapshot& newest,
                          const ClothSnapshot* previous, double since_newest_s,
                          const DeviceSample& sample, double tick_dt_s, ProxyState* state,
                          const PatchOverlay* patch) {
  ++state->counters.ticks;
  const Vec3 goal = model.ToWorld(sample.p_D_m);  // step 1
  const TickCloth cloth = ChooseTickCloth(model, newest, previous, since_newest_s, state, patch);
  const TickBodies bodies = MoveProxies(model, newest, cloth, goal, state);
  const TickForces f = CouplingForces(model, cloth, goal, sample, tick_dt_s, *state);
  const ClampedForce force = ClampDeviceForce(model, f.w_main * f.main_D + f.w_prev * f.prev_D);
  const ClothPress press =
      AddReactions(model, newest, cloth.mode, goal, f, force.factor, tick_dt_s, state);
  // The hand's velocity for the sim's spring (ProxyModel::predict_hand), world.
  const Vec3 hand_v_W = model.predict_hand
                            ? Vec3(model.scale * (model.rotation_WD * sample.v_D_m_per_s))
                            : Vec3::Zero();
  SetHandSpring(model, newest, goal, hand_v_W, press, cloth.first, state);
  const ProxyTickResult out = TickResult(model, *state, bodies, f, force, goal);
  RecordTick(cloth, bodies, out, state);
  return out;
}

}  // namespace felt
