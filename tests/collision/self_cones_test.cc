// The normal-cone culling of SelfBvh (SelfBroadPhaseOptions::normal_cones): a patch whose normals
// over the step lie in a cone below pi/2 and whose contour stays star-shaped about its center is
// not traversed against itself, nor two such patches whose union is certified. Checked against
// the all-pairs continuous reference (AllPairsCcd): on folded, falling, crumpled and twisted
// cloth, SelfCcd with cones finds every colliding pair the reference finds (same hits, same
// order, same toi), its candidates are a subset of the brute-force box set, and the cones did
// cull (so that the comparison can fail).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <numbers>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "base/simd.h"
#include "collision/ccd_all_pairs.h"
#include "collision/self_broadphase.h"
#include "tests/collision/collision_test_util.h"
#include "tests/test_env.h"

namespace felt {
namespace {

using testing::HingedGrid;
using testing::SpacedGrid;

// The culled detection's hits `got` are the reference's, in the same order, toi bit for bit.
void ExpectSameHits(const std::vector<CcdPairHit>& got, const std::vector<CcdPairHit>& ref,
                    const std::string& label) {
  ASSERT_EQ(got.size(), ref.size()) << label;
  for (size_t i = 0; i < ref.size(); ++i) {
    EXPECT_EQ(got[i].kind, ref[i].kind) << label;
    EXPECT_EQ(got[i].first, ref[i].first) << label;
    EXPECT_EQ(got[i].second, ref[i].second) << label;
    EXPECT_EQ(got[i].toi, ref[i].toi) << label;
  }
}

// The reference's options at thickness h [m]: every pair, with AllPairsCcd's box prefilter, which
// skips only pairs whose swept boxes, padded by h / 2, are apart on an axis (never within h; the
// same hits as the plain loop: CcdAllPairs tests, and FoldedAndFalling's first case below). Plain,
// each of the ~1e6 pairs of a 20 x 20 cloth ran the cubic: 18 s of CI's ASan run per test.
AllPairsCcdOptions ReferenceOptions(double h) {
  AllPairsCcdOptions options;
  options.ccd.thickness_m = h;
  options.box_prefilter = true;
  return options;
}

// Runs SelfCcd with normal cones on x0 -> x1 and compares with AllPairsCcd at thickness h;
// returns the number of reference hits and the patches the cones skipped.
void ConeCheck(std::span<const Vec3> rest, std::span<const Vec3> x0, std::span<const Vec3> x1,
               std::span<const Triangle> tris, double h, const std::string& label,
               size_t* reference_hits, int32_t* culled) {
  const std::vector<CcdPairHit> ref = AllPairsCcd(x0, x1, tris, ReferenceOptions(h));
  AllPairsCcdOptions options;
  options.ccd.thickness_m = h;
  SelfBroadPhaseOptions cone_options;
  cone_options.normal_cones = true;
  SelfBvh cones(tris, rest, cone_options);
  SelfBvh plain(tris, rest);
  std::vector<CcdPairHit> hits;
  hits.reserve(ref.size() + 16);
  const SelfCcdStats st = SelfCcd(&cones, x0, x1, options, &hits);
  ASSERT_FALSE(st.overflow) << label;
  ExpectSameHits(hits, ref, label);
  if (::testing::Test::HasFatalFailure()) return;
  // The cones only remove candidates: a subset of the plain traversal's box-overlap set.
  const SelfBroadPhaseStats all = plain.FindCandidates(x0, x1, h);
  EXPECT_LE(st.broad.vertex_triangle + st.broad.edge_edge, all.vertex_triangle + all.edge_edge)
      << label;
  *reference_hits += ref.size();
  *culled += cones.cone_culled() + cones.union_culled();
}

// The narrow phase (AllPairsCcd's pair tests) over the broad phase's candidates on x0 -> x1,
// sorted as AllPairsCcd sorts; fails the test if a candidate comes twice.
std::vector<CcdPairHit> NarrowOverCandidates(const SelfBroadPhase& broad, std::span<const Vec3> x0,
                                             std::span<const Vec3> x1,
                                             const AllPairsCcdOptions& options,
                                             const std::string& label) {
  std::vector<CcdPairHit> hits;
  std::vector<std::array<int32_t, 3>> seen;
  for (const SelfCandidate& c : broad.candidates()) {
    seen.push_back({static_cast<int32_t>(c.kind), c.first, c.second});
    CcdPairHit h;
    const bool hit = c.kind == CcdPairHit::Kind::kVertexTriangle
                         ? VertexTrianglePairHit(x0, x1, c.first, c.second,
                                                 broad.triangles()[c.second], options, &h)
                         : EdgeEdgePairHit(x0, x1, c.first, broad.edges()[c.first], c.second,
                                           broad.edges()[c.second], options, &h);
    if (hit) hits.push_back(h);
  }
  std::sort(seen.begin(), seen.end());
  EXPECT_EQ(std::adjacent_find(seen.begin(), seen.end()), seen.end()) << label << ": duplicate";
  std::sort(hits.begin(), hits.end(), [](const CcdPairHit& a, const CcdPairHit& b) {
    if (a.kind != b.kind) return a.kind < b.kind;
    if (a.first != b.first) return a.first < b.first;
    return a.second < b.second;
  });
  return hits;
}

// One run of UpdateCheck (below) with start boxes of start_h [m] (0: none).
void UpdateCheckOnce(std::span<const Vec3> rest, std::span<const Vec3> x0, std::span<const Vec3> x1,
                     std::span<const Triangle> tris, double h, double start_h, double step,
                     const std::string& label, std::mt19937_64* rng, size_t* reference_hits,
                     size_t* kept) {
  AllPairsCcdOptions options;
  options.ccd.thickness_m = h;
  SelfBroadPhaseOptions cone_options;
  cone_options.normal_cones = true;
  SelfBvh cones(tris, rest, cone_options);
  ASSERT_FALSE(cones.FindCandidates(x0, x1, h, start_h).overflow) << label;
  const AllPairsCcdOptions reference = ReferenceOptions(h);
  std::vector<Vec3> x1b(x1.begin(), x1.end());
  std::vector<uint8_t> moved(x1.size(), 0);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (int32_t round = 0; round < 2; ++round) {
    const std::string name = label + " update " + std::to_string(round);
    const Vec3 center =
        x0[static_cast<size_t>(u01(*rng) * static_cast<double>(x0.size())) % x0.size()];
    std::fill(moved.begin(), moved.end(), 0);
    for (size_t i = 0; i < x1b.size(); ++i) {
      const bool pick = round == 0 ? u01(*rng) < 0.2 : (x0[i] - center).norm() < 3 * step;
      if (!pick) continue;
      moved[i] = 1;
      const double along = u01(*rng) < 0.5 ? 0.3 : 1.5;
      x1b[i] = x0[i] + along * (x1[i] - x0[i]) + 0.2 * step * Vec3(n01(*rng), n01(*rng), n01(*rng));
    }
    const SelfBroadPhaseStats st = cones.UpdateCandidates(x0, x1b, h, start_h, moved);
    ASSERT_FALSE(st.overflow) << name;
    EXPECT_EQ(st.vertex_triangle + st.edge_edge, std::ssize(cones.candidates())) << name;
    *kept += cones.kept_from().size();
    const std::vector<CcdPairHit> got = NarrowOverCandidates(cones, x0, x1b, options, name);
    const std::vector<CcdPairHit> ref = AllPairsCcd(x0, x1b, tris, reference);
    ExpectSameHits(got, ref, name);
    if (::testing::Test::HasFatalFailure()) return;
    *reference_hits += ref.size();
  }
}

// SelfBvh::UpdateCandidates carries a cone-culled broad phase over to a motion whose end
// differs at some vertices: after a first FindCandidates on x0 -> x1, two updates in a row move
// a random fifth of the vertices, then a cluster around one vertex (stopping them early or
// pushing them further along their motion, plus noise), and each time the narrow phase over the
// updated candidates equals AllPairsCcd on the new motion (pairs and toi), no candidate comes
// twice, and the update kept candidates (so that the kept path is exercised); with and without
// start boxes (the 4-argument FindCandidates).
void UpdateCheck(std::span<const Vec3> rest, std::span<const Vec3> x0, std::span<const Vec3> x1,
                 std::span<const Triangle> tris, double h, double step, const std::string& label,
                 std::mt19937_64* rng, size_t* reference_hits, size_t* kept) {
  // Without and with start boxes (the proximity pass's thickness around x0, 3 h here); under a
  // sanitizer with them only (test_env.h: the all-pairs reference is O(T^2); FindCandidates
  // without start boxes is ConeCheck's, below).
  for (double start_h : {0.0, 3 * h}) {
    if (testing::Sanitized() && start_h == 0.0) continue;
    UpdateCheckOnce(rest, x0, x1, tris, h, start_h, step,
                    label + " start " + std::to_string(start_h), rng, reference_hits, kept);
  }
}

// A motion both cone tests check: a grid (rest, tris) moving from x0 to x1, its spacing and the
// thickness to test it at, m.
struct MotionCase {
  std::vector<Triangle> tris;
  std::vector<Vec3> rest, x0, x1;
  double step = 0.0, thickness = 0.0;
};

// A w x w grid `step` apart at rest, thickness 0.001 m, its motion still to fill in.
MotionCase GridCase(int32_t w, double step) {
  return {MakeGridTriangles(w, w), SpacedGrid(w, w, step), {}, {}, step, 0.001};
}

// Wave case c: a 20 x 20 grid 0.02 m apart with smooth waves of amplitude 0.02 (1 + c) m and a
// crumple of 0.05 step at x0, moving a little to x1 (a fifth of the amplitude along z, plus noise
// of 0.1 step), drawn from rng.
MotionCase Waves(int32_t c, std::mt19937_64* rng) {
  MotionCase m = GridCase(20, 0.02);
  std::normal_distribution<double> n01(0.0, 1.0);
  const auto noise = [&] { return Vec3(n01(*rng), n01(*rng), n01(*rng)); };
  const double amp = 0.02 * (1 + c), phase = 0.3 * c;
  m.x0 = m.rest;
  m.x1 = m.rest;
  for (size_t i = 0; i < m.rest.size(); ++i) {
    const Vec3& p = m.rest[i];
    m.x0[i].z() = amp * std::sin(9 * p.x() + phase) * std::sin(7 * p.y());
    m.x0[i] += 0.05 * m.step * noise();
    m.x1[i] = m.x0[i] + Vec3(0.0, 0.0, amp * 0.2 * std::sin(11 * p.y())) + 0.1 * m.step * noise();
  }
  return m;
}

// A 14 x 14 grid 0.04 m apart folded at row 7 into a U whose top layer falls 5 cm through the
// bottom within the step (testing::FallingUFold), drawn from rng.
MotionCase FallingFold(std::mt19937_64& rng) {
  MotionCase m = GridCase(14, 0.04);
  testing::FallingUFold(14, 7, m.step, 0.01, 0.05, rng, &m.x0, &m.x1);
  return m;
}

// A grid of `len` rows 0.01 m apart (rest) wound into a ramp of 2.3 turns (radius 0.1 m plus
// the column's x) rising 0.002 m per radian at x0 and falling as much at x1: its last turn passes
// through its first within the step.
void SpiralRamp(std::span<const Vec3> rest, int32_t len, std::vector<Vec3>* x0,
                std::vector<Vec3>* x1) {
  const double pi = std::numbers::pi;
  x0->resize(rest.size());
  x1->resize(rest.size());
  for (size_t i = 0; i < rest.size(); ++i) {
    const double r = 0.1 + rest[i].x();
    const double theta = 2.3 * 2 * pi * rest[i].y() / ((len - 1) * 0.01);
    (*x0)[i] = Vec3(r * std::cos(theta), r * std::sin(theta), 0.002 * theta);
    (*x1)[i] = Vec3(r * std::cos(theta), r * std::sin(theta), -0.002 * theta);
  }
}

TEST(SelfNormalCones, UpdatedCandidatesMissNothingAgainstAllPairs) {
  const double pi = std::numbers::pi;
  std::mt19937_64 rng(2222);
  size_t reference_hits = 0, kept = 0;
  {
    const int32_t w = 16;
    const double step = 0.05, h = 0.002;
    const std::vector<Triangle> tris = MakeGridTriangles(w, w);
    const std::vector<Vec3> rest = SpacedGrid(w, w, step);
    UpdateCheck(rest, HingedGrid(w, 7, step, pi - 10 * pi / 180),
                HingedGrid(w, 7, step, pi + 10 * pi / 180), tris, h, step, "fold through", &rng,
                &reference_hits, &kept);
  }
  // Four wave motions; one under a sanitizer (test_env.h: the all-pairs reference is O(T^2)).
  for (int32_t c = 0; c < (testing::Sanitized() ? 1 : 4); ++c) {
    const MotionCase m = Waves(c, &rng);
    UpdateCheck(m.rest, m.x0, m.x1, m.tris, m.thickness, m.step, "waves " + std::to_string(c), &rng,
                &reference_hits, &kept);
  }
  {
    const MotionCase m = FallingFold(rng);
    UpdateCheck(m.rest, m.x0, m.x1, m.tris, m.thickness, m.step, "falling", &rng, &reference_hits,
                &kept);
  }
  {
    const int32_t w = 5, len = 80;
    const std::vector<Triangle> tris = MakeGridTriangles(w, len);
    const std::vector<Vec3> rest = SpacedGrid(w, len, 0.01);
    std::vector<Vec3> x0, x1;
    SpiralRamp(rest, len, &x0, &x1);
    UpdateCheck(rest, x0, x1, tris, 0.0005, 0.01, "spiral ramp", &rng, &reference_hits, &kept);
  }
  EXPECT_GT(reference_hits, 100u);  // the updated motions do collide
  EXPECT_GT(kept, 100u);            // and the updates kept candidates
}

TEST(SelfNormalCones, FoldedAndFallingClothMissNothingAgainstAllPairs) {
  const double pi = std::numbers::pi;
  size_t reference_hits = 0;
  int32_t culled = 0;
  // A 16 x 16 grid folded from 170 to 190 degrees through itself (every folded primitive hits).
  {
    const int32_t w = 16;
    const double step = 0.05, h = 0.002;
    const std::vector<Triangle> tris = MakeGridTriangles(w, w);
    const std::vector<Vec3> rest = SpacedGrid(w, w, step);
    ConeCheck(rest, HingedGrid(w, 7, step, pi - 10 * pi / 180),
              HingedGrid(w, 7, step, pi + 10 * pi / 180), tris, h, "fold through",
              &reference_hits, &culled);
    // The reference's box prefilter drops no hit of the plain loop over every pair (release only:
    // the plain loop runs the cubic on every pair).
    if (!testing::Sanitized()) {
      AllPairsCcdOptions plain;
      plain.ccd.thickness_m = h;
      const std::vector<Vec3> a = HingedGrid(w, 7, step, pi - 10 * pi / 180);
      const std::vector<Vec3> b = HingedGrid(w, 7, step, pi + 10 * pi / 180);
      ExpectSameHits(AllPairsCcd(a, b, tris, ReferenceOptions(h)), AllPairsCcd(a, b, tris, plain),
                     "prefiltered reference");
    }
    // Folded flat at 1.5 h above the bottom layer, coming down to contact and through it.
    std::vector<Vec3> x0 = HingedGrid(w, 7, step, pi), x1 = x0;
    for (size_t i = 0; i < x0.size(); ++i) {
      if (rest[i].x() > 7 * step + 1e-9) {
        x0[i].z() += 1.5 * h + 0.3 * step;
        x1[i].z() -= 0.5 * h;
      }
    }
    ConeCheck(rest, x0, x1, tris, h, "flat fold closing", &reference_hits, &culled);
    // The same fold at rest (x1 is x0, the same array: SelfBvh's still path, as the proximity
    // pass's broad phase), its top layer 0.5 h above the bottom: every pair across the layers
    // within h is found.
    std::vector<Vec3> still = HingedGrid(w, 7, step, pi);
    for (size_t i = 0; i < still.size(); ++i) {
      if (rest[i].x() > 7 * step + 1e-9) still[i].z() += 0.5 * h;
    }
    size_t still_hits = 0;
    ConeCheck(rest, still, still, tris, h, "flat fold at rest", &still_hits, &culled);
    EXPECT_GT(still_hits, 100u);
    reference_hits += still_hits;
  }
  // Random smooth waves with a crumple, moving a little (mostly culled, some folds).
  // Under a sanitizer the first and the last only (all six drawn, so the rest of the test sees the
  // same random numbers; test_env.h: the all-pairs reference is O(T^2)).
  std::mt19937_64 rng(2210);
  for (int32_t c = 0; c < 6; ++c) {
    const MotionCase m = Waves(c, &rng);
    if (testing::Sanitized() && c != 0 && c != 5) continue;
    ConeCheck(m.rest, m.x0, m.x1, m.tris, m.thickness, "waves " + std::to_string(c),
              &reference_hits, &culled);
  }
  // A U-fold whose top layer falls 5 cm through the bottom within the step.
  {
    const MotionCase m = FallingFold(rng);
    ConeCheck(m.rest, m.x0, m.x1, m.tris, m.thickness, "falling", &reference_hits, &culled);
  }
  // A strip twisted by a full turn along its length, twisting further in the step.
  {
    const int32_t w = 6, len = 40;
    const double step = 0.01, h = 0.0005;
    const std::vector<Triangle> tris = MakeGridTriangles(w, len);
    const std::vector<Vec3> rest = SpacedGrid(w, len, step);
    std::vector<Vec3> x0 = rest, x1 = rest;
    for (size_t i = 0; i < rest.size(); ++i) {
      const double u = rest[i].x() - 0.5 * (w - 1) * step, v = rest[i].y();
      const double a0 = 2 * pi * v / (len * step), a1 = 1.3 * a0;
      x0[i] = Vec3(u * std::cos(a0), v, u * std::sin(a0));
      x1[i] = Vec3(u * std::cos(a1), v, u * std::sin(a1));
    }
    ConeCheck(rest, x0, x1, tris, h, "twist", &reference_hits, &culled);
  }
  // A spiral ramp (an annular strip over 2.3 turns, rising 2 mm per radian) whose pitch turns
  // over within the step, so that its last 0.3 turn passes through its first. Its normals stay
  // within a few degrees of +z: only the contour rule (star-shaped, winding once) keeps the whole
  // ramp from being skipped.
  {
    const int32_t w = 5, len = 80;
    const std::vector<Triangle> tris = MakeGridTriangles(w, len);
    const std::vector<Vec3> rest = SpacedGrid(w, len, 0.01);
    std::vector<Vec3> x0, x1;
    SpiralRamp(rest, len, &x0, &x1);
    size_t ramp_hits = 0;
    ConeCheck(rest, x0, x1, tris, 0.0005, "spiral ramp", &ramp_hits, &culled);
    EXPECT_GT(ramp_hits, 10u);
    reference_hits += ramp_hits;
  }
  EXPECT_GT(reference_hits, 100u);  // the cases do collide
  EXPECT_GT(culled, 20);            // and the cones did skip patches
}

// A flat cloth compressed in its own plane: all its normals are one, so a cone certificate that
// only excluded contact would skip the whole patch, yet a row squeezed to within the thickness of
// the row before brings vertices within the thickness of triangles they are not corners of (the
// 64 x 64 curtain released flat does this near its top edge: `felt bench self-collision --case
// curtain` found 5 such pairs missed in one frame before the fatness rule). The certificate also
// needs every triangle's altitude, bounded over the step, at least twice the thickness over the
// cone's cosine (SelfBvh::SelfFat); then the culled detection equals the reference.
TEST(SelfNormalCones, InPlaneCompressionMissesNothingAgainstAllPairs) {
  const int32_t w = 12;
  const double step = 0.01, h = 0.001;
  const std::vector<Triangle> tris = MakeGridTriangles(w, w);
  const std::vector<Vec3> rest = SpacedGrid(w, w, step);
  size_t reference_hits = 0;
  int32_t culled = 0;
  for (const double gap : {0.5 * h, 0.9 * h, 1.5 * h}) {
    // Rows 6 and up slide toward row 5 until they are `gap` from it, in the plane (z stays 0),
    // columns 3 to 8 only (a local squeeze), with a sideways drift.
    std::vector<Vec3> x1 = rest;
    for (size_t i = 0; i < rest.size(); ++i) {
      const int32_t col = static_cast<int32_t>(i) % w, row = static_cast<int32_t>(i) / w;
      if (row >= 6 && col >= 3 && col <= 8) x1[i] += Vec3(0.1 * step, -(step - gap), 0.0);
    }
    size_t hits = 0;
    ConeCheck(rest, rest, x1, tris, h, "squeezed to " + std::to_string(gap), &hits, &culled);
    if (gap < h) {
      EXPECT_GT(hits, 0u) << "gap " << gap;  // the case collides
    }
    reference_hits += hits;
  }
  EXPECT_GT(reference_hits, 0u);
}

// The leaves' cones are computed four at a time with AVX2 (SelfLeafConesAvx2) and one at a time
// at the portable level and in the incremental refit (RefitLeaf): every level must give every
// node's cone and fat bound bit for bit, moving and at rest, on grids whose leaf counts are and
// are not multiples of four.
TEST(SelfNormalCones, LeafConesGiveThePortableBitsAtEveryLevel) {
  std::mt19937_64 rng(77);
  for (int32_t c : {0, 3}) {
    MotionCase m = Waves(c, &rng);
    for (const int32_t rows : {20, 7}) {
      const int32_t w = 20;
      const size_t n = static_cast<size_t>(w * rows);
      const std::vector<Triangle> tris = MakeGridTriangles(w, rows);
      const std::vector<Vec3> rest(m.rest.begin(), m.rest.begin() + n);
      const std::vector<Vec3> x0(m.x0.begin(), m.x0.begin() + n);
      const std::vector<Vec3> x1(m.x1.begin(), m.x1.begin() + n);
      SelfBroadPhaseOptions options;
      options.normal_cones = true;
      SelfBvh bvh(tris, rest, options);
      const auto cones_at = [&](SimdLevel level, bool still) {
        LimitSimdLevel(level);
        bvh.FindCandidates(x0, still ? std::span<const Vec3>(x0) : std::span<const Vec3>(x1),
                           m.thickness);
        LimitSimdLevel(kWidestSimdLevel);
        std::vector<double> all;
        for (int32_t node = 0; node < bvh.num_nodes(); ++node) {
          const std::array<double, 7> cone = bvh.ConeOf(node);
          all.insert(all.end(), cone.begin(), cone.end());
        }
        return all;
      };
      for (const bool still : {false, true}) {
        const std::vector<double> portable = cones_at(SimdLevel::kPortable, still);
        for (SimdLevel level : {SimdLevel::kAvx2, SimdLevel::kAvx512}) {
          if (level > CpuSimdLevel()) continue;
          const std::vector<double> got = cones_at(level, still);
          ASSERT_EQ(got.size(), portable.size());
          EXPECT_EQ(std::memcmp(got.data(), portable.data(), got.size() * sizeof(double)), 0)
              << "waves " << c << ", " << rows << " rows, still " << still << ", level "
              << static_cast<int>(level);
        }
      }
    }
  }
}

}  // namespace
}  // namespace felt
