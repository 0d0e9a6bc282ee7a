#include "sim_loop/cloth_patch.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

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

}  // namespace

ClothPatch::ClothPatch(const ClothModel& model, int32_t radius, int32_t max_windows)
    : model_(model), radius_(radius) {
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
  restart_.assign(n, 1);
  for (size_t i = 0; i < model.provot_families.size(); ++i) {
    if (model.provot_families[i].level == 1) level1_.push_back(static_cast<int32_t>(i));
  }
}

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
      const bool keep = a >= 0 && std::abs(a % w - c % w) < kPatchRecentreDistance &&
                        std::abs(a / w - c / w) < kPatchRecentreDistance;
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

void ClothPatch::ComputeAccelerations() {
  ForEachParticle([&](int32_t p) {
    f_[3 * p] = 0.0;
    f_[3 * p + 1] = 0.0;
    f_[3 * p + 2] = 0.0;
  });
  // Springs with an end free: Hooke plus the dashpot along the unit direction u from i to j,
  // f_i = (k (l - L) + c (v_j - v_i) . u) u, f_j = -f_i (001 §2), as AddSpringForces.
  const int32_t w = model_.width;
  constexpr double kMinLength2 = kMinSpringLength_m * kMinSpringLength_m;
  for (size_t k = 0; k < window_count_; ++k) {
    const PatchWindow& win = windows_[k];
    for (const SpringFamily& fam : model_.spring_families) {
      const PatchWindow range = PairRange(win, fam.dc, fam.dr);
      const int32_t offset = fam.dr * w + fam.dc;
      for (int32_t r = range.row0; r <= range.row1; ++r) {
        for (int32_t c = range.col0; c <= range.col1; ++c) {
          const int32_t i = r * w + c, j = i + offset;
          if (role_[i] != PatchRole::kFree && role_[j] != PatchRole::kFree) continue;
          const Vec3 d = x_[j] - x_[i];
          const double len2 = d.squaredNorm();
          if (!(len2 > kMinLength2)) continue;
          const double len = std::sqrt(len2);
          const double rel_speed = (v_[j] - v_[i]).dot(d) / len;
          const double scale = (fam.stiffness_N_per_m * (len - fam.rest_length_m) +
                                fam.damping_N_s_per_m * rel_speed) /
                               len;
          for (int a = 0; a < 3; ++a) {
            f_[3 * i + a] += scale * d[a];
            f_[3 * j + a] -= scale * d[a];
          }
        }
      }
    }
  }
  // The contact springs (sim_loop/cloth_coupling.h), then gravity and drag (001 §6.1).
  AddCouplingForces(springs_, x_, 1.0, f_.data());
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
  // its limit (as ApplyProvot); the velocity follows the particle's whole move / h.
  const int32_t w = model_.width;
  ForEachParticle([&](int32_t p) { a_[p] = x_[p]; });  // a_ is free scratch after Integrate
  for (int32_t it = 0; it < model_.provot_iterations; ++it) {
    bool loose = false;
    for (size_t k = 0; k < window_count_; ++k) {
      for (int32_t index : level1_) {
        const ProvotFamily& fam = model_.provot_families[static_cast<size_t>(index)];
        const double max2 = fam.max_length_m * fam.max_length_m;
        const double loose2 = (1.0 + 1e-3) * (1.0 + 1e-3) * max2;
        const PatchWindow range = PairRange(windows_[k], fam.dc, fam.dr);
        const int32_t offset = fam.dr * w + fam.dc;
        for (int32_t r = range.row0; r <= range.row1; ++r) {
          for (int32_t c = range.col0; c <= range.col1; ++c) {
            const int32_t i = r * w + c, j = i + offset;
            const Vec3 d = x_[j] - x_[i];
            const double len2 = d.squaredNorm();
            if (!(len2 > max2)) continue;
            const bool free_i = role_[i] == PatchRole::kFree;
            const bool free_j = role_[j] == PatchRole::kFree;
            if (!free_i && !free_j) continue;
            loose = loose || len2 > loose2;
            const double len = std::sqrt(len2);
            const Vec3 corr = ((len - fam.max_length_m) / len) * d;  // moves i toward j
            if (free_i && free_j) {
              x_[i] += 0.5 * corr;
              x_[j] -= 0.5 * corr;
            } else if (free_i) {
              x_[i] += corr;
            } else {
              x_[j] -= corr;
            }
          }
        }
      }
    }
    if (!loose) break;
  }
  const double inv_h = 1.0 / h;
  ForEachParticle([&](int32_t p) {
    if (role_[p] == PatchRole::kFree) v_[p] += inv_h * (x_[p] - a_[p]);
  });
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
  BeginCouplingFrame(&springs_);
  for (const ExternalForce& e : external) {
    if (!(e.stiffness_N_per_m > 0.0)) continue;
    if (!SpringInside(e)) {
      ++counters_.springs_outside;
      continue;
    }
    AddCouplingSpring(model_, e, h, x_, &springs_, &counters_.coupling);
  }
  const bool provot = model_.provot_enabled && !level1_.empty();
  for (int32_t s = 0; s < substeps; ++s) {
    if (s > 0) AdvanceCouplingSprings(s * h, &springs_);
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
  out.springs = springs_.count;
  ForEachParticle([&](int32_t p) { out.free_particles += role_[p] == PatchRole::kFree ? 1 : 0; });
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
