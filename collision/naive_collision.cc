#include "collision/naive_collision.h"

#include <stdexcept>
#include <string>

namespace felt {

NaiveCollision::NaiveCollision(std::shared_ptr<const std::vector<Triangle>> triangles)
    : triangles_(std::move(triangles)) {
  if (!triangles_) throw std::invalid_argument("NaiveCollision: triangles must not be null");
  for (size_t i = 0; i < triangles_->size(); ++i) {
    for (int32_t v : (*triangles_)[i]) {
      if (v < 0) {
        throw std::invalid_argument("NaiveCollision: triangle " + std::to_string(i) +
                                    " has a negative vertex index");
      }
    }
  }
}

WithinResult NaiveCollision::TrianglesWithin(std::span<const Vec3> x, const Vec3& p, double r,
                                             std::span<PointContact> out, bool ids_only) const {
  WithinAccumulator acc{p, r, out, {}, ids_only};
  const std::vector<Triangle>& tris = *triangles_;
  TestEveryTriangle(tris.size(), [&](int32_t tri) { acc.Test(tri, tris[tri], x); });
  return acc.result;
}

SweepHit NaiveCollision::SweepSphere(std::span<const Vec3> x, const Vec3& p0, const Vec3& p1,
                                     double r) const {
  SweepAccumulator acc{p0, p1, r, {}};
  const std::vector<Triangle>& tris = *triangles_;
  TestEveryTriangle(tris.size(), [&](int32_t tri) { acc.Test(tri, tris[tri], x); });
  return acc.best;
}

SweepHit NaiveCollision::SweepSphereMoving(std::span<const Vec3> x_old, std::span<const Vec3> x_new,
                                           const Vec3& c0, const Vec3& c1, double r,
                                           const MovingContactOptions& options) const {
  return SweepMovingOver(*triangles_, x_old, x_new, c0, c1, r, options, /*culls=*/false,
                         [](const auto&, const MovingAccumulator&) {});
}

}  // namespace felt
