// Snapshot velocities as the frame's motion (sim_loop/frame_motion.h).
#include "sim_loop/frame_motion.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "scene/scene_file.h"
#include "sim_loop/cloth.h"
#include "sim_loop/cloth_scene.h"
#include "sim_loop/snapshot.h"
#include "tests/alloc_counter.h"

namespace felt {
namespace {

constexpr double kMotionFrame_s = 1.0 / 60.0;

ClothModel Curtain(double drag_scale) {
  const SceneDocument doc =
      LoadSceneDocument(std::string(FELT_SOURCE_DIR) + "/scenes/curtain.toml");
  SimSpec spec = ParseSimSpec(doc);
  spec.cloth.drag_N_s_per_m *= drag_scale;
  return BuildClothModel(spec);
}

double MaxSpeed(const std::vector<Vec3>& v) {
  double m = 0.0;
  for (const Vec3& s : v) m = std::max(m, s.norm());
  return m;
}

TEST(FrameMotionTest, VelocitiesAreTheFramesDisplacementOverItsDurationWithoutAllocating) {
  const ClothModel model = Curtain(1.0);
  ClothState state = MakeClothState(model);
  ClothSnapshot s = MakeClothSnapshot(model, state, CollisionStructureSpec{});
  std::vector<Vec3> x_start(state.x.size());
  std::vector<Vec3> v(state.x.size());
  // The released curtain falls and swings: every free particle moves.
  for (int f = 0; f < 10; ++f) StepFrame(model, {}, kMotionFrame_s, &state);
  x_start = state.x;
  StepFrame(model, {}, kMotionFrame_s, &state);
  AllocationGuard guard;
  FillSnapshotWithFrameMotion(state, x_start, kMotionFrame_s, 11, v, &s);
  EXPECT_EQ(guard.allocations(), 0u);
  EXPECT_EQ(s.frame, 11u);
  EXPECT_EQ(s.time_s, state.time_s);
  EXPECT_EQ(s.frame_dt_s, kMotionFrame_s);
  EXPECT_EQ(s.x, state.x);
  EXPECT_EQ(s.normals, state.normals);
  double max_speed = 0.0;
  for (size_t i = 0; i < s.v.size(); ++i) {
    EXPECT_EQ(s.v[i], Vec3((state.x[i] - x_start[i]) * (1.0 / kMotionFrame_s))) << i;
    max_speed = std::max(max_speed, s.v[i].norm());
  }
  EXPECT_GT(max_speed, 0.0);
  EXPECT_EQ(s.max_speed_m_per_s, max_speed);
  // The frame's largest displacement, as MaxDisplacement from the frame's start gives it.
  ClothState start = state;
  start.x = x_start;
  const ClothSnapshot before = MakeClothSnapshot(model, start, CollisionStructureSpec{});
  EXPECT_GT(s.displacement_from_previous_m, 0.0);
  EXPECT_EQ(s.displacement_from_previous_m, MaxDisplacement(before, s));
  // No elapsed time: no motion.
  FillSnapshotWithFrameMotion(state, x_start, 0.0, 12, v, &s);
  EXPECT_EQ(MaxSpeed(s.v), 0.0);
  EXPECT_EQ(s.max_speed_m_per_s, 0.0);
}

TEST(FrameMotionTest, AClothHeldStillByItsConstraintsPublishesNoMotion) {
  // The curtain hanging at Provot's stretch limit (drag raised so its sway is gone): its
  // particles do not move, but leapfrog's synchronised velocity is h/2 g where the constraints
  // cancel gravity each substep (001 §3.5; 000 slide 9).
  const ClothModel model = Curtain(10.0);
  ClothState state = MakeClothState(model);
  for (int f = 0; f < 600; ++f) StepFrame(model, {}, kMotionFrame_s, &state);
  ClothSnapshot s = MakeClothSnapshot(model, state, CollisionStructureSpec{});
  std::vector<Vec3> x_start = state.x;
  std::vector<Vec3> v(state.x.size());
  StepFrame(model, {}, kMotionFrame_s, &state);
  FillSnapshotWithFrameMotion(state, x_start, kMotionFrame_s, 1, v, &s);
  const double h = 1.0 / (model.frame_rate_hz * model.substeps);
  EXPECT_GT(MaxSpeed(state.v), 0.25 * h * 9.81) << "the state's velocity is not the motion";
  EXPECT_LT(s.max_speed_m_per_s, 0.02 * MaxSpeed(state.v));
}

}  // namespace
}  // namespace felt
