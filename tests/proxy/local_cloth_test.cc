// The gather of proxy/local_cloth.h in mode patch against a brute-force reference: every triangle
// within the radius of the query point, now or before (exact point-triangle distance), is
// gathered, once, with the patch centimetres from the snapshot: by the query enlarged by the
// patch's offset, and, when that overflows, with the windows' triangles taken at their own
// positions.
#include "proxy/local_cloth.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <utility>
#include <vector>

#include "collision/geometry.h"
#include "sim_loop/cloth_patch.h"
#include "tests/sim_loop/cloth_test_util.h"

namespace felt {
namespace {

int32_t At(const ClothModel& m, int32_t col, int32_t row) { return row * m.width + col; }

// A hand 3 cm behind particle `centre` of a resting sheet pressing from +z (sphere 4 mm).
ExternalForce PressBehind(const ClothModel& model, int32_t centre) {
  ExternalForce e;
  for (size_t t = 0; t < model.triangles.size(); ++t) {
    if (model.triangles[t][0] == centre) e.triangle = static_cast<int32_t>(t);
  }
  e.stiffness_N_per_m = 44.0;
  e.normal = Vec3::UnitZ();
  e.radius_m = 0.004;
  e.anchor_m = model.rest_position_m[centre] - Vec3(0, 0, 0.03) - e.radius_m * e.normal;
  e.max_force_N = 3.0;
  return e;
}

// Triangles within radius_m of c in `now` or `before` (exact distance), by testing every one.
std::set<int32_t> Reference(const ClothModel& model, const ClothView& now, const ClothView& before,
                            const Vec3& c, double radius_m) {
  std::set<int32_t> out;
  for (int32_t t = 0; t < static_cast<int32_t>(model.triangles.size()); ++t) {
    for (const ClothView* view : {&now, &before}) {
      Vec3 a, b, cc;
      view->Corners(t, &a, &b, &cc);
      if (ClosestPointOnTriangle(c, a, b, cc).distance_sq <= radius_m * radius_m) out.insert(t);
    }
  }
  return out;
}

TEST(LocalClothTest, PatchGatherHoldsEveryTriangleWithinTheRadiusOnce) {
  SimSpec spec = cloth_test::Curtain(25);
  spec.cloth.gravity_m_per_s2 = Vec3::Zero();
  const ClothModel model = BuildClothModel(spec);
  const ClothSnapshot s = MakeClothSnapshot(model, MakeClothState(model), CollisionStructureSpec{});
  // Two windows: one inside the sheet, one clipped by its left edge; both pressed 3 cm back.
  ClothPatch patch(model, 4, 2);
  const std::vector<int32_t> centres = {At(model, 14, 12), At(model, 2, 5)};
  patch.Place(centres, s, 0.0, 1e-3);
  ASSERT_EQ(patch.windows().size(), 2u);
  const std::vector<ExternalForce> springs = {PressBehind(model, centres[0]),
                                              PressBehind(model, centres[1])};
  for (int k = 0; k < 60; ++k) patch.Step(springs, 1e-3, s, 0.0);
  ASSERT_GT(patch.DistanceFromDrive(), 0.01);  // the patch is well away from the snapshot

  ClothView now = ClothView::Of(s);
  now.patch_role = patch.roles();
  now.patch_x = patch.x();
  now.patch = &patch;
  ClothView before = now;
  before.patch_x = patch.x_before();
  // Enlarged by the patch's true offset (room for all: the plain path), and by 1 m, which finds
  // the whole cloth (1152 triangles) and overflows 1000, so the windows are gathered directly.
  LocalCloth roomy(4096), tight(1000);
  int32_t checked = 0;
  for (const int32_t centre : {centres[0], centres[1], At(model, 20, 20), At(model, 9, 12)}) {
    for (const double radius : {0.002, 0.01, 0.03, 0.08}) {
      // Query points at the patch's pushed cloth, at the snapshot's, and between.
      for (const double w : {0.0, 0.5, 1.0}) {
        const Vec3 c = w * patch.x()[centre] + (1.0 - w) * s.x[centre] + Vec3(0.001, 0.002, 0.0);
        const std::set<int32_t> want = Reference(model, now, before, c, radius);
        for (const auto& [local, offset] :
             {std::pair{&roomy, patch.DistanceFromDrive()}, std::pair{&tight, 1.0}}) {
          ASSERT_TRUE(local->Gather(s, 0.0, now, &before, c, radius, offset));
          std::set<int32_t> got;
          for (const LocalTriangle& t : local->triangles()) {
            EXPECT_TRUE(got.insert(t.triangle).second) << "triangle " << t.triangle << " twice";
            Vec3 a, b, cc;
            now.Corners(t.triangle, &a, &b, &cc);
            EXPECT_EQ(t.a, a);
            EXPECT_EQ(t.c, cc);
          }
          for (const int32_t t : want) {
            EXPECT_TRUE(got.count(t))
                << "missed triangle " << t << " radius " << radius << " offset " << offset;
          }
          if (local == &tight) {
            EXPECT_LT(got.size(), 1000u);
          }
        }
        checked += static_cast<int32_t>(want.size());
      }
    }
  }
  EXPECT_GT(checked, 1000);
}

TEST(LocalClothTest, PatchGatherThatDoesNotFitFallsBack) {
  SimSpec spec = cloth_test::Curtain(25);
  spec.cloth.gravity_m_per_s2 = Vec3::Zero();
  const ClothModel model = BuildClothModel(spec);
  const ClothSnapshot s = MakeClothSnapshot(model, MakeClothState(model), CollisionStructureSpec{});
  ClothPatch patch(model, 6, 1);
  const std::vector<int32_t> centres = {At(model, 12, 12)};
  patch.Place(centres, s, 0.0, 1e-3);
  patch.Step({}, 1e-3, s, 0.0);
  ClothView now = ClothView::Of(s);
  now.patch_role = patch.roles();
  now.patch_x = patch.x();
  now.patch = &patch;
  LocalCloth local(16);
  EXPECT_FALSE(local.Gather(s, 0.0, now, nullptr, s.x[centres[0]], 0.05, 0.01));
  EXPECT_TRUE(local.fallback());
  EXPECT_LE(local.triangles().size(), 16u);
}

}  // namespace
}  // namespace felt
