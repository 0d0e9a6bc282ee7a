#pragma once
// Mesh basics shared by the cloth (sim_loop), the collision structures and the proxy.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace felt {

/// A 3-vector of doubles: a position [m] or a vector in the units its name gives.
using Vec3 = Eigen::Vector3d;

/// A triangle as three particle indices, counter-clockwise seen from the side its normal faces.
using Triangle = std::array<int32_t, 3>;

/// Index of the particle at column `col`, row `row` of a grid `width` particles wide.
constexpr int32_t GridIndex(int32_t width, int32_t col, int32_t row) { return row * width + col; }

/// The triangles of a `width` x `height` particle grid (width, height >= 2), two per cell split
/// along the cell's (col,row)-(col+1,row+1) diagonal, cells in row-major order: 2 (W-1)(H-1)
/// triangles (001_0f9f1b7fedff7723.txt §6.3: a 50 x 50 grid has 4802).
std::vector<Triangle> MakeGridTriangles(int32_t width, int32_t height);

/// Area-weighted vertex normals: each triangle adds its unnormalised normal (cross product, whose
/// length is twice its area) to its three vertices, then each sum is normalised. A vertex whose
/// triangles are all degenerate gets the zero vector. `normals` must have x.size() entries.
/// Real-time safe (no allocation).
void ComputeVertexNormals(std::span<const Vec3> x, std::span<const Triangle> triangles,
                          std::span<Vec3> normals);

}  // namespace felt
