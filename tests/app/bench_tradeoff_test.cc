// `felt bench cloth --tradeoff` (bench/cloth_tradeoff.h, bench/bullet_peer.h): the "Felt below
// Bullet" judgement on hand-made points, the Felt settings list, the Bullet curtain's set-up and
// its stretch measurement on tiny grids (when this build has Bullet), and a smoke run of the
// command. Loose, machine-independent bounds only; no timing is asserted.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "bench/bench_util.h"
#include "bench/bullet_peer.h"
#include "bench/cloth_tradeoff.h"
#include "tests/app/felt_process.h"

namespace felt::bench {
namespace {

const std::string kCurtain = std::string(FELT_SOURCE_DIR) + "/scenes/curtain.toml";

TEST(TradeoffFront, KeepsOnlyPointsNoOtherBeatsSortedByCost) {
  const std::vector<CostStretch> points = {{4.0, 1.2},   {1.0, 2.0}, {2.0, 2.5},  // (2, 2.5) beaten
                                           {8.0, 1.2},  // beaten by (4, 1.2)
                                           {16.0, 1.05}, {NAN, 1.0}, {3.0, NAN}};
  const std::vector<CostStretch> front = FeltFront(points);
  ASSERT_EQ(front.size(), 3u);
  EXPECT_EQ(front[0].cost_ms, 1.0);
  EXPECT_EQ(front[1].cost_ms, 4.0);
  EXPECT_EQ(front[2].cost_ms, 16.0);
  for (size_t i = 1; i < front.size(); ++i) {
    EXPECT_LT(front[i - 1].cost_ms, front[i].cost_ms);
    EXPECT_GT(front[i - 1].stretch, front[i].stretch);
  }
  EXPECT_TRUE(FeltFront({}).empty());
}

TEST(TradeoffBelow, MeasuredInterpolatedAndNo) {
  // Felt's front: 1 ms at 1.5, 10 ms at 1.1.
  const std::vector<CostStretch> front = {{1.0, 1.5}, {10.0, 1.1}};

  // A measured Felt point at most as costly and as stretched.
  BelowVerdict v = JudgeBelow(front, {2.0, 1.6});
  EXPECT_EQ(v.by, BelowBy::kMeasured);
  EXPECT_DOUBLE_EQ(v.felt_stretch, 1.5);
  EXPECT_DOUBLE_EQ(v.felt_cost_at_stretch_ms, 1.0);
  EXPECT_EQ(JudgeBelow(front, {1.0, 1.5}).by, BelowBy::kMeasured);  // ties count
  EXPECT_EQ(JudgeBelow(front, {50.0, 1.1}).by, BelowBy::kMeasured);

  // At sqrt(10) ms the line in (log10 cost, stretch) is halfway: 1.3.
  v = JudgeBelow(front, {std::sqrt(10.0), 1.31});
  EXPECT_EQ(v.by, BelowBy::kInterpolated);
  EXPECT_NEAR(v.felt_stretch, 1.3, 1e-12);
  EXPECT_DOUBLE_EQ(v.felt_cost_at_stretch_ms, 10.0);  // the cheapest Felt point as good
  v = JudgeBelow(front, {std::sqrt(10.0), 1.29});
  EXPECT_EQ(v.by, BelowBy::kNo);
  EXPECT_NEAR(v.felt_stretch, 1.3, 1e-12);

  // Cheaper than every Felt point: no, and no Felt stretch at that cost.
  v = JudgeBelow(front, {0.5, 40.0});
  EXPECT_EQ(v.by, BelowBy::kNo);
  EXPECT_TRUE(std::isnan(v.felt_stretch));
  EXPECT_DOUBLE_EQ(v.felt_cost_at_stretch_ms, 1.0);

  // Beyond the costliest Felt point and less stretched than all: no, nothing as good.
  v = JudgeBelow(front, {100.0, 1.05});
  EXPECT_EQ(v.by, BelowBy::kNo);
  EXPECT_DOUBLE_EQ(v.felt_stretch, 1.1);
  EXPECT_TRUE(std::isnan(v.felt_cost_at_stretch_ms));

  // No Felt point at all.
  EXPECT_EQ(JudgeBelow({}, {1.0, 2.0}).by, BelowBy::kNo);
  EXPECT_STREQ(BelowByName(BelowBy::kInterpolated), "interpolated");
}

TEST(TradeoffBelow, ABulletClothThatCameApartIsNotJudged) {
  EXPECT_TRUE(BulletPointJudged(10, 9.0, 2.0));
  EXPECT_FALSE(BulletPointJudged(10, 9.5, 2.0));  // a link longer than the side (9 rest lengths)
  EXPECT_FALSE(BulletPointJudged(10, 2.0, 9.5));
  EXPECT_FALSE(BulletPointJudged(10, NAN, 2.0));
}

TEST(TradeoffSettings, TheShippedSettingOnceAndEveryCurve) {
  TradeoffOptions o;
  o.substeps = {6, 12};
  o.sweeps = {1, 10, 10};  // the scene's 3 is added; the duplicate dropped
  o.small_steps = {6, 12};
  o.limits = {0.05};
  o.sweeps_alone = {3};  // the shipped sweep count without the worklist: not the shipped setting
  const std::vector<FeltSetting> settings = FeltSettings(o, 3);
  int shipped = 0;
  for (const FeltSetting& s : settings) {
    shipped +=
        s.substeps == 0 && s.sweeps == 3 && s.max_elongation == 0.0 && !s.sweeps_alone ? 1 : 0;
  }
  EXPECT_EQ(shipped, 1);
  ASSERT_EQ(settings.size(), 2u + 3u + 2u + 1u + 1u);
  EXPECT_EQ(settings[0].curve, "felt_substeps");
  EXPECT_EQ(settings[0].sweeps, 3);
  EXPECT_EQ(settings[2].curve, "felt_sweeps");
  EXPECT_EQ(settings[3].sweeps, 3);
  EXPECT_EQ(settings[3].max_elongation, 0.0);
  EXPECT_EQ(settings[5].curve, "felt_small_steps");
  EXPECT_EQ(settings[5].sweeps, 1);
  EXPECT_EQ(settings[7].curve, "felt_limit");
  EXPECT_EQ(settings[7].max_elongation, 0.05);
  EXPECT_EQ(settings[8].curve, "felt_sweeps_alone");
  EXPECT_TRUE(settings[8].sweeps_alone);
}

TEST(BulletPeer, SpecFollowsTheCurtain) {
  const SimSpec sim = ResizedCurtain(kCurtain, 4);
  const BulletCurtainSpec b = BulletCurtainFromSim(sim, 10, true);
  EXPECT_EQ(b.width, 4);
  EXPECT_EQ(b.height, 4);
  EXPECT_NEAR(b.spacing_m, 0.496 / 3, 1e-12);
  EXPECT_NEAR(b.particle_mass_kg, 0.1 / 16, 1e-15);
  EXPECT_EQ(b.pinned, (std::vector<int32_t>{0, 3}));  // the two top corners
  EXPECT_EQ(b.gravity_m_per_s2, Vec3(0.0, -9.81, 0.0));
  // Felt's drag rate c / m as a velocity decay per 1/60 s step.
  const double rate = sim.cloth.drag_N_s_per_m / (sim.cloth.mass_kg / 16);
  EXPECT_NEAR(b.velocity_damping, 1.0 - std::exp(-rate / 60.0), 1e-12);
  EXPECT_GT(b.velocity_damping, 0.0);
  EXPECT_LT(b.velocity_damping, 0.05);
  EXPECT_EQ(b.position_iterations, 10);
  EXPECT_TRUE(b.bending);
  EXPECT_THROW(BulletCurtainFromSim(sim, 0, true), std::invalid_argument);
}

// The largest length / rest length over the grid's row and column neighbours, from NodePosition
// (the reference the peer's own measurement is checked against).
double ReferenceStretch(const BulletCurtain& c, int32_t n, double spacing_m) {
  double max_stretch = 1.0;
  for (int32_t row = 0; row < n; ++row) {
    for (int32_t col = 0; col < n; ++col) {
      if (col + 1 < n) {
        max_stretch =
            std::max(max_stretch,
                     (c.NodePosition(col + 1, row) - c.NodePosition(col, row)).norm() / spacing_m);
      }
      if (row + 1 < n) {
        max_stretch =
            std::max(max_stretch,
                     (c.NodePosition(col, row + 1) - c.NodePosition(col, row)).norm() / spacing_m);
      }
    }
  }
  return max_stretch;
}

TEST(BulletPeer, MeasuresStructuralStretchOnATinyGrid) {
  if (!BulletAvailable()) GTEST_SKIP() << BulletMissingReason();
  const int32_t n = 4;
  const SimSpec sim = ResizedCurtain(kCurtain, n);
  BulletCurtainSpec spec = BulletCurtainFromSim(sim, 1, false);
  BulletCurtain one(spec);
  // 24 structural links and one diagonal per cell (9); bending adds the two-apart pairs.
  EXPECT_EQ(one.links(), 24 + 9);
  EXPECT_NEAR(one.MaxStructuralStretch(), 1.0, 1e-6);  // at rest (float nodes)
  const Vec3 top_left = one.NodePosition(0, 0);
  const Vec3 top_right = one.NodePosition(n - 1, 0);
  EXPECT_NEAR(top_left.x(), -0.248, 1e-6);
  EXPECT_NEAR(top_right.x(), 0.248, 1e-6);
  EXPECT_NEAR(one.NodePosition(0, n - 1).y(), 0.25 - 0.496, 1e-6);

  spec.position_iterations = 50;
  BulletCurtain fifty(spec);
  spec.bending = true;
  BulletCurtain bending(spec);
  EXPECT_GT(bending.links(), fifty.links());
  for (int f = 0; f < 60; ++f) {
    one.StepFrame();
    fifty.StepFrame();
    bending.StepFrame();
  }
  // The measurement is the reference's (rest = spacing up to float rounding of the nodes).
  for (const BulletCurtain* c : {&one, &fifty, &bending}) {
    EXPECT_NEAR(c->MaxStructuralStretch(), ReferenceStretch(*c, n, spec.spacing_m), 1e-5);
  }
  // The pins hold; the cloth hangs below them; more iterations stretch it less.
  EXPECT_EQ(one.NodePosition(0, 0), top_left);
  EXPECT_EQ(fifty.NodePosition(n - 1, 0), top_right);
  EXPECT_LT(fifty.NodePosition(1, n - 1).y(), 0.25 - 0.4);
  EXPECT_GT(one.MaxStructuralStretch(), 1.0);
  EXPECT_LT(fifty.MaxStructuralStretch(), one.MaxStructuralStretch());
  EXPECT_LT(fifty.MaxStructuralStretch(), 1.5);
  EXPECT_LT(bending.MaxStructuralStretch(), 1.5);
}

TEST(BulletPeer, WithoutBulletSaysWhy) {
  if (BulletAvailable()) GTEST_SKIP() << "this build has Bullet";
  const BulletCurtainSpec spec = BulletCurtainFromSim(ResizedCurtain(kCurtain, 4), 1, true);
  try {
    BulletCurtain curtain(spec);
    FAIL() << "no throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("libbullet-dev"), std::string::npos) << e.what();
  }
}

// `felt bench cloth --tradeoff --quick` writes its files; with Bullet its rows are in them, without
// it the report says they were skipped and why.
TEST(BenchSmoke, ClothTradeoffQuickWritesItsFiles) {
  const std::filesystem::path dir = std::filesystem::path(::testing::TempDir()) / "felt_tradeoff";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string out = dir.string();
  const test::Outcome outcome =
      test::RunFelt("bench cloth --tradeoff --quick --out " + out + " --json " + out +
                    "/cloth_tradeoff.json --scene " + kCurtain + " --gnuplot-script " +
                    std::string(FELT_SOURCE_DIR) + "/bench/cloth_tradeoff.gp");
  ASSERT_EQ(outcome.exit_code, 0) << outcome.output;
  const std::string json = test::ReadFile(out + "/cloth_tradeoff.json");
  for (const char* key :
       {"command", "machine", "load_average_end", "points", "targets", "curve", "frame_ms_median",
        "cpu_ms_median", "release_max_stretch", "settled_max_stretch", "below_met", "ratio_met"}) {
    EXPECT_NE(json.find(std::string("\"") + key + "\":"), std::string::npos) << key;
  }
  for (const char* curve :
       {"felt_substeps", "felt_sweeps", "felt_small_steps", "felt_limit", "felt_sweeps_alone"}) {
    EXPECT_NE(json.find(std::string("\"curve\": \"") + curve + "\""), std::string::npos) << curve;
  }
  const std::string md = test::ReadFile(out + "/cloth_tradeoff.md");
  EXPECT_EQ(md.rfind("# Cloth speed against stretch", 0), 0u);
  EXPECT_NE(md.find("## Targets (issue 21)"), std::string::npos);
  if (BulletAvailable()) {
    EXPECT_NE(json.find("\"curve\": \"bullet_bending\""), std::string::npos);
    EXPECT_NE(json.find("\"curve\": \"bullet_links\""), std::string::npos);
    EXPECT_NE(md.find("Bullet's setup"), std::string::npos);
  } else {
    EXPECT_NE(md.find("Bullet rows skipped"), std::string::npos);
    EXPECT_NE(outcome.output.find("Bullet rows skipped"), std::string::npos);
  }
  EXPECT_TRUE(std::filesystem::exists(out + "/cloth_tradeoff.csv"));
}

}  // namespace
}  // namespace felt::bench
