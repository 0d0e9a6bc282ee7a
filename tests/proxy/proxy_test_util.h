#pragma once
// Meshes and snapshots for the proxy tests: small analytic cloths (flat sheets, creases, a
// corner, a cap draped over a sphere) whose answers are known in closed form.

#include <cmath>
#include <functional>
#include <memory>
#include <vector>

#include "proxy/proxy.h"
#include "sim_loop/snapshot.h"

namespace felt::testing {

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

/// A snapshot of `mesh` with the default structure (bvh-sphere-4) unless `spec` says otherwise.
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

/// One tick against a single static snapshot (mode a), device at p_D.
inline ProxyTickResult TickAt(const DeviceSpec& d, const ProxySpec& p, const ClothSnapshot& s,
                              const Vec3& p_D, ProxyState* state) {
  return ProxyTick(d, p, s, nullptr, 0.0, DeviceSample{p_D, Vec3::Zero()}, 1e-3, state);
}

/// Angle between two vectors [rad] (0 if either is zero).
inline double Angle(const Vec3& a, const Vec3& b) {
  const double na = a.norm();
  const double nb = b.norm();
  if (na == 0.0 || nb == 0.0) return 0.0;
  return std::acos(std::clamp(a.dot(b) / (na * nb), -1.0, 1.0));
}

}  // namespace felt::testing
