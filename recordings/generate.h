#pragma once
// The generator of the bundled pointer traces (recordings/*.trace, `felt trace generate`):
// motion a person would make with a Touch-class device against the default scene's curtain.
//
// Two sets: the five smooth bundled traces (recordings/*.trace) and the hard ones
// (recordings/hard/*.trace: scrubbing, dragging at a pin, vibration, one-sample jumps, a random
// walk with bursts), plus RealPenTrace, a real handwriting recording written onto the curtain
// (made at run time from third-party data, never committed).
//
// Geometry (device frame _D, metres; the default scene maps p_W = 3.0 * p_D): the curtain hangs in
// the plane z_D = 0 with x_D in [-0.0827, 0.0827] and its pinned top edge at y_D = +0.0833; the
// user is on the +z side, so pressing into the cloth is moving toward -z. The device workspace is
// taken as |x_D|, |y_D|, |z_D| <= kWorkspaceHalfExtent_m.
//
// Each trace is the sum of
//  - voluntary motion: minimum-jerk point-to-point segments (Flash & Hogan, J. Neurosci. 5(7),
//    1985: x(s) = x0 + (x1 - x0)(10 s^3 - 15 s^4 + 6 s^5), s = t / T), holds, and for the circle a
//    minimum-jerk profile of the angle; the hard traces add oscillations under a minimum-jerk
//    envelope (scrub, vibrate), one-sample jumps, and an Ornstein-Uhlenbeck walk with flicks;
//  - physiological tremor: per axis a sum of kTremorComponents sinusoids with frequencies drawn
//    uniformly in 8-12 Hz and random phases, scaled to kTremorRms_m RMS (band-limited noise of
//    about 0.1-0.5 mm amplitude; Elble & Koller, "Tremor", 1990: 8-12 Hz physiological tremor);
//  - sensor noise on the position only: white Gaussian noise (kSensorNoiseSigma_m) then encoder
//    quantisation to kEncoderStep_m.
// The velocity column is the exact derivative of voluntary motion + tremor (both analytic); the
// sensor noise, zero-mean and bounded by about kEncoderStep_m / 2 + 4 sigma, is not differentiated
// (as from an ideal velocity filter), so integrating the velocity reproduces the position to within
// that bound. Everything is deterministic from the seed (own SplitMix64 generator and Box-Muller
// transform, no std:: distributions, whose output differs between standard libraries).

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "recordings/trace.h"

namespace felt {

/// Half extent of the device workspace box used for the bundled traces [m, device frame].
inline constexpr double kWorkspaceHalfExtent_m = 0.08;
/// Scale of the default scene's device-to-world map, p_W = kDefaultDeviceScale * p_D.
inline constexpr double kDefaultDeviceScale = 3.0;
/// Half width of the default curtain in the device frame, 0.248 m / 3 [m]: x_D in [-this, this].
inline constexpr double kCurtainHalfWidth_m = 0.248 / kDefaultDeviceScale;
/// Height of the default curtain's pinned top edge in the device frame, 0.25 m / 3 [m]; its two
/// top corners (+-kCurtainHalfWidth_m, kCurtainTopY_m, 0) are the only pins.
inline constexpr double kCurtainTopY_m = 0.25 / kDefaultDeviceScale;
/// RMS of the tremor per axis [m].
inline constexpr double kTremorRms_m = 0.00015;
/// Sinusoids per axis in the tremor sum.
inline constexpr int kTremorComponents = 12;
/// Standard deviation of the white position noise [m].
inline constexpr double kSensorNoiseSigma_m = 0.00001;
/// Encoder quantisation step of the reported position [m].
inline constexpr double kEncoderStep_m = 0.00003;
/// Sample rate of every generated trace [Hz].
inline constexpr double kGeneratedRate_hz = 1000.0;
/// The seed `felt trace generate` uses by default and the bundled traces were made with.
inline constexpr uint64_t kDefaultTraceSeed = 1;
/// Decimals the bundled files are written with (1 um, 1 um/s, 1 us; keeps each file < 1 MB).
inline constexpr int kBundledDecimals = 6;

/// Frequency of the `vibrate` trace's vibration [Hz].
inline constexpr double kVibrateFrequency_hz = 250.0;
/// Amplitude of the `vibrate` trace's vibration along z_D [m] (in phase with the x_D one).
inline constexpr double kVibrateAmplitudeZ_m = 0.0004;
/// Amplitude of the `vibrate` trace's vibration along x_D [m].
inline constexpr double kVibrateAmplitudeX_m = 0.0002;
/// Sideways amplitude of the `scrub` trace [m].
inline constexpr double kScrubAmplitude_m = 0.03;
/// Frequency of the `scrub` trace's back-and-forth [Hz]; peak speed 2 pi f A = 0.94 m/s.
inline constexpr double kScrubFrequency_hz = 5.0;
/// The real recording RealPenTrace reads from its data directory (cran/fda `handwrit`, GPL).
inline constexpr const char* kRealPenFile = "fda_handwrit_optotrak_600Hz.csv";
/// Trials (repetitions) in kRealPenFile: RealPenTrace's `trial` is 1..this.
inline constexpr int64_t kRealPenTrials = 20;
/// RealPenTrace scales the handwriting to fit x_D, y_D in [-this, this] [m].
inline constexpr double kRealPenHalfExtent_m = 0.05;

/// The names of the bundled traces, in generation order:
/// poke_hold, slow_stroke, fast_swipe, circle, pinch_drag.
const std::vector<std::string>& BundledTraceNames();

/// The names of the hard traces (recordings/hard/), in generation order:
/// scrub, pin_drag, vibrate, jump, burst_walk.
const std::vector<std::string>& HardTraceNames();

/// One generated trace, bundled or hard (samples at k / kGeneratedRate_hz, device frame), by name;
/// throws std::invalid_argument for an unknown name. Each trace draws its noise from a stream
/// seeded by (seed, name), so traces are independent of each other and of generation order.
/// In `jump` the position steps between two samples; the first sample after each step reports
/// the step divided by the sample period (1 ms) on top of the analytic velocity, the backward
/// difference a device differentiating its encoders would report (recordings/README.md).
Trace GenerateTrace(std::string_view name, uint64_t seed);

/// Generates every bundled trace into `out_dir`/NAME.trace with kBundledDecimals decimals and
/// returns the paths written. Throws std::runtime_error if a file cannot be written.
std::vector<std::string> WriteBundledTraces(const std::string& out_dir, uint64_t seed);

/// Generates every hard trace into `out_dir`/NAME.trace (the committed ones live in
/// recordings/hard/) with kBundledDecimals decimals and returns the paths written. Throws
/// std::runtime_error if a file cannot be written.
std::vector<std::string> WriteHardTraces(const std::string& out_dir, uint64_t seed);

/// A real pen recording written onto the curtain: trial `trial` of `real_motion_dir`/kRealPenFile
/// (pen tip x, y at 609 Hz, imported with ImportTrace at kGeneratedRate_hz), centred on the
/// curtain and scaled uniformly to fit x_D, y_D in +-kRealPenHalfExtent_m, written press_depth_m
/// [m] into the cloth (z_D = -press_depth_m). Minimum-jerk segments approach from and withdraw to
/// z_D = +0.045 at rest; the pen starts and stops along its path with a minimum-jerk time warp.
/// No synthetic tremor or noise is added. The result derives from GPL data: never commit it.
/// Throws TraceError if the file is missing or malformed, std::invalid_argument for a bad depth.
Trace RealPenTrace(const std::string& real_motion_dir, int64_t trial = 1,
                   double press_depth_m = 0.008);

}  // namespace felt
