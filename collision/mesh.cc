#include "collision/mesh.h"

#include "base/check.h"

namespace felt {

std::vector<Triangle> MakeGridTriangles(int32_t width, int32_t height) {
  FELT_CHECK(width >= 2 && height >= 2);
  std::vector<Triangle> triangles;
  triangles.reserve(static_cast<size_t>(2 * (width - 1) * (height - 1)));
  for (int32_t row = 0; row + 1 < height; ++row) {
    for (int32_t col = 0; col + 1 < width; ++col) {
      const int32_t a = GridIndex(width, col, row);
      const int32_t b = GridIndex(width, col + 1, row);
      const int32_t c = GridIndex(width, col + 1, row + 1);
      const int32_t d = GridIndex(width, col, row + 1);
      // Both triangles wind the same way, so every normal faces the same side of a flat grid.
      triangles.push_back({a, b, c});
      triangles.push_back({a, c, d});
    }
  }
  return triangles;
}

void ComputeVertexNormals(std::span<const Vec3> x, std::span<const Triangle> triangles,
                          std::span<Vec3> normals) {
  FELT_CHECK(normals.size() == x.size());
  for (Vec3& n : normals) n.setZero();
  // Sum the area-weighted face normals (|cross| = 2 area) into each vertex.
  for (const Triangle& t : triangles) {
    const Vec3 face = (x[t[1]] - x[t[0]]).cross(x[t[2]] - x[t[0]]);
    normals[t[0]] += face;
    normals[t[1]] += face;
    normals[t[2]] += face;
  }
  for (Vec3& n : normals) {
    const double len = n.norm();
    if (len > 0.0) n /= len;
  }
}

}  // namespace felt
