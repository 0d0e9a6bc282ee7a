#pragma once
// Two-way coupling (issue 4): every haptic tick puts the opposite of the proxy's force on the
// cloth at the contact point. The haptic side accumulates those forces per device over a sim
// frame; the sim applies their time average as its ExternalForce list (sim_loop/cloth.h), so a
// force held for the whole frame is applied at full strength and no tick's force is lost.
//
// Each contact force is split over its triangle's three particles by the barycentric weights and
// summed per particle, so the accumulator stays small (one entry per touched particle), exact in
// total force, and exact in where each particle's share lands.
//
// A force sampled once per frame and held is unstable for a held contact: the contact stiffness
// (device k / scale^2) on the light particles has omega dt ~ 6 at 60 Hz, far past the zero-order
// hold's limit. So while the proxy is in contact at the frame's last tick, the drain emits the
// contact itself instead: a unilateral spring from the contact point to the user's hand that the
// sim evaluates at its substep rate (virtual coupling, Colgate, Stanley & Brown 1995, on the
// god-object contact of Ruspini, Kolarov & Khatib 1997; ExternalForce::stiffness_N_per_m). The
// proxy keeps that spring, as a sphere at the user's hand, while it stays within three radii of
// where its contact ended (proxy/proxy.cc, ProxyTick). Brief contacts that end within the frame
// and leave (swipes) still get the time-averaged impulse.

#include <cstdint>
#include <span>
#include <vector>

#include "collision/mesh.h"
#include "sim_loop/cloth.h"

namespace felt {

/// Per-device accumulator of reaction impulses over one sim frame. Owned by one thread at a time
/// (the haptic thread adds; whoever drains must own it then, e.g. the haptic thread draining
/// into an SPSC queue slot the sim thread reads).
class ReactionAccumulator {
 public:
  /// Room for `capacity` >= 1 distinct particles per frame. Allocates (set-up time).
  explicit ReactionAccumulator(int32_t capacity = 256);

  /// Adds force_W_N [N, world] acting on the cloth for dt_s [s] at the point with barycentric
  /// weights `barycentric` of triangle `triangle`, whose particles are `corners`. When the
  /// capacity is full, a new particle's share goes to the first entry (the total is kept; the
  /// overflow is counted). Real-time safe.
  void AddForce(int32_t triangle, const Triangle& corners, const Vec3& barycentric,
                const Vec3& force_W_N, double dt_s);

  /// Records the proxy's contact at this tick as the frame's contact spring (replacing the one of
  /// an earlier tick): triangle, barycentric point, unit normal from the cloth toward the proxy
  /// [world], anchor [m, world: where the contact point sits when the proxy is at the user's
  /// hand], stiffness [N/m, world], force clamp [N, world] and a sphere radius [m, world: the sim
  /// presses a sphere of that radius centred at anchor + radius normal onto the cloth's nearest
  /// point; ExternalForce] and the hand's predicted velocity [m/s, world; zero: held]. Real-time
  /// safe.
  void SetContactSpring(int32_t triangle, const Vec3& barycentric, const Vec3& normal_W,
                        const Vec3& anchor_W_m, double stiffness_N_per_m, double max_force_N,
                        double radius_m = 0.0,
                        const Vec3& anchor_velocity_W_m_per_s = Vec3::Zero());

  /// No contact at this tick: the drain falls back to the averaged impulses. Real-time safe.
  void ClearContactSpring() { has_spring_ = false; }

  /// True if the last tick recorded a contact spring.
  bool has_contact_spring() const { return has_spring_; }
  /// The contact spring of the last tick (meaningful when has_contact_spring()).
  const ExternalForce& contact_spring() const { return spring_; }

  /// Adds dt_s [s] of elapsed time (every tick calls it once, in contact or not), the time the
  /// impulses are averaged over. Real-time safe.
  void AddTime(double dt_s) { time_s_ += dt_s; }

  /// Writes the frame's reaction into `out`, then clears the accumulator (the contact spring
  /// included). With a contact spring (the last tick was in contact): one ExternalForce carrying
  /// the spring (stiffness_N_per_m > 0), whose force_N holds the frame's time-averaged total
  /// reaction for information. Otherwise the time-averaged forces (impulse / accumulated time),
  /// one per touched particle (its triangle with a unit barycentric weight on it); entries that
  /// do not fit are merged into the last written one's force (total kept). Returns the number
  /// written; 0 when no time has accumulated. Real-time safe.
  int32_t DrainInto(std::span<ExternalForce> out);

  /// DrainInto a new vector. Allocates (for the sim side or tests).
  std::vector<ExternalForce> Drain();

  /// Sum of the accumulated impulses [N s, world].
  Vec3 TotalImpulse() const;
  /// Accumulated time [s].
  double time_s() const { return time_s_; }
  /// Distinct particles held now.
  int32_t size() const { return size_; }
  /// Particle shares merged into the first entry because the capacity was full (since creation).
  uint64_t overflows() const { return overflows_; }
  /// Forgets everything accumulated (counters kept). Real-time safe.
  void Clear();

 private:
  struct Entry {
    int32_t particle = -1;
    int32_t triangle = -1;
    int32_t corner = 0;
    Vec3 impulse_N_s = Vec3::Zero();
  };
  std::vector<Entry> entries_;  // [capacity]
  ExternalForce spring_;        // the contact spring of the last tick in contact
  bool has_spring_ = false;
  int32_t size_ = 0;
  double time_s_ = 0.0;
  uint64_t overflows_ = 0;
};

}  // namespace felt
