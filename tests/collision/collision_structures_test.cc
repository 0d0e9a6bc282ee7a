// Every collision structure against the naive all-triangle reference (shared/STYLE.md: fast
// structures vs an obviously correct one, thousands of random cases, fixed seeds).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <random>

#include "collision/collision_structure.h"
#include "tests/collision/collision_test_util.h"
#include "tests/test_env.h"

namespace felt {
namespace {

// Under a sanitizer a quarter of the random queries (tests/test_env.h): the same code paths.
int SanitizedScale() { return testing::Sanitized() ? 4 : 1; }

using testing::AllSpecs;
using testing::FlatGrid;
using testing::MakeTestCloths;
using testing::RandomQueryPoint;
using testing::TestCloth;

constexpr int32_t kGrid = 21;         // 800 triangles per cloth
constexpr double kInflation = 0.004;  // m, about a tenth of an edge
constexpr double kRadii[] = {0.0, 0.0005, 0.005, 0.02};

// Builds every structure at the flat rest shape and repairs it to the cloth's shape twice (the
// second repair sees no motion), so queries run on repaired, not freshly built, volumes.
std::vector<CollisionStructure> BuildRepaired(const TestCloth& c) {
  std::vector<CollisionStructure> out;
  const std::vector<Vec3> rest = FlatGrid(kGrid, kGrid);
  for (const CollisionStructureSpec& spec : AllSpecs(kInflation)) {
    out.push_back(MakeCollisionStructure(spec, c.triangles, rest));
    Repair(out.back(), c.x);
    Repair(out.back(), c.x);
  }
  return out;
}

std::vector<PointContact> Sorted(std::vector<PointContact> v, WithinResult r) {
  v.resize(static_cast<size_t>(r.written));
  std::sort(v.begin(), v.end(),
            [](const PointContact& a, const PointContact& b) { return a.triangle < b.triangle; });
  return v;
}

void ExpectSameHit(const SweepHit& ref, const SweepHit& got, const std::string& what) {
  ASSERT_EQ(ref.hit, got.hit) << what;
  if (!ref.hit) return;
  EXPECT_NEAR(ref.toi, got.toi, 1e-12) << what;
  EXPECT_EQ(ref.triangle, got.triangle) << what;
  EXPECT_EQ(ref.normal, got.normal) << what;
  EXPECT_EQ(ref.point_m, got.point_m) << what;
  EXPECT_EQ(ref.barycentric, got.barycentric) << what;
}

TEST(CollisionStructuresTest, TrianglesWithinMatchesNaiveExactly) {
  std::mt19937_64 rng(11);
  const std::vector<CollisionStructureSpec> specs = AllSpecs(kInflation);
  std::vector<PointContact> ref_buf(4096), got_buf(4096);
  int64_t nonempty = 0;
  for (const TestCloth& c : MakeTestCloths(kGrid, 5)) {
    const std::vector<CollisionStructure> structures = BuildRepaired(c);
    for (int q = 0; q < 400 / SanitizedScale(); ++q) {
      const double r = kRadii[q % 4];
      const Vec3 p = RandomQueryPoint(c, r, rng);
      const WithinResult ref_r = TrianglesWithin(structures[0], c.x, p, r, ref_buf);
      ASSERT_FALSE(ref_r.overflowed());
      const std::vector<PointContact> ref = Sorted(ref_buf, ref_r);
      nonempty += ref.empty() ? 0 : 1;
      for (size_t s = 1; s < structures.size(); ++s) {
        const WithinResult got_r = TrianglesWithin(structures[s], c.x, p, r, got_buf);
        const std::vector<PointContact> got = Sorted(got_buf, got_r);
        const std::string what =
            c.name + " " + CollisionStructureName(specs[s]) + " query " + std::to_string(q);
        ASSERT_EQ(ref_r.found, got_r.found) << what;
        ASSERT_EQ(ref.size(), got.size()) << what;
        for (size_t i = 0; i < ref.size(); ++i) {
          EXPECT_EQ(ref[i].triangle, got[i].triangle) << what;
          EXPECT_EQ(ref[i].point_m, got[i].point_m) << what;
          EXPECT_EQ(ref[i].barycentric, got[i].barycentric) << what;
          EXPECT_EQ(ref[i].distance_m, got[i].distance_m) << what;
        }
      }
    }
  }
  // The generator must actually produce contacts (else the comparison proves little).
  EXPECT_GT(nonempty, 1000 / SanitizedScale());
}

// ids_only finds the same triangles as the exact query on every structure, with radii up to the
// cloth's size so that whole triangles fall inside (the shortcut's case) as well as partly.
TEST(CollisionStructuresTest, TrianglesWithinIdsOnlyFindsTheSameTriangles) {
  std::mt19937_64 rng(13);
  const std::vector<CollisionStructureSpec> specs = AllSpecs(kInflation);
  std::vector<PointContact> ref_buf(4096), got_buf(4096);
  int64_t found = 0;
  for (const TestCloth& c : MakeTestCloths(kGrid, 5)) {
    const std::vector<CollisionStructure> structures = BuildRepaired(c);
    for (int q = 0; q < 100 / SanitizedScale(); ++q) {
      const double r = std::array{0.0, 0.005, 0.02, 0.1, 0.4}[q % 5];
      const Vec3 p = RandomQueryPoint(c, r, rng);
      for (size_t s = 0; s < structures.size(); ++s) {
        const WithinResult ref_r = TrianglesWithin(structures[s], c.x, p, r, ref_buf);
        const WithinResult got_r = TrianglesWithin(structures[s], c.x, p, r, got_buf, true);
        const std::string what =
            c.name + " " + CollisionStructureName(specs[s]) + " query " + std::to_string(q);
        ASSERT_EQ(ref_r.found, got_r.found) << what;
        const std::vector<PointContact> ref = Sorted(ref_buf, ref_r);
        const std::vector<PointContact> got = Sorted(got_buf, got_r);
        for (size_t i = 0; i < ref.size(); ++i) EXPECT_EQ(ref[i].triangle, got[i].triangle) << what;
        found += ref_r.found;
      }
    }
  }
  EXPECT_GT(found, 5000 / SanitizedScale());
}

TEST(CollisionStructuresTest, TrianglesWithinReportsOverflow) {
  const TestCloth c = MakeTestCloths(kGrid, 5)[0];
  for (const CollisionStructureSpec& spec : AllSpecs(kInflation)) {
    const CollisionStructure s = MakeCollisionStructure(spec, c.triangles, c.x);
    std::vector<PointContact> buf(3);
    const WithinResult r = TrianglesWithin(s, c.x, Vec3(0.5, 0.5, 0.01), 0.1, buf);
    EXPECT_GT(r.found, 3) << CollisionStructureName(spec);
    EXPECT_EQ(r.written, 3) << CollisionStructureName(spec);
    EXPECT_TRUE(r.overflowed()) << CollisionStructureName(spec);
  }
}

TEST(CollisionStructuresTest, SweepSphereMatchesNaiveExactly) {
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  const std::vector<CollisionStructureSpec> specs = AllSpecs(kInflation);
  int64_t hits = 0, zero_toi = 0;
  for (const TestCloth& c : MakeTestCloths(kGrid, 6)) {
    const std::vector<CollisionStructure> structures = BuildRepaired(c);
    for (int q = 0; q < 600 / SanitizedScale(); ++q) {
      const double r = kRadii[q % 4];
      const Vec3 p0 = RandomQueryPoint(c, r, rng);
      const Vec3 dir = Vec3(g(rng), g(rng), g(rng)).normalized();
      Vec3 p1;
      switch (q % 5) {
        case 0:  // a haptic tick's worth of motion
          p1 = p0 + 0.002 * u(rng) * dir;
          break;
        case 1:  // a few cells
          p1 = p0 + 0.1 * u(rng) * dir;
          break;
        case 2:  // very fast: 10 m in one tick, straight through the cloth
          p1 = p0 + 10.0 * dir;
          break;
        case 3:  // from far above to far below
          p1 = Vec3(p0.x(), p0.y(), -5.0);
          break;
        default:  // no motion at all
          p1 = p0;
          break;
      }
      const SweepHit ref = SweepSphere(structures[0], c.x, p0, p1, r);
      hits += ref.hit ? 1 : 0;
      zero_toi += ref.hit && ref.toi == 0.0 ? 1 : 0;
      for (size_t s = 1; s < structures.size(); ++s) {
        ExpectSameHit(
            ref, SweepSphere(structures[s], c.x, p0, p1, r),
            c.name + " " + CollisionStructureName(specs[s]) + " query " + std::to_string(q));
      }
    }
  }
  EXPECT_GT(hits, 600 / SanitizedScale());
  EXPECT_GT(zero_toi, 50 / SanitizedScale());
}

TEST(CollisionStructuresTest, SweepSphereMovingMatchesNaiveExactly) {
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const std::vector<CollisionStructureSpec> specs = AllSpecs(kInflation);
  const std::vector<Vec3> rest = FlatGrid(kGrid, kGrid);
  int64_t hits = 0;
  for (const TestCloth& c : MakeTestCloths(kGrid, 7)) {
    // The new snapshot: the cloth lifted by up to 3 cm in a smooth wave plus a little noise.
    std::vector<Vec3> x_new = c.x;
    for (Vec3& p : x_new) {
      p += Vec3(0.002 * u(rng), 0.002 * u(rng), 0.03 * std::sin(3 * p.x() + 2 * p.y()));
    }
    std::vector<CollisionStructure> structures;
    for (const CollisionStructureSpec& spec : specs) {
      structures.push_back(MakeCollisionStructure(spec, c.triangles, rest));
      RepairSwept(structures.back(), c.x, x_new);
    }
    for (int q = 0; q < 120; ++q) {
      const double r = kRadii[1 + q % 3];
      const Vec3 c0 = RandomQueryPoint(c, r, rng) + Vec3(0, 0, 0.02 * u(rng));
      const Vec3 c1 =
          q % 2 == 0 ? c0 : Vec3(c0 + Vec3(0.01 * u(rng), 0.01 * u(rng), 0.01 * u(rng)));
      const SweepHit ref = SweepSphereMoving(structures[0], c.x, x_new, c0, c1, r);
      hits += ref.hit ? 1 : 0;
      for (size_t s = 1; s < structures.size(); ++s) {
        ExpectSameHit(
            ref, SweepSphereMoving(structures[s], c.x, x_new, c0, c1, r),
            c.name + " " + CollisionStructureName(specs[s]) + " query " + std::to_string(q));
      }
    }
  }
  EXPECT_GT(hits, 100);
}

TEST(CollisionStructuresTest, TenMetresInOneTickNeverTunnelsThroughACentimetreSheet) {
  // A 1 cm x 1 cm sheet of 7 x 7 particles; segments from z = +5 m to z = -5 m through it.
  const int32_t w = 7;
  std::vector<Vec3> x = FlatGrid(w, w);
  for (Vec3& p : x) p *= 0.01;
  const auto tris = std::make_shared<const std::vector<Triangle>>(MakeGridTriangles(w, w));
  std::mt19937_64 rng(14);
  std::uniform_real_distribution<double> u(0.0, 0.01);
  for (const CollisionStructureSpec& spec : AllSpecs(kInflation)) {
    const CollisionStructure s = MakeCollisionStructure(spec, tris, x);
    for (int q = 0; q < 200; ++q) {
      const double r = kRadii[q % 4];
      const Vec3 p0(u(rng), u(rng), 5.0);
      const Vec3 p1 = q % 2 == 0 ? Vec3(p0.x(), p0.y(), -5.0) : Vec3(u(rng), u(rng), -5.0);
      const SweepHit hit = SweepSphere(s, x, p0, p1, r);
      ASSERT_TRUE(hit.hit) << CollisionStructureName(spec) << " query " << q;
      // Closed form: the centre is at height r when it first touches the sheet.
      EXPECT_NEAR(hit.toi, (5.0 - r) / 10.0, 1e-12) << CollisionStructureName(spec);
      EXPECT_NEAR(hit.normal.z(), 1.0, 1e-9);
      // And upward from below, the normal faces down.
      const SweepHit up = SweepSphere(s, x, p1, p0, r);
      ASSERT_TRUE(up.hit);
      EXPECT_NEAR(up.normal.z(), -1.0, 1e-9);
    }
  }
}

TEST(CollisionStructuresTest, RestingSphereSlidesButCannotPushIn) {
  // The proxy's convention: resting at exactly r, tangential or outward motion is free, inward
  // motion stops at toi = 0 with the surface normal.
  const TestCloth c = MakeTestCloths(kGrid, 5)[0];
  const double r = 0.005;
  for (const CollisionStructureSpec& spec : AllSpecs(kInflation)) {
    const CollisionStructure s = MakeCollisionStructure(spec, c.triangles, c.x);
    const std::string name = CollisionStructureName(spec);
    for (const Vec3& p0 : {Vec3(0.31, 0.42, r), Vec3(0.5, 0.5, r), Vec3(0.25, 0.3, r)}) {
      EXPECT_FALSE(SweepSphere(s, c.x, p0, p0 + Vec3(0.2, 0.13, 0), r).hit) << name;
      EXPECT_FALSE(SweepSphere(s, c.x, p0, p0 + Vec3(0.0, 0.0, 0.01), r).hit) << name;
      EXPECT_FALSE(SweepSphere(s, c.x, p0, p0 + Vec3(-0.1, 0.01, 0.02), r).hit) << name;
      const SweepHit in = SweepSphere(s, c.x, p0, p0 + Vec3(0.01, 0.0, -0.001), r);
      ASSERT_TRUE(in.hit) << name;
      EXPECT_EQ(in.toi, 0.0) << name;
      EXPECT_NEAR((in.normal - Vec3(0, 0, 1)).norm(), 0.0, 1e-12) << name;
    }
    // From below, resting at -r: the normal faces down.
    const SweepHit below = SweepSphere(s, c.x, Vec3(0.4, 0.4, -r), Vec3(0.4, 0.4, 0.1), r);
    ASSERT_TRUE(below.hit) << name;
    EXPECT_EQ(below.toi, 0.0);
    EXPECT_NEAR((below.normal - Vec3(0, 0, -1)).norm(), 0.0, 1e-12) << name;
  }
}

TEST(CollisionStructuresTest, CopiesAreIndependentSnapshots) {
  // A copy shares the immutable topology but repairing one leaves the other's answers intact.
  const std::vector<TestCloth> cloths = MakeTestCloths(kGrid, 5);
  const TestCloth& flat = cloths[0];
  const TestCloth& draped = cloths[1];
  for (const CollisionStructureSpec& spec : AllSpecs(kInflation)) {
    CollisionStructure a = MakeCollisionStructure(spec, flat.triangles, flat.x);
    const CollisionStructure b = a;
    Repair(a, draped.x);
    const Vec3 p0(0.5, 0.5, 1.0), p1(0.5, 0.5, -1.0);
    const SweepHit on_a = SweepSphere(a, draped.x, p0, p1, 0.01);
    const SweepHit on_b = SweepSphere(b, flat.x, p0, p1, 0.01);
    ASSERT_TRUE(on_a.hit && on_b.hit) << CollisionStructureName(spec);
    EXPECT_NEAR(on_b.toi, (1.0 - 0.01) / 2.0, 1e-12) << CollisionStructureName(spec);
    EXPECT_LT(on_a.toi, on_b.toi) << CollisionStructureName(spec);  // the drape is higher
  }
}

TEST(CollisionStructuresTest, BadInputThrowsNamingTheField) {
  const TestCloth c = MakeTestCloths(kGrid, 5)[0];
  CollisionStructureSpec spec;
  spec.bvh.arity = 3;
  EXPECT_THROW(
      {
        try {
          MakeCollisionStructure(spec, c.triangles, c.x);
        } catch (const std::invalid_argument& e) {
          EXPECT_STREQ(e.what(), "BvhOptions.arity: must be 2 or 4, got 3");
          throw;
        }
      },
      std::invalid_argument);
  spec.bvh.arity = 2;
  const std::vector<Vec3> too_few(3, Vec3::Zero());
  EXPECT_THROW(MakeCollisionStructure(spec, c.triangles, too_few), std::invalid_argument);
  spec.kind = CollisionStructureSpec::Kind::kSpatialHash;
  spec.hash.cell_size_m = -1.0;
  EXPECT_THROW(MakeCollisionStructure(spec, c.triangles, c.x), std::invalid_argument);
  EXPECT_THROW(NaiveCollision(nullptr), std::invalid_argument);
}

}  // namespace
}  // namespace felt
