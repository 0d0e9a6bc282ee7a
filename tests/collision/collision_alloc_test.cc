// Queries and repairs of every collision structure allocate nothing (real-time safe).
#include <gtest/gtest.h>

#include "collision/collision_structure.h"
#include "tests/alloc_counter.h"
#include "tests/collision/collision_test_util.h"

namespace felt {
namespace {

using testing::AllSpecs;
using testing::MakeTestCloths;

TEST(CollisionAllocTest, GuardCountsAllocations) {
  // The guard itself works (so a zero below means something).
  AllocationGuard guard;
  auto* p = new std::vector<int>(10);
  EXPECT_GE(guard.allocations(), 2u);
  delete p;
}

TEST(CollisionAllocTest, RepairsQueriesAndSnapshotCopiesAllocateNothing) {
  const auto cloths = MakeTestCloths(15, 3);
  const auto& flat = cloths[0];
  const auto& draped = cloths[1];
  std::vector<PointContact> buf(64);
  for (const CollisionStructureSpec& spec : AllSpecs(0.004)) {
    CollisionStructure s = MakeCollisionStructure(spec, flat.triangles, flat.x);
    CollisionStructure snapshot = s;  // the haptic side's copy, sized once
    AllocationGuard guard;
    Repair(s, draped.x);
    Repair(s, flat.x);
    RepairSwept(s, flat.x, draped.x);
    int64_t found = 0;
    for (int i = 0; i < 50; ++i) {
      const Vec3 p(0.02 * i, 0.5, 0.3 - 0.01 * i);
      found += TrianglesWithin(s, draped.x, p, 0.05, buf).found;
      found += SweepSphere(s, draped.x, p, p + Vec3(0.01, 0.0, -10.0), 0.005).hit ? 1 : 0;
      found += SweepSphereMoving(s, flat.x, draped.x, p, p, 0.005).hit ? 1 : 0;
    }
    snapshot = s;  // publishing: a copy into an existing structure of the same kind and size
    EXPECT_EQ(guard.allocations(), 0u) << CollisionStructureName(spec);
    EXPECT_GT(found, 0);
  }
}

}  // namespace
}  // namespace felt
