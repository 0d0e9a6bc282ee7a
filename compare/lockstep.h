#pragma once
// The server in lock-step virtual time, for `felt compare` (issue 7; docs/compare.md): a pointer
// trace drives the real Server (server/server.h) through its public HapticTick and SimFrame
// on a virtual clock, one thread, no DDS, so every variant of a scene (collision structure,
// integrator, snapshot mode, proxy settings) receives the same input and the forces it produces
// can be compared tick by tick (the evaluation method of 001_0f9f1b7fedff7723.txt §6).
//
// Virtual time, for a haptic rate R (Hz) and a frame rate F (Hz) of the variant's scene:
//  - t0 = kLockstepEpochNs: the rest state (frame 0) is published (Server::PublishInitialSnapshot,
//    as Server::Start does);
//  - haptic tick k = 1, 2, ... at t0 + round(k * 1e9 / R) ns, HapticTick(t, 1 / R): the first tick
//    releases the trace's first sample (TracePointerSource), so the trace plays from there;
//  - sim frame j = 1, 2, ... at t0 + round(j * 1e9 / F) ns, SimFrame(1 / F, t): run before a tick
//    at the same or a later time, its snapshot stamped at its own virtual time (a frame takes no
//    virtual time: the snapshot is as fresh as a sim thread with zero compute time makes it);
//  - the run ends with the tick that releases the trace's last sample (or at max_duration_s).
// Every result is a function of the scene, the variant and the trace only: repeated runs give the
// same forces bit for bit. Costs are thread CPU time (CLOCK_THREAD_CPUTIME_ID) of each call, so
// they vary from run to run. After every tick, outside the timed call, each device's proxy is
// probed (proxy/proxy_probe.h: how deep it reaches into the cloth it was rendered on, and
// pop-through).
//
// The truth (issue 20; docs/compare.md, "The truth"): the scene with its cloth stepped once per
// haptic tick (frame rate = haptic rate) and the proxy in mode newest, so every tick renders the
// exact cloth of its own time, coupled both ways at the haptic rate. It is the reference the
// snapshot modes are judged against (`felt compare --truth`, `felt bench haptic`).
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "base/json.h"
#include "collision/mesh.h"
#include "recordings/trace.h"
#include "scene/scene_file.h"
#include "server/server_spec.h"

namespace felt {

class Server;

/// The virtual clock's origin, ns: any value > 0 (0 means "now" to Server::SimFrame).
inline constexpr int64_t kLockstepEpochNs = 1'000'000'000'000;

/// One override of a scene value: `key` as written (a shorthand such as "snapshot", or a dotted
/// scene path such as "proxy.max_iterations") and `value` as written ("blend_forces", "8").
struct VariantOverride {
  std::string key;    ///< as written
  std::string value;  ///< as written (TOML literal, or a bare word taken as a string)
};

/// The name of the truth variant (TruthVariant, `felt compare --truth`).
inline constexpr char kTruthName[] = "truth";

/// One variant of a comparison: a name and the overrides that make it from the scene.
struct LockstepVariant {
  std::string name;                        ///< unique in the list; shown in tables
  std::vector<VariantOverride> overrides;  ///< applied in order (empty: the scene as written)
  /// The overrides as "key=value,key=value" ("" when none).
  std::string OverridesText() const;
};

/// Parses a --variants list (docs/compare.md): variants separated by ';', each `[NAME:]
/// key=value[,key=value...]`, or the bare word `scene` (no override); the bare word `truth`
/// stands for the override truth=on. A variant without NAME is named by its overrides ("scene"
/// when it has none, "truth" for the bare word alone). Commas and semicolons inside [...] or "..."
/// do not split. Throws std::invalid_argument naming the variant (1-based) and the bad part: an
/// empty list, a part without '=', an empty key or value, an unknown shorthand or section, a
/// duplicate name.
std::vector<LockstepVariant> ParseVariantList(std::string_view text);

/// The shorthand keys (structure, snapshot, shading, friction, integrator, substeps, provot,
/// truth) with the scene keys they set, as "shorthand -> scene key" lines, for --help and messages.
std::vector<std::pair<std::string, std::string>> VariantShorthands();

/// The truth as a variant named kTruthName (file comment): the override truth=on, i.e.
/// integration.frame_rate_hz = haptic.haptic_rate_hz (read from the scene, 1000 Hz by default)
/// and proxy.snapshot_mode = newest. `frames_per_tick` > 1 steps the cloth that many frames per
/// tick instead (truth=N, frame rate N x haptic rate, named "truth_Nx"), for convergence checks.
/// Throws std::invalid_argument for frames_per_tick < 1.
LockstepVariant TruthVariant(int frames_per_tick = 1);

/// `scene` with `variant`'s overrides applied to its TOML tree, parsed into a ServerSpec
/// (ParseServerSpec: every key checked as in a scene file). Throws std::invalid_argument
/// "variant N 'NAME': KEY=VALUE: <scene error>" naming the override the error is about (or all of
/// them when the error names none).
ServerSpec VariantSpec(const SceneDocument& scene, const LockstepVariant& variant, int index);

/// How a lock-step run is limited, and what a comparison adds to the variants it is given.
struct LockstepOptions {
  double max_duration_s = 0.0;  ///< stop after this much virtual time, s (0: the whole trace)
  /// CompareVariants only: run TruthVariant() first, as variant 0 and the reference, before the
  /// variants given (which keep their numbers 1, 2, ... in messages).
  bool prepend_truth = false;
  /// RunLockstep only, for tests that check the run as it goes (optional): called after every
  /// SimFrame with the server and the frame's number (1, 2, ...), and after every HapticTick (and
  /// its probes) with the server and the tick's number (1, 2, ...). The server's cloth, model and
  /// haptic loop may be read there (Server::cloth, Server::haptic); not timed.
  std::function<void(const Server&, int64_t frame)> on_frame;
  std::function<void(const Server&, int64_t tick)> on_tick;  ///< see on_frame
};

/// Everything one lock-step run recorded. Arrays are indexed [tick * devices + device].
struct LockstepRun {
  std::string name;                  ///< the variant's name
  std::string overrides;             ///< LockstepVariant::OverridesText
  uint32_t devices = 0;              ///< devices of the scene (each replays the trace)
  double tick_dt_s = 0.0;            ///< haptic period, s
  int64_t ticks = 0;                 ///< HapticTick calls
  int64_t frames = 0;                ///< SimFrame calls
  std::vector<Vec3> force_D_N;       ///< force sent, device frame, N (after the safety layer)
  std::vector<uint8_t> in_contact;   ///< 1 when the proxy touched the cloth at that tick
  std::vector<double> reach_m;       ///< ProbeProxy reach after that tick, m (0: not touching)
  std::vector<uint8_t> popped;       ///< 1 when ProbeProxy flagged pop-through at that tick
  std::vector<double> tick_cpu_us;   ///< thread CPU time of each HapticTick, us
  std::vector<double> frame_cpu_ms;  ///< thread CPU time of each SimFrame, ms
  /// Median thread CPU time between two back-to-back clock reads (1000 pairs before the run), us:
  /// the timer's own share of each tick and frame figure (not subtracted from them).
  double timer_overhead_us = 0.0;
  uint64_t clamped_ticks = 0;     ///< device ticks flagged clamped (force or rate)
  uint64_t stalled_ticks = 0;     ///< device ticks flagged sim stalled
  uint64_t nan_events = 0;        ///< safety NaN events
  uint64_t cloth_nan_events = 0;  ///< sim frames that recovered from non-finite values
};

/// The most haptic ticks one lock-step run makes: 4 hours at 1 kHz (its arrays hold about 70 bytes
/// a tick and device, and each tick steps the server).
inline constexpr int64_t kMaxLockstepTicks = int64_t{4} * 3600 * 1000;

/// The haptic ticks a lock-step run of `samples` at `rate_hz` makes: one per period from the first
/// sample to the last (or to max_duration_s of virtual time when > 0). Throws
/// std::invalid_argument for no samples, or naming the span when it needs more than
/// kMaxLockstepTicks (a corrupt time in the trace, or a recording to cut with --duration).
int64_t LockstepTicks(const std::vector<TraceSample>& samples, double rate_hz,
                      double max_duration_s);

/// Runs `spec` driven by `samples` (fed to every device) in lock-step virtual time (file
/// comment). Set-up allocates; the ticks do not. Throws std::invalid_argument for an empty trace
/// or a spec the Server refuses.
LockstepRun RunLockstep(const ServerSpec& spec, const std::vector<TraceSample>& samples,
                        const LockstepOptions& options = {});

/// One variant's figures, against the reference (the first run). Units in the names.
struct VariantSummary {
  std::string name;                ///< the variant's name
  std::string overrides;           ///< its overrides ("" for none)
  int64_t ticks = 0;               ///< haptic ticks
  int64_t frames = 0;              ///< sim frames
  double tick_us_median = 0.0;     ///< HapticTick thread CPU time, median, us
  double tick_us_p99 = 0.0;        ///< ... 99th percentile (nearest rank), us
  double frame_ms_median = 0.0;    ///< SimFrame thread CPU time, median, ms
  double frame_ms_p99 = 0.0;       ///< ... 99th percentile (nearest rank), ms
  double timer_overhead_us = 0.0;  ///< LockstepRun::timer_overhead_us, us
  double force_rms_error_N = 0.0;  ///< sqrt(mean |F - F_ref|^2) over every tick and device, N
  double force_max_error_N = 0.0;  ///< max |F - F_ref|, N
  double max_jump_N = 0.0;         ///< this variant's largest |F(k) - F(k-1)|, N
  double max_jump_vs_ref_N = 0.0;  ///< max_jump_N minus the reference's max_jump_N, N
  double peak_force_N = 0.0;       ///< largest |F|, N
  /// peak_force_N minus the reference's peak_force_N, N: > 0 a spike the reference does not have
  double peak_minus_ref_peak_N = 0.0;
  uint64_t contacts = 0;            ///< device ticks in contact
  uint64_t contact_mismatches = 0;  ///< device ticks whose contact differs from the reference
  uint64_t pop_through = 0;         ///< device ticks ProbeProxy flagged popped (through the cloth)
  double max_reach_mm = 0.0;        ///< deepest ProbeProxy reach into the tick's cloth, mm
  uint64_t clamped_ticks = 0;       ///< LockstepRun::clamped_ticks
  uint64_t stalled_ticks = 0;       ///< LockstepRun::stalled_ticks
  uint64_t nan_events = 0;          ///< safety plus cloth NaN events
};

/// Summarises `runs` against runs[0] (whose errors are 0 by construction: it is compared with
/// itself). Throws std::invalid_argument when a run's ticks or devices differ from the reference
/// (the forces cannot be paired tick by tick).
std::vector<VariantSummary> SummarizeRuns(const std::vector<LockstepRun>& runs);

/// One variant's figures as `felt compare --json` and `felt bench haptic --json` write them, every
/// field of VariantSummary under its own name, in its order (the CSV columns follow it).
Json VariantSummaryJson(const VariantSummary& s);

/// A whole comparison: every variant's run and summary, in the order given.
struct CompareResult {
  std::vector<LockstepRun> runs;          ///< one per variant
  std::vector<VariantSummary> summaries;  ///< one per variant; [0] is the reference
};

/// What `--truth` (LockstepOptions::prepend_truth) would compare unlike with like: one line per
/// variant that overrides a key of the scene's [cloth] table (its grid, spacing, mass, drag ...),
/// naming the variant and its keys, since the prepended truth runs the cloth as the scene file has
/// it (the same trace on another cloth); empty when none does. The remedy is to list the truth
/// with the same cloth keys ("truth: truth=on,cloth.width=64,...") instead of `--truth`.
std::vector<std::string> TruthClothMismatches(const std::vector<LockstepVariant>& variants);

/// Builds every variant's spec (VariantSpec) and checks they can be paired with the first (same
/// haptic_rate_hz and number of devices) before running any, then runs each (RunLockstep) and
/// summarises them (SummarizeRuns). With options.prepend_truth the truth (TruthVariant) runs
/// first as variant 0 and is the reference. Throws std::invalid_argument naming the variant (also
/// for a given variant named kTruthName beside prepend_truth).
CompareResult CompareVariants(const SceneDocument& scene, const std::vector<TraceSample>& samples,
                              const std::vector<LockstepVariant>& variants,
                              const LockstepOptions& options = {});

}  // namespace felt
