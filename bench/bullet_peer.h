#pragma once
// Bullet's btSoftBody as a benchmark peer of Felt's cloth (issue 21): the default curtain built as
// a Bullet soft body, stepped at the scene's frame rate, its structural links measured the way
// Felt's structural springs are (length / rest length). Only the benchmarks use it; no library of
// Felt links Bullet. Built from Debian's libbullet-dev when CMake finds it (FELT_HAVE_BULLET);
// without it BulletAvailable() is false and BulletCurtain's constructor throws, with the reason.
// Not real-time safe.
//
// How the curtain is set up (what a careful Bullet user does, after Bullet's own SoftDemo
// Init_Cloth and btSoftBody.cpp; BulletCurtainSpec has the numbers):
//  - btSoftRigidDynamicsWorld (btSoftBodyRigidBodyCollisionConfiguration, btCollisionDispatcher,
//    btDbvtBroadphase, btSequentialImpulseConstraintSolver, btDefaultSoftBodySolver), holding the
//    soft body only; one frame is stepSimulation(dt, 1, dt): one internal step of dt (counted).
//  - btSoftBodyHelpers::CreatePatch over the same four corners as the curtain, width x height
//    nodes, node index row * width + col (Felt's order), structural links plus one diagonal link
//    per cell (gendiags; Bullet's patch has no second diagonal), all at the default material's
//    kLST = 1 (hard distance constraints).
//  - With `bending`: generateBendingConstraints(2, m) with a second material of kLST =
//    bend_stiffness: a link between every two nodes two links apart.
//  - Every free node has the mass of a Felt particle (total mass / particle count); the pinned
//    ones mass 0 (Bullet's "fixed"). Gravity in the soft body world info (Bullet's own default is
//    -10 m/s^2; the curtain's is set). Felt's viscous drag c (per particle) as Bullet's velocity
//    damping: kDP = 1 - exp(-(c / m) dt), the same decay of a particle's velocity per frame.
//  - The default Positions solver preset (Anchors, RContacts, SContacts, Linear), with
//    m_cfg.piterations = position_iterations. viterations stays 0: with the Positions preset the
//    velocity solver sequence is empty, so velocity iterations would solve nothing.
//  - Collision margin = the particle spacing (the ratio of Bullet's cloth demo); no other body
//    exists, so nothing collides; deactivation disabled.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "collision/mesh.h"
#include "sim_loop/cloth_spec.h"

namespace felt::bench {

/// The curtain as Bullet is given it (file comment). World frame, SI units.
struct BulletCurtainSpec {
  int32_t width = 0;                     ///< nodes along u (columns), >= 2
  int32_t height = 0;                    ///< nodes along v (rows), >= 2
  double spacing_m = 0.0;                ///< rest distance between grid neighbours, m
  Vec3 origin_m = Vec3::Zero();          ///< rest place of node (col 0, row 0), m
  Vec3 u_axis = Vec3::UnitX();           ///< unit direction of increasing column
  Vec3 v_axis = -Vec3::UnitY();          ///< unit direction of increasing row
  double particle_mass_kg = 0.0;         ///< mass of every free node, kg
  std::vector<int32_t> pinned;           ///< node indices (row * width + col) held fixed
  Vec3 gravity_m_per_s2 = Vec3::Zero();  ///< world frame
  double velocity_damping = 0.0;         ///< Bullet's m_cfg.kDP, in [0, 1)
  int32_t position_iterations = 1;       ///< Bullet's m_cfg.piterations, >= 1
  bool bending = true;                   ///< generateBendingConstraints(2, ...)
  double bend_stiffness = 1.0;           ///< the bending material's kLST, in (0, 1]
  double frame_dt_s = 1.0 / 60.0;        ///< one frame, s
};

/// The Bullet curtain matching `spec`'s cloth (SimSpec of a resized curtain): grid, spacing, axes,
/// particle mass, pins, gravity and drag as in the file comment, with `position_iterations` and
/// `bending`. Throws std::invalid_argument when the cloth has what this peer cannot express
/// (scripted pins, obstacles) or for iterations < 1.
BulletCurtainSpec BulletCurtainFromSim(const SimSpec& spec, int32_t position_iterations,
                                       bool bending);

/// Whether this build has Bullet (CMake found libbullet-dev).
bool BulletAvailable();

/// Why the Bullet rows are missing ("" when BulletAvailable()).
std::string BulletMissingReason();

/// Bullet's version as its headers and library give it, e.g. "3.24 (headers 3.24), float".
std::string BulletVersionText();

/// One Bullet soft-body curtain in its own world (file comment).
class BulletCurtain {
 public:
  /// Builds the world and the curtain. Throws std::runtime_error (BulletMissingReason) without
  /// Bullet, std::invalid_argument for a bad spec.
  explicit BulletCurtain(const BulletCurtainSpec& spec);
  ~BulletCurtain();
  BulletCurtain(const BulletCurtain&) = delete;
  BulletCurtain& operator=(const BulletCurtain&) = delete;

  /// One frame: world->stepSimulation(dt, 1, dt). Throws std::logic_error if Bullet did not take
  /// exactly one internal step.
  void StepFrame();

  /// Largest length / rest length over the structural links (grid neighbours along a row or a
  /// column; rest = their distance when built), in double precision from Bullet's float nodes.
  /// NaN when a node is not finite.
  double MaxStructuralStretch() const;

  /// Links Bullet solves (structural, diagonal and bending), for the tables.
  int64_t links() const;

  /// Node (col, row)'s position, m (for tests).
  Vec3 NodePosition(int32_t col, int32_t row) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace felt::bench
