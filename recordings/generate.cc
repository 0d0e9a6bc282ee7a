#include "recordings/generate.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <numbers>
#include <stdexcept>
#include <utility>

#include "recordings/hermite.h"
#include "recordings/import.h"

namespace felt {
namespace {

constexpr double kPi = std::numbers::pi;

// SplitMix64 (Steele, Lea & Flood, "Fast splittable pseudorandom number generators", OOPSLA 2014):
// fully specified, so the same seed gives the same numbers on every platform.
class SplitMix64 {
 public:
  explicit SplitMix64(uint64_t seed) : state_(seed) {}
  uint64_t Next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  // Uniform in [0, 1) with 53 random bits.
  double Uniform() { return static_cast<double>(Next() >> 11) * 0x1.0p-53; }
  // Standard normal by the Box-Muller transform (Box & Muller 1958), one value per call.
  double Normal() {
    const double u1 = 1.0 - Uniform();  // (0, 1]
    const double u2 = Uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
  }

 private:
  uint64_t state_;
};

// FNV-1a hash of a name, to give each trace its own noise stream.
uint64_t HashName(std::string_view name) {
  uint64_t h = 0xCBF29CE484222325ull;
  for (char c : name) {
    h ^= static_cast<unsigned char>(c);
    h *= 0x100000001B3ull;
  }
  return h;
}

// Position [m] and velocity [m/s] of the voluntary motion.
struct Motion {
  Vec3 p = Vec3::Zero();
  Vec3 v = Vec3::Zero();
};

// Minimum-jerk profile (Flash & Hogan 1985): position fraction and its derivative w.r.t. s.
double MinJerk(double s) { return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s); }
double MinJerkRate(double s) { return 30.0 * s * s * (1.0 - s) * (1.0 - s); }

// A script of voluntary motion: consecutive segments, each a function of the time since its start.
class Script {
 public:
  explicit Script(const Vec3& start) : end_(start) {}

  // Stays at the current position for duration_s.
  void Hold(double duration_s) {
    const Vec3 at = end_;
    Add(
        duration_s,
        [at](double) {
          return Motion{at, Vec3::Zero()};
        },
        at);
  }

  // Minimum-jerk point-to-point move to `target` in duration_s (Flash & Hogan 1985).
  void MoveTo(const Vec3& target, double duration_s) {
    const Vec3 from = end_;
    const double T = duration_s;
    Add(
        duration_s,
        [from, target, T](double tau) {
          const double s = tau / T;
          return Motion{from + (target - from) * MinJerk(s),
                        (target - from) * (MinJerkRate(s) / T)};
        },
        target);
  }

  // A swipe: minimum-jerk in x, y to `target` (same z) while z dips by depth_m * sin^2(pi s),
  // timed so the peak x-y speed is peak_speed_m_per_s (minimum jerk peaks at 1.875 x mean).
  void Swipe(const Vec3& target, double depth_m, double peak_speed_m_per_s) {
    const Vec3 from = end_;
    const double T = 1.875 * (target - from).head<2>().norm() / peak_speed_m_per_s;
    Add(
        T,
        [from, target, T, depth_m](double tau) {
          const double s = tau / T;
          Motion m{from + (target - from) * MinJerk(s), (target - from) * (MinJerkRate(s) / T)};
          const double sn = std::sin(kPi * s);
          m.p.z() = from.z() - depth_m * sn * sn;
          m.v.z() = -depth_m * kPi * std::sin(2.0 * kPi * s) / T;
          return m;
        },
        target);
  }

  // `turns` circles of radius r_m about centre (in the x-y plane at the current z), starting and
  // ending at the current position, the angle following a minimum-jerk profile.
  void Circle(const Vec3& centre, double turns, double duration_s) {
    const Vec3 start = end_;
    const double r = (start - centre).head<2>().norm();
    const double phase0 = std::atan2(start.y() - centre.y(), start.x() - centre.x());
    const double total = 2.0 * kPi * turns;
    const double T = duration_s;
    Add(
        duration_s,
        [centre, r, phase0, total, T, z = start.z()](double tau) {
          const double s = tau / T;
          const double theta = phase0 + total * MinJerk(s);
          const double rate = total * MinJerkRate(s) / T;
          return Motion{Vec3(centre.x() + r * std::cos(theta), centre.y() + r * std::sin(theta), z),
                        Vec3(-r * rate * std::sin(theta), r * rate * std::cos(theta), 0.0)};
        },
        start);
  }

  // An oscillation about the current position for duration_s:
  //   p = at + amplitude_m e(tau) sin(2 pi f tau + phase),  v = amplitude_m (e' sin + e 2 pi f cos)
  // with e a minimum-jerk envelope (Flash & Hogan 1985 profile) rising from 0 to 1 over the first
  // ramp_s and falling back over the last ramp_s, so the segment starts and ends at rest.
  void Oscillate(const Vec3& amplitude_m, double frequency_hz, double phase, double duration_s,
                 double ramp_s) {
    const Vec3 at = end_;
    const double omega = 2.0 * kPi * frequency_hz;
    const double T = duration_s;
    const double R = ramp_s;
    Add(
        duration_s,
        [at, amplitude_m, omega, phase, T, R](double tau) {
          double e = 1.0, de = 0.0;  // envelope and its time derivative [1/s]
          if (tau < R) {
            e = MinJerk(tau / R);
            de = MinJerkRate(tau / R) / R;
          } else if (tau > T - R) {
            e = MinJerk((T - tau) / R);
            de = -MinJerkRate((T - tau) / R) / R;
          }
          const double sn = std::sin(omega * tau + phase);
          const double cs = std::cos(omega * tau + phase);
          return Motion{at + amplitude_m * (e * sn), amplitude_m * (de * sn + e * omega * cs)};
        },
        at);
  }

  // A step of the position to `target` at the current time, between two samples: the segments
  // before end there and the next one starts at `target`.
  void Jump(const Vec3& target) {
    jumps_.push_back({duration_s(), target - end_});
    end_ = target;
  }

  // A segment given as a function of the time since its start, tau in [0, duration_s), which the
  // caller guarantees starts at the current position and ends at `end`.
  void Follow(double duration_s, std::function<Motion(double)> f, const Vec3& end) {
    Add(duration_s, std::move(f), end);
  }

  // Buttons reported from the next segment on.
  void SetButtons(uint32_t buttons) { buttons_ = buttons; }

  double duration_s() const { return segments_.empty() ? 0.0 : segments_.back().t1; }

  // The position the script has reached (where the next segment starts) [m].
  const Vec3& end() const { return end_; }

  // A one-sample step: at time t_s [s] the position moves by step_m [m].
  struct Step {
    double t_s;
    Vec3 step_m;
  };
  const std::vector<Step>& jumps() const { return jumps_; }

  // Motion and buttons at t [s]; after the last segment the end position is held.
  Motion At(double t, uint32_t* buttons) const {
    for (const Segment& seg : segments_) {
      if (t < seg.t1) {
        *buttons = seg.buttons;
        return seg.f(t - seg.t0);
      }
    }
    *buttons = buttons_;
    return Motion{end_, Vec3::Zero()};
  }

 private:
  struct Segment {
    double t0, t1;
    std::function<Motion(double)> f;
    uint32_t buttons;
  };
  void Add(double length_s, std::function<Motion(double)> f, const Vec3& end) {
    const double t0 = duration_s();
    segments_.push_back({t0, t0 + length_s, std::move(f), buttons_});
    end_ = end;
  }
  std::vector<Segment> segments_;
  std::vector<Step> jumps_;
  Vec3 end_;
  uint32_t buttons_ = 0;
};

// Physiological tremor: per axis a sum of sinusoids in 8-12 Hz with random phases, scaled to
// kTremorRms_m RMS; analytic, so its velocity is exact.
class Tremor {
 public:
  explicit Tremor(SplitMix64* rng) {
    for (int a = 0; a < 3; ++a) {
      double power = 0.0;
      for (int i = 0; i < kTremorComponents; ++i) {
        Component& c = c_[a][i];
        c.omega = 2.0 * kPi * (8.0 + 4.0 * rng->Uniform());
        c.phase = 2.0 * kPi * rng->Uniform();
        c.amplitude = 0.5 + 0.5 * rng->Uniform();
        power += 0.5 * c.amplitude * c.amplitude;  // mean square of a sinusoid
      }
      const double gain = kTremorRms_m / std::sqrt(power);
      for (Component& c : c_[a]) c.amplitude *= gain;
    }
  }
  Motion At(double t) const {
    Motion m;
    for (int a = 0; a < 3; ++a) {
      for (const Component& c : c_[a]) {
        m.p[a] += c.amplitude * std::sin(c.omega * t + c.phase);
        m.v[a] += c.amplitude * c.omega * std::cos(c.omega * t + c.phase);
      }
    }
    return m;
  }

 private:
  struct Component {
    double omega = 0.0, phase = 0.0, amplitude = 0.0;
  };
  Component c_[3][kTremorComponents];
};

// The burst_walk's voluntary motion, as an offset from where it starts: per axis an
// Ornstein-Uhlenbeck process (Uhlenbeck & Ornstein, Phys. Rev. 36, 1930) sampled exactly every
// kWalkKnot_s (Gillespie, Phys. Rev. E 54(2), 1996: x' = x e^(-theta dt) + sd sqrt(1 - e^(-2 theta
// dt)) N) and joined by a C1 cubic Hermite curve with Bessel tangents (recordings/hermite.h), zero
// at both ends so the walk starts and ends at rest; plus flicks, minimum-jerk moves of 2-4 cm in
// x-y at a peak speed of 0.8-1.2 m/s (Flash & Hogan 1985), at random times, each displacing the
// walk's centre for good. Velocity is the exact derivative of both.
class BurstWalk {
 public:
  static constexpr double kWalkKnot_s = 0.04;
  // Reversion rates [1/s] and stationary standard deviations [m] of the OU process per axis.
  static constexpr double kTheta_per_s[3] = {1.0, 1.0, 2.0};
  static constexpr double kSd_m[3] = {0.006, 0.006, 0.0015};
  // The flicks keep the walk's centre within this radius of the start in x-y [m].
  static constexpr double kFlickRadius_m = 0.04;

  BurstWalk(uint64_t seed, double duration_s) : ou_(MakeOu(seed, duration_s)) {
    // Flicks: a random direction, 2-4 cm, peak speed 0.8-1.2 m/s; the gaps between them are
    // 0.35 s plus an exponential of mean 0.5 s; none in the first 0.3 s or the last 0.3 s.
    SplitMix64 rng(seed ^ HashName("burst_walk/flicks"));
    Vec3 centre = Vec3::Zero();
    double t = 0.3 + Exponential(&rng, 0.5);
    for (;;) {
      const double length = 0.02 + 0.02 * rng.Uniform();
      const double angle = 2.0 * kPi * rng.Uniform();
      const double peak_speed = 0.8 + 0.4 * rng.Uniform();
      const double T = 1.875 * length / peak_speed;  // minimum jerk peaks at 1.875 x mean speed
      if (t + T > duration_s - 0.3) break;
      Vec3 d(length * std::cos(angle), length * std::sin(angle), 0.0);
      // Stay within kFlickRadius_m of the start: flip the flick, else aim it at the start.
      if ((centre + d).norm() > kFlickRadius_m) d = -d;
      if ((centre + d).norm() > kFlickRadius_m) d = -centre.normalized() * length;
      flicks_.push_back({t, T, d});
      centre += d;
      t += T + 0.35 + Exponential(&rng, 0.5);
    }
  }

  // Offset [m] and its velocity [m/s] at tau [s] after the walk's start.
  Motion At(double tau) const {
    const CurvePoint o = ou_.Evaluate(tau);
    Motion m{o.p, o.v};
    for (const Flick& f : flicks_) {
      const double s = (tau - f.t0_s) / f.duration_s;
      if (s <= 0.0) break;
      if (s >= 1.0) {
        m.p += f.d_m;
      } else {
        m.p += f.d_m * MinJerk(s);
        m.v += f.d_m * (MinJerkRate(s) / f.duration_s);
      }
    }
    return m;
  }

  int flick_count() const { return static_cast<int>(flicks_.size()); }

 private:
  struct Flick {
    double t0_s, duration_s;
    Vec3 d_m;
  };

  // Exponential with the given mean, by inversion.
  static double Exponential(SplitMix64* rng, double mean) {
    return -mean * std::log(1.0 - rng->Uniform());
  }

  static HermiteCurve MakeOu(uint64_t seed, double duration_s) {
    SplitMix64 rng(seed ^ HashName("burst_walk/ou"));
    const int n = static_cast<int>(std::llround(duration_s / kWalkKnot_s));
    const double dt = duration_s / n;
    std::vector<double> t(static_cast<size_t>(n) + 1);
    std::vector<Vec3> p(t.size(), Vec3::Zero());
    for (int i = 0; i <= n; ++i) t[i] = i * dt;
    for (int i = 1; i <= n; ++i) {
      for (int a = 0; a < 3; ++a) {
        // Exact OU step (Gillespie 1996).
        const double decay = std::exp(-kTheta_per_s[a] * dt);
        p[i][a] = p[i - 1][a] * decay + kSd_m[a] * std::sqrt(1.0 - decay * decay) * rng.Normal();
      }
    }
    std::vector<Vec3> m = BesselTangents(t, p);
    m.front() = m.back() = Vec3::Zero();  // at rest at both ends
    return HermiteCurve(std::move(t), std::move(p), std::move(m));
  }

  HermiteCurve ou_;
  std::vector<Flick> flicks_;
};

// The voluntary motion of each generated trace, its total duration [s], and for the hard traces
// header lines that describe what is special about them.
struct Plan {
  Script script;
  double duration_s;
  const char* description;
  std::vector<std::pair<std::string, std::string>> notes = {};
};

// The hard traces (recordings/hard/); throws std::invalid_argument for an unknown name.
Plan MakeHardPlan(std::string_view name, uint64_t seed) {
  if (name == "scrub") {
    // Press 1.2 cm in near the centre, scrub +-3 cm sideways at 5 Hz for 2.2 s, withdraw.
    Script s(Vec3(0.003, -0.004, 0.045));
    s.Hold(0.3);
    s.MoveTo(Vec3(0.0, -0.005, 0.008), 0.7);
    s.MoveTo(Vec3(0.0, -0.005, -0.012), 0.5);
    s.Hold(0.3);
    s.Oscillate(Vec3(kScrubAmplitude_m, 0.0, 0.0), kScrubFrequency_hz, 0.0, 2.2, 0.2);
    s.Hold(0.3);
    s.MoveTo(Vec3(0.002, -0.004, 0.045), 0.9);
    return {std::move(s),
            6.0,
            "press 1.2 cm in near the centre, scrub x +-3 cm at 5 Hz for 2.2 s (peak 2 pi f A = "
            "0.94 m/s device = 2.8 m/s world), withdraw",
            {{"set", "hard"}}};
  }
  if (name == "pin_drag") {
    // Press 1.5 cm in at the middle left, drag to 1 cm from the top-left pin in x and y, hold 1 s,
    // drag back, withdraw.
    const Vec3 press(-0.04, 0.0, -0.015);
    const Vec3 near_pin(-kCurtainHalfWidth_m + 0.01, kCurtainTopY_m - 0.01, -0.015);
    Script s(Vec3(-0.04, 0.0, 0.045));
    s.Hold(0.3);
    s.MoveTo(Vec3(-0.04, 0.0, 0.005), 0.8);
    s.MoveTo(press, 0.6);
    s.Hold(0.3);
    s.MoveTo(near_pin, 1.6);
    s.Hold(1.0);
    s.MoveTo(press, 1.6);
    s.Hold(0.3);
    s.MoveTo(Vec3(-0.04, 0.0, 0.045), 0.9);
    return {std::move(s),
            8.0,
            "press 1.5 cm in at (-0.04, 0), drag 8 cm in 1.6 s to 1 cm from the top-left pinned "
            "corner in x and y, hold 1 s, drag back, withdraw",
            {{"set", "hard"}}};
  }
  if (name == "vibrate") {
    // Press 1 cm in, hold, vibrate at 250 Hz for 2 s (20 ms ramps), hold, withdraw.
    Script s(Vec3(0.01, -0.01, 0.045));
    s.Hold(0.3);
    s.MoveTo(Vec3(0.01, -0.01, 0.005), 0.8);
    s.MoveTo(Vec3(0.01, -0.01, -0.01), 0.5);
    s.Hold(0.5);
    // Phase pi/4: at 4 samples a period the samples never sit on the zeros.
    s.Oscillate(Vec3(kVibrateAmplitudeX_m, 0.0, kVibrateAmplitudeZ_m), kVibrateFrequency_hz,
                0.25 * kPi, 2.0, 0.02);
    s.Hold(0.5);
    s.MoveTo(Vec3(0.01, -0.01, 0.045), 0.9);
    return {std::move(s),
            6.0,
            "press 1 cm in, hold, vibrate 2 s at 250 Hz (0.4 mm along z, 0.2 mm along x, 20 ms "
            "minimum-jerk ramps), hold, withdraw",
            {{"set", "hard"},
             {"vibration",
              "250 Hz, amplitude 0.4 mm z and 0.2 mm x; the velocity column is its "
              "exact derivative"}}};
  }
  if (name == "jump") {
    // Press 1 cm in, jump 4.5 cm sideways within one sample, hold, withdraw to 2 cm in front,
    // jump to 1 cm behind the cloth within one sample, hold, withdraw. The jumps fall half way
    // between samples (t = 2.1005 s and 4.2005 s).
    Script s(Vec3(-0.025, -0.005, 0.045));
    s.Hold(0.3);
    s.MoveTo(Vec3(-0.025, -0.005, 0.005), 0.8);
    s.MoveTo(Vec3(-0.025, -0.005, -0.01), 0.5);
    s.Hold(0.5005);
    s.Jump(Vec3(0.02, -0.005, -0.01));
    s.Hold(1.0);
    s.MoveTo(Vec3(0.02, -0.005, 0.02), 0.6);
    s.Hold(0.5);
    s.Jump(Vec3(0.02, -0.005, -0.01));
    s.Hold(1.0);
    s.MoveTo(Vec3(0.02, -0.005, 0.045), 0.9);
    return {std::move(s),
            7.0,
            "press 1 cm in, jump 4.5 cm sideways within one 1 ms sample, hold 1 s, withdraw to "
            "z_D = +0.02, jump to z_D = -0.01 (through the cloth) within one sample, hold 1 s, "
            "withdraw",
            {{"set", "hard"},
             {"velocity_at_jumps",
              "the first sample after each step adds step / 1 ms (the backward difference a "
              "device differentiating its encoders reports), so the trapezoid integral of the "
              "velocity matches the position again from the next sample on"}}};
  }
  if (name == "burst_walk") {
    // Press 5 mm in at (0, -0.01), random walk with flicks for 5.3 s, withdraw.
    const Vec3 start(0.0, -0.01, -0.005);
    const double walk_s = 5.3;
    const BurstWalk walk(seed, walk_s);
    Script s(Vec3(0.002, -0.008, 0.045));
    s.Hold(0.3);
    s.MoveTo(Vec3(0.0, -0.01, 0.005), 0.8);
    s.MoveTo(start, 0.4);
    const Vec3 walk_end = start + walk.At(walk_s).p;
    s.Follow(
        walk_s,
        [start, walk](double tau) {
          Motion m = walk.At(tau);
          m.p += start;
          return m;
        },
        walk_end);
    s.MoveTo(Vec3(walk_end.x(), walk_end.y(), 0.045), 0.9);
    return {std::move(s),
            8.0,
            "press 5 mm in at (0, -0.01), 5.3 s random walk (Ornstein-Uhlenbeck, 6 mm sd in x, y, "
            "1.5 mm in z) with random minimum-jerk flicks of 2-4 cm at 0.8-1.2 m/s peak, withdraw",
            {{"set", "hard"},
             {"walk",
              "OU per axis (theta 1, 1, 2 /s; sd 6, 6, 1.5 mm) sampled every 40 ms, C1 "
              "Hermite between; " +
                  std::to_string(walk.flick_count()) +
                  " flicks; own streams seeded by (seed, 'burst_walk/ou' and '/flicks')"}}};
  }
  throw std::invalid_argument("unknown trace '" + std::string(name) +
                              "' (bundled: poke_hold, slow_stroke, fast_swipe, circle, "
                              "pinch_drag; hard: scrub, pin_drag, vibrate, jump, burst_walk)");
}

Plan MakePlan(std::string_view name, uint64_t seed) {
  if (name == "poke_hold") {
    // Approach from 5 cm in front, press 1.5 cm into the cloth near its centre, hold 2 s, withdraw.
    Script s(Vec3(0.004, -0.006, 0.05));
    s.Hold(0.4);
    s.MoveTo(Vec3(0.0, -0.005, 0.01), 1.0);
    s.MoveTo(Vec3(0.0, -0.005, -0.015), 0.7);
    s.Hold(2.0);
    s.MoveTo(Vec3(0.003, -0.004, 0.05), 1.1);
    return {std::move(s), 6.0,
            "approach from z_D = +0.05, press 1.5 cm into the cloth near its centre, hold 2 s, "
            "withdraw"};
  }
  if (name == "slow_stroke") {
    // Press 8 mm in, drag 10 cm across at a mean 5 cm/s, step down, drag back, withdraw.
    Script s(Vec3(-0.05, 0.02, 0.045));
    s.Hold(0.3);
    s.MoveTo(Vec3(-0.05, 0.02, 0.005), 0.8);
    s.MoveTo(Vec3(-0.05, 0.02, -0.008), 0.5);
    s.MoveTo(Vec3(0.05, 0.015, -0.008), 2.0);
    s.MoveTo(Vec3(0.05, -0.015, -0.008), 0.8);
    s.MoveTo(Vec3(-0.05, -0.02, -0.008), 2.0);
    s.MoveTo(Vec3(-0.05, -0.02, 0.045), 0.9);
    return {std::move(s), 8.0,
            "press 8 mm in, drag 10 cm across at a mean 5 cm/s (peak 9.4 cm/s), step down 3 cm, "
            "drag back, withdraw"};
  }
  if (name == "fast_swipe") {
    // Two swipes across the cloth, dipping 1.2 cm through its plane, peak 2 m/s in the world.
    const double peak_D = 2.0 / kDefaultDeviceScale;
    Script s(Vec3(-0.07, 0.0, 0.04));
    s.Hold(0.5);
    s.MoveTo(Vec3(-0.07, 0.0, 0.02), 0.5);
    s.Swipe(Vec3(0.07, -0.01, 0.02), 0.032, peak_D);
    s.Hold(1.0);
    s.Swipe(Vec3(-0.07, 0.005, 0.02), 0.032, peak_D);
    s.Hold(1.0);
    s.MoveTo(Vec3(-0.07, 0.005, 0.045), 0.8);
    return {std::move(s), 6.0,
            "two 14 cm swipes across the cloth, dipping to z_D = -0.012 through its plane, peak "
            "0.667 m/s device = 2 m/s world"};
  }
  if (name == "circle") {
    // Press 6 mm in and trace two 3 cm circles on the surface.
    Script s(Vec3(0.03, -0.01, 0.045));
    s.Hold(0.3);
    s.MoveTo(Vec3(0.03, -0.01, 0.004), 0.8);
    s.MoveTo(Vec3(0.03, -0.01, -0.006), 0.4);
    s.Circle(Vec3(0.0, -0.01, -0.006), 2.0, 5.0);
    s.MoveTo(Vec3(0.03, -0.01, 0.045), 0.9);
    return {std::move(s), 8.0,
            "press 6 mm in, two circles of radius 3 cm on the surface in 5 s (peak 0.14 m/s), "
            "withdraw"};
  }
  if (name == "pinch_drag") {
    // Press 2 cm in, hold button 0 (the grasp), drag the cloth sideways and back, release.
    Script s(Vec3(0.0, 0.01, 0.045));
    s.Hold(0.3);
    s.MoveTo(Vec3(0.0, 0.01, 0.005), 0.8);
    s.MoveTo(Vec3(0.0, 0.01, -0.02), 0.6);
    s.SetButtons(1);
    s.Hold(0.3);
    s.MoveTo(Vec3(0.05, 0.012, -0.02), 1.2);
    s.Hold(0.5);
    s.MoveTo(Vec3(-0.03, 0.008, -0.02), 1.6);
    s.MoveTo(Vec3(0.0, 0.01, -0.02), 0.8);
    s.Hold(0.3);
    s.SetButtons(0);
    s.MoveTo(Vec3(0.0, 0.01, 0.045), 0.9);
    return {std::move(s), 8.0,
            "press 2 cm in, button 0 down (grasp), drag 5 cm sideways, 8 cm back, return, button "
            "up, withdraw"};
  }
  return MakeHardPlan(name, seed);
}

// A value in millimetres, 3 significant digits.
std::string Mm(double value_m) {
  char text[64];
  std::snprintf(text, sizeof text, "%.3g", value_m * 1e3);
  return text;
}

}  // namespace

const std::vector<std::string>& HardTraceNames() {
  static const std::vector<std::string> names = {"scrub", "pin_drag", "vibrate", "jump",
                                                 "burst_walk"};
  return names;
}

const std::vector<std::string>& BundledTraceNames() {
  static const std::vector<std::string> names = {"poke_hold", "slow_stroke", "fast_swipe", "circle",
                                                 "pinch_drag"};
  return names;
}

Trace GenerateTrace(std::string_view name, uint64_t seed) {
  const Plan plan = MakePlan(name, seed);

  // One noise stream per (seed, name): tremor parameters first, then per-sample sensor noise.
  SplitMix64 rng(seed ^ HashName(name));
  const Tremor tremor(&rng);

  Trace trace;
  trace.header = MakeTraceHeader(
      kGeneratedRate_hz, "touch (Touch-class, workspace +-0.08 m)",
      "felt trace generate: " + std::string(name) + ", seed " + std::to_string(seed));
  TraceHeader& h = trace.header;
  h.Set("seed", std::to_string(seed));
  h.Set("motion", plan.description);
  h.Set("scene", "default curtain in the plane z_D = 0 (p_W = 3.0 * p_D), user on +z");
  h.Set("voluntary", "minimum-jerk segments (Flash & Hogan 1985)");
  h.Set("tremor", std::to_string(kTremorComponents) + " sinusoids per axis in 8-12 Hz, " +
                      Mm(kTremorRms_m) + " mm RMS; in the velocity");
  h.Set("sensor_noise", "white " + Mm(kSensorNoiseSigma_m) + " mm sigma, then quantised to " +
                            Mm(kEncoderStep_m) + " mm; position only");
  for (const auto& [key, value] : plan.notes) h.Set(key, value);

  // Sample: voluntary + tremor (exact velocity), sensor noise on the position only.
  const int64_t count = static_cast<int64_t>(std::llround(plan.duration_s * kGeneratedRate_hz)) + 1;
  trace.samples.reserve(static_cast<size_t>(count));
  for (int64_t k = 0; k < count; ++k) {
    const double t = static_cast<double>(k) / kGeneratedRate_hz;
    TraceSample sample;
    sample.t_s = t;
    const Motion voluntary = plan.script.At(t, &sample.buttons);
    const Motion shake = tremor.At(t);
    for (int a = 0; a < 3; ++a) {
      const double measured = voluntary.p[a] + shake.p[a] + kSensorNoiseSigma_m * rng.Normal();
      sample.p_D[a] = kEncoderStep_m * std::round(measured / kEncoderStep_m);
    }
    sample.v_D = voluntary.v + shake.v;
    // A step between the previous sample and this one: report its backward difference.
    for (const Script::Step& jump : plan.script.jumps()) {
      const double t_prev = static_cast<double>(k - 1) / kGeneratedRate_hz;
      if (k > 0 && t_prev < jump.t_s && jump.t_s <= t) sample.v_D += jump.step_m / (t - t_prev);
    }
    trace.samples.push_back(sample);
  }
  return trace;
}

std::vector<std::string> WriteBundledTraces(const std::string& out_dir, uint64_t seed) {
  std::vector<std::string> paths;
  for (const std::string& name : BundledTraceNames()) {
    const std::string path = out_dir + "/" + name + ".trace";
    WriteTrace(path, GenerateTrace(name, seed), TraceWriteOptions{kBundledDecimals});
    paths.push_back(path);
  }
  return paths;
}

std::vector<std::string> WriteHardTraces(const std::string& out_dir, uint64_t seed) {
  std::vector<std::string> paths;
  for (const std::string& name : HardTraceNames()) {
    const std::string path = out_dir + "/" + name + ".trace";
    WriteTrace(path, GenerateTrace(name, seed), TraceWriteOptions{kBundledDecimals});
    paths.push_back(path);
  }
  return paths;
}

Trace RealPenTrace(const std::string& real_motion_dir, int64_t trial, double press_depth_m) {
  if (!(press_depth_m > 0.0 && press_depth_m < kWorkspaceHalfExtent_m)) {
    throw std::invalid_argument("RealPenTrace: press_depth_m must be in (0, 0.08) m");
  }
  // One trial of the pen-tip recording, resampled to 1 kHz (x, y; z = 0).
  ImportOptions options;
  options.format = ImportFormat::kCsv;
  options.select_trial = trial;
  options.rate_hz = kGeneratedRate_hz;
  const std::string path = real_motion_dir + "/" + kRealPenFile;
  const Trace pen = ImportTrace(path, options);

  // Centre it on the curtain, scaled uniformly to fit +-kRealPenHalfExtent_m.
  Eigen::Vector2d lo = pen.samples.front().p_D.head<2>();
  Eigen::Vector2d hi = lo;
  for (const TraceSample& s : pen.samples) {
    lo = lo.cwiseMin(s.p_D.head<2>());
    hi = hi.cwiseMax(s.p_D.head<2>());
  }
  const Eigen::Vector2d centre = 0.5 * (lo + hi);
  const double scale = kRealPenHalfExtent_m / (0.5 * (hi - lo).maxCoeff());

  // The mapped writing, pressed in, as a Hermite curve through the 1 kHz samples with their
  // exact velocities as tangents (recordings/hermite.h), to evaluate it at warped times.
  std::vector<double> knot_t;
  std::vector<Vec3> knot_p, knot_m;
  for (const TraceSample& s : pen.samples) {
    knot_t.push_back(s.t_s);
    knot_p.emplace_back(scale * (s.p_D.x() - centre.x()), scale * (s.p_D.y() - centre.y()),
                        -press_depth_m);
    knot_m.emplace_back(scale * s.v_D.x(), scale * s.v_D.y(), 0.0);
  }
  const Vec3 first = knot_p.front();
  const Vec3 last = knot_p.back();
  const double D = knot_t.back();
  const HermiteCurve writing(std::move(knot_t), std::move(knot_p), std::move(knot_m));

  // The recording starts and ends mid-stroke; a time warp tau(t) with a minimum-jerk rate
  // tau' = MinJerk(t / R) over the first and last R seconds (Flash & Hogan 1985 profile; its
  // integral R (2.5 s^4 - 3 s^5 + s^6) is R / 2 at s = 1) starts and stops the pen at rest on its
  // own path. The warped writing lasts L = D + R.
  const double R = std::min(0.2, 0.5 * D);
  const double L = D + R;
  const auto ramp_integral = [](double s) { return s * s * s * s * (2.5 - 3.0 * s + s * s); };
  Script script(Vec3(first.x(), first.y(), 0.045));
  script.Hold(0.3);
  script.MoveTo(Vec3(first.x(), first.y(), 0.005), 0.8);
  script.MoveTo(first, 0.4);
  script.Hold(0.2);
  script.Follow(
      L,
      [writing, D, R, L, ramp_integral](double t) {
        double tau = t - 0.5 * R, rate = 1.0;
        if (t < R) {
          tau = R * ramp_integral(t / R);
          rate = MinJerk(t / R);
        } else if (t > L - R) {
          tau = D - R * ramp_integral((L - t) / R);
          rate = MinJerk((L - t) / R);
        }
        const CurvePoint c = writing.Evaluate(tau);
        return Motion{c.p, c.v * rate};
      },
      last);
  script.Hold(0.2);
  script.MoveTo(Vec3(last.x(), last.y(), 0.045), 0.9);
  script.Hold(0.3);

  Trace trace;
  trace.header = MakeTraceHeader(
      kGeneratedRate_hz, "touch (Touch-class, workspace +-0.08 m)",
      "felt trace generate --real-motion: " + path + ", trial " + std::to_string(trial));
  TraceHeader& h = trace.header;
  char mapping[256];
  std::snprintf(mapping, sizeof mapping,
                "x_D = %.6g (x %+.6g), y_D = %.6g (y %+.6g), z_D = -%.6g while writing", scale,
                -centre.x(), scale, -centre.y(), press_depth_m);
  h.Set("license", "derived from GPL (>= 2) data (cran/fda handwrit): never commit this file");
  h.Set("motion",
        "approach, press in, write one real handwriting trial scaled to +-5 cm on the curtain, "
        "withdraw");
  h.Set("scene", "default curtain in the plane z_D = 0 (p_W = 3.0 * p_D), user on +z");
  h.Set("mapping", mapping);
  if (const auto rate = pen.header.Get("source_rate_hz")) h.Set("source_rate_hz", *rate);
  char warp[160];
  std::snprintf(warp, sizeof warp,
                "minimum-jerk rate ramps over the first and last %.3g s of writing, so the pen "
                "starts and stops at rest on its path",
                R);
  h.Set("time_warp", warp);
  h.Set("noise", "none added (the recording's own)");

  // Sample the script exactly: the recording's own tremor and noise are in it already.
  const int64_t count =
      static_cast<int64_t>(std::llround(script.duration_s() * kGeneratedRate_hz)) + 1;
  trace.samples.reserve(static_cast<size_t>(count));
  for (int64_t k = 0; k < count; ++k) {
    TraceSample sample;
    sample.t_s = static_cast<double>(k) / kGeneratedRate_hz;
    const Motion m = script.At(sample.t_s, &sample.buttons);
    sample.p_D = m.p;
    sample.v_D = m.v;
    trace.samples.push_back(sample);
  }
  return trace;
}

}  // namespace felt
