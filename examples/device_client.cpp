// A haptic device driver for Felt, as small as it can be. Adapt the two functions marked
// "REPLACE" to your hardware and keep the rest: it is the protocol a driver must follow
// (docs/transport.md).
//
// What it does, 1000 times a second, on absolute deadlines:
//   1. reads the device (ReadDevice: here a simulated tip pressing and stroking the cloth),
//   2. publishes a PointerSample on felt/pointer (position in m, velocity in m/s, device frame),
//   3. takes the newest ForceCommand for this device from felt/force and writes a force to the
//      motors (WriteMotorForce: here it only accumulates and prints): between messages it renders
//      the command's local contact model at the tip's CURRENT position (Mark et al. 1996),
//        F = k * max(0, (contact_point - tip) . contact_normal) * contact_normal,  k > 0,
//      and the command's force_N as sent when k = 0 (no contact, or the server ramping). Use it
//      whenever your servo loop runs faster than, or out of step with, the messages: a late message
//      then costs the plane's motion, not the tip's (transport/local_contact.h, docs/transport.md),
//   4. SAFETY: when no ForceCommand has arrived for --silence-ms (default 50 ms), or one holds a
//      non-finite value, it writes ZERO force, every tick, until the server speaks again. It also
//      clamps to the device's own maximum force and writes zero when it exits.
//
// Build: the felt_device_client target (see docs/transport.md), or by hand next to Felt's build:
//   c++ -std=c++20 -O2 -I. -Ibuild/transport examples/device_client.cpp
//       build/libfelt_transport.a build/transport/libfelt_transport_types.a -lddsc -lpthread
// Run:  felt_device_client [--device default] [--seconds 10] [--domain 0] [--dds-config FILE]

#include <signal.h>
#include <time.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <string>

#include "transport/client_transport.h"
#include "transport/local_contact.h"

namespace {

// ---------------------------------------------------------------------------------------------
// REPLACE: read your device. Return the tip position (m) and velocity (m/s) in YOUR device frame
// (the frame the scene's device mapping expects), the buttons, and the time of the measurement on
// CLOCK_MONOTONIC (ns). This simulation makes the default scene's cloth felt: with its mapping
// (world = 3 x device, the curtain hanging in the plane z = 0 from its top corners at y = 0.25 m,
// facing +z; docs/scenes.md) the tip comes from 1.2 cm in front of the cloth, 10 cm below its top
// edge, presses 2.4 cm through its rest place while stroking +-6 cm sideways, and comes back out,
// every 4 s (device frame: x +-2 cm, y 5 cm, z +4 to -8 mm).
struct DeviceReading {
  std::array<double, 3> position_m_D{};
  std::array<double, 3> velocity_m_per_s_D{};
  uint32_t buttons = 0;
  int64_t time_ns = 0;
};

DeviceReading ReadDevice(int64_t now_ns, int64_t start_ns) {
  constexpr double kStroke_m = 0.02;  // sideways amplitude, device frame
  constexpr double kFront_m = 0.004;  // farthest in front of the cloth, device frame
  constexpr double kHeight_m = 0.05;  // above the device origin, device frame
  constexpr double kDepth_m = 0.012;  // how far in from kFront_m at the deepest
  constexpr double kPeriod_s = 4.0;   // one press: in, stroke, out
  constexpr double kOmega = 2.0 * M_PI / kPeriod_s;
  const double t_s = static_cast<double>(now_ns - start_ns) * 1e-9;
  DeviceReading r;
  // x = A sin(w t), z = front - depth (1 - cos(w t)) / 2: in and out once per stroke.
  r.position_m_D = {kStroke_m * std::sin(kOmega * t_s), kHeight_m,
                    kFront_m - kDepth_m * 0.5 * (1.0 - std::cos(kOmega * t_s))};
  r.velocity_m_per_s_D = {kStroke_m * kOmega * std::cos(kOmega * t_s), 0.0,
                          -kDepth_m * 0.5 * kOmega * std::sin(kOmega * t_s)};
  r.buttons = 0;
  r.time_ns = now_ns;
  return r;
}

// ---------------------------------------------------------------------------------------------
// REPLACE: write the force (N, device frame) to the motors. Called every tick with the force to
// hold until the next tick (zero when the server is silent). This simulation only keeps a sum so
// that the once-a-second line can show what the motors would have done.
struct MotorLog {
  std::array<double, 3> last_N{};
  double impulse_N_s = 0;  // sum of |F| dt
  double peak_N = 0;       // largest |F| written
};
MotorLog g_motor;

void WriteMotorForce(const std::array<double, 3>& force_N_D) {
  const double norm_N = std::sqrt(force_N_D[0] * force_N_D[0] + force_N_D[1] * force_N_D[1] +
                                  force_N_D[2] * force_N_D[2]);
  g_motor.last_N = force_N_D;
  g_motor.impulse_N_s += norm_N * 1e-3;
  g_motor.peak_N = std::max(g_motor.peak_N, norm_N);
}
// ---------------------------------------------------------------------------------------------

std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop.store(true); }

int64_t ToNs(const timespec& ts) {
  return static_cast<int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}

timespec FromNs(int64_t ns) {
  return timespec{static_cast<time_t>(ns / 1000000000), static_cast<long>(ns % 1000000000)};
}

int64_t Now() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ToNs(ts);
}

}  // namespace

int main(int argc, char** argv) {
  // Options: which device, which domain and configuration, how long, the safety limits.
  std::string device_id = "default";  // the default scene's device (docs/scenes.md)
  double seconds = 0;  // 0 = until Ctrl-C
  double silence_ms = 50;
  double max_force_N = 10;
  felt::transport::DdsSettings dds;
  std::string topic_suffix;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const char* value = i + 1 < argc ? argv[i + 1] : nullptr;
    if (arg == "--help" || value == nullptr) {
      std::fprintf(arg == "--help" ? stdout : stderr,
                   "usage: %s [--device ID] [--seconds S] [--silence-ms MS] [--max-force N]\n"
                   "          [--domain N] [--dds-config FILE] [--topic-suffix S]\n"
                   "          [--security DIR [--identity NAME]]\n"
                   "A 1 kHz haptic device driver for Felt over DDS (docs/transport.md).\n",
                   argv[0]);
      return arg == "--help" ? 0 : 2;
    }
    ++i;
    if (arg == "--device") {
      device_id = value;
    } else if (arg == "--seconds") {
      seconds = std::atof(value);
    } else if (arg == "--silence-ms") {
      silence_ms = std::atof(value);
    } else if (arg == "--max-force") {
      max_force_N = std::atof(value);
    } else if (arg == "--domain") {
      dds.domain_id = static_cast<uint32_t>(std::atoi(value));
    } else if (arg == "--dds-config") {
      dds.config_file = value;
    } else if (arg == "--security") {  // DDS Security: a directory of `felt security init`
      dds.security_dir = value;
    } else if (arg == "--identity") {  // default: device-<device id>
      dds.identity = value;
    } else if (arg == "--topic-suffix") {
      topic_suffix = value;
    } else {
      std::fprintf(stderr, "%s: unknown option %s (try --help)\n", argv[0], arg.c_str());
      return 2;
    }
  }

  try {
    // Join the DDS domain: writer on felt/pointer, reader on felt/force.
    felt::transport::ClientTransportConfig config;
    config.dds = dds;
    config.topics = felt::transport::TopicNames::WithAffixes("", topic_suffix);
    config.device_ids = {device_id};
    config.subscribe_status = false;
    felt::transport::ClientTransport client(config);
    signal(SIGINT, OnSignal);
    signal(SIGTERM, OnSignal);
    std::printf("device %s: publishing on %s at 1 kHz, forces from %s\n", device_id.c_str(),
                config.topics.pointer.c_str(), config.topics.force.c_str());

    constexpr int64_t kPeriod_ns = 1000000;  // 1 kHz
    const auto silence_ns = static_cast<int64_t>(silence_ms * 1e6);
    const int64_t start_ns = Now();
    const int64_t end_ns = seconds > 0 ? start_ns + static_cast<int64_t>(seconds * 1e9) : INT64_MAX;
    int64_t next_ns = start_ns;
    int64_t last_force_ns = 0;  // CLOCK_MONOTONIC of the last good ForceCommand, 0 = none yet
    int64_t next_report_ns = start_ns + 1000000000;
    uint64_t seq = 0, forces = 0, missed_periods = 0, silent_ticks = 0;
    double last_round_trip_ms = 0;
    bool silent = true;
    std::array<double, 3> force_N{};
    felt::transport::ForceCommandView newest;  // the newest good ForceCommand (its local model)

    while (!g_stop.load() && next_ns < end_ns) {
      // 1-2. Read the device and publish the sample (seq strictly increasing).
      const DeviceReading reading = ReadDevice(Now(), start_ns);
      felt::transport::PointerSampleView sample;
      sample.seq = ++seq;
      sample.device_time_ns = reading.time_ns;
      sample.position_m_D = reading.position_m_D;
      sample.velocity_m_per_s_D = reading.velocity_m_per_s_D;
      sample.buttons = reading.buttons;
      client.PublishPointer(sample);

      // 3. The newest force for this device, if one arrived; a non-finite one is ignored.
      felt::transport::ForceCommandView command;
      const int64_t now_ns = Now();
      if (client.TakeForce(0, &command) && std::isfinite(command.force_N_D[0]) &&
          std::isfinite(command.force_N_D[1]) && std::isfinite(command.force_N_D[2])) {
        newest = command;
        last_force_ns = now_ns;
        ++forces;
        // device_time_ns is this driver's own clock, so the round trip needs no clock sync.
        last_round_trip_ms = static_cast<double>(now_ns - command.answers_device_time_ns) * 1e-6;
      }

      // The force at the tip's current position from the newest command's local contact model
      // (its force_N when it has no plane), clamped to the device's maximum; NaN gives zero.
      force_N = felt::transport::LocalContactForce(newest, reading.position_m_D, max_force_N);

      // 4. Safety: zero force while the server is silent.
      const bool now_silent = last_force_ns == 0 || now_ns - last_force_ns > silence_ns;
      if (now_silent != silent) {
        std::printf(now_silent ? "server silent for > %.0f ms: ZERO force\n"
                               : "server forces arriving (silence limit %.0f ms)\n",
                    silence_ms);
        silent = now_silent;
      }
      if (silent) {
        force_N = {0.0, 0.0, 0.0};
        ++silent_ticks;
      }
      WriteMotorForce(force_N);

      // Once a second: what happened (a real driver logs from another thread).
      if (now_ns >= next_report_ns) {
        std::printf(
            "samples %llu  forces %llu  silent ticks %llu  missed periods %llu  "
            "F = (%.3f, %.3f, %.3f) N  round trip %.3f ms\n",
            static_cast<unsigned long long>(seq), static_cast<unsigned long long>(forces),
            static_cast<unsigned long long>(silent_ticks),
            static_cast<unsigned long long>(missed_periods), g_motor.last_N[0], g_motor.last_N[1],
            g_motor.last_N[2], last_round_trip_ms);
        std::fflush(stdout);
        next_report_ns += 1000000000;
      }

      // Sleep to the next absolute deadline; after an overrun skip the missed periods.
      next_ns += kPeriod_ns;
      const int64_t after_ns = Now();
      if (after_ns > next_ns) {
        const int64_t missed = (after_ns - next_ns) / kPeriod_ns + 1;
        missed_periods += static_cast<uint64_t>(missed);
        next_ns += missed * kPeriod_ns;
      }
      const timespec deadline = FromNs(next_ns);
      while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &deadline, nullptr) == EINTR &&
             !g_stop.load()) {
      }
    }

    // Leaving: the motors must not keep the last force.
    WriteMotorForce({0.0, 0.0, 0.0});
    std::printf(
        "stopped: samples %llu, forces %llu, motor impulse %.3f N s, peak force %.3f N, zero force "
        "written\n",
        static_cast<unsigned long long>(seq), static_cast<unsigned long long>(forces),
        g_motor.impulse_N_s, g_motor.peak_N);
    return 0;
  } catch (const std::exception& e) {
    WriteMotorForce({0.0, 0.0, 0.0});
    std::fprintf(stderr, "felt_device_client: error: %s\n", e.what());
    return 1;
  }
}
