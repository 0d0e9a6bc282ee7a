#include "server/server.h"

#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "base/json.h"
#include "rt/periodic_loop.h"

namespace felt {
namespace {

int64_t PeriodNs(double rate_hz) { return std::llround(1e9 / rate_hz); }

}  // namespace

Server::Server(ServerSpec spec, PointerSource* source, ForceSink* sink, ServerOptions options)
    : spec_(std::move(spec)),
      options_(std::move(options)),
      haptic_dt_s_(1.0 / spec_.haptic.haptic_rate_hz),
      sim_dt_s_(1.0 / spec_.sim.integration.frame_rate_hz),
      haptic_stats_(std::make_unique<LoopStats>(PeriodNs(spec_.haptic.haptic_rate_hz))),
      sim_stats_(std::make_unique<LoopStats>(PeriodNs(spec_.sim.integration.frame_rate_hz))),
      sim_(spec_.sim, spec_.proxy.structure),
      haptic_(spec_.proxy, spec_.devices, spec_.haptic, sim_.model(),
              sim_.snapshots().read_slot().snapshot, &sim_.snapshots(), &sim_.reactions(), source,
              sink, haptic_stats_.get()),
      source_(source),
      tick_device_(TickDeviceIndex(spec_)) {
  if (tick_device_ < 0) {
    throw std::invalid_argument("ServerSpec.haptic.tick_device: '" + spec_.haptic.tick_device +
                                "' is not one of the devices");
  }
}

Server::~Server() { Stop(); }

void Server::Start() {
  if (running_) return;
  // The first snapshot (the rest state) is published before the threads start, so the haptic
  // thread always has a cloth.
  PublishInitialSnapshot(MonotonicNowNs());
  // No deep C-states while the loops run (a refusal logs one warning; the loops run anyway).
  if (options_.apply_realtime && spec_.haptic.cpu_dma_latency_zero) {
    dma_hold_ = std::make_unique<CpuDmaLatencyHold>();
    dma_held_.store(dma_hold_->held());
  }

  stop_.store(false);
  running_ = true;
  sim_thread_ = std::thread([this] { SimThread(); });
  haptic_thread_ = std::thread([this] { HapticThread(); });
  monitor_thread_ = std::thread([this] { MonitorThread(); });
}

void Server::PublishInitialSnapshot(int64_t publish_ns) { sim_.PublishInitialSnapshot(publish_ns); }

void Server::Stop() {
  if (!running_) return;
  {
    std::lock_guard<std::mutex> lock(monitor_mutex_);
    stop_.store(true);
  }
  monitor_wake_.notify_all();
  haptic_thread_.join();
  sim_thread_.join();
  monitor_thread_.join();
  dma_hold_.reset();
  running_ = false;
}

LoopRunOptions Server::ThreadLoop(double rate_hz, const RealtimeSettings& realtime,
                                  RealtimeReport* granted, std::atomic<bool>* ready) const {
  LoopRunOptions loop;
  loop.period_ns = PeriodNs(rate_hz);
  loop.stop = &stop_;
  // Not applied: normal scheduling, no spin. The spin never takes more than half the period.
  if (options_.apply_realtime) {
    loop.realtime = realtime;
    loop.realtime.spin_us =
        static_cast<int>(std::min<int64_t>(realtime.spin_us, loop.period_ns / 2 / 1000));
  }
  loop.on_started = [granted, ready](const RealtimeReport& report) {
    *granted = report;
    ready->store(true, std::memory_order_release);
  };
  return loop;
}

void Server::HapticThread() {
  LoopRunOptions loop = ThreadLoop(spec_.haptic.haptic_rate_hz, spec_.haptic.haptic_realtime,
                                   &haptic_report_, &haptic_ready_);
  // Tick on arrival: the tick device's samples wake the loop, the periodic deadline stays the
  // fallback and the bound (rt/periodic_loop.h). A source that cannot signal (a trace) leaves the
  // loop periodic.
  if (spec_.haptic.tick_trigger == HapticTickTrigger::kArrival && source_ != nullptr) {
    loop.arrival = source_->Arrivals(static_cast<uint32_t>(tick_device_));
  }
  RunLoop(loop, haptic_stats_.get(),
          [this](const TickInfo& tick) { HapticTick(tick.wake_ns, haptic_dt_s_); });
}

void Server::SimThread() {
  // Each frame integrates one period, also after an overrun: the skipped periods are counted
  // (sim.skipped_periods) and their time is dropped, so the cloth runs slow for a moment instead
  // of falling further behind. Integrating the missed time as well (more substeps in the next
  // frame) made a frame that overran once cost twice as much, which overran again: at 64 x 64
  // (8.5 ms frames) 4.8 % of the frames of a 10-minute run overran, p99 22 ms (bench/results/
  // loops.md), the real-time "spiral of death" (Fiedler 2004, "Fix your timestep!").
  const LoopRunOptions loop = ThreadLoop(spec_.sim.integration.frame_rate_hz,
                                         spec_.haptic.sim_realtime, &sim_report_, &sim_ready_);
  RunLoop(loop, sim_stats_.get(), [this](const TickInfo&) { SimFrame(sim_dt_s_, 0); });
}

void Server::MonitorThread() {
  auto previous = std::make_unique<ServerReport>();
  bool have_previous = false;
  const auto period = std::chrono::duration<double>(spec_.haptic.monitor_period_s);
  std::unique_lock<std::mutex> lock(monitor_mutex_);
  while (!stop_.load()) {
    monitor_wake_.wait_for(lock, period, [this] { return stop_.load(); });
    if (stop_.load()) break;
    lock.unlock();
    std::unique_ptr<ServerReport> report = Report();
    if (options_.monitor_log) {
      spdlog::info("{} | {}",
                   FormatMonitorLine(report->haptic, have_previous ? &previous->haptic : nullptr,
                                     report->sim, have_previous ? &previous->sim : nullptr),
                   FormatCounters(*report));
    }
    if (options_.on_report) options_.on_report(*report);
    previous = std::move(report);
    have_previous = true;
    lock.lock();
  }
}

void Server::HapticTick(int64_t now_ns, double dt_s) {
  haptic_.Tick(now_ns, dt_s);
  if (taps_.empty()) return;
  PublishViewDevices();
}

void Server::PublishViewDevices() {
  // Each observer's copy of each device (fixed size: no allocation; one exchange to publish).
  for (ViewTap* tap : taps_) {
    ViewDevices& out = tap->devices.write_slot();
    out.tick = haptic_.counters().ticks.load(std::memory_order_relaxed);
    for (uint32_t i = 0; i < haptic_.device_count(); ++i) {
      const ProxyTickResult& r = haptic_.last_result(i);
      const GodObject& body = haptic_.proxy_state(i).body;
      ViewDevice& d = out.devices[i];
      d.goal_W_m = r.goal_W_m;
      d.proxy_W_m = r.proxy_W_m;
      d.force_W_N = r.force_W_N;
      d.num_contacts = body.num_contacts;
      d.contacts = body.contacts;
      d.fresh = haptic_.input_fresh(i);
    }
    tap->devices.Publish();
  }
}

std::unique_ptr<ViewTap> Server::NewTap() {
  // The loop threads read taps_ without synchronisation: it must be complete before they start.
  if (running_) throw std::logic_error("Server: observer taps are added before Start()");
  if (taps_.size() >= kMaxObserverTaps) {
    throw std::length_error("Server: at most " + std::to_string(kMaxObserverTaps) +
                            " observer taps");
  }
  taps_.reserve(kMaxObserverTaps);
  auto tap = std::make_unique<ViewTap>(model().num_particles(), haptic_.device_count());
  // The cloth as it is now (the rest state before Start), so an observer has a cloth at once.
  PublishViewCloth(tap.get());
  taps_.push_back(tap.get());
  return tap;
}

ViewTap* Server::EnableViewTap() {
  if (view_tap_ == nullptr) {
    if (running_) throw std::logic_error("Server::EnableViewTap: call it before Start()");
    view_tap_ = NewTap();
  }
  return view_tap_.get();
}

ViewTap* Server::AddObserverTap() {
  observer_taps_.push_back(NewTap());
  return observer_taps_.back().get();
}

void Server::SimFrame(double frame_dt_s, int64_t publish_ns) {
  // Test hook: a stalled sim (blocks this thread only).
  const int64_t stall_ns = stall_request_ns_.exchange(0);
  if (stall_ns > 0) std::this_thread::sleep_for(std::chrono::nanoseconds(stall_ns));
  sim_.Frame(frame_dt_s, publish_ns);
  if (taps_.empty()) return;
  PublishViewCloth();
}

void Server::PublishViewCloth() {
  for (ViewTap* tap : taps_) PublishViewCloth(tap);
}

void Server::PublishViewCloth(ViewTap* tap) {
  // One observer's copy of the positions as float32 (sized once: no allocation).
  const ClothState& state = sim_.cloth();
  ViewCloth& out = tap->cloth.write_slot();
  out.frame = sim_.counters().frames.load(std::memory_order_relaxed);
  out.time_s = state.time_s;
  for (size_t i = 0; i < state.x.size(); ++i) {
    for (int k = 0; k < 3; ++k) out.xyz_m[3 * i + k] = static_cast<float>(state.x[i][k]);
  }
  tap->cloth.Publish();
}

std::unique_ptr<ServerReport> Server::Report() const {
  auto r = std::make_unique<ServerReport>();
  haptic_stats_->Snapshot(&r->haptic);
  sim_stats_->Snapshot(&r->sim);
  if (haptic_ready_.load(std::memory_order_acquire)) {
    r->realtime = haptic_report_.fifo_granted;
    r->haptic_realtime_summary = options_.apply_realtime ? haptic_report_.Summary() : "not applied";
  }
  if (sim_ready_.load(std::memory_order_acquire)) {
    r->sim_realtime = sim_report_.fifo_granted;
    r->sim_realtime_summary = options_.apply_realtime ? sim_report_.Summary() : "not applied";
  }
  r->cpu_dma_latency_zero = dma_held_.load();
  const HapticCounters& h = haptic_.counters();
  r->body_ticks = h.ticks.load();
  r->sim_stalled_ticks = h.sim_stalled_ticks.load();
  r->sim_stalled = h.sim_stalled.load();
  r->reaction_batches = h.reaction_batches.load();
  r->reaction_queue_full = h.reaction_queue_full.load();
  r->reaction_batches_applied = sim_.counters().reaction_batches_applied.load();
  r->cloth_nan_events = sim_.counters().cloth_nan_events.load();
  r->held_spring_frames = sim_.counters().held_spring_frames.load();
  r->patch_ticks = h.patch_ticks.load();
  r->patch_nan_events = h.patch_nan_events.load();
  r->guard_pushes = sim_.counters().guard_pushes.load();
  r->patch_guard_pushes = h.patch_guard_pushes.load();
  for (uint32_t i = 0; i < haptic_.device_count(); ++i) {
    r->devices.push_back(ReportDevice(haptic_.device_spec(i), haptic_.device_counters(i)));
    const DeviceReport& dr = r->devices.back();
    r->contacts += dr.contact_ticks;
    r->peak_force_N = std::max(r->peak_force_N, dr.peak_force_N);
    r->nan_events += dr.nan_events;
    r->energy_J += dr.energy_J;
    if (dr.connected) ++r->devices_connected;
  }
  return r;
}

DeviceReport ReportDevice(const DeviceSpec& spec, const DeviceCounters& c) {
  DeviceReport dr;
  dr.id = spec.id;
  dr.ticks_with_input = c.ticks_with_input.load();
  dr.contact_ticks = c.contact_ticks.load();
  dr.stale_ticks = c.stale_ticks.load();
  dr.ramping_ticks = c.ramping_ticks.load();
  dr.clamped_ticks = c.clamped_ticks.load();
  dr.stalled_ticks = c.stalled_ticks.load();
  dr.nan_events = c.nan_events.load();
  dr.connects = c.connects.load();
  dr.forces_sent = c.forces_sent.load();
  dr.peak_force_N = c.peak_force_N.load();
  dr.max_force_N = spec.max_force_N;
  dr.energy_J = c.energy_J.load();
  dr.dissipated_J = c.dissipated_J.load();
  dr.reaction_impulse_N_s = c.reaction_impulse_N_s.load();
  dr.connected = c.connected.load();
  return dr;
}

std::string Server::ReportJson(const ServerReport& r) {
  uint64_t stale = 0, ramping = 0, clamped = 0;
  Json devices = Json::object();
  for (const DeviceReport& d : r.devices) {
    stale += d.stale_ticks;
    ramping += d.ramping_ticks;
    clamped += d.clamped_ticks;
    devices[d.id] = Json{{"connected", d.connected},
                         {"connects", d.connects},
                         {"ticks_with_input", d.ticks_with_input},
                         {"forces_sent", d.forces_sent},
                         {"contacts", d.contact_ticks},
                         {"peak_force_N", d.peak_force_N},
                         {"max_force_N", d.max_force_N},
                         {"stale_input_ticks", d.stale_ticks},
                         {"ramping_ticks", d.ramping_ticks},
                         {"clamped_ticks", d.clamped_ticks},
                         {"sim_stalled_ticks", d.stalled_ticks},
                         {"nan_events", d.nan_events},
                         {"passivity_energy_J", d.energy_J},
                         {"passivity_dissipated_J", d.dissipated_J},
                         {"reaction_impulse_N_s", d.reaction_impulse_N_s}};
  }
  const Json safety{{"nan_events", r.nan_events},
                    {"stale_input_ticks", stale},
                    {"ramping_ticks", ramping},
                    {"clamped_ticks", clamped},
                    {"sim_stalled_ticks", r.sim_stalled_ticks},
                    {"sim_stalled", r.sim_stalled},
                    {"passivity_energy_J", r.energy_J}};
  const Json reactions{{"batches", r.reaction_batches},
                       {"batches_applied", r.reaction_batches_applied},
                       {"queue_full_retries", r.reaction_queue_full},
                       {"cloth_nan_events", r.cloth_nan_events},
                       {"held_spring_frames", r.held_spring_frames},
                       {"patch_ticks", r.patch_ticks},
                       {"patch_nan_events", r.patch_nan_events},
                       {"guard_pushes", r.guard_pushes},
                       {"patch_guard_pushes", r.patch_guard_pushes}};
  return JsonText(Json{{"realtime", r.realtime},
                       {"sim_realtime", r.sim_realtime},
                       {"cpu_dma_latency_zero", r.cpu_dma_latency_zero},
                       {"haptic_realtime_steps", r.haptic_realtime_summary},
                       {"sim_realtime_steps", r.sim_realtime_summary},
                       {"haptic", HapticJson(r.haptic)},
                       {"sim", SimJson(r.sim)},
                       {"contacts", r.contacts},
                       {"peak_force_N", r.peak_force_N},
                       {"devices_connected", r.devices_connected},
                       {"safety", safety},
                       {"reactions", reactions},
                       {"devices", devices}});
}

std::string Server::FormatCounters(const ServerReport& r) {
  uint64_t stale = 0, clamped = 0;
  for (const DeviceReport& d : r.devices) {
    stale += d.stale_ticks;
    clamped += d.clamped_ticks;
  }
  return fmt::format(
      "devices {}/{} contacts {} peak {:.2f} N clamped {} stale {} nan {} stalled {}{} energy "
      "{:.4f} J",
      r.devices_connected, r.devices.size(), r.contacts, r.peak_force_N, clamped, stale,
      r.nan_events, r.sim_stalled_ticks, r.sim_stalled ? " (now)" : "", r.energy_J);
}

}  // namespace felt
