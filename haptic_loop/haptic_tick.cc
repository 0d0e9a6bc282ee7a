#include "haptic_loop/haptic_tick.h"

#include <algorithm>
#include <cmath>
#include <span>
#include <stdexcept>
#include <utility>

#include "rt/counters.h"

namespace felt {

HapticLoop::HapticLoop(const ProxySpec& proxy, const std::vector<DeviceSpec>& devices,
                       const HapticSpec& haptic, const ClothModel& cloth,
                       const ClothSnapshot& initial, SnapshotBuffer* snapshots,
                       ReactionQueue* reactions, PointerSource* source, ForceSink* sink,
                       LoopStats* stats)
    : stale_ns_(static_cast<int64_t>(haptic.stale_input_s * 1e9)),
      stall_ns_(static_cast<int64_t>(haptic.sim_stall_s * 1e9)),
      snapshots_(snapshots),
      reactions_(reactions),
      source_(source),
      sink_(sink),
      stats_(stats) {
  if (devices.empty()) throw std::invalid_argument("devices: the scene declares no device");
  if (snapshots_ == nullptr || reactions_ == nullptr || source_ == nullptr || sink_ == nullptr ||
      stats_ == nullptr) {
    throw std::invalid_argument(
        "HapticLoop: the handoffs, a pointer source, a force sink and statistics are required");
  }
  // Two haptic-owned copies for the newest and the previous snapshot; the staged batch.
  copies_.assign(2, initial);
  staged_ = std::make_unique<ReactionBatch>();

  // One proxy and safety state per device; the batch's room shared among them.
  const int32_t per_device =
      std::max<int32_t>(1, kMaxReactionForces / static_cast<int32_t>(devices.size()));
  for (const DeviceSpec& d : devices) {
    SafetySpec safety = DeviceSafetySpec(haptic, d);
    ValidateSafetySpec(safety);
    ProxyModel model = CompileProxyModel(d, proxy);
    ProxyState state(model.candidate_capacity, std::min(per_device, 256));
    devices_.emplace_back(d, safety, std::move(model), std::move(state));
  }

  // Mode patch: one patch for every device (their windows merge where they meet).
  if (proxy.snapshot_mode == SnapshotMode::kPatch) {
    if (cloth.num_particles() != initial.num_particles()) {
      throw std::invalid_argument("HapticLoop: the cloth model and the snapshot differ in size");
    }
    const auto n_devices = static_cast<int32_t>(devices.size());
    patch_ = std::make_unique<ClothPatch>(cloth, proxy.patch_radius, n_devices, proxy.patch_follow);
    overlay_.patch = patch_.get();
    patch_centres_.assign(devices.size(), -1);
    patch_springs_.resize(devices.size());
  }
}

void HapticLoop::Tick(int64_t now_ns, double dt_s) {
  Bump(counters_.ticks);
  bool arrived = false;
  const TickCloth cloth = TakeNewestSnapshot(now_ns, &arrived);
  // Mode patch: the patch to this tick, before the proxies run on it (with the contact springs
  // of the last tick).
  if (patch_ != nullptr) StepPatch(cloth, dt_s);
  // Each device: newest sample, proxy while the input is fresh, safety, force out.
  for (uint32_t i = 0; i < devices_.size(); ++i) TickDevice(i, now_ns, dt_s, cloth);
  if (patch_ != nullptr) KeepPatchSprings();
  // A new snapshot: hand the reactions of the frame that ended, this tick's included, to the sim
  // (or retry a batch that found the queue full). Staged before the proxies ran, the sim's next
  // frame missed this tick's contact: with a frame every tick (the truth of felt compare) the
  // cloth answered the hand two ticks late instead of one.
  if (arrived || staged_pending_) StageReactions();
}

void HapticLoop::KeepPatchSprings() {
  // The contact springs of this tick, for the next tick's patch step (StageReactions drains them
  // from the accumulators).
  patch_spring_count_ = 0;
  for (const Device& d : devices_) {
    if (d.fresh && d.proxy.reaction.has_contact_spring()) {
      patch_springs_[static_cast<size_t>(patch_spring_count_++)] =
          d.proxy.reaction.contact_spring();
    }
  }
}

HapticLoop::TickCloth HapticLoop::TakeNewestSnapshot(int64_t now_ns, bool* arrived) {
  // The newest snapshot, without waiting. A new one: keep a copy as the next "previous" (the
  // caller then hands the reactions of the frame that ended to the sim).
  const bool fresh_snapshot = snapshots_->Acquire();
  PublishedSnapshot& slot = snapshots_->read_slot_mutable();
  const bool first_snapshot = newest_copy_ < 0;
  if ((fresh_snapshot || first_snapshot) &&
      (slot.snapshot.frame != newest_frame_ || first_snapshot)) {
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
    *arrived = true;
  }

  // The newest lives in a haptic-owned copy (the first tick made one); its age says whether the
  // sim has stalled.
  TickCloth cloth;
  cloth.newest = &copies_[newest_copy_];
  cloth.previous = previous_copy_ >= 0 ? &copies_[previous_copy_] : nullptr;
  const int64_t age_ns = now_ns - slot.publish_ns;
  stats_->RecordSnapshotAge(age_ns);
  cloth.stalled = age_ns > stall_ns_;
  if (cloth.stalled) Bump(counters_.sim_stalled_ticks);
  counters_.sim_stalled.store(cloth.stalled, std::memory_order_relaxed);
  cloth.since_newest_s = std::max(0.0, static_cast<double>(age_ns) * 1e-9);
  // Modes extrapolate and patch carry the snapshot along its velocities for the time since it
  // was published: at most the stall threshold (or one frame, so that mode interpolate still
  // reaches the newest); past it the tick renders the cloth as extrapolated then. Unbounded, a
  // 20 s stall carried the proxy 1.37 m (device frame) in mode extrapolate and 0.45 m in mode
  // patch (ServerTick.ALongStallDoesNotCarryTheProxyAway).
  cloth.horizon_s = std::max(static_cast<double>(stall_ns_) * 1e-9, cloth.newest->frame_dt_s);
  return cloth;
}

void HapticLoop::StageReactions() {
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
    Bump(counters_.reaction_batches);
  } else {
    Bump(counters_.reaction_queue_full);
  }
}

void HapticLoop::StepPatch(const TickCloth& cloth, double dt_s) {
  // Each device's window centre: the cloth particle nearest one of its last contact points (the
  // corner with the largest barycentric weight), or nearest where its free proxy still presses
  // the cloth for the sim (hand_seed); none for a device without fresh input or away from the
  // cloth. Of several contacts (a crease, a fold's two layers) the one nearest the window the
  // device has now (in grid steps) is taken, so a proxy between layers does not pull its window
  // back and forth across the fold each tick (on curtain_128 that let the cloth under the proxy
  // jump as particles left the window, and the proxy went through).
  const std::vector<Triangle>& tris = *cloth.newest->triangles;
  const int32_t width = patch_->width();
  for (size_t i = 0; i < devices_.size(); ++i) {
    const Device& d = devices_[i];
    const ProxyState& ps = d.proxy;
    const int32_t anchor = patch_->anchor(i);
    int32_t centre = -1;
    int32_t best = 0;
    const auto consider = [&](const ProxyContact& c) {
      if (c.triangle < 0 || c.triangle >= static_cast<int32_t>(tris.size())) return;
      Eigen::Index corner = 0;
      c.barycentric.maxCoeff(&corner);
      const int32_t p = tris[c.triangle][corner];
      const int32_t dist = anchor < 0 ? 0
                                      : std::max(std::abs(p % width - anchor % width),
                                                 std::abs(p / width - anchor / width));
      if (centre < 0 || dist < best) {
        centre = p;
        best = dist;
      }
    };
    if (d.fresh) {
      for (int32_t k = 0; k < ps.body.num_contacts; ++k) consider(ps.body.contacts[k]);
      if (centre < 0) consider(ps.hand_seed);
    }
    patch_centres_[i] = centre;
  }
  // Particles entering a window start where the previous tick's cloth had them.
  const double tau_s = cloth.since_newest_s;
  patch_->set_drive_horizon(cloth.horizon_s);
  patch_->Place(patch_centres_, *cloth.newest, std::max(0.0, tau_s - dt_s), dt_s);
  if (!patch_->active()) return;
  const PatchStepResult step =
      patch_->Step(std::span<const ExternalForce>(patch_springs_.data(),
                                                  static_cast<size_t>(patch_spring_count_)),
                   dt_s, *cloth.newest, tau_s);
  overlay_.offset_m = patch_->DistanceFromDrive();
  Bump(counters_.patch_ticks);
  if (step.recovered) Bump(counters_.patch_nan_events);
  counters_.patch_guard_pushes.store(patch_->counters().guard_pushes, std::memory_order_relaxed);
}

bool HapticLoop::ReadInput(uint32_t index, int64_t now_ns, Device* d) {
  // The newest sample; a non-finite one keeps the last good sample and makes this tick's force 0.
  PointerInput in;
  if (!source_->Latest(index, now_ns, &in)) return false;
  if (!in.p_D_m.allFinite() || !in.v_D_m_per_s.allFinite()) return true;
  d->input = in;
  d->have_input = true;
  return false;
}

void HapticLoop::TickDevice(uint32_t index, int64_t now_ns, double dt_s, const TickCloth& cloth) {
  Device& d = devices_[index];
  DeviceCounters& c = *d.counters;
  const bool input_nan = ReadInput(index, now_ns, &d);
  if (!d.have_input && !input_nan) return;  // the device has not spoken yet: nothing to send
  Bump(c.ticks_with_input);
  const bool fresh = d.have_input && now_ns - d.input.receive_time_ns <= stale_ns_;
  if (fresh && !d.fresh) Bump(c.connects);
  d.fresh = fresh;

  // The proxy runs on fresh, finite input only; stale input keeps its last force (ramped out).
  if (fresh && !input_nan) {
    DeviceSample sample;
    sample.p_D_m = d.input.p_D_m;
    sample.v_D_m_per_s = d.input.v_D_m_per_s;
    const double since_s = std::min(cloth.since_newest_s, cloth.horizon_s);
    d.last_result =
        ProxyTick(d.model, *cloth.newest, cloth.previous, since_s, sample, dt_s, &d.proxy,
                  patch_ != nullptr && patch_->active() ? &overlay_ : nullptr);
  }
  const SafetyOutput out = ApplyDeviceSafety(cloth, input_nan, dt_s, &d);
  SendForce(index, now_ns, out, &d);
}

SafetyOutput HapticLoop::ApplyDeviceSafety(const TickCloth& cloth, bool input_nan, double dt_s,
                                           Device* d) {
  SafetyInput in;
  in.proxy_force_D_N = d->last_result.force_D_N;
  in.velocity_D_m_per_s = d->fresh ? d->input.v_D_m_per_s : Vec3::Zero();
  in.input_fresh = d->fresh;
  in.input_nan = input_nan;
  in.sim_stalled = cloth.stalled;
  return ApplySafety(d->safety_spec, in, dt_s, &d->safety);
}

void HapticLoop::SendForce(uint32_t index, int64_t now_ns, const SafetyOutput& out, Device* d) {
  // Out to the device.
  ForceOutput force;
  force.answers_seq = d->input.seq;
  force.answers_device_time_ns = d->input.device_time_ns;
  force.force_D_N = out.force_D_N;
  force.proxy_D_m = d->model.ToDevice(d->last_result.proxy_W_m);
  force.in_contact = d->fresh && d->last_result.num_contacts > 0;
  force.flags = out.flags;
  force.tick_time_ns = now_ns;
  // The local contact model (Mark et al. 1996): the plane through the proxy centre with the first
  // contact's normal, so that k max(0, (proxy - p) . n) n is the spring force for one frictionless
  // contact. Sent only while the force is the proxy's own (not ramped, stale or NaN).
  const GodObject& body = d->proxy.body;
  const uint32_t not_own = kSafetyStaleInput | kSafetyRamping;
  if (force.in_contact && body.num_contacts > 0 && (out.flags & not_own) == 0 && !out.nan) {
    force.contact_point_D_m = force.proxy_D_m;
    force.contact_normal_D = d->model.rotation_WD.transpose() * body.contacts[0].normal_W;
    force.contact_stiffness_N_per_m = d->model.stiffness_N_per_m;
  }
  sink_->Push(index, force);

  // Counters.
  DeviceCounters& c = *d->counters;
  Bump(c.forces_sent);
  if (force.in_contact) Bump(c.contact_ticks);
  if (out.flags & kSafetyStaleInput) Bump(c.stale_ticks);
  if (out.flags & kSafetyRamping) Bump(c.ramping_ticks);
  if (out.flags & kSafetyClamped) Bump(c.clamped_ticks);
  if (out.flags & kSafetySimStalled) Bump(c.stalled_ticks);
  if (out.nan) Bump(c.nan_events);
  RaiseTo(c.peak_force_N, out.force_D_N.norm());
  c.energy_J.store(d->safety.energy_J, std::memory_order_relaxed);
  c.dissipated_J.store(d->safety.dissipated_J, std::memory_order_relaxed);
  c.connected.store(d->fresh, std::memory_order_relaxed);
}

}  // namespace felt
