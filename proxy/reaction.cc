#include "proxy/reaction.h"

#include <algorithm>
#include <stdexcept>

namespace felt {

ReactionAccumulator::ReactionAccumulator(int32_t capacity) {
  if (capacity < 1) throw std::invalid_argument("ReactionAccumulator: capacity must be >= 1");
  entries_.resize(static_cast<size_t>(capacity));
}

void ReactionAccumulator::AddForce(int32_t triangle, const Triangle& corners,
                                   const Vec3& barycentric, const Vec3& force_W_N, double dt_s) {
  for (int k = 0; k < 3; ++k) {
    if (barycentric(k) == 0.0) continue;
    const Vec3 share = (barycentric(k) * dt_s) * force_W_N;
    const int32_t particle = corners[k];
    // One entry per particle: find it, else open a new one, else merge into the first.
    int32_t found = -1;
    for (int32_t e = 0; e < size_; ++e) {
      if (entries_[e].particle == particle) {
        found = e;
        break;
      }
    }
    if (found < 0 && size_ < static_cast<int32_t>(entries_.size())) {
      found = size_++;
      entries_[found] = Entry{particle, triangle, k, Vec3::Zero()};
    }
    if (found < 0) {
      found = 0;
      ++overflows_;
    }
    entries_[found].impulse_N_s += share;
  }
}

void ReactionAccumulator::SetContactSpring(int32_t triangle, const Vec3& barycentric,
                                           const Vec3& normal_W, const Vec3& anchor_W_m,
                                           double stiffness_N_per_m, double max_force_N,
                                           double radius_m,
                                           const Vec3& anchor_velocity_W_m_per_s) {
  spring_.triangle = triangle;
  spring_.barycentric = barycentric;
  spring_.normal = normal_W;
  spring_.anchor_m = anchor_W_m;
  spring_.stiffness_N_per_m = stiffness_N_per_m;
  spring_.max_force_N = max_force_N;
  spring_.radius_m = radius_m;
  spring_.anchor_velocity_m_per_s = anchor_velocity_W_m_per_s;
  has_spring_ = true;
}

int32_t ReactionAccumulator::DrainInto(std::span<ExternalForce> out) {
  int32_t written = 0;
  if (has_spring_ && time_s_ > 0.0 && !out.empty()) {
    // Held contact: the sim evaluates the spring at its substep rate (Colgate et al. 1995).
    out[0] = spring_;
    out[0].force_N = TotalImpulse() / time_s_;
    written = 1;
  } else if (time_s_ > 0.0 && !out.empty()) {
    // Impulse / time: the time average over the ticks of the frame.
    const double inv_t = 1.0 / time_s_;
    for (int32_t e = 0; e < size_; ++e) {
      const Entry& entry = entries_[e];
      const Vec3 f = entry.impulse_N_s * inv_t;
      if (static_cast<size_t>(written) < out.size()) {
        // A whole new entry: a slot the caller reuses may still hold an earlier frame's contact
        // spring (stiffness_N_per_m > 0), which the sim would apply instead of this force.
        ExternalForce ef;
        ef.triangle = entry.triangle;
        ef.barycentric = Vec3::Zero();
        ef.barycentric(entry.corner) = 1.0;
        ef.force_N = f;
        out[written++] = ef;
      } else {
        out[written - 1].force_N += f;
      }
    }
  }
  Clear();
  return written;
}

std::vector<ExternalForce> ReactionAccumulator::Drain() {
  std::vector<ExternalForce> out(static_cast<size_t>(size_));
  out.resize(static_cast<size_t>(DrainInto(out)));
  return out;
}

Vec3 ReactionAccumulator::TotalImpulse() const {
  Vec3 sum = Vec3::Zero();
  for (int32_t e = 0; e < size_; ++e) sum += entries_[e].impulse_N_s;
  return sum;
}

void ReactionAccumulator::Clear() {
  size_ = 0;
  time_s_ = 0.0;
  has_spring_ = false;
}

}  // namespace felt
