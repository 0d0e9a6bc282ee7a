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
                                             std::span<PointContact> out) const {
  WithinAccumulator acc{p, r, out, {}};
  const std::vector<Triangle>& tris = *triangles_;
  for (size_t i = 0; i < tris.size(); ++i) {
    acc.Test(static_cast<int32_t>(i), x[tris[i][0]], x[tris[i][1]], x[tris[i][2]]);
  }
  return acc.result;
}

SweepHit NaiveCollision::SweepSphere(std::span<const Vec3> x, const Vec3& p0, const Vec3& p1,
                                     double r) const {
  SweepAccumulator acc{p0, p1, r, {}};
  const std::vector<Triangle>& tris = *triangles_;
  for (size_t i = 0; i < tris.size(); ++i) {
    acc.Test(static_cast<int32_t>(i), x[tris[i][0]], x[tris[i][1]], x[tris[i][2]]);
  }
  return acc.best;
}

SweepHit NaiveCollision::SweepSphereMoving(std::span<const Vec3> x_old, std::span<const Vec3> x_new,
                                           const Vec3& c0, const Vec3& c1, double r,
                                           const MovingContactOptions& options) const {
  MovingAccumulator acc{c0, c1, r, options, {}};
  const std::vector<Triangle>& tris = *triangles_;
  for (size_t i = 0; i < tris.size(); ++i) {
    const Triangle& t = tris[i];
    acc.Test(static_cast<int32_t>(i), x_old[t[0]], x_old[t[1]], x_old[t[2]], x_new[t[0]],
             x_new[t[1]], x_new[t[2]]);
  }
  return acc.keep.best;
}

}  // namespace felt
