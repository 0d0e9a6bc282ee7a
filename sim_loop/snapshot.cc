#include "sim_loop/snapshot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

namespace felt {
namespace {

// Broken preconditions of the real-time fill are programming errors: abort (shared/STYLE.md).
void CheckOrAbort(bool ok, const char* what) {
  if (!ok) {
    std::fprintf(stderr, "FillSnapshot: %s\n", what);
    std::abort();
  }
}

}  // namespace

ClothSnapshot MakeClothSnapshot(std::shared_ptr<const std::vector<Triangle>> triangles,
                                std::span<const Vec3> x, const CollisionStructureSpec& spec) {
  if (triangles == nullptr) throw std::invalid_argument("MakeClothSnapshot: triangles is null");
  const int64_t n = static_cast<int64_t>(x.size());
  for (const Triangle& t : *triangles) {
    for (int32_t i : t) {
      if (i < 0 || i >= n) {
        throw std::invalid_argument("MakeClothSnapshot: triangle index out of range");
      }
    }
  }
  // The structure is built first so that a throw leaves nothing half made.
  CollisionStructure structure = MakeCollisionStructure(spec, triangles, x);
  ClothSnapshot s{.x = std::vector<Vec3>(x.begin(), x.end()),
                  .v = std::vector<Vec3>(x.size(), Vec3::Zero()),
                  .normals = std::vector<Vec3>(x.size(), Vec3::Zero()),
                  .triangles = triangles,
                  .structure = std::move(structure)};
  ComputeVertexNormals(s.x, *s.triangles, s.normals);
  return s;
}

ClothSnapshot MakeClothSnapshot(const ClothModel& model, const ClothState& state,
                                const CollisionStructureSpec& spec) {
  auto triangles = std::make_shared<const std::vector<Triangle>>(model.triangles);
  ClothSnapshot s = MakeClothSnapshot(std::move(triangles), state.x, spec);
  std::copy(state.v.begin(), state.v.end(), s.v.begin());
  if (state.normals.size() == s.normals.size()) {
    std::copy(state.normals.begin(), state.normals.end(), s.normals.begin());
  }
  s.time_s = state.time_s;
  return s;
}

RepairStats FillSnapshot(std::span<const Vec3> x, std::span<const Vec3> v,
                         std::span<const Vec3> normals, uint64_t frame, double time_s,
                         double frame_dt_s, ClothSnapshot* snapshot) {
  CheckOrAbort(snapshot != nullptr, "snapshot is null");
  const size_t n = snapshot->x.size();
  CheckOrAbort(x.size() == n && v.size() == n && normals.size() == n,
               "array sizes differ from the snapshot's");
  // Copy the arrays (same sizes: no allocation), then the bound on extrapolated motion.
  std::copy(x.begin(), x.end(), snapshot->x.begin());
  std::copy(v.begin(), v.end(), snapshot->v.begin());
  std::copy(normals.begin(), normals.end(), snapshot->normals.begin());
  double max_speed2 = 0.0;
  for (const Vec3& vi : v) max_speed2 = std::max(max_speed2, vi.squaredNorm());
  snapshot->max_speed_m_per_s = std::sqrt(max_speed2);
  snapshot->displacement_from_previous_m = -1.0;
  snapshot->frame = frame;
  snapshot->time_s = time_s;
  snapshot->frame_dt_s = frame_dt_s;
  // The structure must bound exactly these positions (001 §6.3: repaired in the sim thread).
  return Repair(snapshot->structure, snapshot->x);
}

RepairStats FillSnapshot(const ClothModel& model, const ClothState& state, uint64_t frame,
                         double frame_dt_s, ClothSnapshot* snapshot) {
  CheckOrAbort(state.x.size() == static_cast<size_t>(model.num_particles()),
               "state does not belong to the model");
  return FillSnapshot(state.x, state.v, state.normals, frame, state.time_s, frame_dt_s, snapshot);
}

double MaxDisplacement(const ClothSnapshot& a, const ClothSnapshot& b) {
  if (a.x.size() != b.x.size()) return 0.0;
  double m2 = 0.0;
  for (size_t i = 0; i < a.x.size(); ++i) m2 = std::max(m2, (a.x[i] - b.x[i]).squaredNorm());
  return std::sqrt(m2);
}

}  // namespace felt
