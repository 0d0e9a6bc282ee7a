#include "server/server.h"

#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <span>
#include <stdexcept>
#include <utility>

#include "base/json.h"
#include "rt/periodic_loop.h"
#include "sim_loop/frame_motion.h"

namespace felt {
namespace {

constexpr size_t kReactionQueueCapacity = 8;  // batches (frames) in flight haptic -> sim

bool Finite(const Vec3& v) {
  return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z());
}

// Single-writer counter increment (plain load + store: no read-modify-write on the tick).
void Bump(std::atomic<uint64_t>& counter) {
  counter.store(counter.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
}

void AddTo(std::atomic<double>& value, double delta) {
  value.store(value.load(std::memory_order_relaxed) + delta, std::memory_order_relaxed);
}

int64_t PeriodNs(double rate_hz) { return std::llround(1e9 / rate_hz); }

}  // namespace

Server::Server(ServerSpec spec, PointerSource* source, ForceSink* sink, ServerOptions options)
    : spec_(std::move(spec)),
      model_(BuildClothModel(spec_.sim)),
      cloth_(MakeClothState(model_)),
      source_(source),
      sink_(sink),
      options_(std::move(options)) {
  // Validate what the scene parser cannot see.
  if (spec_.devices.empty()) throw std::invalid_argument("devices: the scene declares no device");
  if (source_ == nullptr || sink_ == nullptr) {
    throw std::invalid_argument("Server: a pointer source and a force sink are required");
  }
  haptic_dt_s_ = 1.0 / spec_.haptic.haptic_rate_hz;
  sim_dt_s_ = 1.0 / spec_.sim.integration.frame_rate_hz;

  // Snapshots: three slots in the triple buffer, two haptic-owned copies for "previous".
  PublishedSnapshot initial{MakeClothSnapshot(model_, cloth_, spec_.proxy.structure), 0};
  snapshots_ = std::make_unique<TripleBuffer<PublishedSnapshot>>(initial);
  copies_.assign(2, initial.snapshot);
  frame_start_x_ = cloth_.x;
  frame_motion_v_.assign(cloth_.x.size(), Vec3::Zero());

  // Reactions: the queue, the staged batch, the sim's scratch and its ExternalForce list.
  reactions_ = std::make_unique<SpscQueue<ReactionBatch>>(kReactionQueueCapacity);
  staged_ = std::make_unique<ReactionBatch>();
  popped_ = std::make_unique<ReactionBatch>();
  external_.resize(static_cast<size_t>(kMaxReactionForces) * (kReactionQueueCapacity + 1));

  // One proxy and safety state per device.
  const int32_t per_device =
      std::max<int32_t>(1, kMaxReactionForces / static_cast<int32_t>(spec_.devices.size()));
  for (const DeviceSpec& d : spec_.devices) {
    SafetySpec safety = DeviceSafetySpec(spec_.haptic, d);
    ValidateSafetySpec(safety);
    ProxySpec proxy = spec_.proxy;
    devices_.emplace_back(d, safety,
                          ProxyState(proxy.candidate_capacity, std::min(per_device, 256)));
  }

  haptic_stats_ = std::make_unique<LoopStats>(PeriodNs(spec_.haptic.haptic_rate_hz));
  sim_stats_ = std::make_unique<LoopStats>(PeriodNs(spec_.sim.integration.frame_rate_hz));
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

void Server::PublishInitialSnapshot(int64_t publish_ns) {
  PublishedSnapshot& first = snapshots_->write_slot();
  FillSnapshot(model_, cloth_, 0, 0.0, &first.snapshot);
  first.publish_ns = publish_ns;
  snapshots_->Publish();
}

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

void Server::HapticThread() {
  const int64_t period_ns = PeriodNs(spec_.haptic.haptic_rate_hz);
  const RealtimeSettings& rt = spec_.haptic.haptic_realtime;
  if (options_.apply_realtime) haptic_report_ = ApplyRealtime(rt);
  haptic_ready_.store(true, std::memory_order_release);
  const int64_t spin_ns = options_.apply_realtime ? int64_t{rt.spin_us} * 1000 : 0;
  PeriodicLoop loop(period_ns, std::min(spin_ns, period_ns / 2));
  loop.Start(MonotonicNowNs() + period_ns);
  // The ticks: wait for the deadline, run the tick, record (real-time safe from here).
  while (!stop_.load(std::memory_order_relaxed)) {
    const TickInfo tick = loop.WaitNext();
    HapticTick(tick.wake_ns, haptic_dt_s_);
    haptic_stats_->RecordTick(tick, MonotonicNowNs() - tick.wake_ns);
  }
}

void Server::SimThread() {
  const int64_t period_ns = PeriodNs(spec_.sim.integration.frame_rate_hz);
  const RealtimeSettings& rt = spec_.haptic.sim_realtime;
  if (options_.apply_realtime) sim_report_ = ApplyRealtime(rt);
  sim_ready_.store(true, std::memory_order_release);
  const int64_t spin_ns = options_.apply_realtime ? int64_t{rt.spin_us} * 1000 : 0;
  PeriodicLoop loop(period_ns, std::min(spin_ns, period_ns / 2));
  loop.Start(MonotonicNowNs() + period_ns);
  // Each frame integrates one period, also after an overrun: the skipped periods are counted
  // (sim.skipped_periods) and their time is dropped, so the cloth runs slow for a moment instead
  // of falling further behind. Integrating the missed time as well (more substeps in the next
  // frame) made a frame that overran once cost twice as much, which overran again: at 64 x 64
  // (8.5 ms frames) 4.8 % of the frames of a 10-minute run overran, p99 22 ms (bench/results/
  // loops.md), the real-time "spiral of death" (Fiedler 2004, "Fix your timestep!").
  while (!stop_.load(std::memory_order_relaxed)) {
    const TickInfo tick = loop.WaitNext();
    SimFrame(sim_dt_s_, 0);
    sim_stats_->RecordTick(tick, MonotonicNowNs() - tick.wake_ns);
  }
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

void Server::StageReactions() {
  // A staged batch still waiting keeps the accumulators untouched (they keep accumulating).
  if (!staged_pending_) {
    double duration_s = 0.0;
    for (const Device& d : devices_) duration_s = std::max(duration_s, d.proxy.reaction.time_s());
    if (duration_s <= 0.0) return;  // no proxy ran since the last batch
    ReactionBatch& batch = *staged_;
    batch.count = 0;
    batch.duration_s = duration_s;
    const int32_t per_device = kMaxReactionForces / static_cast<int32_t>(devices_.size());
    for (Device& d : devices_) {
      ReactionAccumulator& acc = d.proxy.reaction;
      const double t = acc.time_s();
      if (t <= 0.0) continue;
      AddTo(d.counters->reaction_impulse_N_s, acc.TotalImpulse().norm());
      const int32_t n =
          acc.DrainInto(std::span<ExternalForce>(batch.forces.data() + batch.count, per_device));
      // The accumulator averaged over its own time: rescale to the batch's duration so that
      // force x duration is the impulse (devices that ran for part of the batch count less).
      for (int32_t i = 0; i < n; ++i) batch.forces[batch.count + i].force_N *= t / duration_s;
      batch.count += n;
    }
    staged_pending_ = true;
  }
  if (reactions_->TryPush(*staged_)) {
    staged_pending_ = false;
    Bump(reaction_batches_);
  } else {
    Bump(reaction_queue_full_);
  }
}

void Server::HapticTick(int64_t now_ns, double dt_s) {
  Bump(body_ticks_);

  // The newest snapshot, without waiting. A new one: keep a copy as the next "previous", and
  // hand the reactions of the frame that ended to the sim.
  const bool fresh_snapshot = snapshots_->Acquire();
  PublishedSnapshot& slot = snapshots_->read_slot_mutable();
  const bool first_snapshot = newest_copy_ < 0;
  if (fresh_snapshot || first_snapshot) {
    if (slot.snapshot.frame != newest_frame_ || first_snapshot) {
      newest_frame_ = slot.snapshot.frame;
      // Every mode keeps the previous snapshot: mode newest needs it as well, to carry a proxy in
      // contact with its triangle and to catch a free proxy the cloth sweeps over (ProxyTick
      // treats a missing previous snapshot as a cloth that did not move).
      // The triple buffer's slot cannot serve as "previous": the next Acquire hands it back to
      // the sim. So the new snapshot's arrays are swapped into the older haptic-owned copy
      // (O(1), no allocation: equally sized vectors trade buffers), and that copy's arrays go
      // back to the sim in the slot, which refills them whole. A deep copy here (positions,
      // velocities, normals and the BVH, ~1 MB at 64 x 64) cost ~0.2 ms on the 6 % of ticks that
      // took a new snapshot: the tick's compute-time p99 (bench/results/loops.md).
      const int next = newest_copy_ == 0 ? 1 : 0;
      using std::swap;
      swap(copies_[next], slot.snapshot);
      previous_copy_ = newest_copy_;
      newest_copy_ = next;
      StageReactions();
    }
  } else if (staged_pending_) {
    StageReactions();  // retry the push of a batch that found the queue full
  }
  // The newest lives in a haptic-owned copy (the first tick made one).
  const ClothSnapshot& newest_snapshot = copies_[newest_copy_];
  const ClothSnapshot* previous = previous_copy_ >= 0 ? &copies_[previous_copy_] : nullptr;
  const int64_t age_ns = now_ns - slot.publish_ns;
  haptic_stats_->RecordSnapshotAge(age_ns);
  const bool stalled = age_ns > static_cast<int64_t>(spec_.haptic.sim_stall_s * 1e9);
  if (stalled) Bump(sim_stalled_ticks_);
  sim_stalled_.store(stalled, std::memory_order_relaxed);
  const double since_newest_s = std::max(0.0, static_cast<double>(age_ns) * 1e-9);
  const int64_t stale_ns = static_cast<int64_t>(spec_.haptic.stale_input_s * 1e9);

  // Each device: newest sample, proxy while the input is fresh, safety, force out.
  for (uint32_t i = 0; i < devices_.size(); ++i) {
    Device& d = devices_[i];
    DeviceCounters& c = *d.counters;
    PointerInput in;
    bool input_nan = false;
    if (source_->Latest(i, now_ns, &in)) {
      if (!Finite(in.p_D_m) || !Finite(in.v_D_m_per_s)) {
        input_nan = true;  // keep the last good sample; this tick's force is zero
      } else {
        d.input = in;
        d.have_input = true;
      }
    }
    if (!d.have_input && !input_nan) continue;  // the device has not spoken yet: nothing to send
    Bump(c.ticks_with_input);
    const bool fresh = d.have_input && now_ns - d.input.receive_time_ns <= stale_ns;
    if (fresh && !d.fresh) Bump(c.connects);
    d.fresh = fresh;

    // The proxy runs on fresh, finite input only; stale input keeps its last force (ramped out).
    if (fresh && !input_nan) {
      DeviceSample sample;
      sample.p_D_m = d.input.p_D_m;
      sample.v_D_m_per_s = d.input.v_D_m_per_s;
      d.last_result = ProxyTick(d.spec, spec_.proxy, newest_snapshot, previous, since_newest_s,
                                sample, dt_s, &d.proxy);
    }
    SafetyInput safety_in;
    safety_in.proxy_force_D_N = d.last_result.force_D_N;
    safety_in.velocity_D_m_per_s = fresh ? d.input.v_D_m_per_s : Vec3::Zero();
    safety_in.input_fresh = fresh;
    safety_in.input_nan = input_nan;
    safety_in.sim_stalled = stalled;
    const SafetyOutput out = ApplySafety(d.safety_spec, safety_in, dt_s, &d.safety);

    // Out to the device.
    ForceOutput force;
    force.answers_seq = d.input.seq;
    force.answers_device_time_ns = d.input.device_time_ns;
    force.force_D_N = out.force_D_N;
    force.proxy_D_m = WorldToDevice(d.spec, d.last_result.proxy_W_m);
    force.in_contact = fresh && d.last_result.num_contacts > 0;
    force.flags = out.flags;
    force.tick_time_ns = now_ns;
    sink_->Push(i, force);

    // Counters.
    Bump(c.forces_sent);
    if (force.in_contact) Bump(c.contact_ticks);
    if (out.flags & kSafetyStaleInput) Bump(c.stale_ticks);
    if (out.flags & kSafetyRamping) Bump(c.ramping_ticks);
    if (out.flags & kSafetyClamped) Bump(c.clamped_ticks);
    if (out.flags & kSafetySimStalled) Bump(c.stalled_ticks);
    if (out.nan) Bump(c.nan_events);
    const double norm = out.force_D_N.norm();
    if (norm > c.peak_force_N.load(std::memory_order_relaxed)) {
      c.peak_force_N.store(norm, std::memory_order_relaxed);
    }
    c.energy_J.store(d.safety.energy_J, std::memory_order_relaxed);
    c.dissipated_J.store(d.safety.dissipated_J, std::memory_order_relaxed);
    c.connected.store(fresh, std::memory_order_relaxed);
  }
}

void Server::SimFrame(double frame_dt_s, int64_t publish_ns) {
  // Test hook: a stalled sim (blocks this thread only).
  const int64_t stall_ns = stall_request_ns_.exchange(0);
  if (stall_ns > 0) std::this_thread::sleep_for(std::chrono::nanoseconds(stall_ns));

  // The reactions queued since the last frame, weighted by their durations (impulse kept).
  size_t count = 0;
  double total_s = 0.0;
  while (count + kMaxReactionForces <= external_.size() && reactions_->TryPop(popped_.get())) {
    for (int32_t i = 0; i < popped_->count; ++i) {
      external_[count] = popped_->forces[i];
      external_[count].force_N *= popped_->duration_s;  // impulse for now
      AddTo(applied_impulse_N_s_, external_[count].force_N.norm());
      ++count;
    }
    total_s += popped_->duration_s;
    Bump(reaction_batches_applied_);
  }
  for (size_t i = 0; i < count; ++i) external_[i].force_N /= total_s;

  // Step, repair, publish with the frame's motion as the velocities (sim_loop/frame_motion.h).
  std::copy(cloth_.x.begin(), cloth_.x.end(), frame_start_x_.begin());
  const FrameResult result = StepFrame(
      model_, std::span<const ExternalForce>(external_.data(), count), frame_dt_s, &cloth_);
  if (result.recovered) Bump(cloth_nan_events_);
  PublishedSnapshot& slot = snapshots_->write_slot();
  FillSnapshotWithFrameMotion(cloth_, frame_start_x_, result.dt_s, ++sim_frame_counter_,
                              frame_motion_v_, &slot.snapshot);
  slot.publish_ns = publish_ns == 0 ? MonotonicNowNs() : publish_ns;
  snapshots_->Publish();
  sim_time_s_.store(cloth_.time_s, std::memory_order_relaxed);
  sim_frames_.store(sim_frame_counter_, std::memory_order_release);
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
  r->body_ticks = body_ticks_.load();
  r->sim_stalled_ticks = sim_stalled_ticks_.load();
  r->sim_stalled = sim_stalled_.load();
  r->reaction_batches = reaction_batches_.load();
  r->reaction_batches_applied = reaction_batches_applied_.load();
  r->reaction_queue_full = reaction_queue_full_.load();
  r->cloth_nan_events = cloth_nan_events_.load();
  for (const Device& d : devices_) {
    const DeviceCounters& c = *d.counters;
    DeviceReport dr;
    dr.id = d.spec.id;
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
    dr.max_force_N = d.spec.max_force_N;
    dr.energy_J = c.energy_J.load();
    dr.dissipated_J = c.dissipated_J.load();
    dr.reaction_impulse_N_s = c.reaction_impulse_N_s.load();
    dr.connected = c.connected.load();
    r->contacts += dr.contact_ticks;
    r->peak_force_N = std::max(r->peak_force_N, dr.peak_force_N);
    r->nan_events += dr.nan_events;
    r->energy_J += dr.energy_J;
    if (dr.connected) ++r->devices_connected;
    r->devices.push_back(std::move(dr));
  }
  return r;
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
                       {"cloth_nan_events", r.cloth_nan_events}};
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
