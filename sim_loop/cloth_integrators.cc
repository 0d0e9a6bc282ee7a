// The time integrators behind IntegrateSubstep (001_0f9f1b7fedff7723.txt §3, §6.2), one switch

#include "base/check.h"
// per substep and tight loops over flat arrays inside each. Pinned particles have zero
// acceleration, so every scheme moves them with the velocity ApplyPins gave them.

#include <Eigen/SparseCore>
#include <algorithm>
#include <array>
#include <cmath>
#include <utility>
#include <vector>

#include "base/simd.h"
#include "sim_loop/cloth.h"
#include "sim_loop/cloth_internal.h"

namespace felt {
namespace {

void Accel(const ClothModel& model, std::span<const Vec3> x, std::span<const Vec3> v,
           ClothState::Scratch* s, std::vector<Vec3>* a) {
  ComputeAccelerations(model, x, v, s, *a);
}

// Explicit Euler: x += h v, v += h a(x, v) (001 eq. 2).
void ExplicitEuler(const ClothModel& model, double h, ClothState* st) {
  ClothState::Scratch& s = *st->scratch;
  Accel(model, st->x, st->v, &s, &s.accel);
  const size_t n = st->x.size();
  for (size_t p = 0; p < n; ++p) {
    st->x[p] += h * st->v[p];
    st->v[p] += h * s.accel[p];
  }
}

// Symplectic (semi-implicit) Euler: v += h a(x, v), then x += h v_new.
void SymplecticEuler(const ClothModel& model, double h, ClothState* st) {
  ClothState::Scratch& s = *st->scratch;
  Accel(model, st->x, st->v, &s, &s.accel);
  const size_t n = st->x.size();
  for (size_t p = 0; p < n; ++p) {
    st->v[p] += h * s.accel[p];
    st->x[p] += h * st->v[p];
  }
}

// Explicit midpoint (second-order Runge-Kutta, 001 §3.2): slopes at the half step.
void ExplicitMidpoint(const ClothModel& model, double h, ClothState* st) {
  ClothState::Scratch& s = *st->scratch;
  const size_t n = st->x.size();
  Accel(model, st->x, st->v, &s, &s.accel);
  for (size_t p = 0; p < n; ++p) {
    s.x_stage[p] = st->x[p] + 0.5 * h * st->v[p];
    s.v_stage[p] = st->v[p] + 0.5 * h * s.accel[p];
  }
  Accel(model, s.x_stage, s.v_stage, &s, &s.accel);
  for (size_t p = 0; p < n; ++p) {
    st->x[p] += h * s.v_stage[p];
    st->v[p] += h * s.accel[p];
  }
}

// Classical fourth-order Runge-Kutta (001 §3.2) on (x, v).
void Rk4(const ClothModel& model, double h, ClothState* st) {
  ClothState::Scratch& s = *st->scratch;
  const size_t n = st->x.size();
  // k1 at the start.
  Accel(model, st->x, st->v, &s, &s.accel);
  for (size_t p = 0; p < n; ++p) {
    s.kx_sum[p] = st->v[p];
    s.kv_sum[p] = s.accel[p];
    s.x_stage[p] = st->x[p] + 0.5 * h * st->v[p];
    s.v_stage[p] = st->v[p] + 0.5 * h * s.accel[p];
  }
  // k2 and k3 at the half step, each from the previous slope.
  for (int stage = 0; stage < 2; ++stage) {
    Accel(model, s.x_stage, s.v_stage, &s, &s.accel);
    const double c = stage == 0 ? 0.5 * h : h;
    for (size_t p = 0; p < n; ++p) {
      const Vec3 kx = s.v_stage[p];
      s.kx_sum[p] += 2.0 * kx;
      s.kv_sum[p] += 2.0 * s.accel[p];
      s.x_stage[p] = st->x[p] + c * kx;
      s.v_stage[p] = st->v[p] + c * s.accel[p];
    }
  }
  // k4 at the end, then the weighted sum (1, 2, 2, 1) / 6.
  Accel(model, s.x_stage, s.v_stage, &s, &s.accel);
  for (size_t p = 0; p < n; ++p) {
    st->x[p] += (h / 6.0) * (s.kx_sum[p] + s.v_stage[p]);
    st->v[p] += (h / 6.0) * (s.kv_sum[p] + s.accel[p]);
  }
}

// Velocity Verlet: x += h v + h^2 a / 2, v += h (a + a_next) / 2, with a_next taken at the
// predicted velocity v + h a (the damping force depends on v). Two force evaluations per step:
// a cached a_next would be stale after Provot and the obstacles move the particles.
void VelocityVerlet(const ClothModel& model, double h, ClothState* st) {
  ClothState::Scratch& s = *st->scratch;
  const size_t n = st->x.size();
  Accel(model, st->x, st->v, &s, &s.accel);
  for (size_t p = 0; p < n; ++p) {
    st->x[p] += h * st->v[p] + (0.5 * h * h) * s.accel[p];
    s.v_stage[p] = st->v[p] + h * s.accel[p];
  }
  Accel(model, st->x, s.v_stage, &s, &s.kv_sum);
  for (size_t p = 0; p < n; ++p) st->v[p] += (0.5 * h) * (s.accel[p] + s.kv_sum[p]);
}

// The update runs a row at a time as StreamAccelerations finishes each row's accelerations (one
// pass over the particles; the same bits as computing them all first). a_last takes the row's
// accelerations as it is read.
struct LeapfrogRows {
  ClothState* st;
  int32_t width;
  double h, h_old, kick, back;
  bool start;  // no history: v_{-1/2} = v_0 - h/2 a_0
};

// The fixed-step leapfrog update of `count` coordinates (LeapfrogUpdateRow's common case); a_last
// takes the accelerations.
__attribute__((always_inline)) inline void LeapfrogFlatBody(double* __restrict x,
                                                            double* __restrict v,
                                                            double* __restrict a_last,
                                                            const double* __restrict accel,
                                                            size_t count, double h) {
  const double half_h = 0.5 * h;
  for (size_t k = 0; k < count; ++k) {
    const double v_half = v[k] + h * (accel[k] - 0.5 * a_last[k]);
    x[k] += h * v_half;
    v[k] = v_half + half_h * accel[k];
    a_last[k] = accel[k];
  }
}

// LeapfrogFlatBody for the portable level.
void LeapfrogFlat(double* x, double* v, double* a_last, const double* accel, size_t count,
                  double h) {
  LeapfrogFlatBody(x, v, a_last, accel, count, h);
}

#if defined(__x86_64__)
// LeapfrogFlatBody compiled for AVX2, no fused multiply-add: the same bits. Four-wide loads also
// match the four-wide stores FinishRowAvx2 left the accelerations with; with two-wide ones the
// loads could not be forwarded from those stores (this pass took 20 % of a 128 x 128 frame).
__attribute__((target("avx2"))) void LeapfrogFlatAvx2(double* x, double* v, double* a_last,
                                                      const double* accel, size_t count, double h) {
  LeapfrogFlatBody(x, v, a_last, accel, count, h);
}
constexpr SimdTable<void (*)(double*, double*, double*, const double*, size_t, double)>
    kLeapfrogFlat{LeapfrogFlat, LeapfrogFlatAvx2, LeapfrogFlatAvx2};
#else
constexpr SimdTable<void (*)(double*, double*, double*, const double*, size_t, double)>
    kLeapfrogFlat{LeapfrogFlat, LeapfrogFlat, LeapfrogFlat};
#endif

// LeapfrogVerlet's update of grid row `row`, accelerations accel (xyz per particle of the row).
void LeapfrogUpdateRow(void* context, int32_t row, const double* __restrict accel) {
  const LeapfrogRows& c = *static_cast<const LeapfrogRows*>(context);
  ClothState& st = *c.st;
  ClothState::Scratch& s = *st.scratch;
  const size_t w = static_cast<size_t>(c.width);
  const size_t lo = static_cast<size_t>(row) * w;
  const double h = c.h, half_h = 0.5 * h;
  double* __restrict x = st.x[lo].data();
  double* __restrict v = st.v[lo].data();
  double* __restrict a_last = s.a_last[lo].data();
  uint8_t* restart = s.restart.data() + lo;
  const bool any_restart = std::find(restart, restart + w, uint8_t{1}) != restart + w;
  if (!any_restart && !c.start && c.h_old == h) {
    // The common substep, coordinate by coordinate (vectorises): the fixed-step update below.
    PickSimd(kLeapfrogFlat)(x, v, a_last, accel, 3 * w, h);
    return;
  }
  for (size_t p = 0; p < w; ++p) {
    for (size_t k = 3 * p; k < 3 * p + 3; ++k) {
      const double a = accel[k];
      const double al = c.start ? a : a_last[k];
      double v_half;
      if (restart[p]) {
        v_half = v[k] + half_h * a;
      } else if (c.h_old == h) {
        v_half = v[k] + h * (a - 0.5 * al);
      } else {
        v_half = v[k] + (c.kick * a - c.back * al);
      }
      x[k] += h * v_half;
      v[k] = v_half + half_h * a;
      a_last[k] = a;
    }
    restart[p] = 0;
  }
}

// Leapfrog Verlet (001 §3.5), kick-drift-kick with variable steps: the half-step velocity
// v_{n+1/2} = v_{n-1/2} + (h_old + h)/2 a_n drives x_{n+1} = x_n + h v_{n+1/2}, h_old being the
// previous substep's length (scratch.history_h_s; StepFrame cuts a late frame, or one with a stiff
// contact spring, into a different number of substeps). The state keeps the synchronised velocity
// v_{n+1} = v_{n+1/2} + h/2 a_n (second order), which the damping force and the snapshots use;
// v_{n-1/2} is recovered as v_n - h_old/2 a_{n-1}, so additive corrections to v (Provot's
// v += dx / h) carry over. Recovering it with the new h instead left a velocity error
// (h - h_old)/2 a_{n-1} at every change of length: first order when the length keeps changing
// (LeapfrogStaysSecondOrderWhenTheSubstepChanges). With h_old == h the update is the fixed-step
// v_n + h (a_n - a_{n-1}/2), bit for bit as before.
// A velocity an obstacle replaced is the particle's synchronised velocity after the contact: the
// particle restarts from it, v_{n+1/2} = v_n + h/2 a_n (scratch.restart), as every particle does
// at the start. Recovering v_{n-1/2} from it instead would hand back the half kick h/2 a_{n-1} the
// contact had removed: a particle pressed into a table by a frame's held push (a = -4401 m/s^2)
// and stopped there was thrown up at h/2 a = 36.7 m/s (TableSlideTest).
// One pass over the particles: each row is updated (LeapfrogUpdateRow) as soon as
// StreamAccelerations has its accelerations, with the bits of computing them all first.
void LeapfrogVerlet(const ClothModel& model, double h, ClothState* st) {
  ClothState::Scratch& s = *st->scratch;
  const double h_old = s.history_valid ? s.history_h_s : h;
  LeapfrogRows rows{st,
                    model.width,
                    h,
                    h_old,
                    0.5 * (h_old + h),  // kick: from t_n - h_old/2 to t_n + h/2
                    0.5 * h_old,        // back: from v_n back to v_{n-1/2}
                    !s.history_valid};
  StreamAccelerations(model, st->x, st->v, &s, {&rows, LeapfrogUpdateRow});
}

// Basic (position) Verlet, 001 eq. 5: x_{n+1} = 2 x_n - x_{n-1} + h^2 a_n. The velocity it
// reports (and damps with) is v_{n+1} = (x_{n+1} - x_n) / h + h/2 a_n, second order.
void BasicVerlet(const ClothModel& model, double h, ClothState* st) {
  ClothState::Scratch& s = *st->scratch;
  const size_t n = st->x.size();
  Accel(model, st->x, st->v, &s, &s.accel);
  if (!s.history_valid) {
    // Start from the Taylor expansion x_{-1} = x_0 - h v_0 + h^2/2 a_0 (local error O(h^3)).
    for (size_t p = 0; p < n; ++p) {
      s.x_prev[p] = st->x[p] - h * st->v[p] + (0.5 * h * h) * s.accel[p];
    }
  } else if (s.history_h_s != h) {
    // The substep length changed: re-space x_{n-1} to the new h from the half-step velocity.
    const double h_old = s.history_h_s;
    for (size_t p = 0; p < n; ++p) {
      const Vec3 v_half = (st->x[p] - s.x_prev[p]) / h_old + (0.5 * (h_old - h)) * s.a_last[p];
      s.x_prev[p] = st->x[p] - h * v_half;
    }
  }
  for (size_t p = 0; p < n; ++p) {
    const Vec3 x_next = 2.0 * st->x[p] - s.x_prev[p] + (h * h) * s.accel[p];
    s.x_prev[p] = st->x[p];
    st->v[p] = (x_next - st->x[p]) / h + (0.5 * h) * s.accel[p];
    st->x[p] = x_next;
  }
  std::swap(s.accel, s.a_last);
}

// Sparse matrix-vector product y = A x on the row-major pattern.
void MultiplyA(const Eigen::SparseMatrix<double, Eigen::RowMajor>& A, const Eigen::VectorXd& x,
               Eigen::VectorXd* y) {
  const int* outer = A.outerIndexPtr();
  const int* inner = A.innerIndexPtr();
  const double* value = A.valuePtr();
  for (Eigen::Index row = 0; row < A.rows(); ++row) {
    double sum = 0.0;
    for (int k = outer[row]; k < outer[row + 1]; ++k) sum += value[k] * x[inner[k]];
    (*y)[row] = sum;
  }
}

// Adds `block` to the 3x3 block whose three rows start at value offsets `offset`.
void AddBlock(double* value, const std::array<int32_t, 3>& offset, const Eigen::Matrix3d& block) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) value[offset[r] + c] += block(r, c);
  }
}

// Implicit (backward) Euler linearised once per step, Baraff & Witkin 1998 eq. 16:
// (M - h df/dv - h^2 df/dx) dv = h (f + h df/dx v); v += dv; x += h v.
// Spring Jacobian df_i/dx_j = k (u u^T + (1 - L/l) (I - u u^T)) with (1 - L/l) clamped at 0 for
// compressed springs so the matrix stays positive definite (the usual buckling fix); dashpot
// df_i/dv_j = c u u^T. Pinned rows and columns are filtered out (B&W §5.3: dv = 0 there).
// Solved by Jacobi-preconditioned conjugate gradients on preallocated vectors.
bool ImplicitEuler(const ClothModel& model, double h, ClothState* st) {
  ClothState::Scratch& s = *st->scratch;
  const int32_t n = model.num_particles();
  const double m = model.particle_mass_kg;
  const double drag = model.drag_N_s_per_m;
  const Vec3 g = model.gravity_m_per_s2;
  const double* inv_mass = model.inv_mass_per_kg.data();
  double* value = s.A.valuePtr();
  std::fill(value, value + s.A.nonZeros(), 0.0);

  // Diagonal: M + h c_drag I for free particles, I for pinned; b = h (f_ext + m g - c_drag v).
  for (int32_t p = 0; p < n; ++p) {
    const bool free = inv_mass[p] > 0.0;
    const double d = free ? m + h * drag : 1.0;
    for (int r = 0; r < 3; ++r) value[s.diag_offset[p][r] + r] = d;
    const Vec3 f = free ? Vec3(s.external_N[p] + m * g - drag * st->v[p]) : Vec3(Vec3::Zero());
    s.b.segment<3>(3 * p) = h * f;
  }
  // Haptic contact springs, explicit (bounded by MaxCouplingStiffness; no pinned share).
  AddCouplingForces(s.coupling, st->x, h, s.b.data());
  // Springs: forces into b, Jacobian blocks into A, h^2 df/dx v into b.
  const Eigen::Matrix3d eye = Eigen::Matrix3d::Identity();
  for (size_t k = 0; k < model.springs.size(); ++k) {
    const Spring& sp = model.springs[k];
    const Vec3 d = st->x[sp.j] - st->x[sp.i];
    const double len = d.norm();
    if (!(len > kMinSpringLength_m)) continue;
    const Vec3 u = d / len;
    const Vec3 dvel = st->v[sp.j] - st->v[sp.i];
    const Vec3 force =
        (sp.stiffness_N_per_m * (len - sp.rest_length_m) + sp.damping_N_s_per_m * dvel.dot(u)) * u;
    const Eigen::Matrix3d uu = u * u.transpose();
    const double transverse = std::max(0.0, 1.0 - sp.rest_length_m / len);
    const Eigen::Matrix3d J = sp.stiffness_N_per_m * (uu + transverse * (eye - uu));
    const Eigen::Matrix3d B = (h * sp.damping_N_s_per_m) * uu + (h * h) * J;
    const Vec3 kv = h * h * (J * dvel);  // h^2 (df_i/dx v)
    const bool free_i = inv_mass[sp.i] > 0.0, free_j = inv_mass[sp.j] > 0.0;
    if (free_i) {
      s.b.segment<3>(3 * sp.i) += h * force + kv;
      AddBlock(value, s.diag_offset[sp.i], B);
    }
    if (free_j) {
      s.b.segment<3>(3 * sp.j) -= h * force + kv;
      AddBlock(value, s.diag_offset[sp.j], B);
    }
    if (free_i && free_j) {
      AddBlock(value, s.ij_offset[k], -B);
      AddBlock(value, s.ji_offset[k], -B);
    }
  }

  // Preconditioned conjugate gradients from dv = 0 (Baraff & Witkin 1998 §5.3).
  for (Eigen::Index row = 0; row < s.A.rows(); ++row) {
    s.inv_diag[row] = 1.0 / value[s.diag_offset[row / 3][row % 3] + row % 3];
  }
  s.dv.setZero();
  s.r = s.b;
  const double b_norm2 = s.b.squaredNorm();
  const double threshold = model.cg_tolerance * model.cg_tolerance * b_norm2;
  bool converged = true;
  if (b_norm2 > 0.0) {
    s.z = s.inv_diag.cwiseProduct(s.r);
    s.p = s.z;
    double rz = s.r.dot(s.z);
    converged = false;
    for (int32_t it = 0; it < model.cg_max_iterations; ++it) {
      MultiplyA(s.A, s.p, &s.Ap);
      const double alpha = rz / s.p.dot(s.Ap);
      s.dv += alpha * s.p;
      s.r -= alpha * s.Ap;
      if (s.r.squaredNorm() <= threshold) {
        converged = true;
        break;
      }
      s.z = s.inv_diag.cwiseProduct(s.r);
      const double rz_new = s.r.dot(s.z);
      s.p = s.z + (rz_new / rz) * s.p;
      rz = rz_new;
    }
  }
  // v += dv for free particles, then x += h v_new.
  for (int32_t p = 0; p < n; ++p) {
    if (inv_mass[p] > 0.0) st->v[p] += s.dv.segment<3>(3 * p);
    st->x[p] += h * st->v[p];
  }
  return converged;
}

// Value index of the entry (row, col) of a compressed row-major matrix; the entry must exist.
int32_t ValueIndex(const Eigen::SparseMatrix<double, Eigen::RowMajor>& A, int32_t row,
                   int32_t col) {
  const int* begin = A.innerIndexPtr() + A.outerIndexPtr()[row];
  const int* end = A.innerIndexPtr() + A.outerIndexPtr()[row + 1];
  const int* it = std::lower_bound(begin, end, col);
  FELT_CHECK(it != end && *it == col);
  // Three consecutive columns of one block sit next to each other in a row.
  FELT_CHECK(it + 2 < end && it[2] == col + 2);
  return static_cast<int32_t>(it - A.innerIndexPtr());
}

}  // namespace

void BuildImplicitPattern(const ClothModel& model, ClothState::Scratch* s) {
  const int32_t n = model.num_particles();
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(9 * (static_cast<size_t>(n) + 2 * model.springs.size()));
  const auto add_block = [&](int32_t bi, int32_t bj) {
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) triplets.emplace_back(3 * bi + r, 3 * bj + c, 0.0);
    }
  };
  for (int32_t p = 0; p < n; ++p) add_block(p, p);
  for (const Spring& sp : model.springs) {
    add_block(sp.i, sp.j);
    add_block(sp.j, sp.i);
  }
  s->A.resize(3 * n, 3 * n);
  s->A.setFromTriplets(triplets.begin(), triplets.end());
  s->A.makeCompressed();
  s->diag_offset.resize(static_cast<size_t>(n));
  for (int32_t p = 0; p < n; ++p) {
    for (int r = 0; r < 3; ++r) s->diag_offset[p][r] = ValueIndex(s->A, 3 * p + r, 3 * p);
  }
  s->ij_offset.resize(model.springs.size());
  s->ji_offset.resize(model.springs.size());
  for (size_t k = 0; k < model.springs.size(); ++k) {
    const Spring& sp = model.springs[k];
    for (int r = 0; r < 3; ++r) {
      s->ij_offset[k][r] = ValueIndex(s->A, 3 * sp.i + r, 3 * sp.j);
      s->ji_offset[k][r] = ValueIndex(s->A, 3 * sp.j + r, 3 * sp.i);
    }
  }
  for (Eigen::VectorXd* v : {&s->b, &s->dv, &s->r, &s->z, &s->p, &s->Ap, &s->inv_diag}) {
    v->setZero(3 * n);
  }
}

namespace {

// One substep of each integrator, indexed by IntegratorKind (the enum's order); false when an
// implicit solve hit its iteration cap.
using SubstepFn = bool (*)(const ClothModel&, double, ClothState*);
template <void (*Step)(const ClothModel&, double, ClothState*)>
bool Explicit(const ClothModel& model, double h, ClothState* st) {
  Step(model, h, st);
  return true;
}
constexpr std::array<SubstepFn, 8> kSubstepOf = {Explicit<LeapfrogVerlet>,
                                                 Explicit<ExplicitEuler>,
                                                 Explicit<SymplecticEuler>,
                                                 Explicit<ExplicitMidpoint>,
                                                 Explicit<Rk4>,
                                                 Explicit<BasicVerlet>,
                                                 Explicit<VelocityVerlet>,
                                                 ImplicitEuler};
static_assert(static_cast<size_t>(IntegratorKind::kLeapfrogVerlet) == 0 &&
                  static_cast<size_t>(IntegratorKind::kImplicitEuler) == 7,
              "kSubstepOf follows IntegratorKind's order");

}  // namespace

bool IntegrateSubstep(const ClothModel& model, double h_s, ClothState* state) {
  const auto kind = static_cast<size_t>(model.integrator);
  FELT_CHECK(kind < kSubstepOf.size());
  const bool converged = kSubstepOf[kind](model, h_s, state);
  state->scratch->history_valid = true;
  state->scratch->history_h_s = h_s;
  return converged;
}

void SyncVerletHistory(const ClothModel& model, int32_t p, double h_s, ClothState* state) {
  ClothState::Scratch& s = *state->scratch;
  if (model.integrator == IntegratorKind::kLeapfrogVerlet) s.restart[p] = 1;
  if (model.integrator != IntegratorKind::kBasicVerlet) return;
  // Invert v = (x - x_prev) / h + h/2 a_last for x_prev.
  s.x_prev[p] = state->x[p] - h_s * (state->v[p] - (0.5 * h_s) * s.a_last[p]);
}

}  // namespace felt
