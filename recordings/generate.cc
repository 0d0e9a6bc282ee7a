#include "recordings/generate.h"

#include <cmath>
#include <cstdio>
#include <functional>
#include <numbers>
#include <stdexcept>
#include <utility>

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

  // Buttons reported from the next segment on.
  void SetButtons(uint32_t buttons) { buttons_ = buttons; }

  double duration_s() const { return segments_.empty() ? 0.0 : segments_.back().t1; }

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

// The voluntary motion of each bundled trace and its total duration [s].
struct Plan {
  Script script;
  double duration_s;
  const char* description;
};

Plan MakePlan(std::string_view name) {
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
  throw std::invalid_argument("unknown bundled trace '" + std::string(name) +
                              "' (poke_hold, slow_stroke, fast_swipe, circle, pinch_drag)");
}

// A value in millimetres, 3 significant digits.
std::string Mm(double value_m) {
  char text[64];
  std::snprintf(text, sizeof text, "%.3g", value_m * 1e3);
  return text;
}

}  // namespace

const std::vector<std::string>& BundledTraceNames() {
  static const std::vector<std::string> names = {"poke_hold", "slow_stroke", "fast_swipe", "circle",
                                                 "pinch_drag"};
  return names;
}

Trace GenerateTrace(std::string_view name, uint64_t seed) {
  const Plan plan = MakePlan(name);

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

}  // namespace felt
