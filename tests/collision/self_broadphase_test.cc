// The self-collision broad phases (spatial hash and BVH self-traversal) against the all-pairs
// references: their candidates are exactly the pairs whose padded swept boxes overlap (checked by
// brute force), a superset of every colliding pair, and SelfCcd's hits equal AllPairsCcd's
// (pair and toi, bitwise) on random deformations of grids, a grid folded through itself, a cloth
// falling onto itself and degenerate inputs (zero motion, coincident vertices, repeated indices).
// Overflow is reported, never silent; stepping does not allocate.
#include "collision/self_broadphase.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>
#include <random>
#include <set>
#include <stdexcept>
#include <tuple>
#include <vector>

#include "collision/self_bvox.h"
#include "tests/alloc_counter.h"
#include "tests/collision/collision_test_util.h"

namespace felt {
namespace {

using PairKey = std::tuple<int, int32_t, int32_t>;  // (kind, first, second)

using testing::HingedGrid;
using testing::SpacedGrid;

// The pairs whose padded swept boxes overlap, by brute force (the broad phases' specification).
std::set<PairKey> BruteForceCandidates(std::span<const Vec3> x0, std::span<const Vec3> x1,
                                       std::span<const Triangle> tris, double h) {
  const double pad = 0.5 * h * (1.0 + 1e-5);
  const auto box = [&](std::initializer_list<int32_t> ids) {
    Vec3 lo = x0[*ids.begin()], hi = lo;
    for (int32_t i : ids) {
      lo = lo.cwiseMin(x0[i]).cwiseMin(x1[i]);
      hi = hi.cwiseMax(x0[i]).cwiseMax(x1[i]);
    }
    return std::pair<Vec3, Vec3>(lo.array() - pad, hi.array() + pad);
  };
  const auto overlap = [](const std::pair<Vec3, Vec3>& a, const std::pair<Vec3, Vec3>& b) {
    return (a.first.array() <= b.second.array()).all() &&
           (b.first.array() <= a.second.array()).all();
  };
  std::set<int32_t> used;
  for (const Triangle& t : tris) used.insert(t.begin(), t.end());
  std::set<PairKey> out;
  for (int32_t v : used) {
    for (size_t ti = 0; ti < tris.size(); ++ti) {
      const Triangle& t = tris[ti];
      if (t[0] == v || t[1] == v || t[2] == v) continue;
      if (overlap(box({v}), box({t[0], t[1], t[2]}))) {
        out.insert({0, v, static_cast<int32_t>(ti)});
      }
    }
  }
  const std::vector<MeshEdge> edges = MeshEdges(tris);
  for (size_t i = 0; i < edges.size(); ++i) {
    for (size_t j = i + 1; j < edges.size(); ++j) {
      const MeshEdge &e = edges[i], &f = edges[j];
      if (e[0] == f[0] || e[0] == f[1] || e[1] == f[0] || e[1] == f[1]) continue;
      if (overlap(box({e[0], e[1]}), box({f[0], f[1]}))) {
        out.insert({1, static_cast<int32_t>(i), static_cast<int32_t>(j)});
      }
    }
  }
  return out;
}

struct Method {
  const char* name;
  std::unique_ptr<SelfBroadPhase> (*make)(std::span<const Triangle>, std::span<const Vec3>,
                                          const SelfBroadPhaseOptions&);
};

const Method kMethods[] = {
    {"hash",
     [](std::span<const Triangle> t, std::span<const Vec3> x, const SelfBroadPhaseOptions& o) {
       return std::unique_ptr<SelfBroadPhase>(new SelfSpatialHash(t, x, o));
     }},
    {"bvh",
     [](std::span<const Triangle> t, std::span<const Vec3> x, const SelfBroadPhaseOptions& o) {
       return std::unique_ptr<SelfBroadPhase>(new SelfBvh(t, x, o));
     }},
    {"bvox_aabb",
     [](std::span<const Triangle> t, std::span<const Vec3> x, const SelfBroadPhaseOptions& o) {
       return std::unique_ptr<SelfBroadPhase>(new SelfBvox(t, x, o));
     }},
};

// Checks, for every method (and the hash with tiny cell budgets, forcing its fallback path):
// candidates are unique, equal to the brute-force box set, a superset of the reference's hits,
// and SelfCcd's hits equal AllPairsCcd's exactly. Both the coplanarity and separation tests.
// Stores the number of reference hits of the collision test in *num_reference_hits.
void CheckAgainstReference(std::span<const Vec3> rest, std::span<const Vec3> x0,
                           std::span<const Vec3> x1, std::span<const Triangle> tris, double h,
                           const std::string& label, size_t* num_reference_hits = nullptr) {
  const std::set<PairKey> boxes = BruteForceCandidates(x0, x1, tris, h);
  for (bool separation : {false, true}) {
    AllPairsCcdOptions options;
    options.ccd.thickness_m = h;
    options.minimal_separation = separation;
    const std::vector<CcdPairHit> ref = AllPairsCcd(x0, x1, tris, options);
    if (!separation && num_reference_hits != nullptr) *num_reference_hits = ref.size();
    for (const Method& m : kMethods) {
      for (int32_t variant = 0; variant < 2; ++variant) {
        SelfBroadPhaseOptions bo;
        // Exactly as many as there are (dense degenerate cases exceed the default, and report it).
        bo.max_candidates = std::max<int64_t>(1, std::ssize(boxes));
        if (variant == 1) {
          if (std::string(m.name) != "hash") continue;
          bo.max_cells_per_primitive = 2;  // many primitives tested against all others
          bo.max_entries = 50;
        }
        const std::string where = label + " " + m.name + " variant " + std::to_string(variant) +
                                  (separation ? " separation" : " ccd");
        std::unique_ptr<SelfBroadPhase> broad = m.make(tris, rest, bo);
        std::vector<CcdPairHit> hits;
        hits.reserve(ref.size() + 16);
        const SelfCcdStats st = SelfCcd(broad.get(), x0, x1, options, &hits);
        ASSERT_FALSE(st.overflow) << where;
        if (variant == 1) {
          EXPECT_GT(st.broad.oversized, 0) << where;  // the fallback path ran
        }
        // Candidates: unique and exactly the overlapping boxes.
        std::set<PairKey> cand;
        for (const SelfCandidate& c : broad->candidates()) {
          EXPECT_TRUE(cand.insert({static_cast<int>(c.kind), c.first, c.second}).second)
              << where << " duplicate candidate";
        }
        EXPECT_EQ(cand, boxes) << where;
        EXPECT_EQ(st.broad.vertex_triangle + st.broad.edge_edge, static_cast<int64_t>(cand.size()))
            << where;
        // Superset of the colliding pairs.
        for (const CcdPairHit& r : ref) {
          EXPECT_TRUE(cand.count({static_cast<int>(r.kind), r.first, r.second}))
              << where << " missed candidate " << r.first << " " << r.second;
        }
        // Same hits, same order, same toi bit for bit.
        ASSERT_EQ(hits.size(), ref.size()) << where;
        for (size_t i = 0; i < ref.size(); ++i) {
          EXPECT_EQ(hits[i].kind, ref[i].kind) << where;
          EXPECT_EQ(hits[i].first, ref[i].first) << where;
          EXPECT_EQ(hits[i].second, ref[i].second) << where;
          EXPECT_EQ(hits[i].vertices, ref[i].vertices) << where;
          EXPECT_EQ(hits[i].toi, ref[i].toi) << where;
          EXPECT_EQ(hits[i].capped, ref[i].capped) << where;
          EXPECT_EQ(hits[i].weights, ref[i].weights) << where;
        }
      }
    }
  }
}

#if defined(__SANITIZE_ADDRESS__)
constexpr int kRandomCases = 6;
#else
constexpr int kRandomCases = 24;
#endif

TEST(SelfBroadPhaseTest, RandomDeformationsOfGridsMatchAllPairs) {
  std::mt19937_64 rng(22);
  size_t total_hits = 0;
  for (int c = 0; c < kRandomCases; ++c) {
    std::uniform_int_distribution<int32_t> size(3, 10);
    const int32_t w = size(rng), hgt = size(rng);
    const double step = 0.05;
    const double h = step * std::uniform_real_distribution<double>(0.02, 0.5)(rng);
    const double jitter = step * std::uniform_real_distribution<double>(0.1, 1.5)(rng);
    const double motion = step * std::uniform_real_distribution<double>(0.1, 2.0)(rng);
    std::normal_distribution<double> n01(0.0, 1.0);
    const std::vector<Triangle> tris = MakeGridTriangles(w, hgt);
    const std::vector<Vec3> rest = SpacedGrid(w, hgt, step);
    std::vector<Vec3> x0 = rest, x1 = rest;
    for (size_t i = 0; i < x0.size(); ++i) {
      x0[i] += jitter * Vec3(n01(rng), n01(rng), n01(rng));
      x1[i] = x0[i] + motion * Vec3(n01(rng), n01(rng), n01(rng));
    }
    size_t n = 0;
    CheckAgainstReference(rest, x0, x1, tris, h, "random case " + std::to_string(c), &n);
    total_hits += n;
  }
  EXPECT_GT(total_hits, 0u);  // the cases do collide
}

TEST(SelfBroadPhaseTest, GridFoldedThroughItselfMatchesAllPairs) {
  const int32_t w = 12;
  const double step = 0.05, h = 0.002;
  const double pi = std::numbers::pi;
  const std::vector<Triangle> tris = MakeGridTriangles(w, w);
  const std::vector<Vec3> rest = SpacedGrid(w, w, step);
  const std::vector<Vec3> x0 = HingedGrid(w, 5, step, pi - 10 * pi / 180);
  const std::vector<Vec3> x1 = HingedGrid(w, 5, step, pi + 10 * pi / 180);
  size_t n = 0;
  CheckAgainstReference(rest, x0, x1, tris, h, "fold", &n);
  EXPECT_GT(n, 20u);
}

TEST(SelfBroadPhaseTest, ClothFallingOntoItselfMatchesAllPairs) {
  // A U-fold: the columns past the hinge lie mirrored over the others at height `gap` and fall
  // through them by `fall` within the step (10 m/s over a 5 ms substep), slightly crumpled.
  const int32_t w = 12, hinge = 6;
  const double step = 0.04, h = 0.001, gap = 0.01, fall = 0.05;
  std::mt19937_64 rng(7);
  const std::vector<Triangle> tris = MakeGridTriangles(w, w);
  const std::vector<Vec3> rest = SpacedGrid(w, w, step);
  std::vector<Vec3> x0, x1;
  testing::FallingUFold(w, hinge, step, gap, fall, rng, &x0, &x1);
  size_t n = 0;
  CheckAgainstReference(rest, x0, x1, tris, h, "falling", &n);
  EXPECT_GT(n, 20u);
}

TEST(SelfBroadPhaseTest, DegenerateInputsMatchAllPairs) {
  const int32_t w = 7;
  const double step = 0.05, h = 0.002;
  const std::vector<Triangle> grid = MakeGridTriangles(w, w);
  const std::vector<Vec3> rest = SpacedGrid(w, w, step);
  // Zero motion, flat and folded within h (static layers: only the separation test hits).
  CheckAgainstReference(rest, rest, rest, grid, h, "zero motion flat");
  const double pi = std::numbers::pi;
  const std::vector<Vec3> flat_fold = HingedGrid(w, 3, step, pi);
  CheckAgainstReference(rest, flat_fold, flat_fold, grid, h, "zero motion folded");
  // Coincident vertices: the grid collapsed onto a coarse lattice (many vertices at one point),
  // then moved.
  std::vector<Vec3> x0 = rest, x1 = rest;
  for (size_t i = 0; i < rest.size(); ++i) {
    x0[i] = (rest[i] / (2.5 * step)).array().floor() * (2.5 * step);
    x1[i] = x0[i] + Vec3(0.0, 0.0, (i % 3 == 0) ? 0.03 : -0.02);
  }
  CheckAgainstReference(rest, x0, x1, grid, h, "coincident");
  // Everything at one point, static and moving.
  std::vector<Vec3> point(rest.size(), Vec3(0.1, 0.2, 0.3));
  CheckAgainstReference(rest, point, point, grid, h, "one point");
  // Repeated indices (a degenerate triangle) added to the mesh.
  std::vector<Triangle> with_degenerate = grid;
  with_degenerate.push_back({3, 3, 30});
  with_degenerate.push_back({10, 10, 10});
  CheckAgainstReference(rest, x0, x1, with_degenerate, h, "repeated indices");
  // An empty mesh.
  std::vector<CcdPairHit> hits;
  for (const Method& m : kMethods) {
    std::unique_ptr<SelfBroadPhase> broad = m.make({}, rest, {});
    const SelfCcdStats st = SelfCcd(broad.get(), rest, rest, {}, &hits);
    EXPECT_EQ(st.hits, 0) << m.name;
    EXPECT_FALSE(st.overflow) << m.name;
  }
}

TEST(SelfBroadPhaseTest, LargerGridsGiveTheBoxSetAndTheSameHitsByEveryMethod) {
  // Deeper trees and fuller tables than the cases above; the all-pairs narrow phase would be too
  // slow here, so the candidates are checked against the brute-force box set and every method's
  // hits against the first's.
  const int32_t w = 40;
  const double step = 0.02, h = 0.001, pi = std::numbers::pi;
  const std::vector<Triangle> tris = MakeGridTriangles(w, w);
  const std::vector<Vec3> rest = SpacedGrid(w, w, step);
  std::vector<Vec3> x0 = HingedGrid(w, 19, step, pi - 0.1);
  std::vector<Vec3> x1 = HingedGrid(w, 19, step, pi + 0.1);
  for (size_t i = 0; i < x0.size(); ++i) {
    const double wave = 0.3 * step * std::sin(0.7 * static_cast<double>(i));
    x0[i].z() += wave;
    x1[i].z() += 0.5 * wave;
  }
  const std::set<PairKey> boxes = BruteForceCandidates(x0, x1, tris, h);
  AllPairsCcdOptions options;
  options.ccd.thickness_m = h;
  std::vector<std::vector<CcdPairHit>> results;
  for (const Method& m : kMethods) {
    std::unique_ptr<SelfBroadPhase> broad = m.make(tris, rest, {});
    std::vector<CcdPairHit> hits;
    hits.reserve(boxes.size());
    const SelfCcdStats st = SelfCcd(broad.get(), x0, x1, options, &hits);
    ASSERT_FALSE(st.overflow) << m.name;
    std::set<PairKey> cand;
    for (const SelfCandidate& c : broad->candidates()) {
      cand.insert({static_cast<int>(c.kind), c.first, c.second});
    }
    EXPECT_EQ(cand.size(), broad->candidates().size()) << m.name;
    EXPECT_EQ(cand, boxes) << m.name;
    results.push_back(hits);
  }
  EXPECT_GT(results[0].size(), 100u);
  for (size_t m = 1; m < results.size(); ++m) {
    ASSERT_EQ(results[0].size(), results[m].size()) << kMethods[m].name;
    for (size_t i = 0; i < results[0].size(); ++i) {
      EXPECT_EQ(results[0][i].first, results[m][i].first) << kMethods[m].name;
      EXPECT_EQ(results[0][i].second, results[m][i].second) << kMethods[m].name;
      EXPECT_EQ(results[0][i].toi, results[m][i].toi) << kMethods[m].name;
    }
  }
}

TEST(SelfBroadPhaseTest, OverflowIsReportedNeverSilent) {
  const int32_t w = 8;
  const double step = 0.05, h = 0.002, pi = std::numbers::pi;
  const std::vector<Triangle> tris = MakeGridTriangles(w, w);
  const std::vector<Vec3> rest = SpacedGrid(w, w, step);
  const std::vector<Vec3> x0 = HingedGrid(w, 4, step, pi - 0.2);
  const std::vector<Vec3> x1 = HingedGrid(w, 4, step, pi + 0.2);
  AllPairsCcdOptions options;
  options.ccd.thickness_m = h;
  const std::vector<CcdPairHit> ref = AllPairsCcd(x0, x1, tris, options);
  ASSERT_GT(ref.size(), 4u);
  for (const Method& m : kMethods) {
    // Candidate buffer too small: overflow, full counts, no hits claimed complete.
    SelfBroadPhaseOptions small;
    small.max_candidates = 10;
    std::unique_ptr<SelfBroadPhase> broad = m.make(tris, rest, small);
    const SelfBroadPhaseStats bs = broad->FindCandidates(x0, x1, h);
    EXPECT_TRUE(bs.overflow) << m.name;
    EXPECT_EQ(broad->candidates().size(), 10u) << m.name;
    EXPECT_GT(bs.vertex_triangle + bs.edge_edge, 10) << m.name;
    std::vector<CcdPairHit> hits;
    hits.reserve(1000);
    EXPECT_TRUE(SelfCcd(broad.get(), x0, x1, options, &hits).overflow) << m.name;
    // Hit buffer too small: overflow, the total counted.
    std::unique_ptr<SelfBroadPhase> roomy = m.make(tris, rest, {});
    std::vector<CcdPairHit> few;
    few.reserve(2);
    const size_t capacity = few.capacity();
    const SelfCcdStats st = SelfCcd(roomy.get(), x0, x1, options, &few);
    EXPECT_TRUE(st.overflow) << m.name;
    EXPECT_EQ(st.hits, static_cast<int64_t>(ref.size())) << m.name;
    EXPECT_EQ(few.capacity(), capacity) << m.name;
  }
}

TEST(SelfBroadPhaseTest, SteppingDoesNotAllocate) {
  const int32_t w = 16;
  const double step = 0.05, h = 0.002, pi = std::numbers::pi;
  const std::vector<Triangle> tris = MakeGridTriangles(w, w);
  const std::vector<Vec3> rest = SpacedGrid(w, w, step);
  const std::vector<Vec3> x0 = HingedGrid(w, 8, step, pi - 0.2);
  const std::vector<Vec3> x1 = HingedGrid(w, 8, step, pi + 0.2);
  AllPairsCcdOptions options;
  options.ccd.thickness_m = h;
  for (const Method& m : kMethods) {
    std::unique_ptr<SelfBroadPhase> broad = m.make(tris, rest, {});
    std::vector<CcdPairHit> hits;
    hits.reserve(100000);
    AllocationGuard guard;
    const SelfCcdStats st = SelfCcd(broad.get(), x0, x1, options, &hits);
    SelfCcd(broad.get(), rest, rest, options, &hits);
    EXPECT_EQ(guard.allocations(), 0u) << m.name;
    EXPECT_GT(st.hits, 0) << m.name;
  }
}

TEST(SelfBroadPhaseTest, BadInputThrowsNamingTheProblem) {
  const std::vector<Vec3> x = SpacedGrid(3, 3, 0.1);
  const std::vector<Triangle> bad = {{0, 1, 9}};
  for (const Method& m : kMethods) {
    try {
      m.make(bad, x, {});
      ADD_FAILURE() << m.name << ": no throw";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("index 9 out of range"), std::string::npos) << e.what();
    }
  }
  SelfBroadPhaseOptions o;
  o.max_cells_per_primitive = 0;
  try {
    SelfSpatialHash hash(MakeGridTriangles(3, 3), x, o);
    ADD_FAILURE() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_cells_per_primitive"), std::string::npos);
  }
}


TEST(SelfBvoxTest, VoxelSplitFollowsBaciuAndWongsEquations) {
  using Split = std::array<int32_t, 3>;
  // Eq. (3): a long box (b_x >= 2^(d-1) b_y) is cut along its length only.
  EXPECT_EQ(SelfBvox::VoxelSplit(Vec3(8, 1, 1), 3), (Split{3, 0, 0}));
  EXPECT_EQ(SelfBvox::VoxelSplit(Vec3(1, 0, 0), 5), (Split{5, 0, 0}));
  // Eq. (4): a flat square, n_x = floor((log2(b_x / b_y) + d + 1) / 2), n_y = d - n_x, while
  // b_y / 2^(n_y - 1) >= b_z; the axes in any order.
  EXPECT_EQ(SelfBvox::VoxelSplit(Vec3(1, 1, 0.01), 4), (Split{2, 2, 0}));
  EXPECT_EQ(SelfBvox::VoxelSplit(Vec3(1, 0.01, 1), 4), (Split{2, 0, 2}));
  EXPECT_EQ(SelfBvox::VoxelSplit(Vec3(0.01, 4, 1), 4), (Split{0, 3, 1}));
  // The cube at d = 3 still meets eq. (4)'s condition (b_y / 2^0 = b_z): (2, 1, 0) as written.
  EXPECT_EQ(SelfBvox::VoxelSplit(Vec3(1, 1, 1), 3), (Split{2, 1, 0}));
  // Eq. (5): the cube at d = 6, floor((log2(b_x^2 / (b_y b_z)) + d + 2) / 3) each.
  EXPECT_EQ(SelfBvox::VoxelSplit(Vec3(1, 1, 1), 6), (Split{2, 2, 2}));
  // Every split is d cuts, none negative, whatever the box (not a number included).
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> side(-6.0, 2.0);
  for (int i = 0; i < 2000; ++i) {
    const Vec3 b(std::pow(10.0, side(rng)), std::pow(10.0, side(rng)), std::pow(10.0, side(rng)));
    const int32_t d = 1 + i % 20;
    const Split n = SelfBvox::VoxelSplit(b, d);
    EXPECT_EQ(n[0] + n[1] + n[2], d) << b.transpose() << " d " << d;
    EXPECT_GE(std::min({n[0], n[1], n[2]}), 0) << b.transpose() << " d " << d;
  }
  const Split nan = SelfBvox::VoxelSplit(Vec3(std::nan(""), 1, 1), 4);
  EXPECT_EQ(nan[0] + nan[1] + nan[2], 4);
}

TEST(SelfBvoxTest, TheTreeIsBuiltFromVoxelsAndSkipsNonFiniteTriangles) {
  const int32_t w = 16;
  const double step = 0.05, h = 0.002, pi = std::numbers::pi;
  const std::vector<Triangle> tris = MakeGridTriangles(w, w);
  const std::vector<Vec3> rest = SpacedGrid(w, w, step);
  std::vector<Vec3> x0 = HingedGrid(w, 8, step, pi - 0.2);
  std::vector<Vec3> x1 = HingedGrid(w, 8, step, pi + 0.2);
  SelfBvox bvox(tris, rest);
  const SelfBroadPhaseStats full = bvox.FindCandidates(x0, x1, h);
  const int32_t t = static_cast<int32_t>(tris.size());  // 450: ceil(log2) = 9 levels at most
  EXPECT_LE(bvox.levels(), 9);
  EXPECT_GE(bvox.levels(), 1);
  EXPECT_GT(bvox.num_inner_nodes(), 0);
  EXPECT_LT(bvox.num_inner_nodes(), t);  // every inner node has two children or more
  EXPECT_EQ(bvox.num_nodes(), t + bvox.num_inner_nodes());
  // A vertex that is not a number: its triangles are left out, the rest is still found (a subset
  // of the box set, which holds no pair with a box that is not a number).
  x0[40] = x1[40] = Vec3::Constant(std::nan(""));
  const std::set<PairKey> boxes = BruteForceCandidates(x0, x1, tris, h);
  const SelfBroadPhaseStats some = bvox.FindCandidates(x0, x1, h);
  EXPECT_FALSE(some.overflow);
  // Left out: the triangles whose box the NaN reached (a min or max with a NaN as its first
  // argument; Eigen's cwiseMin keeps the other argument otherwise).
  EXPECT_LT(bvox.num_nodes(), t + bvox.num_inner_nodes());
  EXPECT_GT(some.vertex_triangle + some.edge_edge, 0);
  EXPECT_LT(some.vertex_triangle + some.edge_edge, full.vertex_triangle + full.edge_edge);
  for (const SelfCandidate& c : bvox.candidates()) {
    EXPECT_TRUE(boxes.count({static_cast<int>(c.kind), c.first, c.second}))
        << c.first << " " << c.second;
  }
}


TEST(SelfBvoxTest, FarApartFiniteCoordinatesStillSplitTheTree) {
  // Two halves of a cloth 2e308 m apart: the root box's sides overflow a double, its halves do
  // not (SelfBvox works in halves), so the voxels still part the halves and the candidates are
  // still the box set.
  const int32_t w = 8;
  const double h = 0.002;
  const std::vector<Triangle> tris = MakeGridTriangles(w, w);
  const std::vector<Vec3> rest = SpacedGrid(w, w, 0.05);
  std::vector<Vec3> x0(rest.size());
  for (size_t i = 0; i < x0.size(); ++i) {  // the grid in the y-z plane, its halves at x = +-1e308
    x0[i] = Vec3(i < x0.size() / 2 ? -1e308 : 1e308, rest[i].x(), rest[i].y());
  }
  const std::vector<Vec3> x1 = x0;
  SelfBvox bvox(tris, rest);
  const SelfBroadPhaseStats st = bvox.FindCandidates(x0, x1, h);
  EXPECT_FALSE(st.overflow);
  EXPECT_GT(bvox.num_inner_nodes(), 1);  // one node holding everything is what overflow gave
  std::set<PairKey> cand;
  for (const SelfCandidate& c : bvox.candidates()) {
    cand.insert({static_cast<int>(c.kind), c.first, c.second});
  }
  EXPECT_EQ(cand, BruteForceCandidates(x0, x1, tris, h));
}

}  // namespace
}  // namespace felt
