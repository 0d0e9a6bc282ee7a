#include "proxy/local_cloth.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace felt {
namespace {

// Squared distance from point c to segment [p0, p1].
double SegmentPointDistance2(const Vec3& p0, const Vec3& p1, const Vec3& c) {
  const Vec3 d = p1 - p0;
  const double len2 = d.squaredNorm();
  double s = len2 > 0.0 ? (c - p0).dot(d) / len2 : 0.0;
  s = std::clamp(s, 0.0, 1.0);
  return (p0 + s * d - c).squaredNorm();
}

// Whether a sphere of radius r moving along [p0, p1] can reach the triangle's bounding sphere.
bool MayReach(const LocalTriangle& t, const Vec3& p0, const Vec3& p1, double r) {
  const double reach = t.radius_m + r;
  // Relative slack so that rounding never culls a triangle the exact test would accept.
  const double slack = CullSlack(p0, p1, r);
  return SegmentPointDistance2(p0, p1, t.center) <= (reach + slack) * (reach + slack);
}

// Keeps the earliest contact (lowest toi, then lowest triangle index), as SweepAccumulator does.
void Keep(int32_t tri, const SweepContact& sc, SweepHit* best) {
  if (!sc.hit) return;
  if (best->hit && (sc.toi > best->toi || (sc.toi == best->toi && tri > best->triangle))) return;
  *best = {true, sc.toi, tri, sc.point, sc.normal, sc.barycentric};
}

}  // namespace

Vec3 ClothView::Normal(int32_t i) const {
  if (patch_role != nullptr && patch_role[i] == PatchRole::kFree) return patch->NormalAt(i);
  const Vec3 n = from->normals[i] + alpha * (to->normals[i] - from->normals[i]);
  const double len = n.norm();
  return len > 0.0 ? Vec3(n / len) : Vec3::Zero();
}

void ClothView::Corners(int32_t t, Vec3* a, Vec3* b, Vec3* c) const {
  const Triangle& tri = (*to->triangles)[t];
  *a = Position(tri[0]);
  *b = Position(tri[1]);
  *c = Position(tri[2]);
}

LocalCloth::LocalCloth(int32_t capacity) {
  if (capacity < 1) throw std::invalid_argument("LocalCloth: capacity must be >= 1");
  found_.resize(static_cast<size_t>(capacity));
  tris_.resize(static_cast<size_t>(capacity));
}

bool LocalCloth::Gather(const ClothSnapshot& query, double inflation_m, const ClothView& now,
                        const ClothView* before, const Vec3& center_W, double radius_m,
                        double patch_offset_m) {
  // Query 1 on the snapshot's own positions, enlarged by how far the tick's cloth may lie from it.
  size_ = 0;
  query_ = &query;
  // Only which triangles (the sweeps test them exactly): ids_only.
  WithinResult within =
      TrianglesWithin(query.structure, query.x, center_W,
                      radius_m + std::max(inflation_m, patch_offset_m), found_, true);
  bool overflow = within.overflowed();
  if (now.patch != nullptr && overflow) {
    // Mode patch, and the patch lies so far from the snapshot that the enlarged query overflows:
    // the triangles with a corner in a window are taken from the windows at their own positions
    // (GatherPatch) and the query, enlarged by `inflation_m` alone, gives the rest.
    within =
        TrianglesWithin(query.structure, query.x, center_W, radius_m + inflation_m, found_, true);
    overflow = within.overflowed();
    for (size_t k = 0; k < static_cast<size_t>(within.written); ++k) {
      const int32_t tri = found_[k].triangle;
      if (!TouchesPatch(now, tri)) Place(tri, now, before, &tris_[size_++]);
    }
    if (!overflow) overflow = !GatherPatch(now, before, center_W, radius_m);
  } else {
    for (size_t k = 0; k < static_cast<size_t>(within.written); ++k) {
      Place(found_[k].triangle, now, before, &tris_[size_++]);
    }
  }
  fallback_ = overflow;
  return !overflow;
}

bool LocalCloth::TouchesPatch(const ClothView& now, int32_t triangle) {
  const Triangle& t = (*now.to->triangles)[static_cast<size_t>(triangle)];
  return now.patch_role[t[0]] != PatchRole::kOutside ||
         now.patch_role[t[1]] != PatchRole::kOutside || now.patch_role[t[2]] != PatchRole::kOutside;
}

void LocalCloth::Place(int32_t triangle, const ClothView& now, const ClothView* before,
                       LocalTriangle* t) {
  // The triangle at this tick's cloth (and the previous tick's), with a bounding sphere over both
  // for cheap culling in the sweeps.
  t->triangle = triangle;
  now.Corners(triangle, &t->a, &t->b, &t->c);
  if (before != nullptr) {
    before->Corners(triangle, &t->a0, &t->b0, &t->c0);
  } else {
    t->a0 = t->a;
    t->b0 = t->b;
    t->c0 = t->c;
  }
  t->center = (t->a + t->b + t->c + t->a0 + t->b0 + t->c0) / 6.0;
  const double r2 =
      std::max({(t->a - t->center).squaredNorm(), (t->b - t->center).squaredNorm(),
                (t->c - t->center).squaredNorm(), (t->a0 - t->center).squaredNorm(),
                (t->b0 - t->center).squaredNorm(), (t->c0 - t->center).squaredNorm()});
  t->radius_m = std::sqrt(r2);
  t->lo = t->a.cwiseMin(t->b).cwiseMin(t->c);
  t->hi = t->a.cwiseMax(t->b).cwiseMax(t->c);
}

bool LocalCloth::GatherPatch(const ClothView& now, const ClothView* before, const Vec3& center_W,
                             double radius_m) {
  // Every triangle with a corner in a window lies in a grid cell of the window grown by one
  // particle up and left (MakeGridTriangles: cell (c, r) holds triangles 2 (r (W - 1) + c) and the
  // next). Blocks of kBlock x kBlock cells are culled by the bounding box of their particles now
  // and before (the sphere-box distance, Ericson 2005 §5.1.3), then each triangle by its bounding
  // sphere: a superset of the triangles within radius_m, as the structure's query gives.
  constexpr int32_t kBlock = 4;
  const int32_t width = now.patch->width();
  const int32_t height = static_cast<int32_t>(now.to->x.size()) / width;
  const double reach = radius_m + CullSlack(center_W, center_W, radius_m);
  for (const PatchWindow& w : now.patch->windows()) {
    const int32_t c_lo = std::max(0, w.col0 - 1), c_hi = std::min(width - 2, w.col1);
    const int32_t r_lo = std::max(0, w.row0 - 1), r_hi = std::min(height - 2, w.row1);
    for (int32_t br = r_lo; br <= r_hi; br += kBlock) {
      for (int32_t bc = c_lo; bc <= c_hi; bc += kBlock) {
        const int32_t c_end = std::min(c_hi, bc + kBlock - 1),
                      r_end = std::min(r_hi, br + kBlock - 1);
        Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
        Vec3 hi = -lo;
        for (int32_t row = br; row <= r_end + 1; ++row) {
          for (int32_t col = bc; col <= c_end + 1; ++col) {
            const int32_t p = row * width + col;
            const Vec3 x = now.Position(p);
            lo = lo.cwiseMin(x);
            hi = hi.cwiseMax(x);
            if (before != nullptr) {
              const Vec3 x0 = before->Position(p);
              lo = lo.cwiseMin(x0);
              hi = hi.cwiseMax(x0);
            }
          }
        }
        const Vec3 nearest = center_W.cwiseMax(lo).cwiseMin(hi);
        if ((nearest - center_W).squaredNorm() > reach * reach) continue;
        for (int32_t row = br; row <= r_end; ++row) {
          for (int32_t col = bc; col <= c_end; ++col) {
            const int32_t first = 2 * (row * (width - 1) + col);
            for (int32_t tri = first; tri < first + 2; ++tri) {
              if (!TouchesPatch(now, tri)) continue;
              LocalTriangle t;
              Place(tri, now, before, &t);
              const double d = reach + t.radius_m;
              if ((t.center - center_W).squaredNorm() > d * d) continue;
              if (size_ == tris_.size()) return false;
              tris_[size_++] = t;
            }
          }
        }
      }
    }
  }
  return true;
}

bool LocalCloth::Corners(int32_t triangle, Vec3* a, Vec3* b, Vec3* c) const {
  for (size_t k = 0; k < size_; ++k) {
    const LocalTriangle& t = tris_[k];
    if (t.triangle != triangle) continue;
    *a = t.a;
    *b = t.b;
    *c = t.c;
    return true;
  }
  if (!fallback_ || query_ == nullptr || triangle < 0 || triangle >= query_->num_triangles()) {
    return false;
  }
  ClothView::Of(*query_).Corners(triangle, a, b, c);
  return true;
}

SweepHit LocalCloth::Sweep(const Vec3& p0, const Vec3& p1, double r) const {
  // Overflow: the structure's own exact query on the snapshot it was repaired for.
  if (fallback_) return SweepSphere(query_->structure, query_->x, p0, p1, r);
  SweepHit best;
  // The sphere's path stays in the box of its ends grown by r: a triangle whose box (the tick's
  // corners) is apart from it cannot be touched (with the relative slack of MayReach).
  const double grow = r + CullSlack(p0, p1, r);
  const Vec3 lo = p0.cwiseMin(p1).array() - grow, hi = p0.cwiseMax(p1).array() + grow;
  for (size_t k = 0; k < size_; ++k) {
    const LocalTriangle& t = tris_[k];
    if ((t.lo.array() > hi.array()).any() || (t.hi.array() < lo.array()).any()) continue;
    if (!MayReach(t, p0, p1, r)) continue;
    Keep(t.triangle, SweepSphereTriangle(p0, p1, r, t.a, t.b, t.c), &best);
  }
  return best;
}

SweepHit LocalCloth::SweepMoving(const Vec3& c0, const Vec3& c1, double r,
                                 std::span<const int32_t> skip, double s0, double s1) const {
  SweepHit best;
  // Corners at s along the motion; the ends exactly (s = 0, 1: the whole tick's motion).
  auto at = [](double s, const Vec3& p0, const Vec3& p1) {
    return s == 0.0 ? p0 : (s == 1.0 ? p1 : Vec3(p0 + s * (p1 - p0)));
  };
  for (size_t k = 0; k < size_; ++k) {
    const LocalTriangle& t = tris_[k];
    if (std::find(skip.begin(), skip.end(), t.triangle) != skip.end()) continue;
    if (!MayReach(t, c0, c1, r)) continue;  // the bounding sphere holds the whole motion
    Keep(t.triangle,
         MovingTriangleSphereContact(c0, c1, r, at(s0, t.a0, t.a), at(s0, t.b0, t.b),
                                     at(s0, t.c0, t.c), at(s1, t.a0, t.a), at(s1, t.b0, t.b),
                                     at(s1, t.c0, t.c)),
         &best);
  }
  return best;
}

}  // namespace felt
