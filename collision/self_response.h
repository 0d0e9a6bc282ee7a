#pragma once
// Self-collision response of a cloth over one substep (issue 22; Bridson, Fedkiw & Anderson 2002,
// "Robust treatment of collisions, contact and friction for cloth animation",
// 003_b6c1450a5a1611e7.txt). The integrator (and Provot's constraints, obstacles, pins) has moved
// the cloth x_before -> x over a substep of length h; the response treats v_avg = (x - x_before) /
// h as each particle's candidate velocity and corrects it in three stages:
//  1. proximity repulsion (Bridson §7.2): every vertex-triangle and edge-edge pair closer than the
//     thickness at x_before gets an inelastic impulse (its approach velocity removed) and a spring
//     impulse min(h k d, m (0.1 d / h - v_N)) with d the overlap, plus Coulomb friction (§7.3);
//  2. continuous collisions (Bridson §7.4): the exact CCD of collision/ccd.h over x_before ->
//     x_before + h v_avg, culled by a broad phase of collision/self_broadphase.h; each colliding
//     pair gets an inelastic impulse with friction, and detection is repeated up to `iterations`
//     times while collisions remain;
//  3. the fail-safe, rigid impact zones (Provot 1997; Bridson §7.4): the vertices of every
//     remaining collision are merged into zones (union-find) which move rigidly, with the
//     momentum-preserving linear and angular velocity of their vertices, detection is repeated and
//     zones merged until no collision remains (at most max_zone_iterations rounds, then every free
//     vertex of a zone keeps its x_before: see SelfCollisionStats::frozen).
// Why a zone cannot collide with itself: its free vertices move by x_before + h (v_cm + w x r),
// an affine map I + t h [w]x of the start positions along the substep, whose singular values are
// all >= 1 and determinant > 0: no quadruple of the zone that is not coplanar at t = 0 becomes
// coplanar, and no distance shrinks. A zone holding a pinned particle (infinite mass) moves with
// the mean velocity of its pins (exact for fixed pins and for pins translating together).
// Since x_before holds no intersection, a substep whose final motion has no CCD collision ends
// without a new intersection (a new intersection needs a contact, i.e. a coplanar time at
// distance 0, which the CCD never misses).
//
// Velocities are changed the way Provot's constraints change them in sim_loop (v += dx / h): the
// particle's position moves by dx = h dv_avg and its velocity by dv_avg. Pinned particles
// (inverse mass 0) never move. Allocation only at construction; Resolve is real-time safe.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "collision/ccd_all_pairs.h"
#include "collision/mesh.h"
#include "collision/self_broadphase.h"
#include "collision/self_bvox.h"

namespace felt {

/// The broad phases a scene may choose (collision/self_broadphase.h).
enum class SelfCullingMethod : uint8_t {
  kSpatialHash,  ///< SelfSpatialHash (Teschner et al. 2003)
  kBvh,          ///< SelfBvh (AABB tree self-traversal)
  /// SelfBvh with normal cones (SelfBroadPhaseOptions::normal_cones): patches certified free of
  /// self-contact over the motion are not traversed against themselves. A certificate holds for
  /// its own motion only: a broad phase on the pass's motion (also serving the proximity pass
  /// when the last pass's repulsion moved few vertices; else the proximity pass has its own on
  /// the static positions), which every CCD and zone detection carries over to its own motion,
  /// traversing again only where vertices moved (SelfBvh::UpdateCandidates) and re-testing only
  /// those pairs.
  kBvhCones,
  /// SelfBvox: an AABB tree rebuilt every step by voxels (Baciu & Wong 2004's BVOX-AABB).
  kBvox,
  /// APCCD (Wong 2009, 004_aff31237b107e6f0.txt) on SelfBvh: kBvh's inflated boxes reused across
  /// passes (skipped broad phases), and when some vertices leave their boxes ("dangling"), only
  /// their boxes made again and the tree traversed again where they are
  /// (SelfBvh::UpdateCandidates), instead of a new broad phase.
  kApccd,
};

/// Every culling method, in the order above (for tests and benches that try them all).
inline constexpr std::array<SelfCullingMethod, 5> kSelfCullingMethods = {
    SelfCullingMethod::kSpatialHash, SelfCullingMethod::kBvh, SelfCullingMethod::kBvhCones,
    SelfCullingMethod::kBvox, SelfCullingMethod::kApccd};

/// Settings of the response (SelfCollisionSpec in sim_loop/cloth_spec.h, validated).
struct SelfCollisionSettings {
  double thickness_m = 0.002;  ///< cloth thickness h: primitives are kept this far apart, m (> 0)
  /// Broad phase (the cone-culled BVH measured cheapest, bench/results/self_collision.md).
  SelfCullingMethod method = SelfCullingMethod::kBvhCones;
  int32_t iterations = 4;  ///< CCD impulse rounds per substep before the fail-safe (>= 0)
  double friction = 0.1;   ///< Coulomb coefficient mu between layers (>= 0)
  bool fail_safe = true;   ///< rigid impact zones after the impulse rounds
  /// Spring constant of the repulsion (Bridson §7.2's k), N/m (>= 0; 0 turns the spring off).
  double repulsion_stiffness_N_per_m = 1.0;
  int32_t max_zone_iterations = 64;  ///< fail-safe merge rounds before freezing the zones (>= 1)
  /// The continuous test's thickness as a fraction of thickness_m (in (0, 1]): a collision is a
  /// coplanar time within this distance. Smaller than the cloth's thickness, so that layers the
  /// repulsion holds about thickness_m apart (parallel edges of a fold lying flat are coplanar
  /// at every time) are not collisions; any contact (distance 0) still is (Bridson et al. 2002
  /// run the collision pass with a smaller proximity than the repulsion's).
  double ccd_thickness_fraction = 0.1;
  /// Self-collision passes per frame of the cloth step (Bridson et al. 2002 §7 take a
  /// collision step longer than the dynamics' substeps): each Resolve covers ceil(substeps /
  /// passes_per_frame) substeps, the last one ends with the frame. One pass per frame let piles
  /// be pressed flat onto the floor within the pass (the fold drop's hits overflowed and its
  /// zones froze), a pass per substep costs the most; 8 was the compromise measured
  /// (docs/self_collision.md). A pass per substep for basic Verlet, whose velocity comes from
  /// the last substep's positions (sim_loop/cloth_self_collision.cc: SelfPassSubsteps). >= 1.
  int32_t passes_per_frame = 8;
  /// Slow frames take fewer, longer passes, down to this many (1 <= it; at most
  /// passes_per_frame turns it off): a pass covers up to ceil(substeps / min_passes_per_frame)
  /// substeps while the fastest particle, at its frame-start speed plus gravity's gain over the
  /// frame, moves at most slow_pass_motion thicknesses over it
  /// (sim_loop/cloth_self_collision.cc: SelfPassSubsteps; with a hand on the cloth, while its
  /// measured motion stays within hand_pass_motion). Fast frames keep passes_per_frame.
  /// Measured on the 64 x 64 curtain (docs/self_collision.md, "Fewer passes in quiet frames").
  int32_t min_passes_per_frame = 2;
  /// The most a slow frame's pass may move its fastest particle, in thicknesses, with no hand on
  /// the cloth (>= 0; 0 turns that lengthening off).
  double slow_pass_motion = 4.0;
  /// The most a pass may move its fastest particle, in thicknesses, in a frame after one without
  /// contact while a hand acts on the cloth (>= 0; 0: such frames keep passes_per_frame). The
  /// pass goes on past the count's length substep by substep while the measured motion since
  /// it began, plus one more substep at the present speed, stays within it (a hand's pull is
  /// not in the frame-start speeds; sim_loop/cloth_self_collision.cc: SelfPassMayGoOn). 0.45 =
  /// (1 - ccd_thickness_fraction) / 2: two features close at most 0.9 thickness in a pass, so a
  /// pair coming into contact is first met by the proximity repulsion at a pass's start, as in
  /// the count's passes, never only by the CCD; with 1 or 4 the flap of
  /// LayeredCloth.AFoldNeverClosesOnTheProxy landed differently and closed on the proxy
  /// (docs/self_collision.md, "A hand on a quiet cloth").
  double hand_pass_motion = 0.45;
  /// A pass's length is also capped so that the fastest particle at the frame's start moves at
  /// most this many thicknesses over it (substeps per pass <= max_pass_motion * thickness_m /
  /// (max |v| h), at least 1; sim_loop/cloth_self_collision.cc: SelfPassSubsteps). With the
  /// count alone a fine cloth got passes many thicknesses long: the 150 x 150 fold drop (0.5 mm
  /// thick, 15 substeps of about 0.3 mm each per pass) pushed its bottom layer into the floor,
  /// whose projection back was read as velocity pass after pass until it moved at tens of m/s,
  /// overflowed and froze (docs/self_collision.md, "Pass length"). 0 = no cap (>= 0). Off by
  /// default: on, it failed LayeredCloth.AFoldNeverClosesOnTheProxy (one particle under the
  /// hand at up to 50 m/s cut that scene's passes to one substep); `felt bench self-collision`
  /// sets 4.
  double max_pass_motion = 0.0;
  /// APCCD's inflated bounding volumes (Tang et al., 004_aff31237b107e6f0.txt): the broad
  /// phase's boxes are padded by this fraction of thickness_m beyond the half thickness, so
  /// that later passes whose vertices all stay within the extra padding reuse its candidates
  /// and skip the broad phase (a skipping-frame session). 0 = a broad phase every pass (>= 0).
  double broad_inflation = 1.0;
};

/// What one Resolve call did.
struct SelfCollisionStats {
  int64_t proximity_pairs = 0;     ///< pairs closer than the thickness at x_before
  int64_t proximity_impulses = 0;  ///< of those, pairs whose velocity was changed
  int64_t ccd_hits = 0;            ///< colliding pairs found by the first CCD pass
  int64_t ccd_impulses = 0;        ///< inelastic impulses applied over the CCD rounds
  int32_t ccd_rounds = 0;          ///< CCD detections run before the fail-safe
  int32_t zone_rounds = 0;         ///< fail-safe detections run
  int64_t impact_zones = 0;        ///< distinct impact zones at the end of the fail-safe
  int64_t zone_vertices = 0;       ///< vertices in impact zones
  bool frozen = false;             ///< the zones did not settle: their free vertices kept x_before
  /// Collisions left after everything (only when the fail-safe is off, or frozen zones met moving
  /// pins): the substep may end with a new intersection.
  int64_t unresolved = 0;
  int64_t overflows = 0;  ///< detections whose candidate or hit buffer overflowed (then fail-safe)
  int32_t broad_phases = 0;  ///< broad-phase runs (FindCandidates), proximity's included
  int32_t broad_reuses = 0;  ///< detections that reused an earlier broad phase's candidates
  /// Broad phases carried over by SelfBvh::UpdateCandidates (traversing again only where vertices
  /// moved) instead of a new one: bvh_cones' detections, and apccd's where a few vertices left
  /// their boxes (its dangling vertices).
  int32_t broad_updates = 0;
  /// Detections that re-tested only the candidates with a vertex moved since the last one.
  int32_t incremental_detections = 0;
  int64_t narrow_tests = 0;  ///< continuous pair tests run (VertexTriangleCcd / EdgeEdgeCcd)
  /// Wall time in detection [s]: the broad phases, the box filter and the continuous pair tests
  /// of every CCD and zone round (not the proximity pass's distance tests or any impulse).
  double detect_s = 0.0;
  double first_detect_s = 0.0;  ///< of which the first CCD detection (all candidates), s
  int32_t passes = 0;           ///< Resolve calls (1 per call; their count in totals())
};

/// The response of one cloth mesh. Copyable (a copy owns its own buffers); not thread-safe.
class SelfCollisionResponse {
 public:
  /// Sizes every buffer for the mesh (triangles over inv_mass.size() particles, rest positions x
  /// [m] for the broad phase's cell size). inv_mass [1/kg], 0 for a pinned particle. Throws
  /// std::invalid_argument on a bad setting or index.
  SelfCollisionResponse(std::span<const Triangle> triangles, std::span<const Vec3> x,
                        std::span<const double> inv_mass, const SelfCollisionSettings& settings);

  /// Remembers x as the substep's start positions x_before [m]. Real-time safe.
  void BeginStep(std::span<const Vec3> x);

  /// Corrects the substep x_before -> x of length h_s [s]: positions x [m] and velocities v [m/s]
  /// of free particles change by dx and dx / h_s. Real-time safe.
  SelfCollisionStats Resolve(double h_s, std::span<Vec3> x, std::span<Vec3> v);

  /// The substep's start positions (from BeginStep) [m].
  std::span<const Vec3> x_before() const { return x_before_; }

  /// Keeps, from now on, a copy of each Resolve's first CCD detection: the end positions it
  /// tested (the motion x_before -> first_pass_end()) and the colliding pairs it found, so that a
  /// caller can compare them with an all-pairs reference (AllPairsCcd) on the same motion.
  /// Allocates (call at set-up); Resolve stays real-time safe.
  void KeepFirstPass(bool on);
  /// The end positions of the last Resolve's first CCD detection [m] (empty unless kept).
  std::span<const Vec3> first_pass_end() const { return first_end_; }
  /// The colliding pairs of the last Resolve's first CCD detection, in candidate order (empty
  /// unless kept).
  std::span<const CcdPairHit> first_pass_hits() const { return first_hits_; }
  /// The continuous test's options of the CCD passes (thickness_m * ccd_thickness_fraction).
  AllPairsCcdOptions CcdPassOptions() const;
  const SelfCollisionSettings& settings() const { return settings_; }
  /// Sums of every Resolve's stats since construction (frozen: any pass froze), for callers that
  /// measure over several passes (felt bench self-collision).
  const SelfCollisionStats& totals() const { return totals_; }

 private:
  SelfBroadPhase* Broad();
  const SelfBroadPhase* Broad() const;
  int64_t Detect(std::span<const Vec3> x1, SelfCollisionStats* stats);
  int64_t DetectAll(std::span<const Vec3> x1, SelfCollisionStats* stats);
  int64_t DetectCones(std::span<const Vec3> x1, SelfCollisionStats* stats);
  void ClearMoved();
  void TestCandidate(int32_t i, std::span<const Vec3> x1, const AllPairsCcdOptions& options,
                     SelfCollisionStats* stats, int64_t* hits);
  void RunBroadPhase(std::span<const Vec3> x1, SelfCollisionStats* stats);
  void RefreshBroadPhase(std::span<const Vec3> x1, double margin_m, SelfCollisionStats* stats);
  bool WithinBroadBoxes(int32_t p, const Vec3& q, double margin_m) const;
  bool CanDetectIncrementally() const;
  bool NarrowTest(int32_t candidate, std::span<const Vec3> x1, const AllPairsCcdOptions& options,
                  CcdPairHit* hit);
  void SetCcdBox(int32_t p, std::span<const Vec3> x1);
  void Proximity(double h_s, SelfCollisionStats* stats);
  bool ApplyPairImpulse(const std::array<int32_t, 4>& vid, const std::array<double, 4>& w,
                        const Vec3& dv);
  void SetVelocity(int32_t p, const Vec3& vel);
  void FlushTrial(double h_s);
  int32_t Find(int32_t p);
  void Union(int32_t a, int32_t b);
  void RigidZones(double h_s, SelfCollisionStats* stats);

  SelfCollisionSettings settings_;
  std::vector<Triangle> triangles_;
  std::vector<double> inv_mass_;
  std::optional<SelfSpatialHash> hash_;
  std::optional<SelfBvh> bvh_;
  std::optional<SelfBvox> bvox_;
  bool cones_ = false;  ///< kBvhCones: one cone-culled broad phase per pass, carried over
  bool apccd_ = false;  ///< kApccd: dangling vertices re-traversed (RefreshBroadPhase)
  /// kBvhCones: the BVH's candidates hold for x_before_ -> x_trial_ up to the vertices in
  /// moved_list_ (false after an overflow: the next detection runs a full broad phase).
  bool cone_valid_ = false;
  /// kBvhCones: cand_hit_ holds no narrow results yet (the pass's broad phase just ran).
  bool cone_fresh_ = false;
  /// kBvhCones: this pass's broad phase is on its motion and serves the proximity pass too
  /// (its boxes also hold the start positions padded by the full thickness).
  bool share_ = false;
  int64_t prox_moved_ = 0;        ///< vertices the last pass's repulsion moved
  std::vector<CcdPairHit> hits_;  ///< capacity fixed at construction
  std::vector<Vec3> x_before_;    ///< [n] substep start
  // The last broad phase (on x_before_ -> x1, boxes padded by broad_pad_m_ per side): each
  // vertex's unpadded swept box. Its candidates hold every pair within distance d at any
  // positions less than 0.9 (broad_pad_m_ - d / 2) outside these boxes: the proximity pass
  // (d = thickness) and the CCD (d = its thickness) reuse them while the vertices stay there.
  std::vector<Vec3> broad_lo_, broad_hi_;  ///< [n] m
  bool broad_valid_ = false;               ///< the broad phase holds those candidates
  double broad_pad_m_ = 0.0;
  double ccd_margin_m_ = 0.0;   ///< how far outside the boxes the CCD may reuse them, m
  double prox_margin_m_ = 0.0;  ///< how far outside the boxes the proximity pass may, m
  // The narrow phase's state: cand_hit_[i] is candidate i's CCD result for x_trial_, up to the
  // vertices in moved_list_ (changed since the last detection).
  bool narrow_valid_ = false;
  std::vector<uint8_t> cand_hit_;  ///< [max candidates]
  std::vector<uint8_t> moved_;     ///< [n]
  std::vector<uint8_t> dangling_;  ///< [n] apccd: outside their boxes (RefreshBroadPhase)
  std::vector<int32_t> moved_list_;
  std::vector<Vec3> ccd_lo_, ccd_hi_;  ///< [n] swept box padded for the CCD thickness, m
  SelfCollisionStats totals_;
  bool keep_first_pass_ = false;
  std::vector<Vec3> first_end_;
  std::vector<CcdPairHit> first_hits_;
  std::vector<Vec3> x_trial_;   ///< [n] x_before + h vel (exactly x where vel is untouched)
  std::vector<Vec3> vel_;       ///< [n] candidate average velocity of the substep, m/s
  std::vector<uint8_t> dirty_;  ///< [n] 1 if vel_ changed since x_trial_ was updated
  std::vector<int32_t> dirty_list_;
  // Impact zones (union-find over vertices) and their per-root sums.
  std::vector<int32_t> parent_;
  std::vector<uint8_t> in_zone_;
  std::vector<int32_t> zone_list_;  ///< vertices in some zone, in the order they joined
  std::vector<double> zone_mass_;
  std::vector<Vec3> zone_mx_, zone_mv_, zone_l_, zone_pin_v_, zone_omega_;
  std::vector<Eigen::Matrix3d> zone_inertia_;
  std::vector<int32_t> zone_pins_;
  std::vector<int32_t> zone_stamp_;
  int32_t stamp_ = 0;
  double particle_mass_kg_ = 0.0;  ///< mass of a free particle for the spring impulse, kg
};

/// Parses a culling method name ("spatial_hash", "bvh", "bvh_cones", "bvox_aabb", "apccd");
/// nullopt for any other.
std::optional<SelfCullingMethod> SelfCullingMethodFromName(std::string_view name);

/// The name of a culling method (as SelfCullingMethodFromName reads it).
std::string_view SelfCullingMethodName(SelfCullingMethod method);

}  // namespace felt
