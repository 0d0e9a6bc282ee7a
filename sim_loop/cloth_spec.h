#pragma once
// What a scene declares about the cloth and its simulation: plain structs with defaults and units
// in the field names. A spec is validated once (BuildClothModel in sim_loop/cloth.h) into an
// immutable model; scene files (scene/scene_file.h) parse into these structs.
//
// World frame (_W, the default for every position here): metres, y up, gravity along -y.

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "collision/mesh.h"
#include "collision/self_response.h"

namespace felt {

/// The time integrators a scene may choose (001_0f9f1b7fedff7723.txt §3, §6.2).
enum class IntegratorKind {
  kLeapfrogVerlet,    ///< default: kick-drift with velocities at half steps (001 §3.5)
  kExplicitEuler,     ///< x += h v, v += h a (001 eq. 2)
  kSymplecticEuler,   ///< v += h a(x), x += h v_new
  kExplicitMidpoint,  ///< second-order Runge-Kutta, midpoint rule
  kRk4,               ///< classical fourth-order Runge-Kutta
  kBasicVerlet,       ///< position Verlet, x_next = 2x - x_prev + a h^2 (001 eq. 5)
  kVelocityVerlet,    ///< x += h v + h^2 a / 2, v += h (a + a_next) / 2
  kImplicitEuler,     ///< backward Euler, linearised, solved by CG (Baraff & Witkin 1998)
};

/// One spring type's constants. Damping acts along the spring on the relative velocity.
struct SpringSpec {
  double stiffness_N_per_m = 0.0;  ///< Hooke constant k, > 0
  double damping_N_s_per_m = 0.0;  ///< dashpot constant along the spring, >= 0
};

/// Scripted motion of a pin: offset(t) = velocity * clamp(t, start, stop) - velocity * start
///                                       + amplitude * sin(2 pi frequency (t - start)) for
///                                       t>=start.
/// All zero (the default) means the pin is fixed.
struct PinMotionSpec {
  Vec3 velocity_m_per_s = Vec3::Zero();  ///< constant drift, e.g. a curtain rail sliding sideways
  Vec3 amplitude_m = Vec3::Zero();       ///< sinusoidal amplitude
  double frequency_hz = 0.0;             ///< sinusoid frequency, >= 0
  double start_s = 0.0;                  ///< motion starts at this sim time
  double stop_s = std::numeric_limits<double>::infinity();  ///< drift stops at this sim time
};

/// Which particles a pin holds.
enum class PinKind {
  kParticle,  ///< one particle at (col, row)
  kCorner,    ///< one of "top_left", "top_right", "bottom_left", "bottom_right"
  kEdge,      ///< every particle of "top", "bottom", "left" or "right"
};

/// A pin: the particles it holds have inverse mass 0 and follow `motion` from their rest place.
/// Row 0 is the "top" edge, column 0 the "left" edge.
struct PinSpec {
  PinKind kind = PinKind::kCorner;
  int32_t col = 0;       ///< kParticle only
  int32_t row = 0;       ///< kParticle only
  std::string name;      ///< kCorner / kEdge: the corner's or edge's name
  PinMotionSpec motion;  ///< scripted motion; fixed by default
};

/// An infinite plane through `point_m` with unit `normal` pointing to the free side.
struct PlaneSpec {
  Vec3 point_m = Vec3::Zero();
  Vec3 normal = Vec3::UnitY();
};
/// A solid sphere.
struct SphereSpec {
  Vec3 center_m = Vec3::Zero();
  double radius_m = 0.1;
};
/// A solid axis-aligned box (a table), min corner < max corner on every axis.
struct BoxSpec {
  Vec3 min_m = Vec3(-0.5, -0.1, -0.5);
  Vec3 max_m = Vec3(0.5, 0.0, 0.5);
};
/// A solid capsule: the points within radius_m of the segment a_m-b_m.
struct CapsuleSpec {
  Vec3 a_m = Vec3::Zero();
  Vec3 b_m = Vec3::UnitX();
  double radius_m = 0.05;
};

/// A static obstacle the cloth's particles are kept out of.
struct ObstacleSpec {
  std::variant<PlaneSpec, SphereSpec, BoxSpec, CapsuleSpec> shape;
  double friction = 0.0;    ///< Coulomb coefficient mu >= 0; 0 = frictionless
  double margin_m = 0.002;  ///< particles are kept this far outside the surface, >= 0
};

/// The cloth: a rectangular grid of `width` x `height` particles.
/// Particle (col, row) rests at origin_m + col * spacing_m * u_axis + row * spacing_m * v_axis.
struct ClothSpec {
  int32_t width = 32;                       ///< particles along u, >= 2
  int32_t height = 32;                      ///< particles along v, >= 2
  double spacing_m = 0.016;                 ///< rest distance between neighbours, > 0
  double mass_kg = 0.1;                     ///< total mass, divided uniformly over the particles
  Vec3 origin_m = Vec3(-0.248, 0.25, 0.0);  ///< rest position of particle (0, 0), the top-left
  Vec3 u_axis = Vec3::UnitX();              ///< unit direction of increasing column
  Vec3 v_axis = -Vec3::UnitY();             ///< unit direction of increasing row, orthogonal to u
  // Soft springs, stiff limit: the springs give the cloth its shape and wave; Provot's constraints
  // (ProvotSpec) stop the stretch (000_25210a744b053ca5.txt slide 9: "avoid super elastic effect
  // without decreasing dt"). Stiffer springs shorten the stable step (slide 8) and cost substeps.
  std::optional<SpringSpec> structural = SpringSpec{1.0, 2e-4};  ///< (i,j)-(i+1,j), (i,j)-(i,j+1)
  std::optional<SpringSpec> shear = SpringSpec{0.5, 1e-4};       ///< the two cell diagonals
  std::optional<SpringSpec> bend = SpringSpec{0.1, 2e-5};        ///< (i,j)-(i+2,j), (i,j)-(i,j+2)
  double drag_N_s_per_m = 5e-5;  ///< viscous drag per particle, F = -c v, >= 0
  Vec3 gravity_m_per_s2 = Vec3(0.0, -9.81, 0.0);
  std::vector<PinSpec> pins;            ///< may be empty (a falling cloth)
  std::vector<ObstacleSpec> obstacles;  ///< only these are built and tested
};

/// Limits that the scene parser (sim_loop/cloth_scene.h) and BuildClothModel both enforce, so a
/// key's rule is the same wherever it is validated.
inline constexpr int32_t kMaxGridSide = 4096;               ///< particles along u or v
inline constexpr int64_t kMaxParticles = int64_t{1} << 22;  ///< width * height (2048 x 2048)
inline constexpr double kMaxFrameRate_hz = 10000.0;         ///< integration.frame_rate_hz
inline constexpr int32_t kMaxProvotIterations = 10000;      ///< provot.iterations

/// The smallest local patch radius, particles (proxy.patch_radius; two driven rings around at
/// least one free particle: sim_loop/cloth_patch.h).
inline constexpr int32_t kMinPatchRadius = 3;
/// The largest local patch radius, particles (proxy.patch_radius).
inline constexpr int32_t kMaxPatchRadius = 32;
/// A window follows its centre once the centre is this many particles (Chebyshev) from the
/// window's own centre (proxy.patch_follow): hysteresis, so a contact hopping between nearby
/// particles (a proxy in a crease, a fast swipe) does not move the window back and forth, each
/// move turning particles from free to driven and back. 2 by measurement against the truth
/// (docs/proxy.md, "Where"): at 4 (half the default radius) the contact strayed toward the driven
/// rings, which follow a cloth up to a frame old, and scrub was 0.19 N RMS from the truth (0.13 N
/// at 2; 0.13 N at 1, but then peaks rose on pin_drag and handwriting).
inline constexpr int32_t kPatchDefaultFollow = 2;

/// The most substeps one nominal frame may take, explicit or auto (one rule for the scene parser
/// and BuildClothModel).
inline constexpr int32_t kMaxSubstepsPerFrame = 100000;

/// How a 60 Hz frame is integrated.
struct IntegrationSpec {
  IntegratorKind integrator = IntegratorKind::kLeapfrogVerlet;
  int32_t substeps = 0;                ///< per frame; 0 = "auto" from the stability limit
  double frame_rate_hz = 60.0;         ///< nominal frame rate, > 0
  double max_frame_dt_s = 1.0 / 30.0;  ///< a late frame integrates at most this much time
  double auto_safety = 0.5;         ///< auto substeps keep h <= auto_safety * h_stable, in (0, 1]
  int32_t cg_max_iterations = 200;  ///< implicit Euler: conjugate-gradient iteration cap
  double cg_tolerance = 1e-8;       ///< implicit Euler: relative residual to stop at
};

/// Provot 1995 deformation constraints (000_25210a744b053ca5.txt slide 9).
struct ProvotSpec {
  bool enabled = true;
  double max_elongation = 0.10;  ///< a spring never ends a substep longer than (1 + this) * rest
  /// Relaxation sweeps per substep at most, >= 1; sweeping stops early once no pair exceeds its
  /// sweep length by more than 0.1 %. On their own (without `finish`), with the multiresolution
  /// families, 3 sweeps held the release transient of a 64 x 64 two-corner curtain to about 11.5 %
  /// and the hanging cloth to about 10.4 %; without the families 10 sweeps let the transient reach
  /// 17 %. The finishing worklist then takes what they leave over the limit.
  int32_t iterations = 3;
  bool shear = true;  ///< also constrain shear springs (structural always)
  /// Also keep every free particle within (1 + max_elongation) times its rest distance of the
  /// nearest pinned particle of each group of touching pins, of the four groups nearest it at
  /// most (long range attachments, Kim, Chentanez & Mueller 2012), projected before Provot's
  /// sweeps. Pins are kinematic, so this only removes energy; it stops the stretch that
  /// Gauss-Seidel sweeps carry only O(1/N^2) per sweep down an N-row hanging cloth.
  bool long_range_attachments = true;
  /// Also limit particles 2, 4, 8, ... apart along a row, a column or (with `shear`) a diagonal to
  /// (1 + max_elongation) times their rest distance, swept coarsest first: up to 8 apart with
  /// long_range_attachments (which hold the rest), else up to the grid's size. Implied by the
  /// spring limits (so never an extra restriction), they carry a correction across the cloth in
  /// one sweep instead of one spring per sweep: the coarse levels of multigrid (Briggs, Henson &
  /// McCormick 2000) and of hierarchical position based dynamics (Mueller 2008), as stencils on
  /// the grid.
  bool multiresolution = true;
  /// The multiresolution families join the first `coarse_sweeps` sweeps of a substep only, >= 1
  /// (default: every sweep); the later sweeps visit the spring families alone. With the finishing
  /// worklist the coarse levels need to run once a substep (they carry a correction across the
  /// cloth; the fine sweeps and the worklist settle the rest): the two-corner curtain, 3 sweeps,
  /// probe CPU ms per frame at 64 / 128: 1.75 / 14.8 with the levels in every sweep, 1.37 / 10.8
  /// in the first only, the limit held either way (sim_loop/cloth_limiter.cc).
  int32_t coarse_sweeps = kMaxProvotIterations;
  /// The sweeps aim at (1 - sweep_headroom) times every limit (pairs and attachments' own limits
  /// stay as declared), in [0, 0.5): Gauss-Seidel sweeps stall in taut patches where every pair
  /// sits at its limit, and a little room below the limit is what lets the finishing pass
  /// (`finish`) converge in a few local projections instead of thousands. The cloth then settles
  /// about this much shorter than (1 + max_elongation) times its rest length.
  double sweep_headroom = 0.0;
  /// After the sweeps, project every structural (and, with `shear`, shear) spring still over its
  /// limit exactly, in double precision, re-visiting only the springs each projection pushed over
  /// (a worklist), until none is over: the limit then holds at the end of every substep, not just
  /// up to the sweeps' convergence (bench/results/cloth_finishing.md).
  bool finish = false;
  /// The haptic local patch's sweeps per 1 kHz step (sim_loop/cloth_patch.h), in [1,
  /// kMaxProvotIterations]; unset: `iterations`. The patch has no worklist, so its sweeps alone
  /// hold its free particles; a sim that leans on the worklist (one sweep, more headroom) can keep
  /// the patch at the sweeps it needs (docs/scenes.md, [provot]).
  std::optional<int32_t> patch_iterations;
  /// The haptic local patch's sweeps aim at (1 - this) times every limit, in [0, 0.5); unset:
  /// `sweep_headroom`.
  std::optional<double> patch_sweep_headroom;
};

/// Self-collision of the cloth (issue 22; collision/self_response.h): Bridson, Fedkiw & Anderson
/// 2002's repulsion, CCD impulses and rigid impact zones after every substep. Only built when the
/// scene declares [self_collision].
struct SelfCollisionSpec {
  double thickness_m = 0.002;  ///< cloth thickness, m, > 0 and below half the grid spacing
  /// Broad phase; the BVH with normal cones by default: the cheapest in
  /// bench/results/self_collision.md at 32 x 32 and 64 x 64 (issue 22).
  SelfCullingMethod method = SelfCullingMethod::kBvhCones;
  int32_t iterations = 4;  ///< CCD impulse rounds per substep, in [0, 100]
  double friction = 0.1;   ///< Coulomb coefficient between layers, >= 0
  bool fail_safe = true;   ///< rigid impact zones when the impulses leave collisions
  /// Repulsion spring constant, N/m, >= 0; unset: the structural springs' (1 N/m without them).
  std::optional<double> repulsion_stiffness_N_per_m;
  /// Count intersecting triangle pairs at the end of every frame with the exact O(T^2) test
  /// (collision/self_intersection.h): a diagnostic for tests and small scenes, off by default.
  bool count_intersections = false;
  /// Most self-collision passes per frame, >= 1 (SelfCollisionSettings::passes_per_frame).
  int32_t passes_per_frame = SelfCollisionSettings{}.passes_per_frame;
  /// Fewest passes of a slow frame after one without contact (with a hand: while its measured
  /// motion allows), >= 1
  /// (SelfCollisionSettings::min_passes_per_frame; >= passes_per_frame: never fewer).
  int32_t min_passes_per_frame = SelfCollisionSettings{}.min_passes_per_frame;
  /// A slow frame's pass moves the fastest particle at most this many thicknesses, >= 0
  /// (SelfCollisionSettings::slow_pass_motion; 0: fewer passes never).
  double slow_pass_motion = SelfCollisionSettings{}.slow_pass_motion;
  /// With a hand on a quiet cloth, a pass moves the fastest particle at most this many
  /// thicknesses, >= 0 (SelfCollisionSettings::hand_pass_motion; 0: the count's passes).
  double hand_pass_motion = SelfCollisionSettings{}.hand_pass_motion;
  /// The proxy's sphere keeps the cloth's other layers out, in the sim and the local patch
  /// (ApplySphereGuards; docs/proxy.md, "Layered cloth").
  bool guard_proxy = true;
};

/// Everything the 60 Hz simulation needs from a scene.
struct SimSpec {
  ClothSpec cloth;
  IntegrationSpec integration;
  ProvotSpec provot;
  std::optional<SelfCollisionSpec> self_collision;  ///< absent: no self-collision at all
};

}  // namespace felt
