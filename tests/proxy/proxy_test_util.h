#pragma once
// Meshes and snapshots for the proxy tests: small analytic cloths (flat sheets, creases, a
// corner, a cap draped over a sphere) whose answers are known in closed form; obstacle specs; and
// a lock-step driver of one proxy against the real cloth.

#include <cmath>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "proxy/proxy.h"
#include "sim_loop/cloth.h"
#include "sim_loop/frame_motion.h"
#include "sim_loop/snapshot.h"

namespace felt::testing {

/// A plane obstacle through `point` [m] with outward `normal` (normalised here).
inline ObstacleSpec Plane(const Vec3& point, const Vec3& normal) {
  ObstacleSpec o;
  o.shape = PlaneSpec{point, normal.normalized()};
  return o;
}
/// A sphere obstacle, centre [m] and radius [m].
inline ObstacleSpec Sphere(const Vec3& c, double R) {
  ObstacleSpec o;
  o.shape = SphereSpec{c, R};
  return o;
}
/// An axis-aligned box obstacle between corners lo and hi [m].
inline ObstacleSpec Box(const Vec3& lo, const Vec3& hi) {
  ObstacleSpec o;
  o.shape = BoxSpec{lo, hi};
  return o;
}
/// A capsule obstacle: segment a-b [m], radius [m].
inline ObstacleSpec Capsule(const Vec3& a, const Vec3& b, double R) {
  ObstacleSpec o;
  o.shape = CapsuleSpec{a, b, R};
  return o;
}
/// The table of scenes/tablecloth.toml: a box with its top at y = 0.
inline ObstacleSpec Table() { return Box(Vec3(-0.3, -0.75, -0.2), Vec3(0.3, 0.0, 0.2)); }

/// A mesh: positions [m] and triangles.
struct TestMesh {
  std::vector<Vec3> x;
  std::vector<Triangle> triangles;
};

/// A w x h grid, particle (i, j) at f(u, v) with u = i / (w - 1), v = j / (h - 1) in [0, 1].
inline TestMesh GridMesh(int32_t w, int32_t h, const std::function<Vec3(double, double)>& f) {
  TestMesh m;
  for (int32_t j = 0; j < h; ++j) {
    for (int32_t i = 0; i < w; ++i) m.x.push_back(f(double(i) / (w - 1), double(j) / (h - 1)));
  }
  m.triangles = MakeGridTriangles(w, h);
  return m;
}

/// Appends mesh b to a (indices shifted).
inline void Append(TestMesh* a, const TestMesh& b) {
  const int32_t off = static_cast<int32_t>(a->x.size());
  a->x.insert(a->x.end(), b.x.begin(), b.x.end());
  for (Triangle t : b.triangles) a->triangles.push_back({t[0] + off, t[1] + off, t[2] + off});
}

/// A flat square sheet in the plane z = z0, side `side` m centred on the z axis, n x n particles.
inline TestMesh FlatSheet(double side = 0.2, int32_t n = 11, double z0 = 0.0) {
  return GridMesh(n, n,
                  [&](double u, double v) { return Vec3((u - 0.5) * side, (v - 0.5) * side, z0); });
}

/// A snapshot of `mesh` with the default structure (bvh-aabb-4) unless `spec` says otherwise.
inline ClothSnapshot Snap(const TestMesh& mesh, const CollisionStructureSpec& spec = {}) {
  return MakeClothSnapshot(std::make_shared<const std::vector<Triangle>>(mesh.triangles), mesh.x,
                           spec);
}

/// Refills `s` with positions x (velocities v, normals recomputed), as frame `frame`.
inline void Refill(const std::vector<Vec3>& x, const std::vector<Vec3>& v, uint64_t frame,
                   double time_s, double dt_s, ClothSnapshot* s) {
  std::vector<Vec3> normals(x.size());
  ComputeVertexNormals(x, *s->triangles, normals);
  FillSnapshot(x, v, normals, frame, time_s, dt_s, s);
}

/// A device with the identity workspace map (world = device) and the given radius.
inline DeviceSpec UnitDevice(double radius_m = 0.004) {
  DeviceSpec d;
  d.scale = 1.0;
  d.radius_m = radius_m;
  d.max_force_N = 1e9;
  return d;
}

/// A proxy spec in mode `mode`, shading as given, otherwise defaults.
inline ProxySpec Spec(SnapshotMode mode = SnapshotMode::kNewest, bool shading = false) {
  ProxySpec p;
  p.snapshot_mode = mode;
  p.force_shading = shading;
  return p;
}

/// One tick of `model` against a single static snapshot (mode a), device at p_D [m, device].
inline ProxyTickResult TickAt(const ProxyModel& model, const ClothSnapshot& s, const Vec3& p_D,
                              ProxyState* state) {
  return ProxyTick(model, s, nullptr, 0.0, DeviceSample{p_D, Vec3::Zero()}, 1e-3, state);
}

/// Angle between two vectors [rad] (0 if either is zero).
inline double Angle(const Vec3& a, const Vec3& b) {
  const double na = a.norm();
  const double nb = b.norm();
  if (na == 0.0 || nb == 0.0) return 0.0;
  return std::acos(std::clamp(a.dot(b) / (na * nb), -1.0, 1.0));
}

/// Drives one proxy against the real cloth in lock-step virtual time, as the server does: each
/// 60 Hz frame first runs `on_frame(t)`, then steps the cloth with the reaction the proxy drained
/// (the contact spring while in contact), then publishes a snapshot whose velocities are the
/// frame's motion (sim_loop/frame_motion.h); then the frame's 1 kHz ticks run until `seconds` [s]:
/// `sample(t)` gives the device sample at tick time t [s], `on_tick(t, since_s, result, prev,
/// next)` sees each tick (since_s: time since the newest snapshot, s). Allocates (test code).
template <typename Sample, typename OnTick, typename OnFrame>
void RunLockstep(const ClothModel& model, ClothState* state, const DeviceSpec& device,
                 const ProxySpec& proxy, ProxyState* ps, double seconds, Sample&& sample,
                 OnTick&& on_tick, OnFrame&& on_frame) {
  const double frame_dt = 1.0 / 60.0;
  const ProxyModel proxy_model = CompileProxyModel(device, proxy);
  ClothSnapshot prev = MakeClothSnapshot(model, *state, proxy.structure);
  ClothSnapshot next = MakeClothSnapshot(model, *state, proxy.structure);
  std::vector<ExternalForce> external(512);
  std::vector<Vec3> frame_start_x(state->x.size());
  std::vector<Vec3> frame_v(state->x.size());
  uint64_t frame = 1;
  int64_t tick = 0;
  double t = 0.0;
  while (t < seconds) {
    on_frame(t);
    const int32_t n = ps->reaction.DrainInto(external);
    frame_start_x = state->x;
    StepFrame(model, std::span<const ExternalForce>(external.data(), n), frame_dt, state);
    std::swap(prev, next);
    FillSnapshotWithFrameMotion(*state, frame_start_x, frame_dt, frame++, frame_v, &next);
    const double frame_end = t + frame_dt;
    double since = 0.0;
    while (t < frame_end - 1e-9) {
      const ProxyTickResult r = ProxyTick(proxy_model, next, &prev, since, sample(t), 1e-3, ps);
      on_tick(t, since, r, prev, next);
      t = static_cast<double>(++tick) * 1e-3;
      since += 1e-3;
    }
  }
}

/// A 0.2 m sheet (x, z in [-0.1, 0.1]) with the springs of scenes/tablecloth.toml, dropped from
/// 1 cm onto that scene's table (top y = 0, x in [-0.3, 0.3]; friction 0.5, margin 2 mm): the
/// table is bare beyond x = 0.1.
inline constexpr const char* kSheetOnTable = R"(
[cloth]
width = 21
height = 21
spacing_m = 0.01
mass_kg = 0.008
origin_m = [-0.1, 0.01, -0.1]
u_axis = [1.0, 0.0, 0.0]
v_axis = [0.0, 0.0, 1.0]
drag_N_s_per_m = 4e-5

[cloth.structural]
stiffness_N_per_m = 1.0
damping_N_s_per_m = 0.0002

[cloth.shear]
stiffness_N_per_m = 0.5
damping_N_s_per_m = 0.0001

[cloth.bend]
stiffness_N_per_m = 0.1
damping_N_s_per_m = 2e-05

[[obstacles]]
type = "box"
min_m = [-0.3, -0.75, -0.2]
max_m = [0.3, 0.0, 0.2]
friction = 0.5
margin_m = 0.002
)";

/// The same sheet without springs, held together by Provot's constraints alone (the sheet of
/// ObstacleProxyTest's pinch runs).
inline std::string SpringlessSheet() {
  const std::string text = kSheetOnTable;
  return text.substr(0, text.find("[cloth.structural]")) + text.substr(text.find("[[obstacles]]"));
}

}  // namespace felt::testing
