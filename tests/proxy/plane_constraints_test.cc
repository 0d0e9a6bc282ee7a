#include "proxy/plane_constraints.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace felt {
namespace {

ConstraintPlane Plane(const Vec3& n, double offset, int id = -1) {
  return ConstraintPlane{n.normalized(), offset, id};
}

TEST(PlaneConstraintsTest, FreeGoalIsItsOwnSolution) {
  const ConstraintPlane planes[] = {Plane(Vec3::UnitZ(), 0.0)};
  const PlaneSolveResult r = SolveClosestFeasible(Vec3(0.1, 0.2, 0.3), planes);
  EXPECT_TRUE(r.feasible);
  EXPECT_EQ(r.active_mask, 0);
  EXPECT_EQ(r.point, Vec3(0.1, 0.2, 0.3));
}

TEST(PlaneConstraintsTest, OnePlaneProjectsAlongItsNormal) {
  const ConstraintPlane planes[] = {Plane(Vec3::UnitZ(), 0.01)};
  const PlaneSolveResult r = SolveClosestFeasible(Vec3(0.1, 0.2, -0.05), planes);
  EXPECT_TRUE(r.feasible);
  EXPECT_EQ(r.active_mask, 1);
  EXPECT_NEAR((r.point - Vec3(0.1, 0.2, 0.01)).norm(), 0.0, 1e-15);
}

TEST(PlaneConstraintsTest, TwoPlanesCreaseGivesTheEdgePoint) {
  // A 90-degree crease along the x axis: free side is y >= 0 and z >= 0.
  const ConstraintPlane planes[] = {Plane(Vec3::UnitY(), 0.0), Plane(Vec3::UnitZ(), 0.0)};
  const PlaneSolveResult r = SolveClosestFeasible(Vec3(0.3, -0.1, -0.2), planes);
  EXPECT_TRUE(r.feasible);
  EXPECT_EQ(r.active_mask, 3);
  EXPECT_NEAR((r.point - Vec3(0.3, 0, 0)).norm(), 0.0, 1e-15);
  // Goal on the free side of one plane: only the other stays active.
  const PlaneSolveResult r2 = SolveClosestFeasible(Vec3(0.3, 0.1, -0.2), planes);
  EXPECT_EQ(r2.active_mask, 2);
  EXPECT_NEAR((r2.point - Vec3(0.3, 0.1, 0)).norm(), 0.0, 1e-15);
}

TEST(PlaneConstraintsTest, ThreePlanesCornerGivesTheVertex) {
  const ConstraintPlane planes[] = {Plane(Vec3::UnitX(), 0.1), Plane(Vec3::UnitY(), 0.2),
                                    Plane(Vec3::UnitZ(), 0.3)};
  const PlaneSolveResult r = SolveClosestFeasible(Vec3(-1, -1, -1), planes);
  EXPECT_EQ(r.active_mask, 7);
  EXPECT_NEAR((r.point - Vec3(0.1, 0.2, 0.3)).norm(), 0.0, 1e-15);
}

TEST(PlaneConstraintsTest, OpposedParallelPlanesWithNoGapAreInfeasible) {
  // The cloth pinched from both sides with no room between: nothing is feasible.
  const ConstraintPlane planes[] = {Plane(Vec3::UnitZ(), 0.01), Plane(-Vec3::UnitZ(), 0.0)};
  const PlaneSolveResult r = SolveClosestFeasible(Vec3(0, 0, 0.5), planes);
  EXPECT_FALSE(r.feasible);
}

TEST(PlaneConstraintsTest, MatchesBruteForceOnRandomProblems) {
  // Reference: the optimum of a convex QP is feasible and no feasible point sampled nearby is
  // closer to the goal; also the KKT conditions hold for the reported active set.
  std::mt19937 rng(1234);
  std::normal_distribution<double> g(0.0, 1.0);
  int checked = 0;
  for (int trial = 0; trial < 5000; ++trial) {
    const int k = 1 + trial % 3;
    std::vector<ConstraintPlane> planes;
    for (int i = 0; i < k; ++i) planes.push_back(Plane(Vec3(g(rng), g(rng), g(rng)), 0.1 * g(rng)));
    const Vec3 goal(g(rng), g(rng), g(rng));
    const PlaneSolveResult r = SolveClosestFeasible(goal, planes);
    if (!r.feasible) continue;  // random opposing planes can be infeasible only when k >= 2
    ++checked;
    for (const ConstraintPlane& p : planes) EXPECT_GE(p.Distance(r.point), -1e-9);
    // Local optimality: small feasible perturbations never get closer to the goal.
    const double d = (r.point - goal).norm();
    for (int s = 0; s < 20; ++s) {
      const Vec3 q = r.point + 1e-3 * Vec3(g(rng), g(rng), g(rng));
      bool ok = true;
      for (const ConstraintPlane& p : planes) ok = ok && p.Distance(q) >= 0.0;
      if (ok) {
        EXPECT_GE((q - goal).norm(), d - 1e-12);
      }
    }
  }
  EXPECT_GT(checked, 4000);
}

}  // namespace
}  // namespace felt
