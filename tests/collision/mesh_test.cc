#include "collision/mesh.h"

#include <gtest/gtest.h>

namespace felt {
namespace {

TEST(MeshTest, GridTriangleCountsMatchPaperSizes) {
  // 001_0f9f1b7fedff7723.txt Tables 1-2: 162, 722, 1682, 3042, 4802 for 10..50 grids.
  const int32_t sizes[] = {10, 20, 30, 40, 50};
  const size_t expected[] = {162, 722, 1682, 3042, 4802};
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(MakeGridTriangles(sizes[i], sizes[i]).size(), expected[i]);
  }
  EXPECT_EQ(MakeGridTriangles(128, 128).size(), 32258u);
}

TEST(MeshTest, FlatGridNormalsAllFaceOneSide) {
  const int32_t w = 5, h = 4;
  std::vector<Vec3> x;
  for (int32_t r = 0; r < h; ++r)
    for (int32_t c = 0; c < w; ++c) x.emplace_back(0.1 * c, 0.1 * r, 0.0);
  const auto tris = MakeGridTriangles(w, h);
  std::vector<Vec3> n(x.size());
  ComputeVertexNormals(x, tris, n);
  for (const Vec3& v : n) EXPECT_NEAR((v - Vec3(0, 0, 1)).norm(), 0.0, 1e-12);
  // Every index in range and each triangle non-degenerate.
  for (const Triangle& t : tris) {
    for (int32_t i : t) EXPECT_LT(i, w * h);
    EXPECT_GT((x[t[1]] - x[t[0]]).cross(x[t[2]] - x[t[0]]).norm(), 0.0);
  }
}

TEST(MeshTest, DegenerateTrianglesGiveZeroNormalNotNaN) {
  std::vector<Vec3> x(3, Vec3(1, 2, 3));
  std::vector<Triangle> tris = {{0, 1, 2}};
  std::vector<Vec3> n(3);
  ComputeVertexNormals(x, tris, n);
  for (const Vec3& v : n) EXPECT_EQ(v, Vec3::Zero());
}

}  // namespace
}  // namespace felt
