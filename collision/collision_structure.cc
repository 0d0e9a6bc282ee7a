#include "collision/collision_structure.h"

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
  switch (o.repair) {
    case BvhRepair::kBottomUp:
      name += "-bottomup";
      break;
    case BvhRepair::kTopDown:
      name += "-topdown";
      break;
    case BvhRepair::kRebuild:
      name += "-rebuild";
      break;
    case BvhRepair::kBottomUpQueue:
      name += "-queue";
      break;
  }
  if (o.inflation_m > 0.0) {
    name += "-d" + std::to_string(static_cast<int>(std::lround(o.inflation_m * 1e3))) + "mm";
  }
  return name;
}

}  // namespace felt
