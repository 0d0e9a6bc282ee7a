#include "compare/lockstep.h"

#include <time.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <memory>
#include <optional>
#include <stdexcept>
#include <system_error>

#include "base/report.h"
#include "haptic_loop/haptic_spec.h"
#include "haptic_loop/pointer_source.h"
#include "proxy/proxy_probe.h"
#include "server/server.h"

namespace felt {
namespace {

// report::Percentile of CPU times (p in [0, 100]), 0 for none: a variant without ticks or frames
// reports zero times.
double TimesPercentile(const std::vector<double>& samples, double p) {
  return samples.empty() ? 0.0 : report::Percentile(samples, p);
}

// A shorthand key and the scene keys it sets.
struct Shorthand {
  std::string_view key;
  std::string_view scene_key;
};
constexpr std::array<Shorthand, 8> kShorthands = {{
    {"structure", "proxy.collision_structure"},
    {"snapshot", "proxy.snapshot_mode"},
    {"shading", "proxy.force_shading"},
    {"friction", "proxy.friction_static + proxy.friction_dynamic"},
    {"integrator", "integration.integrator"},
    {"substeps", "integration.substeps"},
    {"provot", "provot.enabled"},
    {"truth", "integration.frame_rate_hz = N x haptic.haptic_rate_hz + proxy.snapshot_mode"},
}};

// The most cloth frames per haptic tick truth=N accepts (the frame rate's own limit,
// kMaxFrameRate_hz, is checked by the scene parser).
constexpr int kMaxTruthFramesPerTick = 10;

std::string_view Trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

// Splits `text` at `separator`, except inside [...] or "..." (array and string values).
std::vector<std::string_view> SplitTopLevel(std::string_view text, char separator) {
  std::vector<std::string_view> parts;
  int depth = 0;
  bool quoted = false;
  size_t start = 0;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '"') quoted = !quoted;
    if (quoted) continue;
    if (c == '[') ++depth;
    if (c == ']' && depth > 0) --depth;
    if (c == separator && depth == 0) {
      parts.push_back(text.substr(start, i - start));
      start = i + 1;
    }
  }
  parts.push_back(text.substr(start));
  return parts;
}

// "variant 2 'blend'" (or "variant 2" before the name is known).
std::string VariantLabel(int index, std::string_view name) {
  std::string label = "variant " + std::to_string(index);
  if (!name.empty()) label += " '" + std::string(name) + "'";
  return label;
}

bool IsShorthand(std::string_view key) {
  return std::any_of(kShorthands.begin(), kShorthands.end(),
                     [&](const Shorthand& s) { return s.key == key; });
}

// A dotted scene path whose first part is a [table] section of the scene format.
bool IsScenePath(std::string_view key, std::string* why) {
  const size_t dot = key.find('.');
  if (dot == std::string_view::npos || dot == 0 || dot + 1 == key.size()) {
    *why = "not a shorthand nor a dotted scene path";
    return false;
  }
  const std::string_view section = key.substr(0, dot);
  for (const SceneSectionInfo& info : KnownSceneSections()) {
    if (info.name != section) continue;
    if (info.shape == SectionShape::kArrayOfTables) {
      *why = "[[" + std::string(section) + "]] is an array of tables, which cannot be overridden";
      return false;
    }
    return true;
  }
  *why = "unknown section '" + std::string(section) + "'";
  return false;
}

std::string ShorthandList() {
  std::string list;
  for (const Shorthand& s : kShorthands) {
    if (!list.empty()) list += ", ";
    list += s.key;
  }
  return list;
}

// on/off (also true/false, yes/no) as a boolean, or nullopt.
std::optional<bool> OnOff(std::string_view value) {
  if (value == "on" || value == "true" || value == "yes") return true;
  if (value == "off" || value == "false" || value == "no") return false;
  return std::nullopt;
}

std::optional<double> ParseDouble(std::string_view text) {
  double value = 0.0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(value)) {
    return std::nullopt;
  }
  return value;
}

// `value` as a TOML value: a TOML literal (8, 2.5, true, "x", [0, 0, 1]) or else a bare word
// taken as a string (newest, bvh-aabb-4, auto).
toml::table LiteralTable(std::string_view value) {
  try {
    const toml::table parsed = toml::parse("v = " + std::string(value));
    const toml::node* v = parsed.get("v");
    if (parsed.size() == 1 && v != nullptr) {
      // Scalars are copied without their position in "v = ...", which is not in the scene file.
      toml::table fresh;
      if (const auto* i = v->as_integer()) {
        fresh.insert_or_assign("v", i->get());
      } else if (const auto* f = v->as_floating_point()) {
        fresh.insert_or_assign("v", f->get());
      } else if (const auto* b = v->as_boolean()) {
        fresh.insert_or_assign("v", b->get());
      } else if (const auto* s = v->as_string()) {
        fresh.insert_or_assign("v", s->get());
      } else {
        return parsed;
      }
      return fresh;
    }
  } catch (const toml::parse_error&) {
    // Not a literal: a bare word.
  }
  toml::table word;
  word.insert_or_assign("v", std::string(value));
  return word;
}

// Sets the dotted scene path `path` of `root` to the value `literal["v"]`, creating tables.
void SetScenePath(toml::table* root, std::string_view path, const toml::table& literal) {
  toml::table* table = root;
  std::vector<std::string_view> parts = SplitTopLevel(path, '.');
  for (size_t i = 0; i + 1 < parts.size(); ++i) {
    const std::string part(parts[i]);
    toml::node* node = table->get(part);
    if (node == nullptr) {
      table->insert_or_assign(part, toml::table{});
      node = table->get(part);
    }
    if (!node->is_table()) {
      throw std::invalid_argument("scene path '" + std::string(path) + "' goes through '" + part +
                                  "', which is not a table");
    }
    table = node->as_table();
  }
  table->insert_or_assign(std::string(parts.back()), *literal.get("v"));
}

// The scene keys an override sets (shorthands expanded), for matching error messages.
std::vector<std::string> SceneKeysOf(const VariantOverride& o) {
  if (o.key == "friction") return {"proxy.friction_static", "proxy.friction_dynamic"};
  if (o.key == "truth") return {"integration.frame_rate_hz", "proxy.snapshot_mode"};
  for (const Shorthand& s : kShorthands) {
    if (s.key == o.key) return {std::string(s.scene_key)};
  }
  return {o.key};
}

// Applies one override to the scene tree. Throws std::invalid_argument (without the variant).
void ApplyOverride(const VariantOverride& o, toml::table* root) {
  const std::string& v = o.value;
  auto literal = [](auto value) {
    toml::table t;
    t.insert_or_assign("v", value);
    return t;
  };
  if (o.key == "shading" || o.key == "provot") {
    const std::optional<bool> on = OnOff(v);
    if (!on) throw std::invalid_argument("expected on or off, got '" + v + "'");
    SetScenePath(root, SceneKeysOf(o)[0], literal(*on));
  } else if (o.key == "friction") {
    // off, MU (static = dynamic) or MU_S/MU_D.
    double mu_s = 0.0, mu_d = 0.0;
    if (v != "off") {
      const size_t slash = v.find('/');
      const std::optional<double> a = ParseDouble(v.substr(0, slash));
      const std::optional<double> b =
          slash == std::string::npos ? a : ParseDouble(std::string_view(v).substr(slash + 1));
      if (!a || !b) {
        throw std::invalid_argument("expected off, MU or MU_STATIC/MU_DYNAMIC, got '" + v + "'");
      }
      mu_s = *a;
      mu_d = *b;
    }
    SetScenePath(root, "proxy.friction_static", literal(mu_s));
    SetScenePath(root, "proxy.friction_dynamic", literal(mu_d));
  } else if (o.key == "truth") {
    // on (one frame per tick) or N frames per tick, at the haptic rate the tree has so far.
    int frames_per_tick = 0;
    if (v == "on") {
      frames_per_tick = 1;
    } else {
      const auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), frames_per_tick);
      if (ec != std::errc() || end != v.data() + v.size() || frames_per_tick < 1 ||
          frames_per_tick > kMaxTruthFramesPerTick) {
        throw std::invalid_argument("expected on or an integer N in [1, " +
                                    std::to_string(kMaxTruthFramesPerTick) +
                                    "] (cloth frames per haptic tick), got '" + v + "'");
      }
    }
    // A bad haptic rate is left for the scene parser to name.
    const double rate_hz =
        (*root)["haptic"]["haptic_rate_hz"].value<double>().value_or(HapticSpec{}.haptic_rate_hz);
    SetScenePath(root, "integration.frame_rate_hz", literal(frames_per_tick * rate_hz));
    SetScenePath(root, "proxy.snapshot_mode",
                 literal(std::string(SnapshotModeName(SnapshotMode::kNewest))));
  } else {
    SetScenePath(root, SceneKeysOf(o)[0], LiteralTable(v));
  }
}

int64_t ThreadCpuNs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// Keeps every force of the run, at [tick * devices + device]; the driver sets the tick.
class RecordingForceSink final : public ForceSink {
 public:
  RecordingForceSink(uint32_t devices, int64_t ticks)
      : devices_(devices),
        force_(static_cast<size_t>(ticks) * devices, Vec3::Zero()),
        contact_(static_cast<size_t>(ticks) * devices, 0) {}
  void set_tick(int64_t tick) { tick_ = tick; }
  // Real-time safe: writes into the preallocated arrays.
  void Push(uint32_t device, const ForceOutput& force) override {
    const size_t i = static_cast<size_t>(tick_) * devices_ + device;
    if (device >= devices_ || i >= force_.size()) return;
    force_[i] = force.force_D_N;
    contact_[i] = force.in_contact ? 1 : 0;
  }
  std::vector<Vec3>& force() { return force_; }
  std::vector<uint8_t>& contact() { return contact_; }

 private:
  uint32_t devices_;
  int64_t tick_ = 0;
  std::vector<Vec3> force_;
  std::vector<uint8_t> contact_;
};

}  // namespace

std::string LockstepVariant::OverridesText() const {
  std::string text;
  for (const VariantOverride& o : overrides) {
    if (!text.empty()) text += ",";
    text += o.key + "=" + o.value;
  }
  return text;
}

std::vector<std::pair<std::string, std::string>> VariantShorthands() {
  std::vector<std::pair<std::string, std::string>> list;
  for (const Shorthand& s : kShorthands) list.emplace_back(s.key, s.scene_key);
  return list;
}

LockstepVariant TruthVariant(int frames_per_tick) {
  if (frames_per_tick < 1) {
    throw std::invalid_argument("TruthVariant: frames_per_tick must be >= 1, got " +
                                std::to_string(frames_per_tick));
  }
  if (frames_per_tick == 1) return LockstepVariant{kTruthName, {{"truth", "on"}}};
  const std::string n = std::to_string(frames_per_tick);
  return LockstepVariant{std::string(kTruthName) + "_" + n + "x", {{"truth", n}}};
}

std::vector<LockstepVariant> ParseVariantList(std::string_view text) {
  if (Trim(text).empty()) throw std::invalid_argument("--variants: the list is empty");
  std::vector<LockstepVariant> variants;
  const std::vector<std::string_view> parts = SplitTopLevel(text, ';');
  for (size_t i = 0; i < parts.size(); ++i) {
    const int index = static_cast<int>(i) + 1;
    std::string_view body = Trim(parts[i]);
    if (body.empty()) {
      if (i + 1 == parts.size() && i > 0) break;  // a trailing ';'
      throw std::invalid_argument("--variants: " + VariantLabel(index, "") +
                                  " is empty (two ';' in a row?)");
    }
    LockstepVariant v;
    // An optional NAME: before the first '='.
    const size_t colon = body.find(':');
    if (colon != std::string_view::npos && colon < body.find('=')) {
      v.name = std::string(Trim(body.substr(0, colon)));
      body = Trim(body.substr(colon + 1));
      if (v.name.empty()) {
        throw std::invalid_argument("--variants: " + VariantLabel(index, "") +
                                    " has an empty name before ':'");
      }
    }
    // The overrides (none for "scene" or an empty body after a name; truth=on for "truth").
    if (body == "truth") {
      v.overrides.push_back(VariantOverride{"truth", "on"});
      if (v.name.empty()) v.name = kTruthName;
    } else if (!body.empty() && body != "scene") {
      for (std::string_view item : SplitTopLevel(body, ',')) {
        item = Trim(item);
        if (item == "truth") {  // the bare word among overrides
          v.overrides.push_back(VariantOverride{"truth", "on"});
          continue;
        }
        const std::string label = "--variants: " + VariantLabel(index, v.name) + ": ";
        const size_t eq = item.find('=');
        if (eq == std::string_view::npos) {
          throw std::invalid_argument(label + "'" + std::string(item) +
                                      "' is not key=value (overrides are separated by ',', "
                                      "variants by ';')");
        }
        VariantOverride o{std::string(Trim(item.substr(0, eq))),
                          std::string(Trim(item.substr(eq + 1)))};
        if (o.key.empty())
          throw std::invalid_argument(label + "'" + std::string(item) + "' has no key");
        if (o.value.empty()) {
          throw std::invalid_argument(label + "key '" + o.key + "' has no value");
        }
        std::string why;
        if (!IsShorthand(o.key) && !IsScenePath(o.key, &why)) {
          throw std::invalid_argument(label + "unknown key '" + o.key + "' (" + why +
                                      "); shorthands: " + ShorthandList() +
                                      ", or a scene path such as proxy.max_iterations");
        }
        v.overrides.push_back(std::move(o));
      }
    }
    if (v.name.empty()) v.name = v.overrides.empty() ? "scene" : v.OverridesText();
    for (const LockstepVariant& other : variants) {
      if (other.name == v.name) {
        throw std::invalid_argument("--variants: " + VariantLabel(index, v.name) +
                                    ": the name is used twice (name variants with NAME: ...)");
      }
    }
    variants.push_back(std::move(v));
  }
  return variants;
}

ServerSpec VariantSpec(const SceneDocument& scene, const LockstepVariant& variant, int index) {
  // The scene's tree with every override applied.
  SceneDocument doc;
  doc.source_name = scene.source_name;
  doc.root = scene.root;
  for (const VariantOverride& o : variant.overrides) {
    try {
      ApplyOverride(o, &doc.root);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(VariantLabel(index, variant.name) + ": " + o.key + "=" + o.value +
                                  ": " + e.what());
    }
  }
  // Parsed like a scene file; an error is laid at the override whose scene key it names.
  try {
    return ParseServerSpec(doc);
  } catch (const SceneError& e) {
    const std::string message = e.what();
    for (const VariantOverride& o : variant.overrides) {
      for (const std::string& key : SceneKeysOf(o)) {
        if (message.find(key) != std::string::npos) {
          throw std::invalid_argument(VariantLabel(index, variant.name) + ": " + o.key + "=" +
                                      o.value + ": " + message);
        }
      }
    }
    throw std::invalid_argument(VariantLabel(index, variant.name) + " (" + variant.OverridesText() +
                                "): " + message);
  }
}

int64_t LockstepTicks(const std::vector<TraceSample>& samples, double rate_hz,
                      double max_duration_s) {
  if (samples.empty()) throw std::invalid_argument("lockstep: the trace has no samples");
  // The first tick releases sample 0, the last the trace's last sample (or the duration cap).
  double span_s = samples.back().t_s - samples.front().t_s;
  if (max_duration_s > 0.0) span_s = std::min(span_s, max_duration_s);
  const double periods = std::floor(span_s * rate_hz + 1e-6);
  if (!(periods < static_cast<double>(kMaxLockstepTicks))) {
    throw std::invalid_argument(
        "the trace spans " + FormatSceneNumber(span_s) + " s of virtual time: at " +
        FormatSceneNumber(rate_hz) + " Hz that is more than the " +
        std::to_string(kMaxLockstepTicks) +
        " haptic ticks (4 h at 1 kHz) a lock-step run makes; a corrupt time in the trace? "
        "(--duration S runs its first S seconds)");
  }
  return static_cast<int64_t>(periods) + 1;
}

LockstepRun RunLockstep(const ServerSpec& spec, const std::vector<TraceSample>& samples,
                        const LockstepOptions& options) {
  const auto devices = static_cast<uint32_t>(spec.devices.size());
  const double rate_hz = spec.haptic.haptic_rate_hz;
  const double frame_rate_hz = spec.sim.integration.frame_rate_hz;
  const int64_t ticks = LockstepTicks(samples, rate_hz, options.max_duration_s);

  // The real server, fed the trace on every device, forces kept, no threads started.
  TracePointerSource source(std::vector<std::vector<TraceSample>>(devices, samples));
  RecordingForceSink sink(devices, ticks);
  ServerOptions server_options;
  server_options.apply_realtime = false;
  server_options.monitor_log = false;
  Server server(spec, &source, &sink, server_options);

  LockstepRun run;
  run.devices = devices;
  run.tick_dt_s = 1.0 / rate_hz;
  run.tick_cpu_us.reserve(static_cast<size_t>(ticks));
  run.reach_m.assign(static_cast<size_t>(ticks) * devices, 0.0);
  run.popped.assign(static_cast<size_t>(ticks) * devices, 0);
  std::vector<ProxyProbeMemory> probe_memory(devices);
  // ticks / rate_hz is at least the run's span: as many frames as it holds, and two more.
  run.frame_cpu_ms.reserve(
      static_cast<size_t>(static_cast<double>(ticks) / rate_hz * frame_rate_hz) + 2);

  // The timer's own cost: back-to-back reads.
  std::vector<double> empty_us;
  empty_us.reserve(1000);
  for (int i = 0; i < 1000; ++i) {
    const int64_t begin = ThreadCpuNs();
    empty_us.push_back(static_cast<double>(ThreadCpuNs() - begin) * 1e-3);
  }
  run.timer_overhead_us = TimesPercentile(empty_us, 50.0);

  // Virtual time (file comment): the rest state at t0, frames before the ticks they precede.
  const int64_t t0 = kLockstepEpochNs;
  server.PublishInitialSnapshot(t0);
  int64_t frame = 1;
  int64_t next_frame_ns = t0 + std::llround(1e9 / frame_rate_hz);
  for (int64_t k = 1; k <= ticks; ++k) {
    const int64_t now_ns = t0 + std::llround(static_cast<double>(k) * 1e9 / rate_hz);
    while (next_frame_ns <= now_ns) {
      const int64_t begin = ThreadCpuNs();
      server.SimFrame(1.0 / frame_rate_hz, next_frame_ns);
      run.frame_cpu_ms.push_back(static_cast<double>(ThreadCpuNs() - begin) * 1e-6);
      if (options.on_frame) options.on_frame(server, frame);
      ++frame;
      next_frame_ns = t0 + std::llround(static_cast<double>(frame) * 1e9 / frame_rate_hz);
    }
    sink.set_tick(k - 1);
    const int64_t begin = ThreadCpuNs();
    server.HapticTick(now_ns, run.tick_dt_s);
    run.tick_cpu_us.push_back(static_cast<double>(ThreadCpuNs() - begin) * 1e-3);
    // Every device's proxy against the cloth it was rendered on, outside the timed call.
    for (uint32_t d = 0; d < devices; ++d) {
      const ProxyProbe probe = ProbeProxy(server.haptic().proxy_model(d),
                                          server.haptic().proxy_state(d), &probe_memory[d]);
      const size_t i = static_cast<size_t>(k - 1) * devices + d;
      run.reach_m[i] = probe.reach_m;
      run.popped[i] = probe.popped ? 1 : 0;
    }
    if (options.on_tick) options.on_tick(server, k);
  }
  run.ticks = ticks;
  run.frames = frame - 1;
  run.force_D_N = std::move(sink.force());
  run.in_contact = std::move(sink.contact());

  // The server's own counters.
  const std::unique_ptr<ServerReport> report = server.Report();
  for (const DeviceReport& d : report->devices) {
    run.clamped_ticks += d.clamped_ticks;
    run.stalled_ticks += d.stalled_ticks;
  }
  run.nan_events = report->nan_events;
  run.cloth_nan_events = report->cloth_nan_events;
  return run;
}

std::vector<VariantSummary> SummarizeRuns(const std::vector<LockstepRun>& runs) {
  std::vector<VariantSummary> out;
  if (runs.empty()) return out;
  const LockstepRun& ref = runs.front();
  // The largest tick-to-tick force change of a run, N.
  auto max_jump = [](const LockstepRun& r) {
    double jump = 0.0;
    for (int64_t k = 1; k < r.ticks; ++k) {
      for (uint32_t d = 0; d < r.devices; ++d) {
        const size_t i = static_cast<size_t>(k) * r.devices + d;
        jump = std::max(jump, (r.force_D_N[i] - r.force_D_N[i - r.devices]).norm());
      }
    }
    return jump;
  };
  const double ref_jump = max_jump(ref);
  // The largest |F| of a run, N.
  auto peak = [](const LockstepRun& r) {
    double p = 0.0;
    for (const Vec3& f : r.force_D_N) p = std::max(p, f.norm());
    return p;
  };
  const double ref_peak = peak(ref);
  for (const LockstepRun& r : runs) {
    if (r.ticks != ref.ticks || r.devices != ref.devices) {
      throw std::invalid_argument("variant '" + r.name + "': " + std::to_string(r.ticks) +
                                  " ticks x " + std::to_string(r.devices) +
                                  " devices, the reference '" + ref.name + "' has " +
                                  std::to_string(ref.ticks) + " x " + std::to_string(ref.devices) +
                                  ": forces cannot be paired tick by tick");
    }
    VariantSummary s;
    s.name = r.name;
    s.overrides = r.overrides;
    s.ticks = r.ticks;
    s.frames = r.frames;
    s.tick_us_median = TimesPercentile(r.tick_cpu_us, 50.0);
    s.tick_us_p99 = TimesPercentile(r.tick_cpu_us, 99.0);
    s.frame_ms_median = TimesPercentile(r.frame_cpu_ms, 50.0);
    s.frame_ms_p99 = TimesPercentile(r.frame_cpu_ms, 99.0);
    s.timer_overhead_us = r.timer_overhead_us;
    // Errors against the reference, tick by tick and device by device.
    double sum2 = 0.0;
    for (size_t i = 0; i < r.force_D_N.size(); ++i) {
      const double e = (r.force_D_N[i] - ref.force_D_N[i]).norm();
      sum2 += e * e;
      s.force_max_error_N = std::max(s.force_max_error_N, e);
      s.peak_force_N = std::max(s.peak_force_N, r.force_D_N[i].norm());
      s.contacts += r.in_contact[i];
      if (r.in_contact[i] != ref.in_contact[i]) ++s.contact_mismatches;
    }
    s.force_rms_error_N =
        r.force_D_N.empty() ? 0.0 : std::sqrt(sum2 / static_cast<double>(r.force_D_N.size()));
    s.peak_minus_ref_peak_N = s.peak_force_N - ref_peak;
    // What the probes saw (a run built without them has none).
    for (uint8_t p : r.popped) s.pop_through += p;
    for (double reach : r.reach_m) s.max_reach_mm = std::max(s.max_reach_mm, 1e3 * reach);
    s.max_jump_N = max_jump(r);
    s.max_jump_vs_ref_N = s.max_jump_N - ref_jump;
    s.clamped_ticks = r.clamped_ticks;
    s.stalled_ticks = r.stalled_ticks;
    s.nan_events = r.nan_events + r.cloth_nan_events;
    out.push_back(std::move(s));
  }
  return out;
}

std::vector<std::string> TruthClothMismatches(const std::vector<LockstepVariant>& variants) {
  std::vector<std::string> out;
  for (const LockstepVariant& v : variants) {
    std::string keys;
    for (const VariantOverride& o : v.overrides) {
      if (o.key.rfind("cloth.", 0) != 0) continue;
      if (!keys.empty()) keys.append(", ");
      keys.append(o.key);
    }
    if (keys.empty()) continue;
    std::string line = "variant '";
    line.append(v.name)
        .append("' overrides ")
        .append(keys)
        .append(
            "; the truth (--truth) runs the scene's own cloth, so this variant is compared with "
            "another cloth: list 'truth: truth=on,...' with the same cloth keys instead");
    out.push_back(std::move(line));
  }
  return out;
}

CompareResult CompareVariants(const SceneDocument& scene, const std::vector<TraceSample>& samples,
                              const std::vector<LockstepVariant>& variants,
                              const LockstepOptions& options) {
  if (variants.empty()) throw std::invalid_argument("compare: no variants");
  // The truth first (variant 0) when asked for; the given variants keep their numbers.
  std::vector<LockstepVariant> all;
  const int first_index = options.prepend_truth ? 0 : 1;
  if (options.prepend_truth) {
    all.push_back(TruthVariant());
    for (size_t i = 0; i < variants.size(); ++i) {
      if (variants[i].name == kTruthName) {
        throw std::invalid_argument(VariantLabel(static_cast<int>(i) + 1, variants[i].name) +
                                    ": the name is used twice (--truth adds the variant '" +
                                    std::string(kTruthName) + "' as variant 0)");
      }
    }
  }
  all.insert(all.end(), variants.begin(), variants.end());
  // Every spec first, so a bad variant stops the comparison before anything runs.
  std::vector<ServerSpec> specs;
  for (size_t i = 0; i < all.size(); ++i) {
    const int index = static_cast<int>(i) + first_index;
    specs.push_back(VariantSpec(scene, all[i], index));
    const ServerSpec& ref = specs.front();
    const ServerSpec& s = specs.back();
    if (s.haptic.haptic_rate_hz != ref.haptic.haptic_rate_hz) {
      throw std::invalid_argument(
          VariantLabel(index, all[i].name) + ": haptic.haptic_rate_hz " +
          FormatSceneNumber(s.haptic.haptic_rate_hz) + " differs from the reference's " +
          FormatSceneNumber(ref.haptic.haptic_rate_hz) + ": ticks cannot be paired");
    }
    if (s.devices.size() != ref.devices.size()) {
      throw std::invalid_argument(VariantLabel(index, all[i].name) +
                                  ": a different number of devices than the reference");
    }
  }
  // The run's length too (the same for every variant: one haptic rate).
  (void)LockstepTicks(samples, specs.front().haptic.haptic_rate_hz, options.max_duration_s);
  CompareResult result;
  for (size_t i = 0; i < all.size(); ++i) {
    try {
      result.runs.push_back(RunLockstep(specs[i], samples, options));
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(VariantLabel(static_cast<int>(i) + first_index, all[i].name) +
                                  ": " + e.what());
    }
    result.runs.back().name = all[i].name;
    result.runs.back().overrides = all[i].OverridesText();
  }
  result.summaries = SummarizeRuns(result.runs);
  return result;
}

Json VariantSummaryJson(const VariantSummary& s) {
  return Json{{"name", s.name},
              {"overrides", s.overrides},
              {"ticks", s.ticks},
              {"frames", s.frames},
              {"tick_us_median", s.tick_us_median},
              {"tick_us_p99", s.tick_us_p99},
              {"frame_ms_median", s.frame_ms_median},
              {"frame_ms_p99", s.frame_ms_p99},
              {"timer_overhead_us", s.timer_overhead_us},
              {"force_rms_error_N", s.force_rms_error_N},
              {"force_max_error_N", s.force_max_error_N},
              {"max_jump_N", s.max_jump_N},
              {"max_jump_vs_ref_N", s.max_jump_vs_ref_N},
              {"peak_force_N", s.peak_force_N},
              {"peak_minus_ref_peak_N", s.peak_minus_ref_peak_N},
              {"contacts", static_cast<int64_t>(s.contacts)},
              {"contact_mismatches", static_cast<int64_t>(s.contact_mismatches)},
              {"pop_through", static_cast<int64_t>(s.pop_through)},
              {"max_reach_mm", s.max_reach_mm},
              {"clamped_ticks", static_cast<int64_t>(s.clamped_ticks)},
              {"stalled_ticks", static_cast<int64_t>(s.stalled_ticks)},
              {"nan_events", static_cast<int64_t>(s.nan_events)}};
}

}  // namespace felt
