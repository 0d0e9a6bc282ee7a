#include "bench/bullet_peer.h"

#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "sim_loop/cloth.h"

#if FELT_HAVE_BULLET
#include <BulletSoftBody/btDefaultSoftBodySolver.h>
#include <BulletSoftBody/btSoftBody.h>
#include <BulletSoftBody/btSoftBodyHelpers.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>
#include <btBulletDynamicsCommon.h>
#endif

namespace felt::bench {

BulletCurtainSpec BulletCurtainFromSim(const SimSpec& spec, int32_t position_iterations,
                                       bool bending) {
  if (position_iterations < 1) {
    throw std::invalid_argument("Bullet position iterations must be >= 1, got " +
                                std::to_string(position_iterations));
  }
  if (!spec.cloth.obstacles.empty()) {
    throw std::invalid_argument("the Bullet peer builds the curtain without obstacles");
  }
  // The model resolves pins (corners, edges) to particle indices and the particle mass.
  const ClothModel model = BuildClothModel(spec);
  for (const uint8_t scripted : model.pin_scripted) {
    if (scripted) throw std::invalid_argument("the Bullet peer cannot move pins (scripted motion)");
  }
  BulletCurtainSpec b;
  b.width = model.width;
  b.height = model.height;
  b.spacing_m = model.spacing_m;
  b.origin_m = spec.cloth.origin_m;
  b.u_axis = spec.cloth.u_axis.normalized();
  b.v_axis = spec.cloth.v_axis.normalized();
  b.particle_mass_kg = model.particle_mass_kg;
  b.pinned = model.pinned;
  b.gravity_m_per_s2 = model.gravity_m_per_s2;
  b.frame_dt_s = 1.0 / model.frame_rate_hz;
  // Felt's drag F = -c v decays a particle's velocity by exp(-(c / m) dt) over a frame; Bullet's
  // kDP scales the velocity by (1 - kDP) once per step.
  b.velocity_damping = 1.0 - std::exp(-model.drag_rate_per_s * b.frame_dt_s);
  b.position_iterations = position_iterations;
  b.bending = bending;
  b.bend_stiffness = 1.0;
  return b;
}

#if FELT_HAVE_BULLET

bool BulletAvailable() { return true; }

std::string BulletMissingReason() { return ""; }

std::string BulletVersionText() {
  const auto dotted = [](int v) { return std::to_string(v / 100) + "." + std::to_string(v % 100); };
  return dotted(btGetVersion()) + " (headers " + dotted(BT_BULLET_VERSION) + "), " +
         (sizeof(btScalar) == sizeof(float) ? "single" : "double") + " precision";
}

namespace {

btVector3 ToBt(const Vec3& v) {
  return btVector3(static_cast<btScalar>(v.x()), static_cast<btScalar>(v.y()),
                   static_cast<btScalar>(v.z()));
}

Vec3 FromBt(const btVector3& v) {
  return Vec3(static_cast<double>(v.x()), static_cast<double>(v.y()), static_cast<double>(v.z()));
}

// Counts Bullet's internal steps (its tick callback, called after each one).
void CountTick(btDynamicsWorld* world, btScalar /*time_step*/) {
  ++*static_cast<int64_t*>(world->getWorldUserInfo());
}

}  // namespace

struct BulletCurtain::Impl {
  BulletCurtainSpec spec;
  // The world's parts, destroyed in reverse order by the destructor.
  std::unique_ptr<btSoftBodyRigidBodyCollisionConfiguration> collision_config;
  std::unique_ptr<btCollisionDispatcher> dispatcher;
  std::unique_ptr<btDbvtBroadphase> broadphase;
  std::unique_ptr<btSequentialImpulseConstraintSolver> solver;
  std::unique_ptr<btDefaultSoftBodySolver> soft_solver;
  std::unique_ptr<btSoftRigidDynamicsWorld> world;
  btSoftBody* body = nullptr;  // owned here, added to the world
  // The structural links to measure: node pairs and their rest lengths, m.
  std::vector<std::pair<int32_t, int32_t>> structural;
  std::vector<double> rest_m;
  int64_t internal_steps = 0;

  ~Impl() {
    if (body != nullptr) {
      world->removeSoftBody(body);
      delete body;
    }
  }
};

BulletCurtain::BulletCurtain(const BulletCurtainSpec& spec) : impl_(std::make_unique<Impl>()) {
  if (spec.width < 2 || spec.height < 2) throw std::invalid_argument("grid must be >= 2 x 2");
  if (spec.position_iterations < 1) throw std::invalid_argument("position_iterations must be >= 1");
  if (!(spec.spacing_m > 0.0) || !(spec.particle_mass_kg > 0.0) || !(spec.frame_dt_s > 0.0)) {
    throw std::invalid_argument("spacing, particle mass and frame dt must be > 0");
  }
  if (!(spec.velocity_damping >= 0.0 && spec.velocity_damping < 1.0)) {
    throw std::invalid_argument("velocity damping (kDP) must be in [0, 1)");
  }
  if (!(spec.bend_stiffness > 0.0 && spec.bend_stiffness <= 1.0)) {
    throw std::invalid_argument("bend stiffness (kLST) must be in (0, 1]");
  }
  Impl& s = *impl_;
  s.spec = spec;

  // The world (Bullet's soft-rigid world with its usual parts), holding the soft body only.
  s.collision_config = std::make_unique<btSoftBodyRigidBodyCollisionConfiguration>();
  s.dispatcher = std::make_unique<btCollisionDispatcher>(s.collision_config.get());
  s.broadphase = std::make_unique<btDbvtBroadphase>();
  s.solver = std::make_unique<btSequentialImpulseConstraintSolver>();
  s.soft_solver = std::make_unique<btDefaultSoftBodySolver>();
  s.world = std::make_unique<btSoftRigidDynamicsWorld>(s.dispatcher.get(), s.broadphase.get(),
                                                       s.solver.get(), s.collision_config.get(),
                                                       s.soft_solver.get());
  s.world->setGravity(ToBt(spec.gravity_m_per_s2));
  s.world->setInternalTickCallback(&CountTick, &s.internal_steps);
  btSoftBodyWorldInfo& info = s.world->getWorldInfo();
  info.m_gravity = ToBt(spec.gravity_m_per_s2);  // the soft body's gravity (default -10 m/s^2)

  // The patch over the curtain's four corners: node (col, row) at index row * width + col.
  const Vec3 across_m = spec.u_axis * spec.spacing_m * (spec.width - 1);
  const Vec3 down_m = spec.v_axis * spec.spacing_m * (spec.height - 1);
  const Vec3& o = spec.origin_m;
  s.body = btSoftBodyHelpers::CreatePatch(info, ToBt(o), ToBt(o + across_m), ToBt(o + down_m),
                                          ToBt(o + across_m + down_m), spec.width, spec.height,
                                          /*fixeds=*/0, /*gendiags=*/true);
  if (s.body == nullptr) throw std::runtime_error("btSoftBodyHelpers::CreatePatch failed");
  btSoftBody& body = *s.body;

  // Bending: a second material for the links between nodes two links apart.
  if (spec.bending) {
    btSoftBody::Material* bend = body.appendMaterial();
    bend->m_kLST = static_cast<btScalar>(spec.bend_stiffness);
    body.generateBendingConstraints(2, bend);
  }

  // Masses: Felt's particle mass for free nodes, 0 (fixed) for the pins.
  const int32_t n = spec.width * spec.height;
  for (int32_t i = 0; i < n; ++i) body.setMass(i, static_cast<btScalar>(spec.particle_mass_kg));
  for (const int32_t p : spec.pinned) {
    if (p < 0 || p >= n) throw std::invalid_argument("pinned node out of range");
    body.setMass(p, 0);
  }

  // Solver settings.
  body.m_cfg.piterations = spec.position_iterations;
  body.m_cfg.kDP = static_cast<btScalar>(spec.velocity_damping);
  body.getCollisionShape()->setMargin(static_cast<btScalar>(spec.spacing_m));
  body.setActivationState(DISABLE_DEACTIVATION);
  s.world->addSoftBody(s.body);

  // The structural links: grid neighbours along rows and columns, rest = built distance.
  for (int32_t row = 0; row < spec.height; ++row) {
    for (int32_t col = 0; col < spec.width; ++col) {
      const int32_t i = row * spec.width + col;
      if (col + 1 < spec.width) s.structural.emplace_back(i, i + 1);
      if (row + 1 < spec.height) s.structural.emplace_back(i, i + spec.width);
    }
  }
  s.rest_m.reserve(s.structural.size());
  for (const auto& [a, b] : s.structural) {
    s.rest_m.push_back((FromBt(body.m_nodes[b].m_x) - FromBt(body.m_nodes[a].m_x)).norm());
  }
}

BulletCurtain::~BulletCurtain() = default;

void BulletCurtain::StepFrame() {
  Impl& s = *impl_;
  const int64_t before = s.internal_steps;
  const btScalar dt = static_cast<btScalar>(s.spec.frame_dt_s);
  s.world->stepSimulation(dt, 1, dt);
  if (s.internal_steps != before + 1) {
    throw std::logic_error("Bullet took " + std::to_string(s.internal_steps - before) +
                           " internal steps in one frame, not 1");
  }
}

double BulletCurtain::MaxStructuralStretch() const {
  const Impl& s = *impl_;
  double max_stretch = 1.0;
  for (size_t k = 0; k < s.structural.size(); ++k) {
    const Vec3 a = FromBt(s.body->m_nodes[s.structural[k].first].m_x);
    const Vec3 b = FromBt(s.body->m_nodes[s.structural[k].second].m_x);
    const double stretch = (b - a).norm() / s.rest_m[k];
    if (!std::isfinite(stretch)) return std::nan("");
    max_stretch = std::max(max_stretch, stretch);
  }
  return max_stretch;
}

int64_t BulletCurtain::links() const { return impl_->body->m_links.size(); }

Vec3 BulletCurtain::NodePosition(int32_t col, int32_t row) const {
  const Impl& s = *impl_;
  if (col < 0 || col >= s.spec.width || row < 0 || row >= s.spec.height) {
    throw std::out_of_range("node out of range");
  }
  return FromBt(s.body->m_nodes[row * s.spec.width + col].m_x);
}

#else  // !FELT_HAVE_BULLET

bool BulletAvailable() { return false; }

std::string BulletMissingReason() {
  return "this felt was built without Bullet (CMake's find_package(Bullet) found no "
         "libbullet-dev, or the build was configured with -DFELT_BULLET=OFF): install Debian's "
         "libbullet-dev (`apt-get install -y libbullet-dev`), then configure and build again";
}

std::string BulletVersionText() { return "none"; }

struct BulletCurtain::Impl {};

BulletCurtain::BulletCurtain(const BulletCurtainSpec& /*spec*/) {
  throw std::runtime_error(BulletMissingReason());
}

BulletCurtain::~BulletCurtain() = default;

void BulletCurtain::StepFrame() {}

double BulletCurtain::MaxStructuralStretch() const { return std::nan(""); }

int64_t BulletCurtain::links() const { return 0; }

Vec3 BulletCurtain::NodePosition(int32_t /*col*/, int32_t /*row*/) const { return Vec3::Zero(); }

#endif  // FELT_HAVE_BULLET

}  // namespace felt::bench
