#include "collision/collision_structure.h"

#include <array>
#include <cmath>

namespace felt {

CollisionStructure MakeCollisionStructure(const CollisionStructureSpec& spec,
                                          std::shared_ptr<const std::vector<Triangle>> triangles,
                                          std::span<const Vec3> x) {
  switch (spec.kind) {
    case CollisionStructureSpec::Kind::kNaive:
      return NaiveCollision(std::move(triangles));
    case CollisionStructureSpec::Kind::kSpatialHash:
      return SpatialHash(std::move(triangles), x, spec.hash);
    case CollisionStructureSpec::Kind::kBvh:
      break;
  }
  return Bvh(std::move(triangles), x, spec.bvh);
}

std::string CollisionStructureName(const CollisionStructureSpec& spec) {
  switch (spec.kind) {
    case CollisionStructureSpec::Kind::kNaive:
      return "naive";
    case CollisionStructureSpec::Kind::kSpatialHash:
      return "osh";
    case CollisionStructureSpec::Kind::kBvh:
      break;
  }
  const BvhOptions& o = spec.bvh;
  std::string name = "bvh-";
  name += o.volume == BoundingVolume::kSphere ? "sphere-" : "aabb-";
  name += std::to_string(o.arity);
  // Each repair's suffix, indexed by BvhRepair (the enum's order).
  constexpr std::array<const char*, 4> kRepairSuffix = {"-bottomup", "-topdown", "-rebuild",
                                                        "-queue"};
  static_assert(static_cast<size_t>(BvhRepair::kBottomUpQueue) == 3, "kRepairSuffix's order");
  name += kRepairSuffix[static_cast<size_t>(o.repair)];
  if (o.inflation_m > 0.0) {
    name += "-d" + std::to_string(static_cast<int>(std::lround(o.inflation_m * 1e3))) + "mm";
  }
  return name;
}

}  // namespace felt
