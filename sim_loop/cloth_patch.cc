#include "sim_loop/cloth_patch.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "sim_loop/cloth_coupling.h"
#include "sim_loop/cloth_internal.h"

namespace felt {
namespace {

// True if windows a and b overlap or come within two particles of each other (a bend spring joins
// particles two apart), so their particles interact.
bool WindowsMeet(const PatchWindow& a, const PatchWindow& b) {
  return a.col0 <= b.col1 + 2 && b.col0 <= a.col1 + 2 && a.row0 <= b.row1 + 2 &&
         b.row0 <= a.row1 + 2;
}

// The bounding rectangle of a and b.
PatchWindow Bounding(const PatchWindow& a, const PatchWindow& b) {
  return {std::min(a.col0, b.col0), std::min(a.row0, b.row0), std::max(a.col1, b.col1),
          std::max(a.row1, b.row1)};
}

bool SameWindow(const PatchWindow& a, const PatchWindow& b) {
  return a.col0 == b.col0 && a.row0 == b.row0 && a.col1 == b.col1 && a.row1 == b.row1;
}

// One row of a spring family's pairs i = 0..count-1 (i ends at xi.., j ends at xj..), window
// arrays in single precision: the force on each i end into t (f_j = -f_i), Hooke plus the dashpot
// along the spring (001 §2). Branch-free, so the compiler vectorises it; a spring shorter than
// 1e-10 m exerts nothing.
void RowSpringForces(
    int32_t count, const float* __restrict xi, const float* __restrict yi,
    const float* __restrict zi, const float* __restrict xj, const float* __restrict yj,
    const float* __restrict zj, const float* __restrict vxi, const float* __restrict vyi,
    const float* __restrict vzi, const float* __restrict vxj, const float* __restrict vyj,
    const float* __restrict vzj, float stiffness, float damping, float rest,
    float* __restrict tx, float* __restrict ty, float* __restrict tz) {
  for (int32_t c = 0; c < count; ++c) {
    const float dx = xj[c] - xi[c], dy = yj[c] - yi[c], dz = zj[c] - zi[c];
    const float len2 = dx * dx + dy * dy + dz * dz;
    const float len = std::sqrt(len2);
    const float live = len2 > 1e-20f ? 1.0f : 0.0f;
    const float inv = live / std::max(len, 1e-10f);
    const float rel =
        ((vxj[c] - vxi[c]) * dx + (vyj[c] - vyi[c]) * dy + (vzj[c] - vzi[c]) * dz) * inv;
    const float scale = (stiffness * (len - rest) + damping * rel) * inv;
    tx[c] = scale * dx;
    ty[c] = scale * dy;
    tz[c] = scale * dz;
  }
}

// a[c] += sign * t[c] for c < count, per coordinate (a row of pair forces onto their ends).
void AddRow(int32_t count, float sign, const float* __restrict tx, const float* __restrict ty,
            const float* __restrict tz, float* __restrict ax, float* __restrict ay,
            float* __restrict az) {
  for (int32_t c = 0; c < count; ++c) {
    ax[c] += sign * tx[c];
    ay[c] += sign * ty[c];
    az[c] += sign * tz[c];
  }
}

// One row of a Provot family's independent pairs (i ends at xi.., j ends at xj..): each pair
// longer than max_len shortened to it, moving each end by its share of the cut (movability m: 1
// free, 0 driven; shares m_i / (m_i + m_j)). Returns how many pairs with a free end were more
// than `loose_ratio` (squared length over squared limit) over. Branch-free.
int32_t RowProvot(int32_t count, float* __restrict xi, float* __restrict yi, float* __restrict zi,
                  float* __restrict xj, float* __restrict yj, float* __restrict zj,
                  const float* __restrict mi, const float* __restrict mj, float max_len,
                  float inv_max2, float loose_ratio) {
  int32_t loose = 0;
  for (int32_t c = 0; c < count; ++c) {
    const float dx = xj[c] - xi[c], dy = yj[c] - yi[c], dz = zj[c] - zi[c];
    const float len2 = dx * dx + dy * dy + dz * dz;
    const float both = mi[c] + mj[c];
    const float ratio = len2 * inv_max2;
    const bool moves = both > 0.0f;
    const float over = static_cast<float>((ratio > 1.0f) & moves);
    loose += static_cast<int32_t>((ratio > loose_ratio) & moves);
    const float len = std::sqrt(len2);
    const float cut = over * (len - max_len) / (std::max(len, 1e-10f) * std::max(both, 1.0f));
    const float si = cut * mi[c], sj = cut * mj[c];
    xi[c] += si * dx;
    yi[c] += si * dy;
    zi[c] += si * dz;
    xj[c] -= sj * dx;
    yj[c] -= sj * dy;
    zj[c] -= sj * dz;
  }
  return loose;
}

}  // namespace

ClothPatch::ClothPatch(const ClothModel& model, int32_t radius, int32_t max_windows)
    : model_(model),
      radius_(radius),
      recentre_(std::max(2, radius / kPatchRecentreFraction)),
      springs_(std::make_unique<CouplingSprings>()) {
  if (radius < kMinPatchRadius || radius > kMaxPatchRadius) {
    throw std::invalid_argument("proxy.patch_radius: must be in [" +
                                std::to_string(kMinPatchRadius) + ", " +
                                std::to_string(kMaxPatchRadius) + "], got " +
                                std::to_string(radius));
  }
  if (max_windows < 1) {
    throw std::invalid_argument("ClothPatch: max_windows must be >= 1, got " +
                                std::to_string(max_windows));
  }
  // Leapfrog at the cloth's nominal substep (chosen stable for the cloth's integrator); for another
  // integrator, within half of leapfrog's own stable step (the auto substeps' default safety).
  const double h_nominal = 1.0 / (model.frame_rate_hz * model.substeps);
  h_max_s_ = h_nominal;
  if (model.integrator != IntegratorKind::kLeapfrogVerlet) {
    h_max_s_ = std::min(h_nominal, 0.5 * StableStep(model, IntegratorKind::kLeapfrogVerlet));
  }
  const size_t n = static_cast<size_t>(model.num_particles());
  windows_.resize(static_cast<size_t>(max_windows));
  next_windows_.resize(static_cast<size_t>(max_windows));
  anchors_.assign(static_cast<size_t>(max_windows), -1);
  linger_s_.assign(static_cast<size_t>(max_windows), 0.0);
  role_.assign(n, PatchRole::kOutside);
  next_role_.assign(n, PatchRole::kOutside);
  for (std::vector<Vec3>* a : {&x_, &v_, &x_before_, &a_, &a_last_}) a->assign(n, Vec3::Zero());
  // The triangles around each particle (for NormalAt), compressed rows.
  vertex_tri_start_.assign(n + 1, 0);
  for (const Triangle& t : model.triangles) {
    for (int32_t corner : t) ++vertex_tri_start_[static_cast<size_t>(corner) + 1];
  }
  for (size_t p = 0; p < n; ++p) vertex_tri_start_[p + 1] += vertex_tri_start_[p];
  vertex_tris_.resize(static_cast<size_t>(vertex_tri_start_[n]));
  std::vector<int32_t> fill(vertex_tri_start_.begin(), vertex_tri_start_.end() - 1);
  for (size_t t = 0; t < model.triangles.size(); ++t) {
    for (int32_t corner : model.triangles[t]) {
      vertex_tris_[static_cast<size_t>(fill[static_cast<size_t>(corner)]++)] =
          static_cast<int32_t>(t);
    }
  }
  f_.assign(3 * n, 0.0);
  // The structure-of-arrays block: 13 arrays (position, velocity, movability, force, one row of
  // pair forces) of the largest window, the whole cloth (merged windows may grow to it).
  soa_stride_ = (n + 15) / 16 * 16 + 16;
  soa_.assign(13 * soa_stride_, 0.0f);
  restart_.assign(n, 1);
  for (size_t i = 0; i < model.provot_families.size(); ++i) {
    if (model.provot_families[i].level == 1) level1_.push_back(static_cast<int32_t>(i));
  }
}

ClothPatch::~ClothPatch() = default;

template <typename Visit>
void ClothPatch::ForEachParticle(Visit&& visit) const {
  const int32_t w = model_.width;
  for (size_t k = 0; k < window_count_; ++k) {
    const PatchWindow& win = windows_[k];
    for (int32_t r = win.row0; r <= win.row1; ++r) {
      for (int32_t c = win.col0; c <= win.col1; ++c) visit(r * w + c);
    }
  }
}

void ClothPatch::MarkRoles(std::span<const PatchWindow> windows, PatchRole* roles) const {
  const int32_t w = model_.width, h = model_.height;
  for (const PatchWindow& win : windows) {
    for (int32_t r = win.row0; r <= win.row1; ++r) {
      for (int32_t c = win.col0; c <= win.col1; ++c) {
        const int32_t p = r * w + c;
        // The outer two rings are driven, except where the window ends on the cloth's own edge.
        const bool ring = (c - win.col0 < 2 && win.col0 > 0) ||
                          (win.col1 - c < 2 && win.col1 < w - 1) ||
                          (r - win.row0 < 2 && win.row0 > 0) ||
                          (win.row1 - r < 2 && win.row1 < h - 1);
        roles[p] = ring || model_.inv_mass_per_kg[p] == 0.0 ? PatchRole::kDriven : PatchRole::kFree;
      }
    }
  }
}

double ClothPatch::DriftFromDrive(const PatchWindow& window, const ClothSnapshot& drive,
                                  double tau_s) const {
  double max2 = 0.0;
  const int32_t w = model_.width;
  for (int32_t r = window.row0; r <= window.row1; ++r) {
    for (int32_t c = window.col0; c <= window.col1; ++c) {
      const int32_t p = r * w + c;
      if (role_[p] != PatchRole::kFree) continue;
      max2 = std::max(max2, (x_[p] - drive.x[p] - tau_s * drive.v[p]).squaredNorm());
    }
  }
  return std::sqrt(max2);
}

void ClothPatch::Place(std::span<const int32_t> centres, const ClothSnapshot& drive, double tau_s,
                       double dt_s) {
  const int32_t w = model_.width, h = model_.height, n = model_.num_particles();
  const auto window_of = [&](int32_t anchor) {
    const int32_t ac = anchor % w, ar = anchor / w;
    return PatchWindow{std::max(0, ac - radius_), std::max(0, ar - radius_),
                       std::min(w - 1, ac + radius_), std::min(h - 1, ar + radius_)};
  };
  // Each slot's anchor follows its centre with hysteresis; without a centre it lingers until its
  // patch has gone back to the drive (or for at most kPatchMaxLinger_s).
  size_t count = 0;
  for (size_t s = 0; s < anchors_.size(); ++s) {
    const int32_t c = s < centres.size() ? centres[s] : -1;
    const int32_t a = anchors_[s];
    if (c < 0 || c >= n) {
      if (a < 0) continue;
      linger_s_[s] += dt_s;
      if (linger_s_[s] > kPatchMaxLinger_s ||
          DriftFromDrive(window_of(a), drive, tau_s) <= kPatchReleaseDistance_m) {
        anchors_[s] = -1;
        continue;
      }
    } else {
      linger_s_[s] = 0.0;
      const bool keep = a >= 0 && std::abs(a % w - c % w) < recentre_ &&
                        std::abs(a / w - c / w) < recentre_;
      if (!keep) anchors_[s] = c;
    }
    next_windows_[count++] = window_of(anchors_[s]);
  }
  // Merge windows that meet, until none do.
  for (bool merged = true; merged;) {
    merged = false;
    for (size_t i = 0; i < count && !merged; ++i) {
      for (size_t j = i + 1; j < count && !merged; ++j) {
        if (!WindowsMeet(next_windows_[i], next_windows_[j])) continue;
        next_windows_[i] = Bounding(next_windows_[i], next_windows_[j]);
        next_windows_[j] = next_windows_[--count];
        ++counters_.merges;
        merged = true;
      }
    }
  }
  bool same = count == window_count_;
  for (size_t i = 0; same && i < count; ++i) same = SameWindow(next_windows_[i], windows_[i]);
  if (same) return;
  ++counters_.placements;

  // New roles; entering particles start from the drive, particles turning free restart.
  const std::span<const PatchWindow> next(next_windows_.data(), count);
  MarkRoles(next, next_role_.data());
  for (const PatchWindow& win : next) {
    for (int32_t r = win.row0; r <= win.row1; ++r) {
      for (int32_t c = win.col0; c <= win.col1; ++c) {
        const int32_t p = r * w + c;
        if (role_[p] == PatchRole::kOutside) {
          x_[p] = drive.x[p] + tau_s * drive.v[p];
          v_[p] = drive.v[p];
          x_before_[p] = x_[p];
          restart_[p] = 1;
        } else if (next_role_[p] == PatchRole::kFree && role_[p] != PatchRole::kFree) {
          restart_[p] = 1;
        }
      }
    }
  }
  ForEachParticle([&](int32_t p) { role_[p] = PatchRole::kOutside; });
  for (size_t i = 0; i < count; ++i) windows_[i] = next_windows_[i];
  window_count_ = count;
  ForEachParticle([&](int32_t p) {
    role_[p] = next_role_[p];
    next_role_[p] = PatchRole::kOutside;
  });
}

void ClothPatch::SetDriven(const ClothSnapshot& drive, double tau_s, double dt_s) {
  // Each driven particle moves with the drive's velocity and closes the fraction
  // beta = dt / (T + dt) of its distance to the drive (backward Euler of x' = v + (target - x) / T,
  // unconditionally stable), T = kPatchDriveTime_s.
  const double beta = dt_s / (kPatchDriveTime_s + dt_s);
  ForEachParticle([&](int32_t p) {
    if (role_[p] != PatchRole::kDriven) return;
    const Vec3 target = drive.x[p] + tau_s * drive.v[p];
    const Vec3 moved = x_[p] + dt_s * drive.v[p];
    x_[p] = moved + beta * (target - moved);
    v_[p] = drive.v[p];
  });
}

bool ClothPatch::SpringInside(const ExternalForce& e) const {
  // The spring's candidates are the triangles of the 3 x 3 cells around its triangle's cell
  // (cloth_coupling.cc): their corners are the 4 x 4 particles from one row and column before it.
  const int32_t cells_per_row = model_.width - 1;
  if (e.triangle < 0 || e.triangle >= static_cast<int32_t>(model_.triangles.size())) return false;
  const int32_t cell = e.triangle / 2;
  const int32_t row = cell / cells_per_row, col = cell % cells_per_row;
  for (int32_t r = std::max(0, row - 1); r <= std::min(model_.height - 1, row + 2); ++r) {
    for (int32_t c = std::max(0, col - 1); c <= std::min(model_.width - 1, col + 2); ++c) {
      if (role_[r * model_.width + c] == PatchRole::kOutside) return false;
    }
  }
  return true;
}

void ClothPatch::Gather(const PatchWindow& win, bool velocities) {
  // The window into the structure-of-arrays block, single precision, metres from its first
  // particle (as ApplyProvot's arrays, ~1e-9 m over a window), with each particle's movability
  // (1 free, 0 driven) for the constraint kernel.
  const int32_t w = model_.width;
  const int32_t cols = win.col1 - win.col0 + 1;
  origin_ = x_[win.row0 * w + win.col0];
  float* __restrict px = soa_.data();
  float* __restrict py = px + soa_stride_;
  float* __restrict pz = py + soa_stride_;
  float* __restrict vx = pz + soa_stride_;
  float* __restrict vy = vx + soa_stride_;
  float* __restrict vz = vy + soa_stride_;
  float* __restrict mv = vz + soa_stride_;
  for (int32_t r = win.row0; r <= win.row1; ++r) {
    const int32_t l0 = (r - win.row0) * cols;
    for (int32_t c = win.col0; c <= win.col1; ++c) {
      const int32_t p = r * w + c, l = l0 + (c - win.col0);
      px[l] = static_cast<float>(x_[p].x() - origin_.x());
      py[l] = static_cast<float>(x_[p].y() - origin_.y());
      pz[l] = static_cast<float>(x_[p].z() - origin_.z());
      mv[l] = role_[p] == PatchRole::kFree ? 1.0f : 0.0f;
      if (velocities) {
        vx[l] = static_cast<float>(v_[p].x());
        vy[l] = static_cast<float>(v_[p].y());
        vz[l] = static_cast<float>(v_[p].z());
      }
    }
  }
}

void ClothPatch::ComputeAccelerations() {
  ForEachParticle([&](int32_t p) {
    f_[3 * p] = 0.0;
    f_[3 * p + 1] = 0.0;
    f_[3 * p + 2] = 0.0;
  });
  // Springs: Hooke plus the dashpot along the unit direction u from i to j,
  // f_i = (k (l - L) + c (v_j - v_i) . u) u, f_j = -f_i (001 §2), as AddSpringForces. Per window,
  // family and row: every pair's force into one row of scratch, then added to its i ends and
  // subtracted from its j ends in two passes (loops the compiler vectorises; the pairs with no
  // free end in the range compute forces nobody reads).
  const int32_t w = model_.width;
  const size_t stride = soa_stride_;
  for (size_t k = 0; k < window_count_; ++k) {
    const PatchWindow& win = windows_[k];
    Gather(win, true);
    const int32_t cols = win.col1 - win.col0 + 1;
    const float* __restrict px = soa_.data();
    const float* __restrict py = px + stride;
    const float* __restrict pz = py + stride;
    const float* __restrict vx = pz + stride;
    const float* __restrict vy = vx + stride;
    const float* __restrict vz = vy + stride;
    float* __restrict fx = soa_.data() + 7 * stride;
    float* __restrict fy = fx + stride;
    float* __restrict fz = fy + stride;
    float* __restrict tx = fz + stride;
    float* __restrict ty = tx + stride;
    float* __restrict tz = ty + stride;
    const size_t size = static_cast<size_t>(win.size());
    std::fill(fx, fx + size, 0.0f);
    std::fill(fy, fy + size, 0.0f);
    std::fill(fz, fz + size, 0.0f);
    for (const SpringFamily& fam : model_.spring_families) {
      const PatchWindow range = PairRange(win, fam.dc, fam.dr);
      if (range.empty()) continue;
      const auto stiffness = static_cast<float>(fam.stiffness_N_per_m);
      const auto damping = static_cast<float>(fam.damping_N_s_per_m);
      const auto rest = static_cast<float>(fam.rest_length_m);
      const int32_t offset = fam.dr * cols + fam.dc;
      const int32_t count = range.col1 - range.col0 + 1;
      for (int32_t r = range.row0; r <= range.row1; ++r) {
        const int32_t li = (r - win.row0) * cols + (range.col0 - win.col0);
        const int32_t lj = li + offset;
        RowSpringForces(count, px + li, py + li, pz + li, px + lj, py + lj, pz + lj, vx + li,
                        vy + li, vz + li, vx + lj, vy + lj, vz + lj, stiffness, damping, rest, tx,
                        ty, tz);
        AddRow(count, 1.0f, tx, ty, tz, fx + li, fy + li, fz + li);
        AddRow(count, -1.0f, tx, ty, tz, fx + lj, fy + lj, fz + lj);
      }
    }
    for (int32_t r = win.row0; r <= win.row1; ++r) {
      const int32_t l0 = (r - win.row0) * cols;
      for (int32_t c = win.col0; c <= win.col1; ++c) {
        const int32_t p = r * w + c, l = l0 + (c - win.col0);
        f_[3 * p] += static_cast<double>(fx[l]);
        f_[3 * p + 1] += static_cast<double>(fy[l]);
        f_[3 * p + 2] += static_cast<double>(fz[l]);
      }
    }
  }
  // The contact springs (sim_loop/cloth_coupling.h), then gravity and drag (001 §6.1).
  AddCouplingForces(*springs_, x_, 1.0, f_.data());
  const double drag = model_.drag_N_s_per_m;
  const Vec3 g = model_.gravity_m_per_s2;
  ForEachParticle([&](int32_t p) {
    if (role_[p] != PatchRole::kFree) return;
    const Vec3 f(f_[3 * p], f_[3 * p + 1], f_[3 * p + 2]);
    a_[p] = model_.inv_mass_per_kg[p] * (f - drag * v_[p]) + g;
  });
}

void ClothPatch::Integrate(double h) {
  // Leapfrog Verlet, kick-drift-kick with variable steps, as sim_loop's LeapfrogVerlet: the
  // half-step velocity v_{n+1/2} = v_{n-1/2} + (h_old + h)/2 a_n, x_{n+1} = x_n + h v_{n+1/2},
  // the state keeping v_{n+1} = v_{n+1/2} + h/2 a_n; a particle restarts from v (v + h/2 a).
  const double h_old = h_last_s_ > 0.0 ? h_last_s_ : h;
  const double kick = 0.5 * (h_old + h);
  const double back = 0.5 * h_old;
  ForEachParticle([&](int32_t p) {
    if (role_[p] != PatchRole::kFree) return;
    Vec3 v_half;
    if (restart_[p]) {
      v_half = v_[p] + (0.5 * h) * a_[p];
    } else if (h_old == h) {
      v_half = v_[p] + h * (a_[p] - 0.5 * a_last_[p]);
    } else {
      v_half = v_[p] + (kick * a_[p] - back * a_last_[p]);
    }
    restart_[p] = 0;
    x_[p] += h * v_half;
    v_[p] = v_half + (0.5 * h) * a_[p];
    a_last_[p] = a_[p];
  });
  h_last_s_ = h;
}

PatchWindow ClothPatch::PairRange(const PatchWindow& win, int32_t dc, int32_t dr) const {
  // The free particles of a window lie in its interior rectangle: the window less its driven
  // rings, except along the cloth's own edge (pins inside are checked pair by pair). The pairs
  // (c, r)-(c + dc, r + dr) with an end in it and both in the window start in this range.
  const int32_t w = model_.width, h = model_.height;
  const int32_t fc0 = win.col0 > 0 ? win.col0 + 2 : win.col0;
  const int32_t fc1 = win.col1 < w - 1 ? win.col1 - 2 : win.col1;
  const int32_t fr0 = win.row0 > 0 ? win.row0 + 2 : win.row0;
  const int32_t fr1 = win.row1 < h - 1 ? win.row1 - 2 : win.row1;
  PatchWindow out;
  out.col0 = std::max({win.col0, win.col0 - dc, std::min(fc0, fc0 - dc)});
  out.col1 = std::min({win.col1, win.col1 - dc, std::max(fc1, fc1 - dc)});
  out.row0 = std::max(win.row0, fr0 - dr);
  out.row1 = std::min(win.row1 - dr, fr1);
  return out;
}

void ClothPatch::ApplyProvotToWindows(double h) {
  // Provot 1995 (000 slide 9): a pair longer than its limit is shortened to it, both ends moving
  // by equal shares, a driven end not at all (as a pin), sweeps until none was more than 1e-3 over
  // its limit (as ApplyProvot, in single precision like it); the velocity follows the particle's
  // whole move / h. Per window in the structure-of-arrays block: the pairs of a family along a row
  // share no particle except for the horizontal families, which are swept in two colours (even,
  // then odd columns), so every loop is a loop over independent pairs.
  const int32_t w = model_.width;
  const size_t stride = soa_stride_;
  const double inv_h = 1.0 / h;
  for (size_t k = 0; k < window_count_; ++k) {
    const PatchWindow& win = windows_[k];
    Gather(win, false);
    const int32_t cols = win.col1 - win.col0 + 1;
    float* __restrict px = soa_.data();
    float* __restrict py = px + stride;
    float* __restrict pz = py + stride;
    const float* __restrict mv = soa_.data() + 6 * stride;
    for (int32_t it = 0; it < model_.provot_iterations; ++it) {
      // Pairs with a free end left more than 1e-3 over their limit by this sweep.
      constexpr float kLoose = (1.0f + 1e-3f) * (1.0f + 1e-3f);
      int32_t loose = 0;
      for (int32_t index : level1_) {
        const ProvotFamily& fam = model_.provot_families[static_cast<size_t>(index)];
        const PatchWindow range = PairRange(win, fam.dc, fam.dr);
        if (range.empty()) continue;
        const auto max_len = static_cast<float>(fam.max_length_m);
        const float inv_max2 = 1.0f / (max_len * max_len);
        const int32_t offset = fam.dr * cols + fam.dc;
        const int32_t count = range.col1 - range.col0 + 1;
        const int32_t step = fam.dr == 0 ? 2 : 1;
        for (int32_t r = range.row0; r <= range.row1; ++r) {
          const int32_t li = (r - win.row0) * cols + (range.col0 - win.col0);
          if (step == 1) {
            loose += RowProvot(count, px + li, py + li, pz + li, px + li + offset, py + li + offset,
                               pz + li + offset, mv + li, mv + li + offset, max_len, inv_max2,
                               kLoose);
            continue;
          }
          // A horizontal family (dc = 1): its pairs share ends along the row, so it is swept in
          // two colours, even then odd columns, each over independent pairs.
          for (int32_t colour = 0; colour < 2; ++colour) {
            for (int32_t c = colour; c < count; c += 2) {
              const float dx = px[li + c + 1] - px[li + c];
              const float dy = py[li + c + 1] - py[li + c];
              const float dz = pz[li + c + 1] - pz[li + c];
              const float len2 = dx * dx + dy * dy + dz * dz;
              const float mi = mv[li + c], mj = mv[li + c + 1];
              const float ratio = len2 * inv_max2;
              if (!(ratio > 1.0f) || mi + mj == 0.0f) continue;
              loose += ratio > kLoose ? 1 : 0;
              const float len = std::sqrt(len2);
              const float cut = (len - max_len) / (len * (mi + mj));
              px[li + c] += cut * mi * dx;
              py[li + c] += cut * mi * dy;
              pz[li + c] += cut * mi * dz;
              px[li + c + 1] -= cut * mj * dx;
              py[li + c + 1] -= cut * mj * dy;
              pz[li + c + 1] -= cut * mj * dz;
            }
          }
        }
      }
      if (loose == 0) break;
    }
    // Back as each free particle's move (exact in double; nothing for one not moved).
    for (int32_t r = win.row0; r <= win.row1; ++r) {
      const int32_t l0 = (r - win.row0) * cols;
      for (int32_t c = win.col0; c <= win.col1; ++c) {
        const int32_t p = r * w + c, l = l0 + (c - win.col0);
        if (role_[p] != PatchRole::kFree) continue;
        // The move in single precision from where Gather put the particle, exactly.
        const auto from = [&](int a) {
          return static_cast<double>(static_cast<float>(x_[p][a] - origin_[a]));
        };
        const Vec3 move(static_cast<double>(px[l]) - from(0), static_cast<double>(py[l]) - from(1),
                        static_cast<double>(pz[l]) - from(2));
        x_[p] += move;
        v_[p] += inv_h * move;
      }
    }
  }
}

void ClothPatch::ApplyObstaclesToWindows() {
  // Projection to the margin shell along the distance's gradient; the inward normal velocity is
  // removed and the particle restarts from its velocity (no sweep and no friction: the patch's
  // steps are 1 ms, and the sim's frame resolves the obstacles fully).
  ForEachParticle([&](int32_t p) {
    if (role_[p] != PatchRole::kFree) return;
    for (const ObstacleSpec& o : model_.obstacles) {
      Vec3 n;
      const double phi = ObstacleDistance(o, x_[p], &n);
      if (!(phi < o.margin_m)) continue;
      x_[p] += (o.margin_m - phi) * n;
      const double vn = v_[p].dot(n);
      if (vn < 0.0) v_[p] -= vn * n;
      restart_[p] = 1;
    }
  });
}

bool ClothPatch::AllFinite() const {
  double probe = 0.0;
  ForEachParticle([&](int32_t p) { probe += (x_[p] * 0.0).sum() + (v_[p] * 0.0).sum(); });
  return probe == 0.0;
}

void ClothPatch::RestartFromDrive(const ClothSnapshot& drive, double tau_s) {
  ForEachParticle([&](int32_t p) {
    x_[p] = drive.x[p] + tau_s * drive.v[p];
    v_[p] = drive.v[p];
    x_before_[p] = x_[p];
    restart_[p] = 1;
  });
}

Vec3 ClothPatch::NormalAt(int32_t p) const {
  Vec3 n = Vec3::Zero();
  for (int32_t k = vertex_tri_start_[p]; k < vertex_tri_start_[p + 1]; ++k) {
    const Triangle& t = model_.triangles[static_cast<size_t>(vertex_tris_[k])];
    n += (x_[t[1]] - x_[t[0]]).cross(x_[t[2]] - x_[t[0]]);
  }
  const double len = n.norm();
  return len > 0.0 ? Vec3(n / len) : Vec3::Zero();
}

PatchStepResult ClothPatch::Step(std::span<const ExternalForce> external, double dt_s,
                                 const ClothSnapshot& drive, double tau_s) {
  PatchStepResult out;
  if (window_count_ == 0 || !(dt_s > 0.0)) return out;
  ++counters_.steps;
  ForEachParticle([&](int32_t p) { x_before_[p] = x_[p]; });

  // Substeps no longer than the patch's nominal one, shortened for a stiff contact spring
  // (CouplingSubsteps: Colgate, Stanley & Brown 1995).
  const int32_t plain = std::max(1, static_cast<int32_t>(std::ceil(dt_s / h_max_s_ - 1e-9)));
  const int32_t substeps = CouplingSubsteps(model_, external, dt_s, plain);
  const double h = dt_s / substeps;
  BeginCouplingFrame(springs_.get());
  for (const ExternalForce& e : external) {
    if (!(e.stiffness_N_per_m > 0.0)) continue;
    if (!SpringInside(e)) {
      ++counters_.springs_outside;
      continue;
    }
    AddCouplingSpring(model_, e, h, x_, springs_.get(), &counters_.coupling);
  }
  const bool provot = model_.provot_enabled && !level1_.empty();
  for (int32_t s = 0; s < substeps; ++s) {
    if (s > 0) AdvanceCouplingSprings(s * h, springs_.get());
    // Forces at the substep's start (the driven particles where they are), then the driven
    // particles to the substep's end, where the constraints see them.
    ComputeAccelerations();
    Integrate(h);
    SetDriven(drive, tau_s - dt_s + (s + 1) * h, h);
    if (provot) ApplyProvotToWindows(h);
    if (!model_.obstacles.empty()) ApplyObstaclesToWindows();
  }
  if (!AllFinite()) {
    ++counters_.nan_events;
    RestartFromDrive(drive, tau_s);
    out.recovered = true;
  }
  out.substeps = substeps;
  out.springs = springs_->count;
  return out;
}

double ClothPatch::MaxDistanceFrom(const ClothSnapshot& s) const {
  double max2 = 0.0;
  ForEachParticle([&](int32_t p) {
    max2 = std::max({max2, (x_[p] - s.x[p]).squaredNorm(), (x_before_[p] - s.x[p]).squaredNorm()});
  });
  return std::sqrt(max2);
}

}  // namespace felt
