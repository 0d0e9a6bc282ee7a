// The local contact model of a ForceCommand (transport/local_contact.h; Mark et al. 1996): its
// closed forms, and what it buys a driver when the force messages arrive late.

#include "transport/local_contact.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <limits>

namespace felt::transport {
namespace {

constexpr double kK_N_per_m = 400.0;  // the default device spring
constexpr double kMax_N = 3.3;        // the default device clamp

// A command with the plane z_D = 0, normal +z, and the force the server computed at `tip`.
ForceCommandView PlaneCommand(const std::array<double, 3>& tip_m_D) {
  ForceCommandView c;
  const double depth_m = std::max(0.0, -tip_m_D[2]);
  c.in_contact = depth_m > 0.0;
  c.force_N_D = {0.0, 0.0, std::min(kMax_N, kK_N_per_m * depth_m)};
  if (c.in_contact) {
    c.contact_point_m_D = {tip_m_D[0], tip_m_D[1], 0.0};  // the proxy on the plane
    c.contact_normal_D = {0.0, 0.0, 1.0};
    c.contact_stiffness_N_per_m = kK_N_per_m;
  }
  return c;
}

TEST(LocalContact, ZeroStiffnessHoldsTheSentForceClamped) {
  ForceCommandView c;
  c.force_N_D = {0.0, 0.0, 1.0};
  EXPECT_EQ(LocalContactForce(c, {0.0, 0.0, -1.0}, kMax_N), (std::array<double, 3>{0, 0, 1.0}));
  c.force_N_D = {0.0, 0.0, 10.0};
  EXPECT_EQ(LocalContactForce(c, {0.0, 0.0, 0.0}, kMax_N), (std::array<double, 3>{0, 0, kMax_N}));
  c.force_N_D = {std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0};
  EXPECT_EQ(LocalContactForce(c, {0.0, 0.0, 0.0}, kMax_N), (std::array<double, 3>{0, 0, 0}));
}

TEST(LocalContact, ThePlaneGivesTheSpringAtTheCurrentTip) {
  ForceCommandView c = PlaneCommand({0.0, 0.0, -0.001});
  // 3 mm in: 1.2 N along the normal, whatever the sideways position.
  const auto f = LocalContactForce(c, {0.01, -0.02, -0.003}, kMax_N);
  EXPECT_NEAR(f[0], 0.0, 1e-12);
  EXPECT_NEAR(f[1], 0.0, 1e-12);
  EXPECT_NEAR(f[2], 1.2, 1e-12);
  // In front of the plane: nothing. Deep: the clamp.
  EXPECT_EQ(LocalContactForce(c, {0.0, 0.0, 0.002}, kMax_N), (std::array<double, 3>{0, 0, 0}));
  EXPECT_NEAR(LocalContactForce(c, {0.0, 0.0, -0.1}, kMax_N)[2], kMax_N, 1e-12);
}

// A tip pressing into a cloth and stroking over it at 1 kHz, out of contact at the top of each
// press, while the cloth's surface itself moves +-1 mm; the server's force messages reach the
// driver 10 ms late. The driver outputs (a) the newest force as sent (hold) or (b) the local model
// of the newest message at its current tip. Reference: the force at the tip's true position
// against the cloth where it truly is. The local model errs only by the cloth's own motion over
// the delay and at contact changes; holding errs by the tip's motion too.
TEST(LocalContact, WithMessagesTenMillisecondsLateThePlaneBeatsHoldingTheForce) {
  constexpr int kDelayTicks = 10;  // 10 ms at 1 kHz
  constexpr int kTicks = 4000;     // 4 s
  // The tip: from 2 mm in front of the rest plane to 8 mm through it at 1 Hz, stroking +-2 cm
  // sideways at 0.5 Hz; the cloth's surface: z_D = 1 mm sin(2 pi 1.5 Hz t).
  auto tip = [](int k) {
    const double t_s = k * 1e-3;
    return std::array<double, 3>{0.02 * std::sin(M_PI * t_s), 0.0,
                                 -0.003 + 0.005 * std::cos(2.0 * M_PI * t_s)};
  };
  auto cloth_z = [](int k) { return 0.001 * std::sin(3.0 * M_PI * k * 1e-3); };
  // The server at tick k: the plane through the cloth (as the proxy sees it), the force at tip(k).
  auto server = [&](int k) {
    std::array<double, 3> p = tip(k);
    p[2] -= cloth_z(k);  // in the cloth's frame
    ForceCommandView c = PlaneCommand(p);
    c.contact_point_m_D[2] += cloth_z(k);
    return c;
  };
  std::deque<ForceCommandView> in_flight;
  double hold_sq = 0, local_sq = 0, hold_max = 0, local_max = 0;
  int n = 0;
  for (int k = 0; k < kTicks; ++k) {
    // The server answers this tick's sample; the message arrives kDelayTicks later.
    in_flight.push_back(server(k));
    if (in_flight.size() <= kDelayTicks) continue;
    const ForceCommandView newest = in_flight.front();
    in_flight.pop_front();
    const double truth_N = server(k).force_N_D[2];
    const double hold_N = newest.force_N_D[2];
    const double local_N = LocalContactForce(newest, tip(k), kMax_N)[2];
    hold_sq += (hold_N - truth_N) * (hold_N - truth_N);
    local_sq += (local_N - truth_N) * (local_N - truth_N);
    hold_max = std::max(hold_max, std::abs(hold_N - truth_N));
    local_max = std::max(local_max, std::abs(local_N - truth_N));
    ++n;
  }
  const double hold_rms = std::sqrt(hold_sq / n), local_rms = std::sqrt(local_sq / n);
  std::printf(
      "10 ms late, %d ticks: hold-last-force error rms %.4f N max %.4f N; local plane error rms "
      "%.4f N max %.4f N\n",
      n, hold_rms, hold_max, local_rms, local_max);
  EXPECT_LT(local_rms, 0.5 * hold_rms);
  EXPECT_LT(local_max, hold_max);
}

}  // namespace
}  // namespace felt::transport
