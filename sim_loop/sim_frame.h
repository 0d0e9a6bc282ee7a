#pragma once
// The 60 Hz loop's frame (docs/server.md): what the sim thread runs each period. One frame pops the
// reaction batches the haptic thread queued and turns them into the frame's ExternalForce list
// (impulse-preserving), steps the cloth (StepFrame), fills the triple buffer's write slot with the
// cloth and the frame's motion as its velocities (FillSnapshotWithFrameMotion, repairing the
// collision structure), stamps the publication time and publishes it.
//
// The two handoffs between the loops live here, since the sim owns both ends' data:
//  - sim -> haptic: the newest snapshot in a triple buffer (one atomic exchange, no copy, no wait);
//  - haptic -> sim: reaction batches in an SPSC queue (a full queue makes the haptic side retry
//    the same batch next tick, so no impulse is lost: haptic_loop/haptic_tick.h).
#include <algorithm>
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "collision/collision_structure.h"
#include "rt/spsc_queue.h"
#include "rt/triple_buffer.h"
#include "sim_loop/cloth.h"
#include "sim_loop/snapshot.h"

namespace felt {

/// The most reaction forces one batch holds (all devices together); beyond it, forces merge into
/// the last entry (total kept, counted by ReactionAccumulator::overflows()).
inline constexpr int32_t kMaxReactionForces = 1024;

/// A frame without reactions reuses the last batch's contact springs for at most this many frames
/// (SimLoop::Frame); then the cloth lets go.
inline constexpr int32_t kMaxHeldSpringFrames = 4;
/// Contact springs one frame can hold (ExternalForce with stiffness; the cloth's own limit).
inline constexpr size_t kMaxHeldContactSprings = 16;

/// Reaction batches (sim frames) in flight haptic -> sim.
inline constexpr size_t kReactionQueueCapacity = 8;

/// The reactions of all devices over one sim frame, haptic -> sim. Fixed-size data; copies copy
/// only the entries in use.
struct ReactionBatch {
  int32_t count = 0;      ///< entries used in `forces`
  double duration_s = 0;  ///< haptic time the forces are averaged over, s
  std::array<ExternalForce, kMaxReactionForces> forces;  ///< world frame, N (time averages)

  ReactionBatch() = default;
  /// Copies the entries in use (a whole batch is ~150 kB; its used part is usually a few hundred
  /// bytes, and the haptic tick copies one into the queue per frame).
  ReactionBatch(const ReactionBatch& other) { *this = other; }
  /// As the copy constructor.
  ReactionBatch& operator=(const ReactionBatch& other) {
    count = other.count;
    duration_s = other.duration_s;
    std::copy_n(other.forces.begin(), count, forces.begin());
    return *this;
  }
};

/// A published snapshot plus when it was published.
struct PublishedSnapshot {
  ClothSnapshot snapshot;  ///< the cloth of one frame
  int64_t publish_ns = 0;  ///< CLOCK_MONOTONIC at Publish, ns (0: the initial rest state)
};

/// Sim -> haptic: the newest snapshot.
using SnapshotBuffer = TripleBuffer<PublishedSnapshot>;
/// Haptic -> sim: reaction batches.
using ReactionQueue = SpscQueue<ReactionBatch>;

/// What the sim loop has done, written by the sim thread, read by any thread.
struct SimCounters {
  std::atomic<uint64_t> frames{0};                    ///< frames stepped
  std::atomic<double> time_s{0.0};                    ///< sim time of the newest frame, s
  std::atomic<uint64_t> reaction_batches_applied{0};  ///< batches the sim applied
  std::atomic<uint64_t> cloth_nan_events{0};     ///< frames that recovered from non-finite values
  std::atomic<double> applied_impulse_N_s{0.0};  ///< sum of |reaction impulse| applied, N s
  std::atomic<uint64_t> held_spring_frames{0};   ///< frames that reused the last batch's springs
  /// Triangles the proxy's sphere guard pushed out (self_collision.guard_proxy), summed over
  /// substeps
  std::atomic<uint64_t> guard_pushes{0};
};

/// The sim loop: the cloth, both handoffs and the frame. Construction is set-up (allocates,
/// validates); Frame() is what the sim thread runs each period.
class SimLoop {
 public:
  /// Builds the cloth of `sim` (BuildClothModel: throws std::invalid_argument naming the field),
  /// its rest state, the snapshot buffer (each snapshot holding a `structure` over the cloth) and
  /// the reaction queue.
  SimLoop(const SimSpec& sim, const CollisionStructureSpec& structure);

  /// Publishes the rest state (frame 0) stamped as published at `publish_ns` [ns, the caller's
  /// clock]. Only before the sim thread runs.
  void PublishInitialSnapshot(int64_t publish_ns);

  /// One frame of `frame_dt_s` [s], its snapshot stamped as published at CLOCK_MONOTONIC
  /// `publish_ns` (0: now). Sim thread only (one thread at a time). Real-time safe (StepFrame's
  /// one-time NaN log aside).
  void Frame(double frame_dt_s, int64_t publish_ns);

  /// The cloth model.
  const ClothModel& model() const { return model_; }
  /// The cloth state: only while the sim thread is not running, or from the thread running Frame.
  const ClothState& cloth() const { return cloth_; }
  /// Sim -> haptic handoff (the haptic loop acquires from it).
  SnapshotBuffer& snapshots() { return *snapshots_; }
  /// Haptic -> sim handoff (the haptic loop pushes to it).
  ReactionQueue& reactions() { return *reactions_; }
  /// The loop's counters (any thread).
  const SimCounters& counters() const { return counters_; }

 private:
  // The reactions queued since the last frame into external_, weighted by their durations
  // (impulse kept); returns how many forces, `*any_batch` whether a batch arrived at all.
  size_t TakeQueuedReactions(bool* any_batch);
  // Keeps the contact springs of a frame that received a batch (`any_batch`, `count` forces), or
  // puts the held ones into external_ for a frame without (see kMaxHeldSpringFrames); returns the
  // frame's force count.
  size_t HoldContactSprings(bool any_batch, size_t count, double frame_dt_s);

  ClothModel model_;
  ClothState cloth_;
  std::unique_ptr<SnapshotBuffer> snapshots_;
  std::unique_ptr<ReactionQueue> reactions_;
  std::unique_ptr<ReactionBatch> popped_;  // scratch
  std::vector<ExternalForce> external_;    // sized once
  std::array<ExternalForce, kMaxHeldContactSprings> held_;  // the last batch's contact springs
  size_t held_count_ = 0;
  int32_t held_frames_ = 0;       // frames that reused them
  double held_elapsed_s_ = 0.0;   // length of the frame that last used them, s
  // The published positions of the last frame and the frame-motion velocities
  // (sim_loop/frame_motion.h), [particles] each, sized once.
  std::vector<Vec3> frame_start_x_;
  std::vector<Vec3> frame_motion_v_;
  uint64_t frame_counter_ = 0;
  SimCounters counters_;
};

}  // namespace felt
