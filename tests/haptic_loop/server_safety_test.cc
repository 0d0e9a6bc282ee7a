// The safety layer (haptic_loop/safety.h): clamp, jerk limit, ramp-in, ramp-out on stale input,
// NaN handling, the passivity observer against its closed form and the passivity controller.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "haptic_loop/safety.h"

namespace felt {
namespace {

constexpr double kDt = 1e-3;

SafetyInput Fresh(const Vec3& force, const Vec3& v = Vec3::Zero()) {
  SafetyInput in;
  in.proxy_force_D_N = force;
  in.velocity_D_m_per_s = v;
  in.input_fresh = true;
  return in;
}

// A state already ramped in and sending `force`.
SafetyState Settled(const Vec3& force) {
  SafetyState s;
  s.gain = 1.0;
  s.last_force_D_N = force;
  return s;
}

TEST(ServerSafety, ClampsToTheDeviceMaximumKeepingTheDirection) {
  SafetySpec spec;
  spec.max_force_N = 2.0;
  spec.max_force_rate_N_per_s = 1e9;
  SafetyState state = Settled(Vec3(0, 0, 2.0));
  const SafetyOutput out = ApplySafety(spec, Fresh(Vec3(0, 3.0, 4.0)), kDt, &state);
  EXPECT_NEAR(out.force_D_N.norm(), 2.0, 1e-12);
  EXPECT_NEAR(out.force_D_N.normalized().dot(Vec3(0, 0.6, 0.8)), 1.0, 1e-12);
  EXPECT_TRUE(out.flags & kSafetyClamped);
  EXPECT_EQ(state.clamped_ticks, 1u);
}

TEST(ServerSafety, ForceRateIsLimited) {
  SafetySpec spec;
  spec.max_force_rate_N_per_s = 100.0;  // 0.1 N per 1 ms tick
  SafetyState state = Settled(Vec3::Zero());
  Vec3 last = Vec3::Zero();
  for (int i = 0; i < 20; ++i) {
    const SafetyOutput out = ApplySafety(spec, Fresh(Vec3(3.0, 0, 0)), kDt, &state);
    EXPECT_LE((out.force_D_N - last).norm(), 0.1 + 1e-12);
    last = out.force_D_N;
  }
  EXPECT_NEAR(last.x(), 2.0, 1e-9);  // 20 ticks x 0.1 N
}

TEST(ServerSafety, RampsInFromZeroOverRampInTime) {
  SafetySpec spec;
  spec.ramp_in_s = 0.5;
  spec.max_force_rate_N_per_s = 1e9;
  SafetyState state;  // gain 0: a device that just connected
  SafetyOutput out;
  for (int i = 1; i <= 250; ++i) {
    out = ApplySafety(spec, Fresh(Vec3(0, 1.0, 0)), kDt, &state);
    EXPECT_TRUE(out.flags & kSafetyRamping);
  }
  EXPECT_NEAR(out.force_D_N.y(), 0.5, 1e-9);  // half-way after 0.25 s
  for (int i = 251; i <= 500; ++i) out = ApplySafety(spec, Fresh(Vec3(0, 1.0, 0)), kDt, &state);
  EXPECT_NEAR(out.force_D_N.y(), 1.0, 1e-9);
  EXPECT_FALSE(out.flags & kSafetyRamping);
}

TEST(ServerSafety, StaleInputRampsTheForceToZeroAndKeepsSendingZero) {
  SafetySpec spec;
  spec.ramp_out_s = 0.05;
  SafetyState state = Settled(Vec3(1.0, 0, 0));
  SafetyInput stale = Fresh(Vec3(1.0, 0, 0));
  stale.input_fresh = false;
  double previous = 1.0;
  for (int i = 0; i < 50; ++i) {
    const SafetyOutput out = ApplySafety(spec, stale, kDt, &state);
    EXPECT_TRUE(out.flags & kSafetyStaleInput);
    EXPECT_LE(out.force_D_N.norm(), previous + 1e-12);  // never grows
    previous = out.force_D_N.norm();
  }
  EXPECT_NEAR(previous, 0.0, 1e-9);
  for (int i = 0; i < 100; ++i) {
    const SafetyOutput out = ApplySafety(spec, stale, kDt, &state);
    EXPECT_EQ(out.force_D_N, Vec3::Zero());
    EXPECT_TRUE(out.flags & kSafetyStaleInput);
  }
}

TEST(ServerSafety, NanAnywhereGivesZeroForceAndIsCounted) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  SafetySpec spec;
  const Vec3 f(1.0, 0, 0);
  // NaN input sample (flagged by the server), NaN proxy force, NaN velocity.
  SafetyInput nan_input = Fresh(f);
  nan_input.input_nan = true;
  const SafetyInput cases[] = {nan_input, Fresh(Vec3(nan, 0, 0)), Fresh(f, Vec3(0, nan, 0)),
                               Fresh(Vec3(std::numeric_limits<double>::infinity(), 0, 0))};
  for (const SafetyInput& in : cases) {
    SafetyState state = Settled(f);
    const SafetyOutput out = ApplySafety(spec, in, kDt, &state);
    EXPECT_TRUE(out.nan);
    EXPECT_EQ(out.force_D_N, Vec3::Zero());
    EXPECT_EQ(state.nan_events, 1u);
    EXPECT_TRUE(std::isfinite(state.energy_J));
    // The next good tick ramps in again, as after a reconnect.
    const SafetyOutput next = ApplySafety(spec, Fresh(f), kDt, &state);
    EXPECT_TRUE(next.flags & kSafetyRamping);
    EXPECT_LT(next.force_D_N.norm(), 0.01);
  }
}

TEST(ServerSafety, SimStalledIsFlaggedAndTheForceStillFlows) {
  SafetySpec spec;
  SafetyState state = Settled(Vec3(0.5, 0, 0));
  SafetyInput in = Fresh(Vec3(0.5, 0, 0));
  in.sim_stalled = true;
  const SafetyOutput out = ApplySafety(spec, in, kDt, &state);
  EXPECT_TRUE(out.flags & kSafetySimStalled);
  EXPECT_NEAR(out.force_D_N.x(), 0.5, 1e-12);
}

TEST(ServerSafety, PassivityObserverMatchesTheClosedForm) {
  // A constant force against a constant velocity: E = -F . v * t (Hannaford & Ryu 2002).
  SafetySpec spec;
  const Vec3 f(0, 0, 1.0);
  const Vec3 v(0, 0, -0.1);  // the hand pushes into a spring that pushes back: energy absorbed
  SafetyState state = Settled(f);
  for (int i = 0; i < 1000; ++i) ApplySafety(spec, Fresh(f, v), kDt, &state);
  EXPECT_NEAR(state.energy_J, 0.1, 1e-9);  // 1 N x 0.1 m/s x 1 s
}

TEST(ServerSafety, PassivityControllerKeepsTheObservedEnergyNonNegative) {
  // An active environment: the force pushes along the hand's motion (it generates energy).
  SafetySpec spec;
  spec.max_force_rate_N_per_s = 1e9;
  const Vec3 v(0.2, 0, 0);
  const Vec3 f(1.0, 0, 0);
  SafetyState without = Settled(f);
  for (int i = 0; i < 200; ++i) ApplySafety(spec, Fresh(f, v), kDt, &without);
  EXPECT_LT(without.energy_J, -0.03);  // 1 N x 0.2 m/s x 0.2 s = 0.04 J generated

  spec.passivity_controller = true;
  SafetyState with = Settled(f);
  for (int i = 0; i < 200; ++i) {
    ApplySafety(spec, Fresh(f, v), kDt, &with);
    EXPECT_GE(with.energy_J, -1e-12);
  }
  EXPECT_GT(with.controller_ticks, 0u);
  EXPECT_GT(with.dissipated_J, 0.03);
}

TEST(ServerSafety, PassivityControllerLeavesAPassiveEnvironmentAlone) {
  SafetySpec spec;
  spec.passivity_controller = true;
  const Vec3 v(-0.2, 0, 0);  // motion against the force: the environment absorbs energy
  const Vec3 f(1.0, 0, 0);
  SafetyState state = Settled(f);
  for (int i = 0; i < 200; ++i) {
    const SafetyOutput out = ApplySafety(spec, Fresh(f, v), kDt, &state);
    EXPECT_NEAR(out.force_D_N.x(), 1.0, 1e-12);
  }
  EXPECT_EQ(state.controller_ticks, 0u);
}

TEST(ServerSafety, ValidationNamesTheField) {
  SafetySpec spec;
  spec.ramp_in_s = 0.0;
  try {
    ValidateSafetySpec(spec);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("safety.ramp_in_s: must be > 0", 0), 0u) << e.what();
  }
  spec = SafetySpec{};
  spec.max_force_N = -1.0;
  EXPECT_THROW(ValidateSafetySpec(spec), std::invalid_argument);
}

}  // namespace
}  // namespace felt
