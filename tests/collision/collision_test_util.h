#pragma once
// Test cloths and query generators for the collision tests: flat, draped, crumpled, folded and
// degenerate sheets, and random queries biased toward the hard cases (grazing vertices and
// edges, points on the surface, very fast segments).

#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "collision/collision_structure.h"
#include "collision/mesh.h"

namespace felt::testing {

/// A test cloth: positions and a shared triangle list.
struct TestCloth {
  std::string name;
  std::vector<Vec3> x;
  std::shared_ptr<const std::vector<Triangle>> triangles;
};

/// A width x height grid over [0, 1] x [0, 1] at z = 0.
inline std::vector<Vec3> FlatGrid(int32_t w, int32_t h) {
  std::vector<Vec3> x;
  for (int32_t r = 0; r < h; ++r)
    for (int32_t c = 0; c < w; ++c) x.emplace_back(c / (w - 1.0), r / (h - 1.0), 0.0);
  return x;
}

/// A width x height grid with spacing `step` [m] in the plane z = 0 (row-major, from the origin).
inline std::vector<Vec3> SpacedGrid(int32_t w, int32_t h, double step) {
  std::vector<Vec3> x;
  for (int32_t r = 0; r < h; ++r)
    for (int32_t c = 0; c < w; ++c) x.emplace_back(c * step, r * step, 0.0);
  return x;
}

/// A w x w SpacedGrid whose columns beyond `hinge` are turned by `angle` [rad] about the line
/// x = hinge * step (angle = pi lays them flat on top of the others).
inline std::vector<Vec3> HingedGrid(int32_t w, int32_t hinge, double step, double angle) {
  std::vector<Vec3> x = SpacedGrid(w, w, step);
  const double x_hinge = hinge * step;
  for (Vec3& p : x) {
    const double d = p.x() - x_hinge;
    if (d > 0.0) p = Vec3(x_hinge + d * std::cos(angle), p.y(), d * std::sin(angle));
  }
  return x;
}

/// A U-fold falling through itself: on a w x w SpacedGrid, the columns past `hinge` lie mirrored
/// over the others at height `gap` [m] (x0) and fall by `fall` [m] through them by x1, each end
/// shifted in-plane by 0.1 step N(0, 1) draws from `rng` (slightly crumpled).
inline void FallingUFold(int32_t w, int32_t hinge, double step, double gap, double fall,
                         std::mt19937_64& rng, std::vector<Vec3>* x0, std::vector<Vec3>* x1) {
  std::normal_distribution<double> n01(0.0, 1.0);
  *x0 = SpacedGrid(w, w, step);
  *x1 = *x0;
  for (size_t i = 0; i < x0->size(); ++i) {
    const int32_t col = static_cast<int32_t>(i) % w;
    if (col <= hinge) continue;
    (*x0)[i].x() = (2 * hinge - col) * step + 0.3 * step;
    (*x0)[i].z() = gap;
    (*x1)[i] = (*x0)[i] + Vec3(0.0, 0.0, -fall) + 0.1 * step * Vec3(n01(rng), n01(rng), 0.0);
  }
}

/// The five test cloths on a w x w grid (w odd so the fold lies on a vertex row).
inline std::vector<TestCloth> MakeTestCloths(int32_t w, uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<TestCloth> out;
  const auto tris = std::make_shared<const std::vector<Triangle>>(MakeGridTriangles(w, w));
  const std::vector<Vec3> flat = FlatGrid(w, w);
  out.push_back({"flat", flat, tris});
  // Draped over a sphere of radius 0.3 at (0.5, 0.5, 0): on the cap where it rests, then
  // hanging along a catenary-like falloff.
  {
    std::vector<Vec3> x = flat;
    for (Vec3& p : x) {
      const double rho = std::hypot(p.x() - 0.5, p.y() - 0.5);
      const double z = rho < 0.25 ? std::sqrt(0.09 - rho * rho)
                                  : std::sqrt(0.09 - 0.0625) - 0.8 * (std::cosh(rho - 0.25) - 1.0) -
                                        0.6 * (rho - 0.25);
      p.z() = z;
    }
    out.push_back({"draped", x, tris});
  }
  // Crumpled: random noise of about an edge length on every coordinate.
  {
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const double h = 1.0 / (w - 1);
    std::vector<Vec3> x = flat;
    for (Vec3& p : x) p += Vec3(u(rng), u(rng), 2 * u(rng)) * 0.6 * h;
    out.push_back({"crumpled", x, tris});
  }
  // Folded onto itself about x = 0.5 with a 2 mm gap between the layers.
  {
    std::vector<Vec3> x = flat;
    for (Vec3& p : x) {
      if (p.x() > 0.5) p = Vec3(1.0 - p.x(), p.y(), 0.002);
    }
    out.push_back({"folded", x, tris});
  }
  // Degenerate: a flat sheet with collapsed vertices (zero-area and needle triangles) plus
  // triangles with repeated indices.
  {
    std::vector<Vec3> x = flat;
    for (int32_t r = 1; r + 1 < w; r += 3) {
      x[GridIndex(w, 2, r)] = x[GridIndex(w, 3, r)];  // repeated point
      x[GridIndex(w, 5, r)] = 0.5 * (x[GridIndex(w, 4, r)] + x[GridIndex(w, 6, r)]);  // collinear
    }
    std::vector<Triangle> t = *tris;
    t.push_back({0, 0, 1});
    t.push_back({w + 1, w + 1, w + 1});
    t.push_back({2, 2 * w + 2, 2});
    out.push_back({"degenerate", x, std::make_shared<const std::vector<Triangle>>(t)});
  }
  return out;
}

/// Every structure configuration the tests cover: the naive reference first, then the spatial
/// hash and sphere/AABB x arity 2/4 x bottom-up/top-down/rebuild x exact/inflated BVHs.
inline std::vector<CollisionStructureSpec> AllSpecs(double inflation_m) {
  std::vector<CollisionStructureSpec> specs;
  specs.push_back({CollisionStructureSpec::Kind::kNaive, {}, {}});
  specs.push_back({CollisionStructureSpec::Kind::kSpatialHash, {}, {}});
  for (BoundingVolume v : {BoundingVolume::kSphere, BoundingVolume::kAabb})
    for (int32_t arity : {2, 4})
      for (BvhRepair m : {BvhRepair::kBottomUp, BvhRepair::kBottomUpQueue, BvhRepair::kTopDown,
                          BvhRepair::kRebuild})
        for (double d : {0.0, inflation_m})
          specs.push_back({CollisionStructureSpec::Kind::kBvh, {v, arity, m, d}, {}});
  return specs;
}

/// A random point near the cloth, biased to the hard cases: on a triangle, at distance exactly r
/// from a vertex or from an edge, near the surface, or anywhere in a box around the cloth.
inline Vec3 RandomQueryPoint(const TestCloth& c, double r, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  const auto& tris = *c.triangles;
  const Triangle& t = tris[std::uniform_int_distribution<size_t>(0, tris.size() - 1)(rng)];
  const Vec3 &a = c.x[t[0]], &b = c.x[t[1]], &cc = c.x[t[2]];
  const Vec3 dir = Vec3(g(rng), g(rng), g(rng)).normalized();
  double s = u(rng), w = u(rng);
  if (s + w > 1) s = 1 - s, w = 1 - w;
  const Vec3 on = a + s * (b - a) + w * (cc - a);
  switch (std::uniform_int_distribution<int>(0, 4)(rng)) {
    case 0:
      return on;  // exactly on the surface (up to rounding)
    case 1:
      return a + r * dir;  // grazing a vertex
    case 2:
      return a + u(rng) * (b - a) + r * dir;  // grazing an edge (when dir is perpendicular)
    case 3:
      return on + (2 * u(rng) - 1) * 2 * r * dir;  // near the surface
    default:
      return Vec3(u(rng) * 1.4 - 0.2, u(rng) * 1.4 - 0.2, u(rng) * 0.8 - 0.4);
  }
}

}  // namespace felt::testing
