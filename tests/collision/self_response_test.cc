// The self-collision response (collision/self_response.h) on small meshes: two sheets driven
// through each other, with and without pins; momentum conservation of the impulses; the fail-safe
// alone resolves what the impulses are not given the rounds to; no allocation in Resolve.

#include "collision/self_response.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <string>
#include <vector>

#include "collision/ccd_all_pairs.h"
#include "collision/self_intersection.h"
#include "tests/alloc_counter.h"

namespace felt {
namespace {

// Two horizontal w x w sheets of side 0.1 m, the lower at y = 0, the upper at y = gap_m (offset
// by a third of a cell in x and z so vertices do not sit over vertices); triangles of both.
struct TwoSheets {
  std::vector<Vec3> x;
  std::vector<Triangle> triangles;
};

TwoSheets MakeTwoSheets(int32_t w, double gap_m) {
  TwoSheets s;
  const double d = 0.1 / (w - 1);
  for (int layer = 0; layer < 2; ++layer) {
    for (int32_t r = 0; r < w; ++r) {
      for (int32_t c = 0; c < w; ++c) {
        const double off = layer * d / 3.0;
        s.x.emplace_back(c * d + off, layer * gap_m, r * d + off);
      }
    }
    for (Triangle t : MakeGridTriangles(w, w)) {
      for (int32_t& i : t) i += layer * w * w;
      s.triangles.push_back(t);
    }
  }
  return s;
}

// Steps the upper sheet down by up to `drop_m` in one substep of h, the lower up by up to
// `rise_m` (both in proportion to x / 0.1 m: the sheets tilt, so one that gets through the other
// ends crossing it), resolves, and returns the stats; x and v are updated.
SelfCollisionStats DriveThrough(const TwoSheets& sheets, const std::vector<double>& inv_mass,
                                const SelfCollisionSettings& settings, double drop_m, double rise_m,
                                std::vector<Vec3>* x, std::vector<Vec3>* v,
                                Vec3* momentum_before = nullptr) {
  constexpr double kH = 1e-3;
  SelfCollisionResponse response(sheets.triangles, sheets.x, inv_mass, settings);
  *x = sheets.x;
  v->assign(x->size(), Vec3::Zero());
  response.BeginStep(*x);
  const size_t half = x->size() / 2;
  for (size_t p = 0; p < x->size(); ++p) {
    if (inv_mass[p] == 0.0) continue;
    const double dy = (p < half ? rise_m : -drop_m) * (sheets.x[p].x() / 0.1);
    (*x)[p].y() += dy;
    (*v)[p].y() = dy / kH;
    if (momentum_before) *momentum_before += (*v)[p] / inv_mass[p];
  }
  return response.Resolve(kH, *x, *v);
}

TEST(SelfResponse, SheetDrivenThroughAPinnedSheetStopsOnIt) {
  const TwoSheets sheets = MakeTwoSheets(6, 0.01);
  std::vector<double> inv_mass(sheets.x.size(), 100.0);
  for (size_t p = 0; p < sheets.x.size() / 2; ++p) inv_mass[p] = 0.0;  // lower sheet pinned
  SelfCollisionSettings settings;
  settings.thickness_m = 1e-3;
  std::vector<Vec3> x, v;
  // Up to 3 cm down in one substep: the far part through the lower sheet and 2 cm past it.
  const SelfCollisionStats st = DriveThrough(sheets, inv_mass, settings, 0.03, 0.0, &x, &v);
  EXPECT_GT(st.ccd_hits, 0);
  EXPECT_EQ(st.unresolved, 0);
  EXPECT_EQ(CountSelfIntersections(x, sheets.triangles), 0);
  // The pinned sheet did not move; the upper one ends above it.
  for (size_t p = 0; p < x.size() / 2; ++p) EXPECT_EQ(x[p], sheets.x[p]);
  // The upper sheet's vertices over the lower one end above it (those past its edge, offset by a
  // third of a cell, may pass beside it).
  for (size_t p = x.size() / 2; p < x.size(); ++p) {
    if (x[p].x() < 0.1 && x[p].z() < 0.1) {
      EXPECT_GT(x[p].y(), 0.0) << p;
    }
  }
  EXPECT_EQ(st.zone_rounds, 0) << "the impulse rounds alone should stop a sheet on a pinned one";
}

TEST(SelfResponse, ImpulsesConserveMomentumBetweenFreeSheets) {
  const TwoSheets sheets = MakeTwoSheets(6, 0.004);
  const std::vector<double> inv_mass(sheets.x.size(), 100.0);
  SelfCollisionSettings settings;
  settings.thickness_m = 1e-3;
  settings.friction = 0.3;
  std::vector<Vec3> x, v;
  // Toward each other, up to 1 cm each: they cross unless stopped.
  Vec3 before = Vec3::Zero();
  const SelfCollisionStats st =
      DriveThrough(sheets, inv_mass, settings, 0.01, 0.01, &x, &v, &before);
  EXPECT_GT(st.ccd_impulses + st.impact_zones, 0);
  EXPECT_EQ(st.unresolved, 0);
  EXPECT_EQ(CountSelfIntersections(x, sheets.triangles), 0);
  Vec3 momentum = Vec3::Zero();
  for (const Vec3& vp : v) momentum += vp / 100.0;
  EXPECT_LT((momentum - before).norm(), 1e-9 * before.norm());  // impulses come in equal pairs
}

TEST(SelfResponse, FailSafeAloneResolvesAndIsNeededWithoutRounds) {
  const TwoSheets sheets = MakeTwoSheets(6, 0.004);
  const std::vector<double> inv_mass(sheets.x.size(), 100.0);
  SelfCollisionSettings settings;
  settings.thickness_m = 1e-3;
  settings.iterations = 0;
  std::vector<Vec3> x, v;
  SelfCollisionStats st = DriveThrough(sheets, inv_mass, settings, 0.01, 0.01, &x, &v);
  EXPECT_GT(st.impact_zones, 0);
  EXPECT_EQ(st.unresolved, 0);
  EXPECT_EQ(CountSelfIntersections(x, sheets.triangles), 0);
  // No rounds, no fail-safe: the crossing stays (the fail-safe is what removed it above).
  settings.fail_safe = false;
  st = DriveThrough(sheets, inv_mass, settings, 0.01, 0.01, &x, &v);
  EXPECT_GT(st.unresolved, 0);
  EXPECT_GT(CountSelfIntersections(x, sheets.triangles), 0);
}

// A zone holding pinned vertices (infinite mass) moves with its pins: here they are fixed, so the
// zone's free vertices keep x_before and the pinned sheet is never moved.
TEST(SelfResponse, FailSafeZoneWithPinsStaysWithThem) {
  const TwoSheets sheets = MakeTwoSheets(6, 0.01);
  std::vector<double> inv_mass(sheets.x.size(), 100.0);
  for (size_t p = 0; p < sheets.x.size() / 2; ++p) inv_mass[p] = 0.0;
  SelfCollisionSettings settings;
  settings.thickness_m = 1e-3;
  settings.iterations = 0;
  std::vector<Vec3> x, v;
  const SelfCollisionStats st = DriveThrough(sheets, inv_mass, settings, 0.03, 0.0, &x, &v);
  EXPECT_GT(st.impact_zones, 0);
  EXPECT_EQ(st.unresolved, 0);
  EXPECT_EQ(CountSelfIntersections(x, sheets.triangles), 0);
  for (size_t p = 0; p < x.size() / 2; ++p) EXPECT_EQ(x[p], sheets.x[p]);
}

TEST(SelfResponse, ProximityRepelsLayersWithinTheThickness) {
  const TwoSheets sheets = MakeTwoSheets(5, 0.0005);  // 0.5 mm apart, thickness 1 mm
  const std::vector<double> inv_mass(sheets.x.size(), 100.0);
  SelfCollisionSettings settings;
  settings.thickness_m = 1e-3;
  settings.repulsion_stiffness_N_per_m = 10.0;
  std::vector<Vec3> x, v;
  const SelfCollisionStats st = DriveThrough(sheets, inv_mass, settings, 0.0, 0.0, &x, &v);
  EXPECT_GT(st.proximity_pairs, 0);
  EXPECT_GT(st.proximity_impulses, 0);
  EXPECT_EQ(st.ccd_hits, 0);  // parallel edges 0.5 mm apart are coplanar: not a collision
  EXPECT_EQ(st.impact_zones, 0);
  // At rest and too close: pushed apart, upper up, lower down.
  const size_t half = x.size() / 2;
  EXPECT_GT(v[half + 12].y(), 0.0);
  EXPECT_LT(v[12].y(), 0.0);
}

// Resolve never allocates, through proximity, CCD rounds and the fail-safe (iterations 0 forces
// impact zones), with every broad phase.
TEST(SelfResponse, ResolveDoesNotAllocate) {
  const TwoSheets sheets = MakeTwoSheets(6, 0.004);
  const std::vector<double> inv_mass(sheets.x.size(), 100.0);
  for (SelfCullingMethod method : kSelfCullingMethods) {
    SelfCollisionSettings settings;
    settings.thickness_m = 1e-3;
    settings.iterations = 0;
    settings.method = method;
    SelfCollisionResponse response(sheets.triangles, sheets.x, inv_mass, settings);
    std::vector<Vec3> x = sheets.x;
    std::vector<Vec3> v(x.size(), Vec3::Zero());
    const size_t half = x.size() / 2;
    for (size_t p = 0; p < x.size(); ++p) {
      x[p].y() += (p < half ? 0.01 : -0.01) * (sheets.x[p].x() / 0.1);
    }
    AllocationGuard guard;
    response.BeginStep(sheets.x);
    const SelfCollisionStats st = response.Resolve(1e-3, x, v);
    EXPECT_EQ(guard.allocations(), 0u) << SelfCullingMethodName(method);
    EXPECT_GT(st.impact_zones, 0);
  }
}

// The later CCD rounds re-test only the candidates whose vertices moved (and the last round's
// hits): the motion Resolve ends with must still have no collision by the all-pairs reference,
// and the first detection kept for the bench equals AllPairsCcd on the same motion. Sheets 4 mm
// apart, driven 2 mm each toward each other (thickness 3 mm): the impulses keep the vertices
// within the broad phase's boxes, so the later rounds run incrementally on its candidates; with
// bvh_cones the pass's one broad phase is carried over to every detection (in the 8 mm case the
// impulses move more than a quarter of the vertices and a full broad phase runs again).
TEST(SelfResponse, IncrementalRoundsLeaveNoCollisionByTheAllPairsReference) {
  const TwoSheets sheets = MakeTwoSheets(7, 0.004);
  const std::vector<double> inv_mass(sheets.x.size(), 100.0);
  for (SelfCullingMethod method : kSelfCullingMethods) {
    for (double drive_m : {0.002, 0.008}) {
      SelfCollisionSettings settings;
      settings.thickness_m = 3e-3;
      settings.method = method;
      settings.iterations = 8;
      SelfCollisionResponse response(sheets.triangles, sheets.x, inv_mass, settings);
      response.KeepFirstPass(true);
      std::vector<Vec3> x = sheets.x;
      std::vector<Vec3> v(x.size(), Vec3::Zero());
      const size_t half = x.size() / 2;
      for (size_t p = 0; p < x.size(); ++p) {
        x[p].y() += (p < half ? drive_m : -drive_m) * (sheets.x[p].x() / 0.1);
      }
      response.BeginStep(sheets.x);
      const SelfCollisionStats st = response.Resolve(1e-3, x, v);
      const std::string name =
          std::string(SelfCullingMethodName(method)) + " drive " + std::to_string(drive_m);
      ASSERT_GT(st.ccd_rounds, 1) << name;  // the rounds ran: the test can fail
      EXPECT_EQ(st.unresolved, 0) << name;
      if (drive_m == 0.002 && method == SelfCullingMethod::kBvhCones) {
        // One broad phase for the pass; every detection carried it over (UpdateCandidates).
        EXPECT_EQ(st.broad_phases, 1) << name;
        EXPECT_GT(st.broad_updates, 0) << name;
      } else if (drive_m == 0.002) {
        EXPECT_GT(st.incremental_detections, 0) << name;
      }
      // The first detection is the reference's, pair for pair.
      const std::vector<CcdPairHit> first = AllPairsCcd(
          sheets.x, response.first_pass_end(), sheets.triangles, response.CcdPassOptions());
      ASSERT_GT(first.size(), 0u) << name;
      std::vector<std::array<int32_t, 3>> a, b;
      for (const CcdPairHit& h : first) {
        a.push_back({static_cast<int32_t>(h.kind), h.first, h.second});
      }
      for (const CcdPairHit& h : response.first_pass_hits()) {
        b.push_back({static_cast<int32_t>(h.kind), h.first, h.second});
      }
      std::sort(b.begin(), b.end());
      EXPECT_EQ(a, b) << name;
      // The final motion: no collision left by the reference, no intersection at its end.
      EXPECT_TRUE(AllPairsCcd(sheets.x, x, sheets.triangles, response.CcdPassOptions()).empty())
          << name;
      EXPECT_EQ(CountSelfIntersections(x, sheets.triangles), 0) << name;
    }
  }
}

TEST(SelfResponse, MethodNames) {
  EXPECT_EQ(SelfCullingMethodFromName("bvh"), SelfCullingMethod::kBvh);
  EXPECT_EQ(SelfCullingMethodFromName("spatial_hash"), SelfCullingMethod::kSpatialHash);
  EXPECT_FALSE(SelfCullingMethodFromName("octree").has_value());
  EXPECT_EQ(SelfCullingMethodName(SelfCullingMethod::kBvh), "bvh");
  for (SelfCullingMethod method : kSelfCullingMethods) {
    EXPECT_EQ(SelfCullingMethodFromName(SelfCullingMethodName(method)), method);
  }
  EXPECT_EQ(SelfCullingMethodFromName("bvox_aabb"), SelfCullingMethod::kBvox);
}

}  // namespace
}  // namespace felt
