// The local patch (sim_loop/cloth_patch.h) on closed-form cases: windows, roles and merging; a
// cloth moving rigidly is followed exactly; a patch with no contact on a cloth at rest stays at
// rest; a contact spring pushes the free particles away from the hand while the rings stay with
// the drive; lingering and release; every vector level gives the same bits; no allocation.
#include "sim_loop/cloth_patch.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <optional>
#include <vector>

#include "base/simd.h"
#include "cloth_test_util.h"
#include "collision/collision_structure.h"
#include "tests/alloc_counter.h"

namespace felt {
namespace {

using cloth_test::Curtain;

// A 21 x 21 curtain without gravity (its rest state is an equilibrium), Provot on.
ClothModel RestingSheet() {
  SimSpec spec = Curtain(21);
  spec.cloth.gravity_m_per_s2 = Vec3::Zero();
  return BuildClothModel(spec);
}

ClothSnapshot SnapshotOf(const ClothModel& model, const ClothState& state) {
  return MakeClothSnapshot(model, state, CollisionStructureSpec{});
}

int32_t At(const ClothModel& m, int32_t col, int32_t row) { return row * m.width + col; }

// The last triangle whose first corner is particle p (-1 if none).
int32_t TriangleFrom(const ClothModel& model, int32_t p) {
  int32_t tri = -1;
  for (size_t t = 0; t < model.triangles.size(); ++t) {
    if (model.triangles[t][0] == p) tri = static_cast<int32_t>(t);
  }
  return tri;
}

// The hand's contact spring on `triangle`, pressing from the +z side with a 4 mm sphere whose
// centre is 2 cm behind the rest place of particle `centre` (k and the clamp of the default
// device in the world).
ExternalForce PressBehind(const ClothModel& model, int32_t triangle, int32_t centre) {
  ExternalForce e;
  e.triangle = triangle;
  e.stiffness_N_per_m = 44.0;
  e.normal = Vec3::UnitZ();
  e.radius_m = 0.004;
  e.anchor_m = model.rest_position_m[centre] - Vec3(0, 0, 0.02) - e.radius_m * e.normal;
  e.max_force_N = 1.1;
  return e;
}

TEST(ClothPatchTest, AWindowHasTwoDrivenRingsExceptAlongTheClothsEdge) {
  const ClothModel model = RestingSheet();
  const ClothSnapshot s = SnapshotOf(model, MakeClothState(model));
  ClothPatch patch(model, 4, 1);
  const std::vector<int32_t> centre = {At(model, 10, 10)};
  patch.Place(centre, s, 0.0, 1e-3);
  ASSERT_EQ(patch.windows().size(), 1u);
  const PatchWindow w = patch.windows()[0];
  EXPECT_EQ(w.col0, 6);
  EXPECT_EQ(w.col1, 14);
  EXPECT_EQ(patch.roles()[At(model, 6, 10)], PatchRole::kDriven);
  EXPECT_EQ(patch.roles()[At(model, 7, 10)], PatchRole::kDriven);
  EXPECT_EQ(patch.roles()[At(model, 8, 10)], PatchRole::kFree);
  EXPECT_EQ(patch.roles()[At(model, 5, 10)], PatchRole::kOutside);
  // At the cloth's left edge the window is clipped and its edge columns are free.
  const std::vector<int32_t> edge = {At(model, 1, 10)};
  patch.Place(edge, s, 0.0, 1e-3);
  EXPECT_EQ(patch.windows()[0].col0, 0);
  EXPECT_EQ(patch.roles()[At(model, 0, 10)], PatchRole::kFree);
  EXPECT_EQ(patch.roles()[At(model, 5, 10)], PatchRole::kDriven);
  EXPECT_EQ(patch.roles()[At(model, 10, 10)], PatchRole::kOutside);
}

TEST(ClothPatchTest, WindowsThatMeetMergeAndFarOnesStayApart) {
  const ClothModel model = RestingSheet();
  const ClothSnapshot s = SnapshotOf(model, MakeClothState(model));
  ClothPatch patch(model, 3, 2);
  // 8 columns apart: windows 7 wide, columns 8 and 10 joined by a bend spring across column 9.
  std::vector<int32_t> centres = {At(model, 5, 10), At(model, 13, 10)};
  patch.Place(centres, s, 0.0, 1e-3);
  EXPECT_EQ(patch.windows().size(), 1u);
  EXPECT_EQ(patch.counters().merges, 1u);
  // 10 apart: separate.
  ClothPatch apart(model, 3, 2);
  centres = {At(model, 4, 10), At(model, 15, 10)};
  apart.Place(centres, s, 0.0, 1e-3);
  EXPECT_EQ(apart.windows().size(), 2u);
}

TEST(ClothPatchTest, ARigidlyMovingClothIsFollowedExactly) {
  // The drive moves every particle at one velocity, springs at rest length, no gravity or drag:
  // the free particles must move with it (to rounding) and the patch must not invent motion.
  SimSpec spec = Curtain(21);
  spec.cloth.gravity_m_per_s2 = Vec3::Zero();
  spec.cloth.drag_N_s_per_m = 0.0;
  spec.cloth.pins.clear();
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  const Vec3 velocity(0.3, -0.2, 0.5);
  for (Vec3& v : state.v) v = velocity;
  ClothSnapshot s = SnapshotOf(model, state);
  FillSnapshot(model, state, 1, 1.0 / 60.0, &s);  // with the velocities
  ClothPatch patch(model, 5, 1);
  const std::vector<int32_t> centre = {At(model, 10, 10)};
  double tau = 0.0;
  patch.Place(centre, s, tau, 1e-3);
  for (int k = 0; k < 15; ++k) {
    tau += 1e-3;
    patch.Step({}, 1e-3, s, tau);
  }
  double worst = 0.0;
  for (int32_t p = 0; p < model.num_particles(); ++p) {
    if (patch.roles()[p] != PatchRole::kFree) continue;
    worst = std::max(worst, (patch.x()[p] - (s.x[p] + tau * velocity)).norm());
    // The spring and constraint kernels work in single precision relative to the window (as the
    // sim's Provot does): a spring at rest length reads its length off by up to ~1e-8 m (6e-8 of
    // the 0.125 m the window spans), a force of ~1e-8 N on a 0.23 g particle, ~1e-6 m/s over the
    // 15 ms (measured: 0.5e-7 m/s in the release build, 1.05e-6 m/s in the ASan build at -O1).
    // The bound is 1e-5 m/s; the driven rings once stood a step ahead of the free particles in
    // the force evaluation: 0.02 m/s here.
    EXPECT_LT((patch.v()[p] - velocity).norm(), 1e-5);
  }
  EXPECT_LT(worst, 1e-7);
  EXPECT_LT(patch.MaxDistanceFrom(s), tau * velocity.norm() + 1e-7);
}

// Places `patch`'s one window around particle (10, 10) of snapshot s at t = 0 (a 1 ms tick) and
// returns that particle.
int32_t PlaceAroundCentre(const ClothModel& model, const ClothSnapshot& s, ClothPatch* patch) {
  const int32_t centre = At(model, 10, 10);
  const std::vector<int32_t> centres = {centre};
  patch->Place(centres, s, 0.0, 1e-3);
  return centre;
}

TEST(ClothPatchTest, AContactSpringPushesTheFreeParticlesAndTheRingsStayWithTheDrive) {
  const ClothModel model = RestingSheet();
  const ClothSnapshot s = SnapshotOf(model, MakeClothState(model));
  ClothPatch patch(model, 4, 1);
  const int32_t centre = PlaceAroundCentre(model, s, &patch);
  // A hand 2 cm behind the centre particle pressing from the +z side (world), sphere radius 4 mm.
  const int32_t tri = TriangleFrom(model, centre);
  ASSERT_GE(tri, 0);
  const std::vector<ExternalForce> springs = {PressBehind(model, tri, centre)};
  for (int k = 0; k < 100; ++k) {
    const PatchStepResult r = patch.Step(springs, 1e-3, s, 0.0);
    ASSERT_EQ(r.springs, 1);
    ASSERT_FALSE(r.recovered);
  }
  // Pushed away from the hand (-z) at the contact, to about the far side of the hand's sphere
  // (centre 2 cm behind, radius 4 mm), give or take the ringing of 0.1 s.
  EXPECT_LT(patch.x()[centre].z(), -0.015);
  EXPECT_GT(patch.x()[centre].z(), -0.03);
  // The rings are the drive's (at rest).
  for (int32_t p = 0; p < model.num_particles(); ++p) {
    if (patch.roles()[p] == PatchRole::kDriven) {
      EXPECT_EQ(patch.x()[p], s.x[p]) << p;
    }
  }
  // Provot's limit holds between free particles (10 % over rest, the sweeps' tolerance).
  const double limit = 1.1 * model.spacing_m * (1.0 + 2e-3);
  EXPECT_LE((patch.x()[centre] - patch.x()[At(model, 11, 10)]).norm(), limit);
}

TEST(ClothPatchTest, AWindowWithoutItsCentreLingersUntilItIsBackOnTheDrive) {
  const ClothModel model = RestingSheet();
  const ClothSnapshot s = SnapshotOf(model, MakeClothState(model));
  ClothPatch patch(model, 4, 1);
  const int32_t centre = At(model, 10, 10);
  std::vector<int32_t> centres = {centre};
  patch.Place(centres, s, 0.0, 1e-3);
  // At rest on the drive: released at once when its centre goes.
  centres = {-1};
  patch.Place(centres, s, 0.0, 1e-3);
  EXPECT_FALSE(patch.active());
  // Displaced by a push: it lingers (the drive is at rest, so it is pulled back), at most
  // kPatchMaxLinger_s.
  centres = {centre};
  patch.Place(centres, s, 0.0, 1e-3);
  const std::vector<ExternalForce> springs = {
      PressBehind(model, 2 * ((10 * (model.width - 1)) + 10), centre)};
  for (int k = 0; k < 50; ++k) patch.Step(springs, 1e-3, s, 0.0);
  centres = {-1};
  int ticks = 0;
  while (ticks < 1000) {
    patch.Place(centres, s, 0.0, 1e-3);
    if (!patch.active()) break;
    patch.Step({}, 1e-3, s, 0.0);
    ++ticks;
  }
  EXPECT_GT(ticks, 0);
  EXPECT_LE(ticks, static_cast<int>(kPatchMaxLinger_s / 1e-3) + 1);
}

// The patch's kernels at every vector level (base/simd.h) give the same bits, over windows of
// every shape the kernels treat apart: narrow ones on the cloth's edge (fewer columns than a
// constraint block), full ones (one block a row), two merged into one wider than a block, with
// odd and even column counts, while the hand presses and the windows move.
TEST(ClothPatchTest, EveryVectorLevelGivesTheSameBits) {
  SimSpec spec = Curtain(40);
  const ClothModel model = BuildClothModel(spec);
  ClothState state = MakeClothState(model);
  const ClothSnapshot s = SnapshotOf(model, state);
  const auto run = [&](SimdLevel level) {
    LimitSimdLevel(level);
    ClothPatch patch(model, 8, 2);
    std::vector<Vec3> out;
    for (int k = 0; k < 240; ++k) {
      const int32_t col = 1 + (k / 8) % 38, row = 20;
      const int32_t a = At(model, col, row);
      const int32_t b = k < 120 ? -1 : At(model, 38 - (k / 16) % 20, 24);
      const int32_t centres[2] = {a, b};
      patch.Place(centres, s, 0.0, 1e-3);
      const std::vector<ExternalForce> springs = {
          PressBehind(model, 2 * (row * (model.width - 1) + std::min(col, model.width - 2)), a)};
      const PatchStepResult r = patch.Step(springs, 1e-3, s, 0.0);
      EXPECT_FALSE(r.recovered);
      for (int32_t p = 0; p < model.num_particles(); ++p) {
        if (patch.roles()[p] != PatchRole::kOutside) out.push_back(patch.x()[p]);
      }
    }
    LimitSimdLevel(kWidestSimdLevel);
    return out;
  };
  const std::vector<Vec3> portable = run(SimdLevel::kPortable);
  for (SimdLevel level : {SimdLevel::kAvx2, SimdLevel::kAvx512}) {
    if (level > CpuSimdLevel()) continue;
    const std::vector<Vec3> wide = run(level);
    ASSERT_EQ(wide.size(), portable.size());
    size_t differ = 0;
    for (size_t i = 0; i < wide.size(); ++i) differ += wide[i] != portable[i] ? 1 : 0;
    EXPECT_EQ(differ, 0u) << SimdLevelName(level);
  }
}

TEST(ClothPatchTest, PlaceAndStepNeverAllocate) {
  const ClothModel model = RestingSheet();
  ClothState state = MakeClothState(model);
  const ClothSnapshot s = SnapshotOf(model, state);
  ClothPatch patch(model, 6, 2);
  ExternalForce e = PressBehind(model, 2 * ((10 * (model.width - 1)) + 10), At(model, 10, 10));
  e.anchor_m = model.rest_position_m[At(model, 10, 10)] - Vec3(0, 0, 0.02);
  const std::vector<ExternalForce> springs = {e};
  AllocationGuard guard;
  for (int k = 0; k < 200; ++k) {
    // Two centres that wander, meet, part and vanish.
    const int32_t a = At(model, 5 + (k / 20) % 10, 10);
    const int32_t b = k % 50 < 40 ? At(model, 15, 5 + (k / 10) % 10) : -1;
    const int32_t centres[2] = {a, b};
    patch.Place(std::span<const int32_t>(centres, 2), s, 0.0, 1e-3);
    patch.Step(springs, 1e-3, s, 0.0);
    patch.MaxDistanceFrom(s);
  }
  EXPECT_EQ(guard.allocations(), 0u);
  EXPECT_EQ(patch.counters().nan_events, 0u);
}

// The patch's own limiter settings (provot.patch_iterations, provot.patch_sweep_headroom): its
// sweeps hold its free particles to the patch's sweep length, whatever the sim's, and the sim's
// own steps never read them (the same bits with and without).
TEST(ClothPatchTest, ThePatchSweepsToItsOwnLengthAndTheSimIgnoresIt) {
  const auto model_with = [](std::optional<double> patch_headroom) {
    SimSpec spec = Curtain(21);
    spec.cloth.gravity_m_per_s2 = Vec3::Zero();
    spec.provot.patch_iterations = 20;  // converged, so the length it holds is the setting's
    spec.provot.patch_sweep_headroom = patch_headroom;
    return BuildClothModel(spec);
  };
  // Largest free-pair length / spacing along the rows after a hard press (as above, 0.1 s).
  const auto pressed_stretch = [](const ClothModel& model) {
    const ClothSnapshot s = SnapshotOf(model, MakeClothState(model));
    ClothPatch patch(model, 4, 1);
    const int32_t centre = PlaceAroundCentre(model, s, &patch);
    const int32_t tri = TriangleFrom(model, centre);
    ExternalForce press = PressBehind(model, tri, centre);
    press.max_force_N = 5.0;
    const std::vector<ExternalForce> springs = {press};
    for (int k = 0; k < 100; ++k) patch.Step(springs, 1e-3, s, 0.0);
    double worst = 0.0;
    for (int32_t p = 0; p + 1 < model.num_particles(); ++p) {
      if (patch.roles()[p] != PatchRole::kFree || patch.roles()[p + 1] != PatchRole::kFree)
        continue;
      worst = std::max(worst, (patch.x()[p + 1] - patch.x()[p]).norm() / model.spacing_m);
    }
    return worst;
  };
  const ClothModel at_limit = model_with(0.0), below = model_with(0.05);
  EXPECT_EQ(at_limit.patch_provot_iterations, 20);
  const double stretch_at_limit = pressed_stretch(at_limit);
  const double stretch_below = pressed_stretch(below);
  // Pressed past 1.045 when the patch aims at the limit, held under it when it aims 5 % below.
  EXPECT_GT(stretch_at_limit, 1.05);
  EXPECT_LE(stretch_at_limit, 1.10 * (1.0 + 1e-3));
  EXPECT_LE(stretch_below, 1.10 * 0.95 * (1.0 + 1e-3));
  // The sim: the same bits whatever the patch's settings.
  SimSpec plain = Curtain(21);
  SimSpec patched = plain;
  patched.provot.patch_iterations = 1;
  patched.provot.patch_sweep_headroom = 0.2;
  const ClothModel a = BuildClothModel(plain), b = BuildClothModel(patched);
  ClothState sa = MakeClothState(a), sb = MakeClothState(b);
  for (int f = 0; f < 30; ++f) {
    StepFrame(a, {}, 1.0 / 60.0, &sa);
    StepFrame(b, {}, 1.0 / 60.0, &sb);
  }
  EXPECT_EQ(sa.x, sb.x);
  EXPECT_EQ(sa.v, sb.v);
}

// A 21 x 21 curtain without gravity, with or without long range attachments, its sweeps in the
// patch off (patch_provot_iterations 0, set on the built model), whose every free particle starts
// 30 cm in front of its rest place: each attachment is over its length (particle (5, 5), 0.395 m
// from the top-right pin at rest, is 0.496 m from it; limit 0.435 m). One 1 ms step of a radius-4
// window around particle (3, 3): columns and rows 0..7, of which 0..5 free (the window ends on the
// cloth's edges), the top-left pin inside, the top-right outside.
struct DisplacedStep {
  std::unique_ptr<ClothModel> model;  // the patch keeps a reference: it lives here
  std::unique_ptr<ClothPatch> patch;
};
DisplacedStep StepDisplacedCorner(bool attachments) {
  SimSpec spec = Curtain(21);
  spec.cloth.gravity_m_per_s2 = Vec3::Zero();
  spec.provot.long_range_attachments = attachments;
  DisplacedStep out;
  out.model = std::make_unique<ClothModel>(BuildClothModel(spec));
  const ClothModel& model = *out.model;
  out.model->patch_provot_iterations = 0;
  ClothState state = MakeClothState(model);
  for (int32_t p = 0; p < model.num_particles(); ++p) {
    if (model.inv_mass_per_kg[p] > 0.0) state.x[p].z() += 0.3;
  }
  const ClothSnapshot s = SnapshotOf(model, state);
  out.patch = std::make_unique<ClothPatch>(model, 4, 1);
  const std::vector<int32_t> centre = {At(model, 3, 3)};
  out.patch->Place(centre, s, 0.0, 1e-3);
  out.patch->Step({}, 1e-3, s, 1e-3);
  return out;
}

// Long range attachments in the patch: a free window particle is held within its attachment's
// length of a pin in its own window (applied before the sweeps, as ApplyProvot; with the sweeps
// off the bound is exact to single precision), and not of a pin outside it (the driven rings
// carry that one); a model without attachments leaves them over.
TEST(ClothPatchTest, AttachmentsHoldTheFreeParticlesToTheWindowsOwnPins) {
  const DisplacedStep with = StepDisplacedCorner(true);
  ASSERT_EQ(with.patch->windows().size(), 1u);
  const PatchRole* roles = with.patch->roles();
  const Vec3* x = with.patch->x();
  int32_t held = 0, over_outside = 0;
  for (const PinAttachment& at : with.model->attachments) {
    if (roles[at.particle] != PatchRole::kFree) continue;
    if (roles[at.pin] == PatchRole::kOutside) {  // the patch's x() is the windows' only
      const double d = (x[at.particle] - with.model->rest_position_m[at.pin]).norm();
      over_outside += d > at.max_length_m ? 1 : 0;
    } else {
      const double d = (x[at.particle] - x[at.pin]).norm();
      EXPECT_LE(d, at.max_length_m * (1.0 + 1e-6)) << "particle " << at.particle;
      ++held;
    }
  }
  EXPECT_EQ(held, 35);         // every free window particle (6 x 6 less the pin), to its pin
  EXPECT_GT(over_outside, 0);  // the top-right pin is outside the window: not applied
  const DisplacedStep without = StepDisplacedCorner(false);
  int32_t over = 0;
  for (const PinAttachment& at : with.model->attachments) {
    if (roles[at.particle] != PatchRole::kFree || roles[at.pin] == PatchRole::kOutside) continue;
    over += (without.patch->x()[at.particle] - without.patch->x()[at.pin]).norm() > at.max_length_m;
  }
  EXPECT_EQ(over, 35);
}

}  // namespace
}  // namespace felt
