#include "collision/spatial_hash.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace felt {
namespace {

// Cell coordinates are clamped to this so that they and their differences fit an int32.
constexpr double kMaxCell = 1 << 29;

bool IsPrime(int64_t n) {
  if (n < 2) return false;
  for (int64_t d = 2; d * d <= n; ++d) {
    if (n % d == 0) return false;
  }
  return true;
}

int32_t CellCoord(double v, double inv_cell) {
  double f = std::floor(v * inv_cell);
  if (!(f >= -kMaxCell)) f = -kMaxCell;  // also maps NaN
  if (f > kMaxCell) f = kMaxCell;
  return static_cast<int32_t>(f);
}

}  // namespace

SpatialHash::SpatialHash(std::shared_ptr<const std::vector<Triangle>> triangles,
                         std::span<const Vec3> x, const SpatialHashOptions& options)
    : options_(options), triangles_(std::move(triangles)) {
  if (!triangles_) throw std::invalid_argument("SpatialHash: triangles must not be null");
  const std::vector<Triangle>& tris = *triangles_;
  for (size_t i = 0; i < tris.size(); ++i) {
    for (int32_t v : tris[i]) {
      if (v < 0 || static_cast<size_t>(v) >= x.size()) {
        throw std::invalid_argument("SpatialHash: triangle " + std::to_string(i) +
                                    " has vertex index " + std::to_string(v) + " outside [0, " +
                                    std::to_string(x.size()) + ")");
      }
    }
  }
  if (!(options_.cell_size_m >= 0.0) || !std::isfinite(options_.cell_size_m)) {
    throw std::invalid_argument("SpatialHashOptions.cell_size_m: must be finite and >= 0, got " +
                                std::to_string(options_.cell_size_m));
  }
  if (options_.table_size < 0) {
    throw std::invalid_argument("SpatialHashOptions.table_size: must be >= 0, got " +
                                std::to_string(options_.table_size));
  }
  if (options_.max_cells_per_triangle < 1) {
    throw std::invalid_argument("SpatialHashOptions.max_cells_per_triangle: must be >= 1, got " +
                                std::to_string(options_.max_cells_per_triangle));
  }
  // Cell size: the average edge length (Teschner 2003 §5), unless given.
  cell_size_m_ = options_.cell_size_m;
  if (cell_size_m_ == 0.0) {
    double sum = 0.0;
    for (const Triangle& t : tris) {
      sum += (x[t[1]] - x[t[0]]).norm() + (x[t[2]] - x[t[1]]).norm() + (x[t[0]] - x[t[2]]).norm();
    }
    cell_size_m_ = tris.empty() ? 1.0 : sum / (3.0 * static_cast<double>(tris.size()));
    if (!(cell_size_m_ > 0.0) || !std::isfinite(cell_size_m_)) cell_size_m_ = 1.0;
  }
  inv_cell_ = 1.0 / cell_size_m_;
  // Table size: a prime (Teschner 2003 §4).
  int64_t n = options_.table_size;
  if (n == 0) {
    n = std::max<int64_t>(17, 4 * static_cast<int64_t>(tris.size()));
    while (!IsPrime(n)) ++n;
  }
  table_size_ = static_cast<int32_t>(n);
  // Everything sized once.
  bucket_start_.assign(static_cast<size_t>(table_size_) + 1, 0);
  cursor_.assign(static_cast<size_t>(table_size_), 0);
  entries_.assign(tris.size() * static_cast<size_t>(options_.max_cells_per_triangle), 0);
  range_.resize(tris.size());
  oversized_.assign(tris.size(), 0);
  Repair(x);
}

SpatialHash::CellRange SpatialHash::CellsOf(const Vec3& lo, const Vec3& hi) const {
  CellRange c;
  for (int i = 0; i < 3; ++i) {
    c.lo[i] = CellCoord(lo[i], inv_cell_);
    c.hi[i] = CellCoord(hi[i], inv_cell_);
  }
  return c;
}

int32_t SpatialHash::Bucket(int32_t ix, int32_t iy, int32_t iz) const {
  // Teschner 2003 eq. (1): (x p1 xor y p2 xor z p3) mod n with three large primes; unsigned
  // arithmetic wraps instead of overflowing.
  const uint32_t h = (static_cast<uint32_t>(ix) * 73856093u) ^
                     (static_cast<uint32_t>(iy) * 19349663u) ^
                     (static_cast<uint32_t>(iz) * 83492791u);
  return static_cast<int32_t>(h % static_cast<uint32_t>(table_size_));
}

RepairStats SpatialHash::Repair(std::span<const Vec3> x) {
  covers_motion_ = false;
  return Rehash(x, {});
}

RepairStats SpatialHash::RepairSwept(std::span<const Vec3> x_old, std::span<const Vec3> x_new) {
  covers_motion_ = true;
  return Rehash(x_old, x_new);
}

RepairStats SpatialHash::Rehash(std::span<const Vec3> x0, std::span<const Vec3> x1) {
  const std::vector<Triangle>& tris = *triangles_;
  const int64_t max_cells = options_.max_cells_per_triangle;
  std::fill(bucket_start_.begin(), bucket_start_.end(), 0);
  num_oversized_ = 0;
  lo_ = Vec3::Constant(std::numeric_limits<double>::infinity());
  hi_ = Vec3::Constant(-std::numeric_limits<double>::infinity());
  // Pass 1: each triangle's cells; count entries per bucket.
  for (size_t i = 0; i < tris.size(); ++i) {
    const Triangle& t = tris[i];
    Vec3 lo = x0[t[0]].cwiseMin(x0[t[1]]).cwiseMin(x0[t[2]]);
    Vec3 hi = x0[t[0]].cwiseMax(x0[t[1]]).cwiseMax(x0[t[2]]);
    if (!x1.empty()) {
      lo = lo.cwiseMin(x1[t[0]]).cwiseMin(x1[t[1]]).cwiseMin(x1[t[2]]);
      hi = hi.cwiseMax(x1[t[0]]).cwiseMax(x1[t[1]]).cwiseMax(x1[t[2]]);
    }
    lo_ = lo_.cwiseMin(lo);
    hi_ = hi_.cwiseMax(hi);
    const CellRange c = CellsOf(lo, hi);
    range_[i] = c;
    const int64_t cells =
        int64_t{c.hi[0] - c.lo[0] + 1} * (c.hi[1] - c.lo[1] + 1) * (c.hi[2] - c.lo[2] + 1);
    if (cells > max_cells) {
      oversized_[num_oversized_++] = static_cast<int32_t>(i);
      range_[i].hi[0] = c.lo[0] - 1;  // empty range: never matched in a bucket
      continue;
    }
    for (int32_t iz = c.lo[2]; iz <= c.hi[2]; ++iz)
      for (int32_t iy = c.lo[1]; iy <= c.hi[1]; ++iy)
        for (int32_t ix = c.lo[0]; ix <= c.hi[0]; ++ix) ++bucket_start_[Bucket(ix, iy, iz) + 1];
  }
  // Prefix sums: bucket b's entries are [bucket_start_[b], bucket_start_[b + 1]).
  for (int32_t b = 0; b < table_size_; ++b) bucket_start_[b + 1] += bucket_start_[b];
  std::copy(bucket_start_.begin(), bucket_start_.end() - 1, cursor_.begin());
  // Pass 2: write the triangle ids.
  for (size_t i = 0; i < tris.size(); ++i) {
    const CellRange& c = range_[i];
    for (int32_t iz = c.lo[2]; iz <= c.hi[2]; ++iz)
      for (int32_t iy = c.lo[1]; iy <= c.hi[1]; ++iy)
        for (int32_t ix = c.lo[0]; ix <= c.hi[0]; ++ix)
          entries_[cursor_[Bucket(ix, iy, iz)]++] = static_cast<int32_t>(i);
  }
  num_entries_ = bucket_start_[table_size_];
  RepairStats stats;
  stats.entries = num_entries_;
  stats.leaves_refit = static_cast<int32_t>(tris.size());
  return stats;
}

template <class Test>
void SpatialHash::VisitCells(const CellRange& q, Test&& test) const {
  for (int32_t iz = q.lo[2]; iz <= q.hi[2]; ++iz) {
    for (int32_t iy = q.lo[1]; iy <= q.hi[1]; ++iy) {
      for (int32_t ix = q.lo[0]; ix <= q.hi[0]; ++ix) {
        const int32_t b = Bucket(ix, iy, iz);
        for (int32_t e = bucket_start_[b]; e < bucket_start_[b + 1]; ++e) {
          const int32_t tri = entries_[e];
          const CellRange& c = range_[tri];
          // Skip hash collisions (the triangle is not in this cell) and repeats (test it only in
          // the first cell its range shares with the query's).
          if (ix < c.lo[0] || ix > c.hi[0] || iy < c.lo[1] || iy > c.hi[1] || iz < c.lo[2] ||
              iz > c.hi[2]) {
            continue;
          }
          if (ix != std::max(c.lo[0], q.lo[0]) || iy != std::max(c.lo[1], q.lo[1]) ||
              iz != std::max(c.lo[2], q.lo[2])) {
            continue;
          }
          test(tri);
        }
      }
    }
  }
}

WithinResult SpatialHash::TrianglesWithin(std::span<const Vec3> x, const Vec3& p, double r,
                                          std::span<PointContact> out, bool ids_only) const {
  WithinAccumulator acc{p, r, out, {}, ids_only};
  const std::vector<Triangle>& tris = *triangles_;
  const auto test = [&](int32_t tri) { acc.Test(tri, tris[tri], x); };
  const double reach = r + CullSlack(p, p, r);
  const CellRange q = CellsOf(p.array() - reach, p.array() + reach);
  const int64_t cells =
      int64_t{q.hi[0] - q.lo[0] + 1} * (q.hi[1] - q.lo[1] + 1) * (q.hi[2] - q.lo[2] + 1);
  if (cells > std::max<int64_t>(64, static_cast<int64_t>(tris.size()))) {
    // A query box wider than the cloth's worth of cells: testing everything is cheaper.
    TestEveryTriangle(tris.size(), test);
    return acc.result;
  }
  for (int32_t k = 0; k < num_oversized_; ++k) test(oversized_[k]);
  VisitCells(q, test);
  return acc.result;
}

template <class Test, class Bound>
void SpatialHash::WalkSegment(const Vec3& p0, const Vec3& p1, double r, Test&& test,
                              Bound&& bound) const {
  const std::vector<Triangle>& tris = *triangles_;
  if (tris.empty()) return;
  const Vec3 d = p1 - p0;
  const double reach = r + CullSlack(p0, p1, r);
  // Clip [0, 1] to the hashed region enlarged by reach (slab test, Ericson §5.3.3).
  double ta = 0.0;
  double tb = 1.0;
  for (int i = 0; i < 3; ++i) {
    const double lo = lo_[i] - reach;
    const double hi = hi_[i] + reach;
    if (d[i] == 0.0) {
      if (p0[i] < lo || p0[i] > hi) return;
      continue;
    }
    double t0 = (lo - p0[i]) / d[i];
    double t1 = (hi - p0[i]) / d[i];
    if (t0 > t1) std::swap(t0, t1);
    ta = std::max(ta, t0);
    tb = std::min(tb, t1);
    if (ta > tb) return;
  }
  for (int32_t k = 0; k < num_oversized_; ++k) test(oversized_[k]);
  // Pieces about one cell long; each piece's box enlarged by reach covers every contact in it.
  const double length = d.norm() * (tb - ta);
  const int64_t pieces = std::max<int64_t>(1, static_cast<int64_t>(std::ceil(length * inv_cell_)));
  const double piece_len = length / static_cast<double>(pieces);
  const int64_t span_cells =
      static_cast<int64_t>(std::ceil((piece_len + 2 * reach) * inv_cell_)) + 1;
  if (pieces * span_cells * span_cells * span_cells >
      std::max<int64_t>(64, static_cast<int64_t>(tris.size()))) {
    // Too many cells to visit: testing every triangle is cheaper (and exact).
    TestEveryTriangle(tris.size(), test);
    return;
  }
  for (int64_t k = 0; k < pieces; ++k) {
    const double ts = ta + (tb - ta) * static_cast<double>(k) / static_cast<double>(pieces);
    const double te = ta + (tb - ta) * static_cast<double>(k + 1) / static_cast<double>(pieces);
    // Every contact up to `ts` was in an earlier piece.
    if (ts > bound()) return;
    const Vec3 a = p0 + ts * d;
    const Vec3 b = p0 + te * d;
    VisitCells(CellsOf(a.cwiseMin(b).array() - reach, a.cwiseMax(b).array() + reach), test);
  }
}

SweepHit SpatialHash::SweepSphere(std::span<const Vec3> x, const Vec3& p0, const Vec3& p1,
                                  double r) const {
  SweepAccumulator acc{p0, p1, r, {}};
  const std::vector<Triangle>& tris = *triangles_;
  WalkSegment(
      p0, p1, r, [&](int32_t tri) { acc.Test(tri, tris[tri], x); }, [&] { return acc.bound(); });
  return acc.best;
}

SweepHit SpatialHash::SweepSphereMoving(std::span<const Vec3> x_old, std::span<const Vec3> x_new,
                                        const Vec3& c0, const Vec3& c1, double r,
                                        const MovingContactOptions& options) const {
  return SweepMovingOver(*triangles_, x_old, x_new, c0, c1, r, options, covers_motion_,
                         [&](const auto& test, const MovingAccumulator& acc) {
                           WalkSegment(c0, c1, r, test, [&] { return acc.bound(); });
                         });
}

}  // namespace felt
