#pragma once
// Virtual coupling of a haptic contact inside the cloth step (issue 4, two-way coupling): a
// unilateral spring from a point of the cloth to the user's hand, evaluated at every force
// evaluation of the integrator (every substep and stage) instead of a force sampled at 60 Hz and
// held for the frame. Colgate, Stanley & Brown 1995 (virtual coupling: the coupling spring is
// what the simulation must integrate stably) applied to the god-object contact of Ruspini,
// Kolarov & Khatib 1997. Not for use outside sim_loop/cloth_*.cc.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "collision/geometry.h"
#include "sim_loop/cloth.h"

namespace felt {

/// Contact springs one StepFrame can hold; further ones are counted (ClothCounters::
/// coupling_overflows) and dropped.
inline constexpr int32_t kMaxCouplingSprings = 16;

/// Triangles a contact spring searches for the cloth's nearest point: those of the 3 x 3 grid
/// cells around the contact triangle's cell (every triangle that shares a vertex with it).
inline constexpr int32_t kMaxCouplingCandidates = 18;

/// The crease smoothing of a contact spring (CouplingSpring::smoothing_m) is this fraction of the
/// spring's penetration at the start of its frame, within [kMinCouplingSmoothing_m,
/// kMaxCouplingSmoothing_m].
inline constexpr double kCouplingSmoothingFraction = 0.1;
/// The smallest crease smoothing, m.
inline constexpr double kMinCouplingSmoothing_m = 1e-6;
/// The largest crease smoothing, m.
inline constexpr double kMaxCouplingSmoothing_m = 20e-6;

/// One contact spring of the frame, resolved against the model: the proxy sphere (centre goal_m,
/// radius_m) pressing on the nearest point of its candidate triangles (ExternalForce), that
/// nearest point smoothed across the mesh's creases over smoothing_m (AddCouplingForces).
struct CouplingSpring {
  std::array<Triangle, kMaxCouplingCandidates> candidates{};  ///< particles of each candidate
  std::array<Vec3, kMaxCouplingCandidates> free{};  ///< per corner: 1 if free, 0 if pinned
  int32_t num_candidates = 0;
  Vec3 goal_m = Vec3::Zero();      ///< sphere centre (the user's hand), world, m
  double radius_m = 0.0;           ///< sphere radius, m
  Vec3 normal = Vec3::UnitZ();     ///< unit, from the cloth toward the proxy's side
  double stiffness_N_per_m = 0.0;  ///< k_eff (after the stability bound)
  double max_force_N = 0.0;        ///< force clamp, N
  double smoothing_m = 0.0;        ///< crease smoothing epsilon, m (0: the exact nearest point)
  Vec3 goal_start_m = Vec3::Zero();         ///< goal_m at the frame's start, m
  Vec3 goal_velocity_m_per_s = Vec3::Zero();  ///< the goal's predicted velocity, m/s
};

/// The frame's contact springs: storage of kMaxCouplingSprings, count in use.
struct CouplingSprings {
  std::array<CouplingSpring, kMaxCouplingSprings> springs;
  int32_t count = 0;
  bool reduced_this_frame = false;  ///< some spring's k was lowered to k_eff this frame
};

/// A frame with a contact spring stiffer than its substep allows is cut into up to this many times
/// the nominal substeps (CouplingSubsteps); beyond that, k is lowered to the bound.
inline constexpr int32_t kMaxCouplingSubstepFactor = 4;

/// The largest coupling stiffness [N/m] the model's integrator integrates stably at substep h_s
/// [s] for a spring
/// whose largest weight on a free particle is `max_weight`: omega_c^2 = k w^2 / m <= (0.8
/// omega_stable(h))^2, with omega_stable(h) = omega_max * stable_dt_s / h (the integrator's
/// critical omega h, damping included); for implicit Euler (stable_dt_s infinite: its springs are
/// implicit) k w^2 / m <= (0.8 * 2 / h)^2, symplectic Euler's limit for the explicit contact
/// spring. +infinity for max_weight <= 0. Real-time safe.
double MaxCouplingStiffness(const ClothModel& model, double max_weight, double h_s);

/// MaxCouplingStiffness at the nominal substep h = 1 / (frame_rate_hz * substeps).
double MaxCouplingStiffness(const ClothModel& model, double max_weight);

/// Substeps for a frame of dt_s [s] normally cut into `substeps`: raised, to at most
/// kMaxCouplingSubstepFactor times `substeps`, until every valid contact spring of `external` has
/// k <= MaxCouplingStiffness at h = dt_s / result, so the hand's stiffness reaches the cloth
/// unreduced (Colgate, Stanley & Brown 1995: the coupling must be stable at the simulation's
/// step). Real-time safe.
int32_t CouplingSubsteps(const ClothModel& model, std::span<const ExternalForce> external,
                         double dt_s, int32_t substeps);

/// Forgets the previous frame's springs. Real-time safe.
void BeginCouplingFrame(CouplingSprings* springs);

/// Adds `e` (stiffness_N_per_m > 0, triangle in range) as a contact spring for substeps of h_s
/// [s], with its crease smoothing set from its penetration at state->x (the frame's start):
/// kCouplingSmoothingFraction * penetration clamped to [kMinCouplingSmoothing_m,
/// kMaxCouplingSmoothing_m], constant over the frame. Weights of pinned particles are zeroed, k is
/// bounded by MaxCouplingStiffness (state->counters. coupling_reduced_frames counts each frame
/// once), entries with non-finite or invalid fields are counted in invalid_external_forces, and
/// entries past kMaxCouplingSprings in coupling_overflows. Real-time safe.
void AddCouplingSpring(const ClothModel& model, const ExternalForce& e, double h_s,
                       ClothState* state);

/// AddCouplingSpring on explicit parts: positions `x` [m, world, n entries; only the candidates'
/// corners are read], the springs to add to and the counters to count in (the local patch of the
/// haptic loop, sim_loop/cloth_patch.h, keeps its own). Real-time safe.
void AddCouplingSpring(const ClothModel& model, const ExternalForce& e, double h_s,
                       std::span<const Vec3> x, CouplingSprings* springs, ClothCounters* counters);

/// Moves every spring's goal to where its predicted hand is `t_s` [s] after the frame's start:
/// goal = goal_start + t_s goal_velocity (ExternalForce::anchor_velocity_m_per_s). Real-time safe.
void AdvanceCouplingSprings(double t_s, CouplingSprings* springs);

/// Adds scale * the contact springs' forces at positions `x` [m, world, n entries] into `f`
/// (3 n packed doubles, xyz per particle). Per spring and candidate triangle i: its nearest point
/// c_i to the goal g (barycentrics b_i), d_i = |g - c_i|, sd_i = d_i signed by the side of
/// `normal`, n_i the unit direction from c_i toward the proxy's side (`normal` where g lies on the
/// cloth). The signed distance is their smooth minimum sd = sum w_i sd_i, w_i proportional to
/// exp(-(d_i - min d) / smoothing_m) (the Boltzmann operator, Asadi & Littman 2017) over the
/// local minima of the distance: w_i = 0 for a triangle on the other side of the goal than the
/// nearest one, or whose nearest point lies on an edge or corner it shares with a nearer
/// candidate (or an as near one listed first). With smoothing_m = 0: the first nearest
/// triangle's sd_i. pen = radius - sd. If pen > 0, triangle i gets F_i = -min(max_force_N,
/// k pen) s_i n_i with s_i = w_i (1 - sign_i (sd_i - sd) / smoothing_m) (the chain rule of sd;
/// sum s_i = 1), its corner j free_j b_ij F_i. The smooth minimum keeps the force continuous
/// where the nearest point moves from one face to another across a crease (around a pressed
/// vertex), which the explicit integrators need to keep energy (Hairer, Lubich & Wanner 2006,
/// Geometric Numerical Integration, ch. IX, assumes smooth forces). The force is minus the
/// gradient of CouplingEnergy. Real-time safe.
void AddCouplingForces(const CouplingSprings& springs, std::span<const Vec3> x, double scale,
                       double* f);

/// One addend of the contact springs' force on a particle (AddCouplingForces adds them in order).
struct CouplingTerm {
  int32_t particle = 0;
  Vec3 value = Vec3::Zero();  ///< scale * force share, same units as AddCouplingForces' f
};

/// The most addends one frame's springs produce: 3 corners of every candidate of every spring.
inline constexpr int32_t kMaxCouplingTerms = kMaxCouplingSprings * kMaxCouplingCandidates * 3;

/// AddCouplingForces' addends grouped by grid row (preallocated; see CouplingTermsByRow).
struct CouplingTermRows {
  std::vector<CouplingTerm> unsorted;  ///< [kMaxCouplingTerms] in AddCouplingForces' order
  std::vector<CouplingTerm> sorted;    ///< [kMaxCouplingTerms] by row, that order within a row
  std::vector<int32_t> row_start;      ///< [rows + 1] row r's addends: sorted[row_start[r], [r+1])
  std::vector<int32_t> cursor;         ///< [rows] work space of the sort
};

/// The addends AddCouplingForces would add to f (scale * the springs' forces at `x`), sorted by
/// the grid row (particle / width) of their particle, stably, so that adding each row's in order
/// gives AddCouplingForces' bits. `out` must be sized for the grid's rows. Returns their count.
/// Real-time safe.
int32_t CouplingTermsByRow(const CouplingSprings& springs, std::span<const Vec3> x, double scale,
                           int32_t width, CouplingTermRows* out);

/// The springs' potential energy at `x` [J], pen as in AddCouplingForces: per spring 1/2 k pen^2
/// while k pen <= max_force_N, then max_force_N (pen - max_force_N / (2 k)) (the clamp's linear
/// continuation), 0 for pen <= 0.
/// Its gradient with respect to the free particles' positions is minus AddCouplingForces' forces
/// (with scale 1). For tests and energy bookkeeping. Real-time safe.
double CouplingEnergy(const CouplingSprings& springs, std::span<const Vec3> x);

/// The proxy's sphere as the sim sees it (the sphere guard, issue 22): with c the point of the
/// spring's candidates nearest the goal (the first of equal ones, as AddCouplingForces without
/// smoothing) and n the unit direction from c toward the proxy's side, centred at
/// c + max(signed distance, radius) n (resting on the cloth while the spring presses; the goal
/// itself while the hand is off it), with the grid particle nearest the contact (the nearest
/// candidate's corner of largest weight at c).
struct CouplingSphere {
  Vec3 centre_m = Vec3::Zero();  ///< world, m
  double radius_m = 0.0;         ///< m
  int32_t contact_col = 0;       ///< grid column of the contact particle
  int32_t contact_row = 0;       ///< grid row of the contact particle
  Vec3 up = Vec3::UnitY();       ///< unit, from the contact toward the proxy's free side
  int32_t excluded_cells = 0;    ///< GuardExcludedCells of the radius
  bool valid = false;            ///< false without candidates or with a zero radius
};

/// CouplingSphere of spring `s` at positions `x` [m, world]. Real-time safe.
CouplingSphere CouplingSphereAt(const ClothModel& model, const CouplingSpring& s,
                                std::span<const Vec3> x);

/// Grid cells around a sphere's contact particle that the guard leaves to the contact spring
/// (the layer the proxy rests on): those within this Chebyshev distance, 1 + ceil(pi radius /
/// spacing). Cloth that reaches the sphere's far side from the contact went around it, over at
/// least half its circumference (pi radius of cloth); nearer cloth is the contact's own layer,
/// dented around the sphere, and is the spring's (docs/proxy.md, "Layered cloth").
int32_t GuardExcludedCells(const ClothModel& model, double radius_m);

/// The sphere guard on one grid cell (cell = row (width - 1) + col; its two triangles, in
/// MakeGridTriangles' order) unless it lies within sphere.excluded_cells of the contact particle:
/// each triangle whose nearest point q to the centre lies inside the sphere, on its free side
/// ((q - centre) . up > 0: above its equator), is moved out to its surface along u, the direction
/// from the centre to the triangle's nearest point at `x_start` (the side it came from; q - centre
/// when that is undefined), its corners by the weights of a point on a triangle against an
/// immovable body (x_i += b_i dx / sum_j b_j^2 over the movable corners: Bridson, Fedkiw & Anderson
/// 2002 §7.1's weighting, so that q moves by dx), and q's velocity toward the centre along u
/// removed the same way (inelastic). movable(p): whether particle p may move; moved(p) is called
/// for every particle moved. Returns the triangles pushed. Real-time safe.
template <typename Movable, typename Moved>
int32_t GuardSphereCell(const ClothModel& model, const CouplingSphere& sphere, int32_t cell,
                        std::span<const Vec3> x_start, std::span<Vec3> x, std::span<Vec3> v,
                        Movable&& movable, Moved&& moved) {
  const int32_t cells_per_row = model.width - 1;
  const int32_t row = cell / cells_per_row, col = cell % cells_per_row;
  // The cell's distance from the contact particle: its nearer corner's.
  const int32_t dc = std::max({0, sphere.contact_col - col - 1, col - sphere.contact_col});
  const int32_t dr = std::max({0, sphere.contact_row - row - 1, row - sphere.contact_row});
  if (std::max(dc, dr) <= sphere.excluded_cells) return 0;
  int32_t pushed = 0;
  for (int32_t k = 0; k < 2; ++k) {
    const Triangle& t = model.triangles[2 * cell + k];
    const TrianglePoint tp = ClosestPointOnTriangle(sphere.centre_m, x[t[0]], x[t[1]], x[t[2]]);
    const double r = sphere.radius_m;
    if (!(tp.distance_sq < r * r) || !(tp.distance_sq > 1e-24)) continue;  // outside, or undecided
    // Only on the free side: below the sphere's equator lies what the proxy presses on (a second
    // layer under the first, felt through it), which the proxy renders and the guard leaves alone.
    if (!((tp.point - sphere.centre_m).dot(sphere.up) > 0.0)) continue;
    // Out on the side it came from: along the direction from the centre to the triangle's
    // nearest point at the start (else its nearest point now), so that cloth reaching the sphere
    // from beside it is not pushed over it.
    const Vec3 rel = tp.point - sphere.centre_m;
    const TrianglePoint start =
        ClosestPointOnTriangle(sphere.centre_m, x_start[t[0]], x_start[t[1]], x_start[t[2]]);
    const Vec3 u = start.distance_sq > 1e-24
                       ? Vec3((start.point - sphere.centre_m) / std::sqrt(start.distance_sq))
                       : Vec3(rel / std::sqrt(tp.distance_sq));
    // The move along u that puts q on the sphere: |rel + delta u| = r, delta > 0.
    const double a = rel.dot(u);
    const double delta = std::sqrt(a * a + (r * r - tp.distance_sq)) - a;
    double sum = 0.0;
    std::array<double, 3> w{};
    for (int j = 0; j < 3; ++j) {
      w[j] = movable(t[j]) ? tp.barycentric[j] : 0.0;
      sum += w[j] * tp.barycentric[j];
    }
    if (!(sum > 0.0)) continue;
    const Vec3 dx = (delta / sum) * u;
    const double vn =
        (tp.barycentric[0] * v[t[0]] + tp.barycentric[1] * v[t[1]] + tp.barycentric[2] * v[t[2]])
            .dot(u);
    const Vec3 dv = vn < 0.0 ? Vec3((-vn / sum) * u) : Vec3(Vec3::Zero());
    for (int j = 0; j < 3; ++j) {
      if (w[j] == 0.0) continue;
      x[t[j]] += w[j] * dx;
      v[t[j]] += w[j] * dv;
      moved(t[j]);
    }
    ++pushed;
  }
  return pushed;
}

/// What the sphere guards did in one call.
struct SphereGuardResult {
  int32_t triangles = 0;      ///< triangles pushed out of a sphere
  int32_t dropped_cells = 0;  ///< cells past kMaxGuardCells, not tested
};

/// The sphere guard of every contact spring of the frame (state->scratch->coupling) on the sim's
/// cloth at its positions, every cell with a corner within reach of a sphere (GuardCellsNear)
/// tested (GuardSphereCell, pinned particles immovable, moved ones' Verlet history synced for
/// substep h_s [s]). StepFrame calls it after the obstacles in scenes with [self_collision] and
/// self_collision.guard_proxy. Real-time safe.
SphereGuardResult ApplySphereGuards(const ClothModel& model, double h_s, ClothState* state);

/// The first corner (lowest particle index, row * width + col) of grid cell `cell` = row (width -
/// 1) + col on a grid `width` particles wide; the others are +1, +width and +width + 1.
inline int32_t GuardCellCorner(int32_t width, int32_t cell) {
  return cell / (width - 1) * width + cell % (width - 1);
}

/// The most grid cells one sphere's guard gathers in one call (GuardCellsNear); more are dropped.
inline constexpr int32_t kMaxGuardCells = 256;

/// A rectangle of the grid to search: columns col0..col1, rows row0..row1, inclusive (any type
/// with these members serves GuardCellsNear, e.g. PatchWindow).
struct GuardRect {
  int32_t col0 = 0, row0 = 0, col1 = -1, row1 = -1;
};

/// Gathers into `cells` (sorted, no repeats; at most kMaxGuardCells) the grid cells with a corner
/// in one of `rects` within radius + 2 spacings + extra_m [m] of the sphere's centre (position(p):
/// particle p's position [m, world]) and not within excluded_cells of the contact particle (whose
/// cells GuardSphereCell leaves out, so they are not looked at): the cells a triangle inside the
/// sphere can be in while its edges stay under 2 spacings (a cell's diagonal stretched 41 %).
/// Returns the cells gathered; *dropped counts those past the capacity. Real-time safe.
template <typename Rect, typename Position>
int32_t GuardCellsNear(const ClothModel& model, const CouplingSphere& sphere,
                       std::span<const Rect> rects, Position&& position,
                       std::array<int32_t, kMaxGuardCells>* cells, int32_t* dropped,
                       double extra_m = 0.0) {
  const double reach = sphere.radius_m + 2.0 * model.spacing_m + extra_m;
  const double reach2 = reach * reach;
  const int32_t w = model.width, cells_per_row = w - 1;
  const int32_t cc = sphere.contact_col, rc = sphere.contact_row, k = sphere.excluded_cells;
  int32_t count = 0;
  const auto near = [&](int32_t col, int32_t row) {
    if (!((position(row * w + col) - sphere.centre_m).squaredNorm() <= reach2)) return;
    for (int32_t r = std::max(0, row - 1); r <= std::min(row, model.height - 2); ++r) {
      for (int32_t c = std::max(0, col - 1); c <= std::min(col, cells_per_row - 1); ++c) {
        const int32_t cell = r * cells_per_row + c;
        // Sorted insertion without repeats (a few dozen cells near a sphere).
        int32_t i = count;
        while (i > 0 && (*cells)[i - 1] > cell) --i;
        if (i > 0 && (*cells)[i - 1] == cell) continue;
        if (count == kMaxGuardCells) {
          ++*dropped;
          continue;
        }
        for (int32_t j = count; j > i; --j) (*cells)[j] = (*cells)[j - 1];
        (*cells)[i] = cell;
        ++count;
      }
    }
  };
  for (const Rect& rect : rects) {
    for (int32_t row = rect.row0; row <= rect.row1; ++row) {
      if (std::abs(row - rc) > k) {
        for (int32_t col = rect.col0; col <= rect.col1; ++col) near(col, row);
        continue;
      }
      // This row's columns within k of the contact are left out: every cell of such a particle
      // has a corner within k.
      for (int32_t col = rect.col0; col <= std::min(rect.col1, cc - k - 1); ++col) near(col, row);
      for (int32_t col = std::max(rect.col0, cc + k + 1); col <= rect.col1; ++col) near(col, row);
    }
  }
  return count;
}

}  // namespace felt
