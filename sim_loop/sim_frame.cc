#include "sim_loop/sim_frame.h"

#include <algorithm>
#include <span>

#include "rt/counters.h"
#include "rt/periodic_loop.h"
#include "sim_loop/frame_motion.h"

namespace felt {

SimLoop::SimLoop(const SimSpec& sim, const CollisionStructureSpec& structure)
    : model_(BuildClothModel(sim)), cloth_(MakeClothState(model_)) {
  // Snapshots: three slots in the triple buffer, each with the collision structure.
  const PublishedSnapshot initial{MakeClothSnapshot(model_, cloth_, structure), 0};
  snapshots_ = std::make_unique<SnapshotBuffer>(initial);
  frame_start_x_ = cloth_.x;
  frame_motion_v_.assign(cloth_.x.size(), Vec3::Zero());

  // Reactions: the queue, the frame's scratch batch and its ExternalForce list (room for a full
  // queue plus one batch).
  reactions_ = std::make_unique<ReactionQueue>(kReactionQueueCapacity);
  popped_ = std::make_unique<ReactionBatch>();
  external_.resize(static_cast<size_t>(kMaxReactionForces) * (kReactionQueueCapacity + 1));
}

void SimLoop::PublishInitialSnapshot(int64_t publish_ns) {
  PublishedSnapshot& first = snapshots_->write_slot();
  FillSnapshot(model_, cloth_, 0, 0.0, &first.snapshot);
  first.publish_ns = publish_ns;
  snapshots_->Publish();
}

size_t SimLoop::TakeQueuedReactions(bool* any_batch) {
  // Each batch's forces as impulses, then divided by the total time: batches weigh by duration.
  *any_batch = false;
  size_t count = 0;
  double total_s = 0.0;
  while (count + kMaxReactionForces <= external_.size() && reactions_->TryPop(popped_.get())) {
    for (int32_t i = 0; i < popped_->count; ++i) {
      external_[count] = popped_->forces[i];
      external_[count].force_N *= popped_->duration_s;  // impulse for now
      AddTo(counters_.applied_impulse_N_s, external_[count].force_N.norm());
      ++count;
    }
    total_s += popped_->duration_s;
    *any_batch = true;
    Bump(counters_.reaction_batches_applied);
  }
  for (size_t i = 0; i < count; ++i) external_[i].force_N /= total_s;
  return count;
}

size_t SimLoop::HoldContactSprings(bool any_batch, size_t count, double frame_dt_s) {
  // A frame with reactions keeps their contact springs; a frame without any (the sim running
  // faster than the haptic loop stages batches, e.g. 2 kHz frames against 1 kHz ticks, or a late
  // haptic tick) reuses them for up to kMaxHeldSpringFrames frames, each spring's hand moved on by
  // its predicted velocity: a hand in contact does not let go of the cloth between batches.
  if (any_batch) {
    held_count_ = 0;
    held_frames_ = 0;
    held_elapsed_s_ = frame_dt_s;
    for (size_t i = 0; i < count && held_count_ < held_.size(); ++i) {
      if (external_[i].stiffness_N_per_m > 0.0) held_[held_count_++] = external_[i];
    }
    return count;
  }
  if (held_count_ == 0 || held_frames_ >= kMaxHeldSpringFrames) return 0;
  ++held_frames_;
  Bump(counters_.held_spring_frames);
  // Each held hand has moved on by the previous frame's length since its frame started.
  for (size_t i = 0; i < held_count_; ++i) {
    held_[i].anchor_m += held_elapsed_s_ * held_[i].anchor_velocity_m_per_s;
    external_[i] = held_[i];
  }
  held_elapsed_s_ = frame_dt_s;
  return held_count_;
}

void SimLoop::Frame(double frame_dt_s, int64_t publish_ns) {
  bool any_batch = false;
  const size_t queued = TakeQueuedReactions(&any_batch);
  const size_t count = HoldContactSprings(any_batch, queued, frame_dt_s);

  // Step, repair, publish with the frame's motion as the velocities (sim_loop/frame_motion.h).
  std::copy(cloth_.x.begin(), cloth_.x.end(), frame_start_x_.begin());
  const FrameResult result = StepFrame(
      model_, std::span<const ExternalForce>(external_.data(), count), frame_dt_s, &cloth_);
  if (result.recovered) Bump(counters_.cloth_nan_events);
  counters_.guard_pushes.store(cloth_.counters.guard_pushes, std::memory_order_relaxed);
  PublishedSnapshot& slot = snapshots_->write_slot();
  FillSnapshotWithFrameMotion(cloth_, frame_start_x_, result.dt_s, ++frame_counter_,
                              frame_motion_v_, &slot.snapshot);
  slot.publish_ns = publish_ns == 0 ? MonotonicNowNs() : publish_ns;
  snapshots_->Publish();
  counters_.time_s.store(cloth_.time_s, std::memory_order_relaxed);
  counters_.frames.store(frame_counter_, std::memory_order_release);
}

}  // namespace felt
