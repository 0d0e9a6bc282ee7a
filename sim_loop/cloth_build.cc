// Validation of a SimSpec into a ClothModel, and the state it is stepped in.

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>

#include "base/check.h"
#include "sim_loop/cloth.h"
#include "sim_loop/cloth_internal.h"

namespace felt {
namespace {

// The coarsest multiresolution stride Provot sweeps when long range attachments are on. Measured on
// the two-corner curtain, 3 sweeps a substep, the 420 frames of `felt bench cloth` (release peak /
// settled structural stretch, frame CPU ms): 64 x 64 with every level (up to 32) 1.1171 / 1.1037,
// 6.94 ms; up to 16 1.1170 / 1.1038, 6.92 ms; up to 8 1.1152 / 1.1039, 6.24 ms; up to 4 1.1276 /
// 1.1039, 5.64 ms. 128 x 128: every level (up to 64) 1.1310 / 1.1158, 58.9 ms; up to 8 1.1297 /
// 1.1136, 50.4 ms (with one attachment per group of pins, two here, rather than to the nearest pin
// only: 1.1257 / 1.1076). Without the attachments the coarse levels do matter (64 x 64: 1.435 with
// every level, 1.569 up to 8), so there every level is kept.
constexpr int32_t kMaxAttachedStride = 8;
// Long range attachments per free particle at most: to the nearest pin of each of the groups of
// touching pins nearest it. Every rank costs a pass over the cloth; four covers a cloth hung from
// its corners, and a scene with many separate pins pays for four.
constexpr size_t kMaxAttachedGroups = 4;

constexpr double kUnitTolerance = 1e-9;  // |norm - 1| and |u . v| allowed for axes

// Formats any streamable value the way error messages show it.
template <typename T>
std::string Show(const T& value) {
  std::ostringstream out;
  out.precision(17);
  out << value;
  return out.str();
}

std::string ShowVec(const Vec3& v) {
  std::ostringstream out;
  out.precision(17);
  out << '(' << v.x() << ", " << v.y() << ", " << v.z() << ')';
  return out.str();
}

[[noreturn]] void Fail(const std::string& field, const std::string& rule) {
  throw std::invalid_argument(field + ": " + rule);
}

void RequireFinite(const std::string& field, double value) {
  if (!std::isfinite(value)) Fail(field, "must be finite, got " + Show(value));
}

void RequirePositive(const std::string& field, double value) {
  RequireFinite(field, value);
  if (!(value > 0.0)) Fail(field, "must be > 0, got " + Show(value));
}

void RequireNonNegative(const std::string& field, double value) {
  RequireFinite(field, value);
  if (!(value >= 0.0)) Fail(field, "must be >= 0, got " + Show(value));
}

void RequireFiniteVec(const std::string& field, const Vec3& v) {
  if (!v.allFinite()) Fail(field, "must be finite, got " + ShowVec(v));
}

void RequireUnitVec(const std::string& field, const Vec3& v) {
  RequireFiniteVec(field, v);
  if (std::abs(v.norm() - 1.0) > kUnitTolerance) {
    Fail(field, "must be a unit vector, got " + ShowVec(v));
  }
}

void ValidateSpring(const std::string& field, const std::optional<SpringSpec>& spring) {
  if (!spring) return;
  RequirePositive(field + ".stiffness_N_per_m", spring->stiffness_N_per_m);
  RequireNonNegative(field + ".damping_N_s_per_m", spring->damping_N_s_per_m);
}

void ValidateMotion(const std::string& field, const PinMotionSpec& m) {
  RequireFiniteVec(field + ".velocity_m_per_s", m.velocity_m_per_s);
  RequireFiniteVec(field + ".amplitude_m", m.amplitude_m);
  RequireNonNegative(field + ".frequency_hz", m.frequency_hz);
  RequireNonNegative(field + ".start_s", m.start_s);
  if (std::isnan(m.stop_s) || m.stop_s < m.start_s) {
    Fail(field + ".stop_s", "must be >= start_s (" + Show(m.start_s) + "), got " + Show(m.stop_s));
  }
}

bool SameMotion(const PinMotionSpec& a, const PinMotionSpec& b) {
  return a.velocity_m_per_s == b.velocity_m_per_s && a.amplitude_m == b.amplitude_m &&
         a.frequency_hz == b.frequency_hz && a.start_s == b.start_s && a.stop_s == b.stop_s;
}

bool IsScripted(const PinMotionSpec& m) {
  return !m.velocity_m_per_s.isZero(0.0) || !m.amplitude_m.isZero(0.0);
}

// The particles a pin holds, as (col, row); throws naming the pin's field if it names nothing.
std::vector<std::pair<int32_t, int32_t>> PinParticles(const std::string& field, const PinSpec& pin,
                                                      int32_t w, int32_t h) {
  std::vector<std::pair<int32_t, int32_t>> out;
  switch (pin.kind) {
    case PinKind::kParticle:
      if (pin.col < 0 || pin.col >= w) {
        Fail(field + ".col", "must be in [0, " + Show(w) + "), got " + Show(pin.col));
      }
      if (pin.row < 0 || pin.row >= h) {
        Fail(field + ".row", "must be in [0, " + Show(h) + "), got " + Show(pin.row));
      }
      out.emplace_back(pin.col, pin.row);
      break;
    case PinKind::kCorner:
      if (pin.name == "top_left") {
        out.emplace_back(0, 0);
      } else if (pin.name == "top_right") {
        out.emplace_back(w - 1, 0);
      } else if (pin.name == "bottom_left") {
        out.emplace_back(0, h - 1);
      } else if (pin.name == "bottom_right") {
        out.emplace_back(w - 1, h - 1);
      } else {
        Fail(field + ".name",
             "unknown corner '" + pin.name + "' (top_left, top_right, bottom_left, bottom_right)");
      }
      break;
    case PinKind::kEdge:
      if (pin.name == "top" || pin.name == "bottom") {
        const int32_t row = pin.name == "top" ? 0 : h - 1;
        for (int32_t c = 0; c < w; ++c) out.emplace_back(c, row);
      } else if (pin.name == "left" || pin.name == "right") {
        const int32_t col = pin.name == "left" ? 0 : w - 1;
        for (int32_t r = 0; r < h; ++r) out.emplace_back(col, r);
      } else {
        Fail(field + ".name", "unknown edge '" + pin.name + "' (top, bottom, left, right)");
      }
      break;
    default:
      Fail(field + ".kind", "unknown pin kind " + Show(static_cast<int>(pin.kind)));
  }
  return out;
}

void ValidateObstacle(const std::string& field, const ObstacleSpec& o) {
  RequireNonNegative(field + ".friction", o.friction);
  RequireNonNegative(field + ".margin_m", o.margin_m);
  if (const auto* plane = std::get_if<PlaneSpec>(&o.shape)) {
    RequireFiniteVec(field + ".point_m", plane->point_m);
    RequireUnitVec(field + ".normal", plane->normal);
  } else if (const auto* sphere = std::get_if<SphereSpec>(&o.shape)) {
    RequireFiniteVec(field + ".center_m", sphere->center_m);
    RequirePositive(field + ".radius_m", sphere->radius_m);
  } else if (const auto* box = std::get_if<BoxSpec>(&o.shape)) {
    RequireFiniteVec(field + ".min_m", box->min_m);
    RequireFiniteVec(field + ".max_m", box->max_m);
    if (!(box->min_m.array() < box->max_m.array()).all()) {
      Fail(field + ".max_m",
           "must be > min_m " + ShowVec(box->min_m) + " on every axis, got " + ShowVec(box->max_m));
    }
  } else if (const auto* capsule = std::get_if<CapsuleSpec>(&o.shape)) {
    RequireFiniteVec(field + ".a_m", capsule->a_m);
    RequireFiniteVec(field + ".b_m", capsule->b_m);
    RequirePositive(field + ".radius_m", capsule->radius_m);
  }
}

void ValidateIntegration(const IntegrationSpec& s) {
  const int kind = static_cast<int>(s.integrator);
  if (kind < 0 || kind > static_cast<int>(IntegratorKind::kImplicitEuler)) {
    Fail("integration.integrator", "unknown integrator " + Show(kind));
  }
  if (s.substeps < 0 || s.substeps > kMaxSubstepsPerFrame) {
    Fail("integration.substeps",
         "must be in [0, " + Show(kMaxSubstepsPerFrame) + "] (0 = auto), got " + Show(s.substeps));
  }
  RequirePositive("integration.frame_rate_hz", s.frame_rate_hz);
  if (s.frame_rate_hz > kMaxFrameRate_hz) {
    Fail("integration.frame_rate_hz",
         "must be in (0, " + Show(kMaxFrameRate_hz) + "], got " + Show(s.frame_rate_hz));
  }
  RequirePositive("integration.max_frame_dt_s", s.max_frame_dt_s);
  RequireFinite("integration.auto_safety", s.auto_safety);
  if (!(s.auto_safety > 0.0 && s.auto_safety <= 1.0)) {
    Fail("integration.auto_safety", "must be in (0, 1], got " + Show(s.auto_safety));
  }
  if (s.cg_max_iterations < 1) {
    Fail("integration.cg_max_iterations", "must be >= 1, got " + Show(s.cg_max_iterations));
  }
  RequireFinite("integration.cg_tolerance", s.cg_tolerance);
  if (!(s.cg_tolerance > 0.0 && s.cg_tolerance < 1.0)) {
    Fail("integration.cg_tolerance", "must be in (0, 1), got " + Show(s.cg_tolerance));
  }
}

void ValidateProvot(const ProvotSpec& s) {
  RequirePositive("provot.max_elongation", s.max_elongation);  // the scene file's rule too
  if (s.iterations < 1 || s.iterations > kMaxProvotIterations) {
    Fail("provot.iterations",
         "must be in [1, " + Show(kMaxProvotIterations) + "], got " + Show(s.iterations));
  }
  if (s.coarse_sweeps < 1 || s.coarse_sweeps > kMaxProvotIterations) {
    Fail("provot.coarse_sweeps",
         "must be in [1, " + Show(kMaxProvotIterations) + "], got " + Show(s.coarse_sweeps));
  }
  if (!(s.sweep_headroom >= 0.0 && s.sweep_headroom < 0.5)) {
    Fail("provot.sweep_headroom", "must be in [0, 0.5), got " + Show(s.sweep_headroom));
  }
  if (s.patch_iterations &&
      (*s.patch_iterations < 1 || *s.patch_iterations > kMaxProvotIterations)) {
    Fail("provot.patch_iterations",
         "must be in [1, " + Show(kMaxProvotIterations) + "], got " + Show(*s.patch_iterations));
  }
  if (s.patch_sweep_headroom &&
      !(*s.patch_sweep_headroom >= 0.0 && *s.patch_sweep_headroom < 0.5)) {
    Fail("provot.patch_sweep_headroom",
         "must be in [0, 0.5), got " + Show(*s.patch_sweep_headroom));
  }
}

// Appends the springs of one type between (c, r) and (c + dc, r + dr) for every valid pair, and
// their family (SpringFamily) if there is any.
void AddSprings(ClothModel* model_out, const SpringSpec& spec, SpringType type, int32_t dc,
                int32_t dr) {
  const ClothModel& model = *model_out;
  std::vector<Spring>* springs = &model_out->springs;
  const size_t first = springs->size();
  for (int32_t r = 0; r < model.height; ++r) {
    for (int32_t c = 0; c < model.width; ++c) {
      const int32_t c2 = c + dc, r2 = r + dr;
      if (c2 < 0 || c2 >= model.width || r2 < 0 || r2 >= model.height) continue;
      Spring s;
      s.i = GridIndex(model.width, c, r);
      s.j = GridIndex(model.width, c2, r2);
      s.rest_length_m = (model.rest_position_m[s.j] - model.rest_position_m[s.i]).norm();
      s.stiffness_N_per_m = spec.stiffness_N_per_m;
      s.damping_N_s_per_m = spec.damping_N_s_per_m;
      s.type = type;
      springs->push_back(s);
    }
  }
  if (springs->size() == first) return;
  SpringFamily family;
  family.dc = dc;
  family.dr = dr;
  family.rest_length_m = (*springs)[first].rest_length_m;
  family.stiffness_N_per_m = spec.stiffness_N_per_m;
  family.damping_N_s_per_m = spec.damping_N_s_per_m;
  family.type = type;
  model_out->spring_families.push_back(family);
}

// The runs of a Provot family (ProvotFamily::runs), in two colours whose pairs share no particle,
// so that a colour's pairs can be projected four at a time: graph-coloured Gauss-Seidel (Adams
// 2001; Fratarcangeli, Tibaldo & Pellacini 2016 for position based dynamics).
std::vector<ProvotFamily::Run> ProvotRuns(const ProvotFamily& f, int32_t width, int32_t height) {
  std::vector<ProvotFamily::Run> runs;
  for (int32_t colour = 0; colour < 2; ++colour) {
    if (f.dr > 0) {
      // Rows r and r + dr: colour (r / dr) mod 2 never holds both.
      const int32_t c_lo = std::max(0, -f.dc), c_hi = width - std::max(0, f.dc);
      if (c_hi <= c_lo) continue;
      for (int32_t r = 0; r + f.dr < height; ++r) {
        if ((r / f.dr) % 2 == colour) runs.push_back({r * width + c_lo, r * width + c_hi});
      }
      continue;
    }
    // Along a row, pairs (c, c + dc): colour (c / dc) mod 2 never holds both ends of two pairs.
    for (int32_t r = 0; r < height; ++r) {
      if (f.strided()) {
        // The first dc of every 2 dc particles from the first of the colour (ProvotFamily::runs).
        if (colour * f.dc + f.dc < width) {
          runs.push_back({r * width + colour * f.dc, r * width + width - f.dc});
        }
        continue;
      }
      for (int32_t c0 = colour * f.dc; c0 + f.dc < width; c0 += 2 * f.dc) {
        runs.push_back({r * width + c0, r * width + std::min(c0 + f.dc, width - f.dc)});
      }
    }
  }
  return runs;
}

// Provot's constraint families in sweep order. Coarse before fine, like the descent of a multigrid
// V-cycle (Briggs, Henson & McCormick 2000, ch. 3): the multiresolution families (stride s = the
// largest power of two below the grid's side, down to 2, along rows, columns and, where shear
// springs are constrained, both diagonals) move whole regions back within reach, then the spring
// families fix the springs themselves. The diagonal levels matter on a cloth hung from points: its
// tension runs along diagonals from each pin, where row and column levels only reach it in steps.
// With long range attachments (and a pin to attach to) the levels stop at kMaxAttachedStride:
// the attachments already hold every particle within reach of its pin, which is what the coarser
// levels did, and those levels cost as much per sweep as a fine one (every particle is in a pair).
std::vector<ProvotFamily> BuildProvotFamilies(const ClothModel& model, const ProvotSpec& spec) {
  std::vector<ProvotFamily> out;
  const auto limit = [&](const SpringFamily& f) {
    return (1.0 + spec.max_elongation) * f.rest_length_m;
  };
  const SpringFamily* along_row = nullptr;
  const SpringFamily* along_column = nullptr;
  std::vector<const SpringFamily*> diagonals;  // the constrained shear families, (1, 1), (-1, 1)
  for (const SpringFamily& f : model.spring_families) {
    if (f.type == SpringType::kShear && spec.shear) diagonals.push_back(&f);
    if (f.type != SpringType::kStructural) continue;
    (f.dr == 0 ? along_row : along_column) = &f;
  }
  if (spec.multiresolution) {
    const bool attached = spec.long_range_attachments && !model.pinned.empty();
    const int32_t max_stride = attached ? kMaxAttachedStride : std::numeric_limits<int32_t>::max();
    int32_t stride = 2;
    while (2 * stride < std::max(model.width, model.height) && 2 * stride <= max_stride) {
      stride *= 2;
    }
    for (; stride >= 2; stride /= 2) {
      // A straight chain of s springs, each at most (1 + e) L long, spans at most (1 + e) s L
      // (triangle inequality): these constraints are implied by the springs' own and never
      // over-constrain a configuration that satisfies them.
      if (along_row != nullptr && stride < model.width) {
        out.push_back({stride, 0, stride * limit(*along_row), stride, {}});
      }
      if (along_column != nullptr && stride < model.height) {
        out.push_back({0, stride, stride * limit(*along_column), stride, {}});
      }
      // A diagonal chain of s shear springs, likewise (only when shear springs are constrained).
      for (const SpringFamily* d : diagonals) {
        if (stride < model.width && stride < model.height) {
          out.push_back({d->dc * stride, d->dr * stride, stride * limit(*d), stride, {}});
        }
      }
    }
  }
  for (const SpringFamily& f : model.spring_families) {
    const bool kept =
        f.type == SpringType::kStructural || (spec.shear && f.type == SpringType::kShear);
    if (kept) out.push_back({f.dc, f.dr, limit(f), 1, {}});
  }
  for (ProvotFamily& f : out) {
    f.sweep_length_m = (1.0 - spec.sweep_headroom) * f.max_length_m;
    f.patch_sweep_length_m =
        (1.0 - spec.patch_sweep_headroom.value_or(spec.sweep_headroom)) * f.max_length_m;
    f.runs = ProvotRuns(f, model.width, model.height);
    // A run whose pairs are all free skips the pinned-end shares (most runs of most cloths).
    const auto pinned = [&](int32_t p) { return model.inv_mass_per_kg[p] == 0.0; };
    for (ProvotFamily::Run& run : f.runs) {
      if (f.strided()) {
        // The strided pairs' ends all lie within [lo, hi + dc).
        for (int32_t p = run.lo; p < run.hi + f.dc; ++p) run.pinned |= pinned(p) ? 1 : 0;
        continue;
      }
      const int32_t off = f.dr * model.width + f.dc;
      for (int32_t p = run.lo; p < run.hi; ++p) run.pinned |= pinned(p) || pinned(p + off) ? 1 : 0;
    }
  }
  return out;
}

// The pinned particles in groups that touch on the grid (8-neighbours): a corner, an edge, a rail.
std::vector<std::vector<int32_t>> PinGroups(const ClothModel& model) {
  const int32_t w = model.width, h = model.height;
  std::vector<int32_t> group(static_cast<size_t>(model.num_particles()), -1);
  std::vector<std::vector<int32_t>> groups;
  for (int32_t seed : model.pinned) {
    if (group[static_cast<size_t>(seed)] >= 0) continue;
    const int32_t g = static_cast<int32_t>(groups.size());
    std::vector<int32_t>& members = groups.emplace_back(1, seed);
    group[static_cast<size_t>(seed)] = g;
    for (size_t head = 0; head < members.size(); ++head) {
      const int32_t r = members[head] / w, c = members[head] % w;
      for (int32_t nr = std::max(0, r - 1); nr <= std::min(h - 1, r + 1); ++nr) {
        for (int32_t nc = std::max(0, c - 1); nc <= std::min(w - 1, c + 1); ++nc) {
          const size_t q = static_cast<size_t>(nr * w + nc);
          if (group[q] >= 0 || model.inv_mass_per_kg[q] != 0.0) continue;
          group[q] = g;
          members.push_back(static_cast<int32_t>(q));
        }
      }
    }
  }
  return groups;
}

// Long range attachments (Kim, Chentanez & Mueller 2012): each free particle to the pinned particle
// nearest its rest place in every group of touching pins (ties: the first in the group), the
// nearest group first, kMaxAttachedGroups groups at most. Rest distances are straight lines on the
// flat rest grid. One attachment per group: a cloth hung from two corners holds its middle from
// both (the weight there hangs from both), while the other pins of an edge add little to its
// nearest one.
std::vector<PinAttachment> BuildAttachments(const ClothModel& model, const ProvotSpec& spec) {
  std::vector<PinAttachment> out;
  const std::vector<std::vector<int32_t>> groups = PinGroups(model);
  std::vector<std::pair<double, int32_t>> nearest(groups.size());  // per group: (distance^2, pin)
  for (int32_t p = 0; p < model.num_particles(); ++p) {
    if (model.inv_mass_per_kg[p] == 0.0) continue;
    for (size_t g = 0; g < groups.size(); ++g) {
      nearest[g] = {std::numeric_limits<double>::infinity(), groups[g].front()};
      for (int32_t q : groups[g]) {
        const double d = (model.rest_position_m[q] - model.rest_position_m[p]).squaredNorm();
        if (d < nearest[g].first) nearest[g] = {d, q};
      }
    }
    std::stable_sort(nearest.begin(), nearest.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    for (size_t k = 0; k < std::min(nearest.size(), kMaxAttachedGroups); ++k) {
      out.push_back(
          {p, nearest[k].second, (1.0 + spec.max_elongation) * std::sqrt(nearest[k].first)});
    }
  }
  return out;
}

// model->attachments as dense ranks (ClothModel::attachment_pin): every free particle has the same
// number of attachments, one per pin group up to kMaxAttachedGroups.
void DenseAttachments(ClothModel* model) {
  const size_t n = static_cast<size_t>(model->num_particles());
  size_t free_particles = 0;
  for (double im : model->inv_mass_per_kg) free_particles += im > 0.0 ? 1 : 0;
  if (free_particles == 0 || model->attachments.empty()) return;
  // BuildAttachments gives every free particle the same count, particle by particle.
  const size_t ranks = model->attachments.size() / free_particles;
  FELT_CHECK(ranks * free_particles == model->attachments.size());
  model->attachment_ranks = static_cast<int32_t>(ranks);
  model->attachment_pin.resize(ranks * n);
  model->attachment_max_m.assign(ranks * n, 0.0f);
  for (size_t k = 0; k < ranks; ++k) {
    for (size_t p = 0; p < n; ++p) model->attachment_pin[k * n + p] = static_cast<int32_t>(p);
  }
  for (size_t i = 0; i < model->attachments.size(); ++i) {
    const PinAttachment& at = model->attachments[i];
    const size_t slot = (i % ranks) * n + static_cast<size_t>(at.particle);
    model->attachment_pin[slot] = at.pin;
    model->attachment_max_m[slot] = static_cast<float>(at.max_length_m);
  }
}

// Largest value over wave vectors theta of the symbol of the grid's weighted Laplacian,
// S(theta) = sum over families f of w_f (2 - 2 cos(theta . e_f)), e_f = (dc, dr), with weight
// w_f = weight(f) (a stiffness or a damping constant). Von Neumann (Fourier) analysis of the
// uniform grid; sampled on a grid of spacing delta over a half period, plus the Taylor margin
// H delta^2 / 4, where H = sum_f 2 w_f |e_f|^2 bounds the Hessian: S is periodic and smooth, so
// its maximum is a critical point, within delta / sqrt(2) of a sample. An upper bound, tight to
// about 0.3 %.
template <typename Weight>
double MaxGridSymbol(const std::vector<SpringFamily>& families, Weight weight) {
  constexpr int kSamples = 32;  // per half period
  const double delta = M_PI / kSamples;
  double best = 0.0, hessian = 0.0;
  for (const SpringFamily& f : families) {
    hessian += 2.0 * weight(f) * (f.dc * f.dc + f.dr * f.dr);
  }
  // S(-theta) = S(theta): a in [0, pi], b in [-pi, pi] covers every wave vector.
  for (int ia = 0; ia <= kSamples; ++ia) {
    for (int ib = -kSamples; ib <= kSamples; ++ib) {
      const double a = ia * delta, b = ib * delta;
      double sum = 0.0;
      for (const SpringFamily& f : families) {
        sum += weight(f) * (2.0 - 2.0 * std::cos(f.dc * a + f.dr * b));
      }
      best = std::max(best, sum);
    }
  }
  return best + 0.25 * hessian * delta * delta;
}

// Fills the stiffness and damping bounds used by StableStep.
//
// Every mode of the linearised cloth obeys M d'' = -K d - D d' (000_25210a744b053ca5.txt slide 8).
// A spring's stiffness block is k (u u^T + (1 - L / l) (I - u u^T)), whose quadratic form is at
// most k |d_i - d_j|^2 for any direction u and any length l (0 <= 1 - L/l < 1 when stretched,
// negative when compressed). So d^T K d <= d^T (L_k (x) I) d, with L_k the graph Laplacian of
// the grid weighted by the spring constants, in every configuration of the cloth. Pinned
// particles only remove rows and columns, and a finite grid's quadratic form is at most that of
// the infinite grid on the zero-extended vector (the missing springs only add non-negative
// terms), so omega_max^2 = lambda_max(M^-1 K) <= max_theta S(theta) / m with uniform masses
// m (MaxGridSymbol). The default curtain: S_max = 8.4 N/m against the Gershgorin row bound
// 2 sum k = 12.8 N/m used before, so 1.23 times the stable step. The dashpots (along the spring
// only) give the same bound on the damping rates with c in place of k.
void ComputeFrequencyBounds(const SimSpec& spec, ClothModel* model) {
  double tau_min = std::numeric_limits<double>::infinity(), tau_max = 0.0;
  for (const SpringFamily& f : model->spring_families) {
    const double tau = f.damping_N_s_per_m / f.stiffness_N_per_m;
    tau_min = std::min(tau_min, tau);
    tau_max = std::max(tau_max, tau);
  }
  bool any_free = false;
  for (double im : model->inv_mass_per_kg) any_free = any_free || im > 0.0;
  const double inv_m = any_free ? 1.0 / model->particle_mass_kg : 0.0;
  const double omega2 = inv_m * MaxGridSymbol(model->spring_families, [](const SpringFamily& f) {
                          return f.stiffness_N_per_m;
                        });
  const double gamma = inv_m * MaxGridSymbol(model->spring_families, [](const SpringFamily& f) {
                         return f.damping_N_s_per_m;
                       });
  model->omega_max_rad_per_s = std::sqrt(omega2);
  // Across a spring stretched to r times its rest length the stiffness is k (1 - 1/r) and no
  // dashpot acts: those modes are damped by drag alone. With Provot on, structural springs (and
  // shear ones if constrained) end each substep at most (1 + e) long, bend springs (two
  // structural ones end to end) too, and unconstrained shear springs at most sqrt(2) (1 + e).
  const ProvotSpec& provot = spec.provot;
  double ratio = std::numeric_limits<double>::infinity();
  if (provot.enabled) {
    ratio =
        (1.0 + provot.max_elongation) * (provot.shear || !spec.cloth.shear ? 1.0 : std::sqrt(2.0));
  }
  model->omega_transverse_rad_per_s = model->omega_max_rad_per_s * std::sqrt(1.0 - 1.0 / ratio);
  model->drag_rate_per_s = model->drag_N_s_per_m / model->particle_mass_kg;
  model->damping_time_min_s = model->spring_families.empty() ? 0.0 : tau_min;
  model->damping_time_max_s = tau_max;
  model->gamma_max_per_s = gamma + model->drag_rate_per_s;
}

// Auto's step bound for a conservative cloth, omega_max h at most this. The undamped 10 x 10
// curtain with Provot off (felt bench stability's undamped hour; omega_max = 91.6 rad/s), energy
// rise over its start in M g L: 600 s at omega_max h = 0.76 (2 substeps) 264, 0.38 (4) 7.8, 0.19
// (8) 0.058, 0.095 (16) 0.011, 0.048 (32) 0.0007; the hour at 0.048 +0.0076, at 0.039 (39)
// +0.0067, within the suite's 1 %; at 0.03 (51 substeps) +0.0041 / -0.0019, the margin taken.
constexpr double kConservativeOmegaH = 0.03;

// True if nothing removes energy from the cloth: no spring dashpot, no drag, no stretch limiter.
bool IsConservative(const SimSpec& spec, const ClothModel& model) {
  if (model.drag_N_s_per_m > 0.0) return false;
  if (spec.provot.enabled && !model.provot_families.empty()) return false;
  for (const SpringFamily& f : model.spring_families) {
    if (f.damping_N_s_per_m > 0.0) return false;
  }
  return true;
}

// The longest substep auto gives a conservative cloth, s: omega_max h = kConservativeOmegaH.
double ConservativeAutoStep(const ClothModel& model) {
  return kConservativeOmegaH / model.omega_max_rad_per_s;
}

}  // namespace

Vec3 PinOffset(const PinMotionSpec& m, double t_s) {
  if (t_s < m.start_s) return Vec3::Zero();
  const double drift_s = std::min(t_s, m.stop_s) - m.start_s;
  return m.velocity_m_per_s * drift_s +
         m.amplitude_m * std::sin(2.0 * M_PI * m.frequency_hz * (t_s - m.start_s));
}

Vec3 PinVelocity(const PinMotionSpec& m, double t_s) {
  if (t_s < m.start_s) return Vec3::Zero();
  const double omega = 2.0 * M_PI * m.frequency_hz;
  const Vec3 drift = t_s < m.stop_s ? m.velocity_m_per_s : Vec3::Zero();
  return drift + m.amplitude_m * omega * std::cos(omega * (t_s - m.start_s));
}

int64_t ProvotPairCount(const ClothModel& model) {
  int64_t pairs = 0;
  for (const ProvotFamily& f : model.provot_families) {
    pairs += static_cast<int64_t>(std::max(0, model.width - std::abs(f.dc))) *
             std::max(0, model.height - f.dr);
  }
  return pairs;
}

ClothModel BuildClothModel(const SimSpec& spec) {
  const ClothSpec& cs = spec.cloth;
  // Validate the cloth, field by field.
  if (cs.width < 2 || cs.width > kMaxGridSide) {
    Fail("cloth.width", "must be in [2, " + Show(kMaxGridSide) + "], got " + Show(cs.width));
  }
  if (cs.height < 2 || cs.height > kMaxGridSide) {
    Fail("cloth.height", "must be in [2, " + Show(kMaxGridSide) + "], got " + Show(cs.height));
  }
  if (int64_t{cs.width} * cs.height > kMaxParticles) {
    Fail("cloth.width", "width * height must be <= " + Show(kMaxParticles) + ", got " +
                            Show(int64_t{cs.width} * cs.height));
  }
  RequirePositive("cloth.spacing_m", cs.spacing_m);
  RequirePositive("cloth.mass_kg", cs.mass_kg);
  RequireFiniteVec("cloth.origin_m", cs.origin_m);
  RequireUnitVec("cloth.u_axis", cs.u_axis);
  RequireUnitVec("cloth.v_axis", cs.v_axis);
  if (std::abs(cs.u_axis.dot(cs.v_axis)) > kUnitTolerance) {
    Fail("cloth.v_axis",
         "must be orthogonal to u_axis, got dot product " + Show(cs.u_axis.dot(cs.v_axis)));
  }
  ValidateSpring("cloth.structural", cs.structural);
  ValidateSpring("cloth.shear", cs.shear);
  ValidateSpring("cloth.bend", cs.bend);
  RequireNonNegative("cloth.drag_N_s_per_m", cs.drag_N_s_per_m);
  RequireFiniteVec("cloth.gravity_m_per_s2", cs.gravity_m_per_s2);
  for (size_t k = 0; k < cs.obstacles.size(); ++k) {
    ValidateObstacle("cloth.obstacles[" + Show(k) + "]", cs.obstacles[k]);
  }
  ValidateIntegration(spec.integration);
  ValidateProvot(spec.provot);

  ClothModel model;
  model.width = cs.width;
  model.height = cs.height;
  model.spacing_m = cs.spacing_m;
  model.obstacles = cs.obstacles;
  model.gravity_m_per_s2 = cs.gravity_m_per_s2;
  model.drag_N_s_per_m = cs.drag_N_s_per_m;
  const IntegrationSpec& is = spec.integration;
  model.integrator = is.integrator;
  model.auto_substeps = is.substeps == 0;
  model.frame_rate_hz = is.frame_rate_hz;
  model.max_frame_dt_s = is.max_frame_dt_s;
  model.cg_max_iterations = is.cg_max_iterations;
  model.cg_tolerance = is.cg_tolerance;
  model.provot_enabled = spec.provot.enabled;
  model.provot_iterations = spec.provot.iterations;
  model.provot_coarse_sweeps = spec.provot.coarse_sweeps;
  model.patch_provot_iterations = spec.provot.patch_iterations.value_or(spec.provot.iterations);
  if (spec.self_collision) {
    const SelfCollisionSpec& sc = *spec.self_collision;
    if (!(sc.thickness_m > 0.0) || !(sc.thickness_m < 0.5 * cs.spacing_m)) {
      Fail("self_collision.thickness_m",
           "must be in (0, cloth.spacing_m / 2), got " + Show(sc.thickness_m));
    }
    if (sc.iterations < 0 || sc.iterations > 100) {
      Fail("self_collision.iterations", "must be in [0, 100], got " + Show(sc.iterations));
    }
    if (!(sc.friction >= 0.0)) Fail("self_collision.friction", "must be >= 0");
    if (sc.repulsion_stiffness_N_per_m && !(*sc.repulsion_stiffness_N_per_m >= 0.0)) {
      Fail("self_collision.repulsion_stiffness_N_per_m", "must be >= 0");
    }
    model.self_collision_enabled = true;
    model.self_collision_count_intersections = sc.count_intersections;
    model.self_collision_guard_proxy = sc.guard_proxy;
    SelfCollisionSettings& set = model.self_collision;
    set.thickness_m = sc.thickness_m;
    set.method = sc.method;
    set.iterations = sc.iterations;
    set.friction = sc.friction;
    set.fail_safe = sc.fail_safe;
    set.passes_per_frame = sc.passes_per_frame;
    set.min_passes_per_frame = sc.min_passes_per_frame;
    set.slow_pass_motion = sc.slow_pass_motion;
    set.hand_pass_motion = sc.hand_pass_motion;
    // Bridson et al. 2002 §7.2 take the repulsion spring's k from the cloth's stretch stiffness.
    set.repulsion_stiffness_N_per_m = sc.repulsion_stiffness_N_per_m.value_or(
        cs.structural ? cs.structural->stiffness_N_per_m : 1.0);
  }
  const int32_t n = model.num_particles();

  // Rest places and uniform masses (001 §6.1: the cloth's mass is divided uniformly).
  model.rest_position_m.resize(static_cast<size_t>(n));
  for (int32_t r = 0; r < cs.height; ++r) {
    for (int32_t c = 0; c < cs.width; ++c) {
      model.rest_position_m[GridIndex(cs.width, c, r)] =
          cs.origin_m + (c * cs.spacing_m) * cs.u_axis + (r * cs.spacing_m) * cs.v_axis;
    }
  }
  model.particle_mass_kg = cs.mass_kg / n;
  model.inv_mass_per_kg.assign(static_cast<size_t>(n), 1.0 / model.particle_mass_kg);

  // Pins: each held particle once; a particle two pins hold must get the same motion from both.
  std::vector<int32_t> holder(static_cast<size_t>(n), -1);
  for (size_t k = 0; k < cs.pins.size(); ++k) {
    const std::string field = "cloth.pins[" + Show(k) + "]";
    ValidateMotion(field + ".motion", cs.pins[k].motion);
    for (const auto& [c, r] : PinParticles(field, cs.pins[k], cs.width, cs.height)) {
      const int32_t p = GridIndex(cs.width, c, r);
      if (holder[p] >= 0) {
        if (!SameMotion(cs.pins[holder[p]].motion, cs.pins[k].motion)) {
          Fail(field, "particle (" + Show(c) + ", " + Show(r) + ") is already held by cloth.pins[" +
                          Show(holder[p]) + "] with a different motion");
        }
        continue;
      }
      holder[p] = static_cast<int32_t>(k);
      model.pinned.push_back(p);
      model.pin_spec.push_back(static_cast<int32_t>(k));
      model.pin_motion.push_back(cs.pins[k].motion);
      model.pin_scripted.push_back(IsScripted(cs.pins[k].motion) ? 1 : 0);
      model.inv_mass_per_kg[p] = 0.0;
    }
  }

  // Springs of the declared types only, grouped by type (001 §2, Figure 1).
  if (cs.structural) {
    AddSprings(&model, *cs.structural, SpringType::kStructural, 1, 0);
    AddSprings(&model, *cs.structural, SpringType::kStructural, 0, 1);
  }
  if (cs.shear) {
    AddSprings(&model, *cs.shear, SpringType::kShear, 1, 1);
    AddSprings(&model, *cs.shear, SpringType::kShear, -1, 1);
  }
  if (cs.bend) {
    AddSprings(&model, *cs.bend, SpringType::kBend, 2, 0);
    AddSprings(&model, *cs.bend, SpringType::kBend, 0, 2);
  }
  model.triangles = MakeGridTriangles(cs.width, cs.height);
  if (spec.provot.enabled) {
    model.provot_families = BuildProvotFamilies(model, spec.provot);
    model.provot_movable.resize(model.inv_mass_per_kg.size());
    for (size_t p = 0; p < model.inv_mass_per_kg.size(); ++p) {
      model.provot_movable[p] = model.inv_mass_per_kg[p] > 0.0 ? 1.0f : 0.0f;
    }
    // The finishing worklist holds the spring families' own limits; the sweeps aim below them.
    if (spec.provot.finish) {
      for (const ProvotFamily& f : model.provot_families) {
        if (f.level != 1) continue;
        model.limit_families.push_back({f.dc, f.dr, f.dr * model.width + f.dc, f.max_length_m,
                                        f.max_length_m * f.max_length_m});
      }
    }
    if (spec.provot.long_range_attachments) {
      model.attachments = BuildAttachments(model, spec.provot);
      DenseAttachments(&model);
    }
  }

  // Substeps: fixed, or derived from the integrator's stability limit with the safety factor.
  ComputeFrequencyBounds(spec, &model);
  model.stable_dt_s = StableStep(model, is.integrator);
  const double frame_s = 1.0 / is.frame_rate_hz;
  if (is.substeps > 0) {
    model.substeps = is.substeps;
  } else if (std::isinf(model.stable_dt_s)) {
    model.substeps = 1;  // implicit Euler (or no free particle): one step per frame is stable
  } else if (!(model.stable_dt_s > 0.0)) {
    Fail("integration.substeps",
         "auto found no stable step for this integrator (it needs damping or drag on the stiffest "
         "mode); give a fixed count");
  } else {
    // Auto (docs/scenes.md, [integration]): h <= auto_safety x the stable step, the largest h at
    // which no mode of the linearised cloth grows (for leapfrog without damping, omega_max h < 2;
    // the default safety 0.5 keeps omega_max h <= 1, 0.75 (scenes/curtain_128.toml, with the
    // finishing limiter) omega_max h <= 1.5, and the grid-symbol omega_max is itself an upper
    // bound). That keeps every damped or stretch-limited cloth bounded for as
    // long as it runs: the dashpots, the drag or Provot's inelastic projections remove what
    // leapfrog's local errors add (felt bench stability: the damped hour, and the undamped 10 x 10
    // curtain with Provot on, 600 s at 2 substeps, never 1e-6 J above its start).
    // A conservative cloth (no dashpot, no drag, no limiter) is different: it stretches under its
    // own weight (7 x for the 10 x 10 curtain) and folds springs to near zero length, where the
    // spring's energy k (l - L)^2 / 2 has a cone (the force flips direction through l = 0). The
    // symplectic bound on leapfrog's energy error needs a smooth energy (Hairer, Lubich & Wanner,
    // Geometric Numerical Integration, ch. IX), so each passage adds an error that nothing removes
    // and the energy climbs even far inside the stability bound (omega_max h = 0.76 at the 2
    // substeps the stable step gives the 10 x 10 curtain). For it auto takes an accuracy bound
    // instead, omega_max h <= kConservativeOmegaH (ConservativeAutoStep).
    double h_auto = is.auto_safety * model.stable_dt_s;
    if (IsConservative(spec, model)) h_auto = std::min(h_auto, ConservativeAutoStep(model));
    const double count = std::ceil(frame_s / h_auto);
    if (count > kMaxSubstepsPerFrame) {
      Fail("integration.substeps",
           "auto needs " + Show(count) + " substeps per frame (stable step " +
               Show(model.stable_dt_s) + " s), over the limit " + Show(kMaxSubstepsPerFrame) +
               "; soften the springs or add mass");
    }
    model.substeps = std::max(1, static_cast<int32_t>(count));
  }
  return model;
}

ClothState MakeClothState(const ClothModel& model) {
  const size_t n = static_cast<size_t>(model.num_particles());
  ClothState state;
  state.x = model.rest_position_m;
  state.v.assign(n, Vec3::Zero());
  state.normals.assign(n, Vec3::Zero());
  ComputeVertexNormals(state.x, model.triangles, state.normals);
  state.scratch = std::make_unique<ClothState::Scratch>();
  ClothState::Scratch& s = *state.scratch;
  for (std::vector<Vec3>* a : {&s.force_N, &s.external_N, &s.accel, &s.x_stage, &s.v_stage,
                               &s.kx_sum, &s.kv_sum, &s.x_start, &s.a_last, &s.x_prev}) {
    a->assign(n, Vec3::Zero());
  }
  s.restart.assign(n, 0);
  s.soa.assign(12 * SoaStride(static_cast<size_t>(n)), 0.0);
  s.stream_rows.assign(StreamScratchSize(model), 0.0);
  s.coupling_rows.unsorted.assign(kMaxCouplingTerms, CouplingTerm{});
  s.coupling_rows.sorted.assign(kMaxCouplingTerms, CouplingTerm{});
  s.coupling_rows.row_start.assign(static_cast<size_t>(model.height) + 1, 0);
  s.coupling_rows.cursor.assign(static_cast<size_t>(model.height), 0);
  s.provot_soa.assign(3 * ProvotSoaStride(n), 0.0f);
  s.limit_queued.assign(model.limit_families.size() * n, 0);
  s.limit_ring.assign(std::max<size_t>(1, model.limit_families.size() * n), 0);
  s.limit_logged.assign(model.limit_families.empty() ? 0 : n, 0);
  s.limit_log_index.assign(model.limit_families.empty() ? 0 : n, 0);
  s.limit_log_xv.assign(model.limit_families.empty() ? 0 : 6 * n, 0.0);
  if (model.integrator == IntegratorKind::kImplicitEuler) {
    BuildImplicitPattern(model, &s);
  }
  // Pins start where their script puts them at t = 0; that is the first good state.
  ApplyPins(model, 0.0, &state);
  if (model.self_collision_enabled) {
    s.self_collision.emplace(model.triangles, state.x, model.inv_mass_per_kg, model.self_collision);
    if (model.self_collision_count_intersections) state.counters.self_intersections_max = 0;
  }
  s.good_x = state.x;
  s.good_v = state.v;
  return state;
}

void ResetIntegratorHistory(ClothState* state) { state->scratch->history_valid = false; }

ClothState::ClothState() = default;
ClothState::~ClothState() = default;
ClothState::ClothState(ClothState&& other) noexcept = default;
ClothState& ClothState::operator=(ClothState&& other) noexcept = default;

ClothState::ClothState(const ClothState& other)
    : x(other.x),
      v(other.v),
      normals(other.normals),
      time_s(other.time_s),
      counters(other.counters),
      scratch(other.scratch ? std::make_unique<Scratch>(*other.scratch) : nullptr) {}

ClothState& ClothState::operator=(const ClothState& other) {
  if (this != &other) *this = ClothState(other);
  return *this;
}

}  // namespace felt
