// Cost per continuous vertex-triangle and edge-edge test, and per exact triangle-triangle test,
// over large random batches (docs/self_collision.md quotes it). Disabled: timing is not a test.
// Run with
//   build/felt_collision_tests --gtest_also_run_disabled_tests --gtest_filter='CcdTiming.*'
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <functional>
#include <random>
#include <vector>

#include "base/report.h"
#include "collision/ccd.h"
#include "collision/self_intersection.h"

namespace felt {
namespace {

// Median over blocks of `block` calls of the mean cost per call [ns]; `count` gets the number of
// calls that returned true.
double MedianNsPerCall(int32_t calls, int32_t block, const std::function<bool(int32_t)>& call,
                       int64_t* count) {
  std::vector<double> per_call;
  *count = 0;
  for (int32_t start = 0; start + block <= calls; start += block) {
    const auto t0 = std::chrono::steady_clock::now();
    int64_t n = 0;
    for (int32_t i = start; i < start + block; ++i) n += call(i);
    const auto t1 = std::chrono::steady_clock::now();
    *count += n;
    per_call.push_back(std::chrono::duration<double, std::nano>(t1 - t0).count() / block);
  }
  std::nth_element(per_call.begin(), per_call.begin() + per_call.size() / 2, per_call.end());
  return per_call[per_call.size() / 2];
}

struct Batch {
  std::vector<CcdPoints> x0, x1;
};

// Random motions of four points in [-0.5, 0.5]^3 m moving up to 0.3 m per axis, of one kind:
// "random" as drawn, "contact" with the first point (or the edges) meeting the others at a random
// time, "coplanar" with every point in z = 0.
Batch MakeBatch(int32_t n, bool edge_edge, const char* kind, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-0.5, 0.5), w(0.0, 1.0);
  const auto p = [&]() -> Vec3 { return Vec3(u(rng), u(rng), u(rng)); };
  Batch b;
  for (int32_t i = 0; i < n; ++i) {
    CcdPoints at = {p(), p(), p(), p()};
    const std::string k = kind;
    if (k == "contact") {
      if (edge_edge) {
        const Vec3 x = at[0] + w(rng) * (at[1] - at[0]);
        const Vec3 d = p();
        const double s = w(rng);
        at[2] = x - s * d;
        at[3] = x + (1 - s) * d;
      } else {
        double a = w(rng), c = w(rng);
        if (a + c > 1) a = 1 - a, c = 1 - c;
        at[0] = at[1] + a * (at[2] - at[1]) + c * (at[3] - at[1]);
      }
    }
    const double ts = w(rng);
    CcdPoints x0, x1;
    for (int j = 0; j < 4; ++j) {
      const Vec3 v = 0.6 * p();
      x0[j] = at[j] - ts * v;
      x1[j] = at[j] + (1 - ts) * v;
      if (k == "coplanar") x0[j].z() = x1[j].z() = 0.0;
    }
    b.x0.push_back(x0);
    b.x1.push_back(x1);
  }
  return b;
}

TEST(CcdTiming, DISABLED_PerTestCost) {
  const report::MachineInfo machine = report::ReadMachineInfo();
  std::printf("host: %s, %ld CPUs, load %s, %s\n", machine.cpu_model.c_str(), machine.cpus_online,
              machine.load_average.c_str(), machine.date_utc.c_str());
  const int32_t n = 200000, block = 500;
  const CcdOptions options{1e-3};
  std::printf("| test | batch | hits | median ns per test |\n|---|---|---:|---:|\n");
  for (const char* kind : {"random", "contact", "coplanar"}) {
    for (bool ee : {false, true}) {
      const Batch b = MakeBatch(n, ee, kind, 22);
      int64_t hits = 0;
      const double ns = MedianNsPerCall(
          n, block,
          [&](int32_t i) {
            return ee ? EdgeEdgeCcd(b.x0[i], b.x1[i], options).hit
                      : VertexTriangleCcd(b.x0[i], b.x1[i], options).hit;
          },
          &hits);
      std::printf("| %s | %s | %lld / %d | %.0f |\n", ee ? "EdgeEdgeCcd" : "VertexTriangleCcd",
                  kind, static_cast<long long>(hits), n, ns);
      const double sep_ns = MedianNsPerCall(
          n, block,
          [&](int32_t i) {
            return ee ? EdgeEdgeSeparation(b.x0[i], b.x1[i], options).hit
                      : VertexTriangleSeparation(b.x0[i], b.x1[i], options).hit;
          },
          &hits);
      std::printf("| %s | %s | %lld / %d | %.0f |\n",
                  ee ? "EdgeEdgeSeparation" : "VertexTriangleSeparation", kind,
                  static_cast<long long>(hits), n, sep_ns);
    }
  }
  // The exact static test, on random pairs of triangles (the first three points at t = 0 and
  // at t = 1) and on exactly coplanar ones.
  for (const char* kind : {"random", "coplanar"}) {
    const Batch b = MakeBatch(n, false, kind, 23);
    int64_t hits = 0;
    const double ns = MedianNsPerCall(
        n, block,
        [&](int32_t i) {
          const CcdPoints& s = b.x0[i];
          const CcdPoints& t = b.x1[i];
          return TrianglesIntersect(s[0], s[1], s[2], t[1], t[2], t[3]);
        },
        &hits);
    std::printf("| TrianglesIntersect | %s | %lld / %d | %.0f |\n", kind,
                static_cast<long long>(hits), n, ns);
  }
  std::printf("load at the end %s\n", report::LoadAverage().c_str());
}

}  // namespace
}  // namespace felt
