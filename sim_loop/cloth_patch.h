#pragma once
// The local patch (issue 20, snapshot mode `patch`): the cloth near each contact, stepped at the
// haptic rate inside the haptic tick, so that the proxy touches a cloth that reacts to it within
// the tick instead of one frame (16.7 ms) later.
//
// The intermediate model of multirate haptics (Astley & Hayward 1998: a fine local model at the
// haptic rate coupled to the coarse global one; Cavusoglu & Tendick 2000: the local model is
// updated by the slow simulation; ../shared/notes/multirate-haptics.md), made of the cloth itself:
// a rectangle of the grid (a window) around each contact, `radius` particles each way. The outer
// two rings of a window (a bend spring's reach) are driven: they follow the 60 Hz cloth, its newest
// snapshot extrapolated in time with the snapshot's frame-motion velocities (x0 + tau v0); so are
// pinned particles. The inner particles are free: integrated with the cloth's own forces (the
// model's springs, gravity, drag), the haptic contact springs of the last tick (the same unilateral
// sphere the sim integrates: sim_loop/cloth_coupling.h), Provot's structural and shear limits
// (000_25210a744b053ca5.txt slide 9, Gauss-Seidel over the window's pairs, driven ends fixed),
// after the long range attachments to the pins inside the window (Kim, Chentanez & Mueller 2012,
// as the sim's ApplyProvot), and the scene's obstacles (projection to the margin, inward velocity
// removed). The integrator is leapfrog Verlet (001_0f9f1b7fedff7723.txt §3.5, kick-drift-kick as
// sim_loop's), at substeps no longer than the cloth's nominal one (and the contact spring's
// stability bound).
//
// A window edge on the cloth's own edge has nothing beyond it, so its rings there are free. Windows
// that overlap or come within two particles of each other (so that a spring joins them) are merged
// into their bounding rectangle: two devices on one cloth share one simulation where their patches
// meet, and each feels the other's push at once.
//
// Hand-back: what reaches the 60 Hz cloth is the proxy's reaction, as in every mode (the contact
// spring the sim integrates at its substeps, moving with the hand's predicted velocity in this
// mode: ProxyModel::predict_hand), so the global cloth gets the push once. The patch's own state
// stays local: it is a finer model of the same cloth near the hand, driven by the global one at
// its rings. Handing its positions (or positions and velocities) back to the sim each frame was
// measured and made the held press oscillate (docs/proxy.md, mode patch).
//
// Storage: the windows' particles live densely (structure of arrays, each window's rows one after
// the other at an even pitch), so that every spring family and every constraint colour of a
// window is one long loop over independent pairs, compiled for each vector level of base/simd.h
// (the same bits at every level); positions and velocities stay in double precision between
// steps, the spring and constraint kernels run in single precision from the window's first
// particle (as ApplyProvot). The per-particle arrays (x(), x_before(), v(), roles()) are the
// cloth's size, written back every step for the proxy. Sized once; Place and Step are real-time
// safe.

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <vector>

#include "sim_loop/cloth.h"
#include "sim_loop/snapshot.h"

namespace felt {

struct CouplingSprings;  // sim_loop/cloth_coupling.h (internal to sim_loop)
struct CouplingSphere;   // sim_loop/cloth_coupling.h
struct WindowPasses;     // sim_loop/cloth_patch.cc
struct PatchAttachment;  // sim_loop/cloth_patch.cc

/// A rectangle of the cloth's grid, columns col0..col1 and rows row0..row1 inclusive.
struct PatchWindow {
  int32_t col0 = 0;   ///< first column
  int32_t row0 = 0;   ///< first row
  int32_t col1 = -1;  ///< last column (< col0: empty)
  int32_t row1 = -1;  ///< last row
  /// True when the window holds no particle.
  bool empty() const { return col1 < col0 || row1 < row0; }
  /// Particles in the window.
  int32_t size() const { return empty() ? 0 : (col1 - col0 + 1) * (row1 - row0 + 1); }
};

/// What a particle is to the patch.
enum class PatchRole : uint8_t {
  kOutside = 0,  ///< not in any window: the 60 Hz cloth's
  kDriven = 1,   ///< in a window's outer rings (or pinned): follows the 60 Hz cloth
  kFree = 2,     ///< integrated by the patch
};

/// Driven particles approach the drive with this time constant [s] (first order, on top of the
/// drive's own motion): a particle that was free and turns driven, or a ring the drive's newest
/// snapshot jumps away from, eases onto the 60 Hz cloth instead of jumping there (a jump of the
/// ring is turned into velocity by Provot's correction v += dx / h next to it).
inline constexpr double kPatchDriveTime_s = 0.010;
/// A window whose centre is gone (its device left the cloth) stays while its free particles lie
/// farther than this from the drive [m], so the patch hands its motion back to the sim before
/// it is forgotten instead of snapping to the 60 Hz cloth ...
inline constexpr double kPatchReleaseDistance_m = 0.0005;
/// ... but at most this long [s].
inline constexpr double kPatchMaxLinger_s = 0.25;

/// What one Step did.
struct PatchStepResult {
  int32_t substeps = 0;    ///< substeps integrated (0: no window)
  int32_t springs = 0;     ///< contact springs applied
  bool recovered = false;  ///< non-finite values appeared: the windows restarted from the drive
};

/// Counters of a patch since it was made.
struct PatchCounters {
  uint64_t steps = 0;                ///< Step calls with at least one window
  uint64_t placements = 0;           ///< windows placed or moved
  uint64_t merges = 0;               ///< windows merged with another
  uint64_t nan_events = 0;           ///< steps that restarted from the drive
  uint64_t springs_outside = 0;      ///< contact springs too near a window's edge, not applied
  ClothCounters coupling;            ///< AddCouplingSpring's counts (invalid, reduced, dropped)
  uint64_t guard_pushes = 0;         ///< triangles the sphere guard pushed (ApplySphereGuards)
  uint64_t guard_dropped_cells = 0;  ///< cells past the guard's capacity, not tested
};

/// The local patch (file comment). Owned by the haptic thread.
class ClothPatch {
 public:
  /// A patch of `model` (kept by reference: it must outlive the patch) with windows of `radius`
  /// particles each way around their centres ([kMinPatchRadius, kMaxPatchRadius]), at most
  /// `max_windows` >= 1 of them, each following its centre once it is `follow` particles away
  /// ([1, radius]). Allocates (set-up time); throws std::invalid_argument naming the bad value.
  ClothPatch(const ClothModel& model, int32_t radius, int32_t max_windows,
             int32_t follow = kPatchDefaultFollow);
  ~ClothPatch();
  ClothPatch(const ClothPatch&) = delete;
  ClothPatch& operator=(const ClothPatch&) = delete;

  /// The windows of this tick: one around each particle index of `centres` (slot k: device k;
  /// negative entries: no centre), a window kept where it is while its centre stays within
  /// `follow` particles of it (kPatchDefaultFollow), then merged where they meet (file comment). A
  /// slot whose centre is gone keeps its window while it lingers (kPatchReleaseDistance_m,
  /// kPatchMaxLinger_s; dt_s [s] is the tick). Particles that enter take the drive's state at tau_s
  /// [s]: x = drive.x + tau_s drive.v, v = drive.v; particles that leave are forgotten. Real-time
  /// safe.
  void Place(std::span<const int32_t> centres, const ClothSnapshot& drive, double tau_s,
             double dt_s);

  /// Advances the windows by dt_s [s]: the driven particles to the drive at tau_s [s] (the
  /// time since the drive's snapshot at the end of the step), the free ones by the forces of the
  /// file comment with the contact springs of `external` (entries with stiffness_N_per_m > 0 whose
  /// 3 x 3 cells of candidates lie inside a window; others are ignored). Keeps the positions at
  /// the start of the step (x_before). Real-time safe.
  PatchStepResult Step(std::span<const ExternalForce> external, double dt_s,
                       const ClothSnapshot& drive, double tau_s);

  /// The drive's snapshot is extrapolated along its velocities at most this long past it [s]
  /// (+inf by default): Place and Step take min(tau_s, horizon), each substep's drive time too.
  /// The haptic loop sets its sim-stall threshold (at least a frame), so that a stalled sim leaves
  /// the windows' rims where the extrapolation was then instead of carrying them on.
  void set_drive_horizon(double horizon_s) { drive_horizon_s_ = horizon_s; }

  /// Largest distance [m] of a window particle's position, now or at the start of the last step,
  /// from `s`'s position of it (0 without windows). Real-time safe; O(window particles).
  double MaxDistanceFrom(const ClothSnapshot& s) const;
  /// MaxDistanceFrom(drive) for the drive of the last Step [m], computed by Step at no extra pass.
  double DistanceFromDrive() const { return drive_distance_m_; }

  /// Role of each particle [cloth's particles].
  const PatchRole* roles() const { return role_.data(); }
  /// Positions [m, world; cloth's particles, meaningful in the windows].
  const Vec3* x() const { return x_.data(); }
  /// Positions at the start of the last step [m, world; meaningful in the windows].
  const Vec3* x_before() const { return x_before_.data(); }
  /// Unit area-weighted vertex normal of particle p at the patch's positions (as
  /// ComputeVertexNormals; every triangle around a free particle lies in its window), computed on
  /// demand (the proxy shades with a few per tick) [world; meaningful for free particles; zero if
  /// degenerate]. Real-time safe.
  Vec3 NormalAt(int32_t p) const;
  /// Velocities [m/s, world; meaningful in the windows].
  const Vec3* v() const { return v_.data(); }
  /// The windows now.
  std::span<const PatchWindow> windows() const { return {windows_.data(), window_count_}; }
  /// True when at least one window is held.
  bool active() const { return window_count_ > 0; }
  /// The centre particle of slot `slot`'s window (-1: none), as Place left it.
  int32_t anchor(size_t slot) const { return slot < anchors_.size() ? anchors_[slot] : -1; }
  /// The cloth's grid width, particles (particle p is at column p % width, row p / width).
  int32_t width() const { return model_.width; }
  /// The window radius, particles.
  int32_t radius() const { return radius_; }
  /// Counters since construction.
  const PatchCounters& counters() const { return counters_; }

 private:
  void MarkRoles(std::span<const PatchWindow> windows, PatchRole* roles) const;
  bool SpringInside(const ExternalForce& e) const;
  PatchWindow PairRange(const PatchWindow& window, int32_t dc, int32_t dr) const;
  double DriftFromDrive(const PatchWindow& window, const ClothSnapshot& drive, double tau_s) const;
  void Flush();
  void Layout();
  void BuildPasses(const PatchWindow& window, WindowPasses* out) const;
  void LoadDrive(const ClothSnapshot& drive);
  void StorePositions(Vec3* x) const;
  void SubstepForces(std::span<const Vec3> positions);
  void ApplyProvotToWindows(double h);
  void BuildAttachments();
  void ApplyObstaclesToWindows();
  void GatherGuardCells();
  void ApplySphereGuardsToWindows();
  bool AllFinite() const;
  void RestartFromDrive(double tau_s);
  template <typename Visit>
  void ForEachParticle(Visit&& visit) const;
  double* D(int32_t array) { return dense_.data() + array * stride_; }
  const double* D(int32_t array) const { return dense_.data() + array * stride_; }
  float* F(int32_t array) { return single_.data() + array * stride_; }
  const float* F(int32_t array) const { return single_.data() + array * stride_; }

  const ClothModel& model_;
  int32_t radius_;
  double h_max_s_;                         // the patch's longest substep, s
  int32_t recentre_;                       // a window follows its centre this many particles away
  std::vector<PatchWindow> windows_;       // [max_windows]
  std::vector<PatchWindow> next_windows_;  // [max_windows], scratch of Place
  std::vector<int32_t> anchors_;           // [max_windows] each slot's window centre (-1: none)
  std::vector<double> linger_s_;           // [max_windows] time each slot has lingered, s
  size_t window_count_ = 0;
  std::vector<PatchRole> role_;       // [n]
  std::vector<PatchRole> next_role_;  // [n], scratch of Place
  // The state by particle (the proxy reads x_ and x_before_; Place starts entering particles here).
  std::vector<Vec3> x_, v_, x_before_, a_last_;  // [n] each
  std::vector<uint8_t> restart_;                 // [n] leapfrog restarts from v
  std::vector<int32_t> vertex_tri_start_;        // [n + 1] CSR: triangles around each particle
  std::vector<int32_t> vertex_tris_;
  // The windows' particles, densely: window k's particle (c, r) at local index
  // base_[k] + (r - row0) pitch + (c - col0), pitch the window's column count made even (a row of
  // odd length ends in one padding entry). The state lives here between Place's layouts (x_ and
  // v_ are written back every step); arrays of stride_ entries each.
  size_t stride_ = 0;
  int32_t locals_ = 0;                    // local entries in all, padding included
  std::vector<int32_t> base_;             // [max_windows + 1] first local index of each window
  std::vector<WindowPasses> passes_;      // [max_windows] each window's passes (BuildPasses)
  std::vector<int32_t> global_;           // [stride_] particle of each local index (-1: padding)
  std::vector<int32_t> local_;            // [n] local index of each particle (-1: outside)
  std::vector<double> dense_;             // [kDenseArrays stride_] (cloth_patch.cc)
  std::vector<float> single_;             // [kSingleArrays stride_] (cloth_patch.cc)
  const ClothSnapshot* drive_ = nullptr;  // the drive dense_ holds, with its frame
  uint64_t drive_frame_ = 0;
  bool drive_loaded_ = false;
  std::vector<double> f_;        // [3 n] AddCouplingForces' output, zero between uses
  std::vector<int32_t> level1_;  // indices of model_.provot_families with level 1
  // The long range attachments of free window particles to pins in the same window (Layout):
  // window k's are [attach_base_[k], attach_base_[k + 1]); room for every attachment of the model.
  std::vector<PatchAttachment> attach_;
  std::vector<int32_t> attach_base_;  // [max_windows + 1]
  double h_last_s_ = 0.0;             // the last substep's length (leapfrog's history), s
  double drive_distance_m_ = 0.0;     // DistanceFromDrive
  double drive_horizon_s_ = std::numeric_limits<double>::infinity();  // set_drive_horizon
  std::unique_ptr<CouplingSprings> springs_;  // the contact springs of the step
  // Their spheres at the step's start (the sphere guard; ApplySphereGuardsToWindows).
  std::vector<CouplingSphere> spheres_;  // [kMaxCouplingSprings]
  // Each sphere's cells to guard in the step (GatherGuardCells): guard_cells_[k][0, count).
  std::vector<std::array<int32_t, 256>> guard_cells_;  // [kMaxCouplingSprings] (kMaxGuardCells)
  std::vector<int32_t> guard_count_;                   // [kMaxCouplingSprings]
  PatchCounters counters_;
};

}  // namespace felt
