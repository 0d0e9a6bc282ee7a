// Disabled timing run of the self-collision broad phases plus the exact narrow phase (SelfCcd) per
// substep, on a 1 m square grid of 64 x 64 and 150 x 150 particles, h = 1 mm: a fold passing
// through itself and a wavy deformation. Prints one row per method and case (median of 7 runs).
// Run: build/felt_collision_tests --gtest_also_run_disabled_tests
//        --gtest_filter='SelfBroadPhaseTiming.*'
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include "collision/self_broadphase.h"

namespace felt {
namespace {

// A w x w grid over [0, 1]^2 m, columns past the middle turned by `angle` [rad] about x = 0.5.
std::vector<Vec3> TimingFold(int32_t w, double angle) {
  std::vector<Vec3> x;
  const double step = 1.0 / (w - 1);
  for (int32_t r = 0; r < w; ++r) {
    for (int32_t c = 0; c < w; ++c) {
      const double d = c * step - 0.5;
      x.emplace_back(d <= 0 ? c * step : 0.5 + d * std::cos(angle), r * step,
                     d <= 0 ? 0.0 : d * std::sin(angle));
    }
  }
  return x;
}

// A w x w grid over [0, 1]^2 m folded flat over x = 0.5, the top layer `gap` [m] above the bottom
// one and shifted by `shift` [m] along x.
std::vector<Vec3> TimingLayers(int32_t w, double gap, double shift) {
  std::vector<Vec3> x;
  const double step = 1.0 / (w - 1);
  for (int32_t r = 0; r < w; ++r) {
    for (int32_t c = 0; c < w; ++c) {
      const double d = c * step - 0.5;
      x.emplace_back(d <= 0 ? c * step : 0.5 - d + shift, r * step, d <= 0 ? 0.0 : gap);
    }
  }
  return x;
}

// A w x w grid over [0, 1]^2 m with waves z = 0.1 sin(6 pi x + phase) sin(4 pi y) m.
std::vector<Vec3> TimingWaves(int32_t w, double phase) {
  std::vector<Vec3> x;
  const double step = 1.0 / (w - 1), pi = std::numbers::pi;
  for (int32_t r = 0; r < w; ++r) {
    for (int32_t c = 0; c < w; ++c) {
      const double px = c * step, py = r * step;
      x.emplace_back(px, py, 0.1 * std::sin(6 * pi * px + phase) * std::sin(4 * pi * py));
    }
  }
  return x;
}

TEST(SelfBroadPhaseTiming, DISABLED_BroadPlusNarrowPerSubstep) {
  const double h = 0.001, pi = std::numbers::pi;
  std::printf("| grid | triangles | case | method | candidates | hits | broad ms | total ms |\n");
  std::printf("|---|---:|---|---|---:|---:|---:|---:|\n");
  for (int32_t w : {64, 150}) {
    const std::vector<Triangle> tris = MakeGridTriangles(w, w);
    const std::vector<Vec3> rest = TimingWaves(w, 0.0);
    struct Case {
      const char* name;
      std::vector<Vec3> x0, x1;
    };
    // The fold passes 4 degrees either side of flat: the top layer through the bottom one (the
    // worst case: every folded primitive collides). Folded layers: the top layer 4 mm above the
    // bottom one comes down to 1.5 mm (h = 1 mm: no contact) while sliding 2 mm. The waves move
    // by a 1/100 of their period (a few mm).
    const Case cases[] = {
        {"fold through itself", TimingFold(w, pi - 4 * pi / 180), TimingFold(w, pi + 4 * pi / 180)},
        {"folded layers settling", TimingLayers(w, 0.004, 0.0), TimingLayers(w, 0.0015, 0.002)},
        {"waves", TimingWaves(w, 0.0), TimingWaves(w, 2 * pi / 100)},
    };
    for (const Case& c : cases) {
      for (int32_t method = 0; method < 2; ++method) {
        std::unique_ptr<SelfBroadPhase> broad;
        if (method == 0) {
          broad = std::make_unique<SelfSpatialHash>(tris, rest);
        } else {
          broad = std::make_unique<SelfBvh>(tris, rest);
        }
        AllPairsCcdOptions options;
        options.ccd.thickness_m = h;
        std::vector<CcdPairHit> hits;
        hits.reserve(1 << 20);
        std::vector<double> broad_ms, total_ms;
        SelfCcdStats st;
        for (int run = 0; run < 7; ++run) {
          const auto t0 = std::chrono::steady_clock::now();
          broad->FindCandidates(c.x0, c.x1, h);
          const auto t1 = std::chrono::steady_clock::now();
          st = SelfCcd(broad.get(), c.x0, c.x1, options, &hits);
          const auto t2 = std::chrono::steady_clock::now();
          broad_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
          total_ms.push_back(std::chrono::duration<double, std::milli>(t2 - t1).count());
        }
        std::sort(broad_ms.begin(), broad_ms.end());
        std::sort(total_ms.begin(), total_ms.end());
        ASSERT_FALSE(st.overflow);
        std::printf("| %d x %d | %zu | %s | %s | %lld | %lld | %.2f | %.2f |\n", w, w, tris.size(),
                    c.name, method == 0 ? "hash" : "bvh",
                    static_cast<long long>(st.broad.vertex_triangle + st.broad.edge_edge),
                    static_cast<long long>(st.hits), broad_ms[3], total_ms[3]);
      }
    }
  }
}

}  // namespace
}  // namespace felt
