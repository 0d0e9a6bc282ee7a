#include "collision/self_broadphase.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include "base/check.h"
#include "base/simd.h"

namespace felt {
namespace {

// Box padding per side: half the thickness, widened by 1e-5 relative so that a pair the narrow
// phase reports at up to h (1 + kCcdDistanceSlack) (collision/ccd.h) always has overlapping boxes.
double SelfBroadPadding(double thickness_m) { return 0.5 * thickness_m * (1.0 + 1e-5); }

// True when the closed boxes [alo, ahi] and [blo, bhi] share a point.
bool SelfBoxesOverlap(const Vec3& alo, const Vec3& ahi, const Vec3& blo, const Vec3& bhi) {
  return alo.x() <= bhi.x() && blo.x() <= ahi.x() && alo.y() <= bhi.y() && blo.y() <= ahi.y() &&
         alo.z() <= bhi.z() && blo.z() <= ahi.z();
}

// True when triangle t has vertex v as a corner.
bool SelfHasCorner(const Triangle& t, int32_t v) { return t[0] == v || t[1] == v || t[2] == v; }

// True when the edges e and f share a vertex.
bool SelfEdgesTouch(const MeshEdge& e, const MeshEdge& f) {
  return e[0] == f[0] || e[0] == f[1] || e[1] == f[0] || e[1] == f[1];
}

// Smallest prime >= n (n >= 2), by trial division (set-up only).
int32_t SelfNextPrime(int64_t n) {
  for (int64_t p = std::max<int64_t>(n, 2);; ++p) {
    bool prime = true;
    for (int64_t d = 2; d * d <= p; ++d) {
      if (p % d == 0) {
        prime = false;
        break;
      }
    }
    if (prime) return static_cast<int32_t>(p);
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// SelfBroadPhase

SelfBroadPhase::SelfBroadPhase(std::span<const Triangle> triangles, int32_t num_vertices,
                               const SelfBroadPhaseOptions& options)
    : triangles_(triangles.begin(), triangles.end()), num_vertices_(num_vertices) {
  for (const Triangle& t : triangles_) {
    for (int32_t v : t) {
      if (v < 0 || v >= num_vertices) {
        throw std::invalid_argument("self broad phase: triangle index " + std::to_string(v) +
                                    " out of range for " + std::to_string(num_vertices) +
                                    " vertices");
      }
    }
  }
  if (options.max_candidates < 0) {
    throw std::invalid_argument("self broad phase: max_candidates must be >= 0, got " +
                                std::to_string(options.max_candidates));
  }
  edges_ = MeshEdges(triangles_);
  // Each triangle's edges by index into the sorted edge list (-1 for an edge with equal ends).
  triangle_edges_.resize(triangles_.size());
  edge_owner_.assign(edges_.size(), -1);
  vertex_owner_.assign(static_cast<size_t>(num_vertices), -1);
  for (size_t ti = 0; ti < triangles_.size(); ++ti) {
    const Triangle& t = triangles_[ti];
    for (int32_t k = 0; k < 3; ++k) {
      if (vertex_owner_[t[k]] < 0) vertex_owner_[t[k]] = static_cast<int32_t>(ti);
      const int32_t a = t[k], b = t[(k + 1) % 3];
      if (a == b) {
        triangle_edges_[ti][k] = -1;
        continue;
      }
      const MeshEdge e = {std::min(a, b), std::max(a, b)};
      const auto it = std::lower_bound(edges_.begin(), edges_.end(), e);
      FELT_CHECK(it != edges_.end() && *it == e);
      const int32_t id = static_cast<int32_t>(it - edges_.begin());
      triangle_edges_[ti][k] = id;
      if (edge_owner_[id] < 0) edge_owner_[id] = static_cast<int32_t>(ti);
    }
  }
  max_candidates_ = options.max_candidates > 0
                        ? options.max_candidates
                        : 16 * (static_cast<int64_t>(num_vertices) + std::ssize(edges_));
  candidates_.reserve(static_cast<size_t>(max_candidates_));
}

void SelfBroadPhase::Emit(CcdPairHit::Kind kind, int32_t first, int32_t second,
                          SelfBroadPhaseStats* stats) {
  if (kind == CcdPairHit::Kind::kVertexTriangle) {
    ++stats->vertex_triangle;
  } else {
    ++stats->edge_edge;
  }
  if (std::ssize(candidates_) < max_candidates_) {
    candidates_.push_back({kind, first, second});
  } else {
    stats->overflow = true;
  }
}

void SelfBroadPhase::BeginStep(std::span<const Vec3> x0, std::span<const Vec3> x1,
                               double thickness_m) const {
  FELT_CHECK(std::ssize(x0) == num_vertices_ && std::ssize(x1) == num_vertices_);
  FELT_CHECK(thickness_m > 0.0);
}

// ---------------------------------------------------------------------------------------------
// SelfSpatialHash

namespace {

// Integer cell coordinate of c [m] for cell edge `inv_cell` = 1 / cell [1/m], clamped to int32.
int32_t SelfCellOf(double c, double inv_cell) {
  const double f = std::floor(c * inv_cell);
  constexpr double kLim = 1e9;
  return static_cast<int32_t>(std::clamp(f, -kLim, kLim));
}

// Teschner et al. 2003 §4's hash: (x p1 xor y p2 xor z p3) mod n, with their three primes.
int32_t SelfHashCell(int32_t x, int32_t y, int32_t z, int32_t table_size) {
  const uint32_t h = (static_cast<uint32_t>(x) * 73856093u) ^
                     (static_cast<uint32_t>(y) * 19349663u) ^
                     (static_cast<uint32_t>(z) * 83492791u);
  return static_cast<int32_t>(h % static_cast<uint32_t>(table_size));
}

// The cell range [lo, hi] (inclusive) covered by a box.
struct SelfCellRange {
  std::array<int32_t, 3> lo;
  std::array<int32_t, 3> hi;
  int64_t count() const {
    return (static_cast<int64_t>(hi[0]) - lo[0] + 1) * (static_cast<int64_t>(hi[1]) - lo[1] + 1) *
           (static_cast<int64_t>(hi[2]) - lo[2] + 1);
  }
};

SelfCellRange SelfRangeOf(const Vec3& lo, const Vec3& hi, double inv_cell) {
  return {
      {SelfCellOf(lo.x(), inv_cell), SelfCellOf(lo.y(), inv_cell), SelfCellOf(lo.z(), inv_cell)},
      {SelfCellOf(hi.x(), inv_cell), SelfCellOf(hi.y(), inv_cell), SelfCellOf(hi.z(), inv_cell)}};
}

// Calls f(x, y, z) for every cell of the range.
template <class F>
void SelfForEachCell(const SelfCellRange& r, F&& f) {
  for (int32_t z = r.lo[2]; z <= r.hi[2]; ++z) {
    for (int32_t y = r.lo[1]; y <= r.hi[1]; ++y) {
      for (int32_t x = r.lo[0]; x <= r.hi[0]; ++x) f(x, y, z);
    }
  }
}

}  // namespace

SelfSpatialHash::SelfSpatialHash(std::span<const Triangle> triangles, std::span<const Vec3> x,
                                 const SelfBroadPhaseOptions& options)
    : SelfBroadPhase(triangles, static_cast<int32_t>(x.size()), options) {
  if (options.cell_size_m < 0.0 || !std::isfinite(options.cell_size_m)) {
    throw std::invalid_argument("self spatial hash: cell_size_m must be finite and >= 0, got " +
                                std::to_string(options.cell_size_m));
  }
  if (options.max_cells_per_primitive < 1) {
    throw std::invalid_argument("self spatial hash: max_cells_per_primitive must be >= 1, got " +
                                std::to_string(options.max_cells_per_primitive));
  }
  if (options.max_entries < 0) {
    throw std::invalid_argument("self spatial hash: max_entries must be >= 0, got " +
                                std::to_string(options.max_entries));
  }
  // Cell edge: the mean edge length (Teschner 2003 §5), unless given.
  cell_size_m_ = options.cell_size_m;
  if (cell_size_m_ == 0.0) {
    double sum = 0.0;
    for (const MeshEdge& e : edges_) sum += (x[e[1]] - x[e[0]]).norm();
    cell_size_m_ = edges_.empty() ? 1.0 : sum / static_cast<double>(edges_.size());
    if (!(cell_size_m_ > 0.0)) cell_size_m_ = 1.0;
  }
  const int64_t primitives = std::max<int64_t>(num_vertices_, std::ssize(edges_));
  max_cells_ = options.max_cells_per_primitive;
  max_entries_ =
      options.max_entries > 0 ? options.max_entries : 16 * std::max<int64_t>(primitives, 1);
  // Teschner 2003: a prime table size larger than the number of primitives.
  table_size_ = SelfNextPrime(2 * primitives + 1);
  vertex_box_.resize(static_cast<size_t>(num_vertices_));
  edge_box_.resize(edges_.size());
  triangle_box_.resize(triangles_.size());
  bucket_start_.resize(static_cast<size_t>(table_size_) + 1);
  bucket_fill_.resize(static_cast<size_t>(table_size_));
  entries_.resize(static_cast<size_t>(max_entries_));
  hashed_.resize(static_cast<size_t>(primitives));
  oversized_.reserve(static_cast<size_t>(primitives));
}

SelfBroadPhaseStats SelfSpatialHash::FindCandidates(std::span<const Vec3> x0,
                                                    std::span<const Vec3> x1, double thickness_m) {
  BeginStep(x0, x1, thickness_m);
  candidates_.clear();
  SelfBroadPhaseStats stats;
  const double pad = SelfBroadPadding(thickness_m);
  const double inv_cell = 1.0 / cell_size_m_;
  using Kind = CcdPairHit::Kind;

  // Swept, padded boxes of the vertices, edges and triangles.
  for (int32_t v = 0; v < num_vertices_; ++v) {
    vertex_box_[v].lo = x0[v].cwiseMin(x1[v]).array() - pad;
    vertex_box_[v].hi = x0[v].cwiseMax(x1[v]).array() + pad;
  }
  for (size_t i = 0; i < edges_.size(); ++i) {
    const Box& a = vertex_box_[edges_[i][0]];
    const Box& b = vertex_box_[edges_[i][1]];
    edge_box_[i] = {a.lo.cwiseMin(b.lo), a.hi.cwiseMax(b.hi)};
  }
  for (size_t i = 0; i < triangles_.size(); ++i) {
    const Triangle& t = triangles_[i];
    const Box& a = vertex_box_[t[0]];
    const Box& b = vertex_box_[t[1]];
    const Box& c = vertex_box_[t[2]];
    triangle_box_[i] = {a.lo.cwiseMin(b.lo).cwiseMin(c.lo), a.hi.cwiseMax(b.hi).cwiseMax(c.hi)};
  }

  // Hashes the primitives [0, n) passing `use` whose boxes fit (counting sort into entries_);
  // the others go to oversized_.
  const auto build = [&](int32_t n, const std::vector<Box>& boxes, auto&& use) {
    std::fill(bucket_start_.begin(), bucket_start_.end(), 0);
    oversized_.clear();
    int64_t total = 0;
    for (int32_t i = 0; i < n; ++i) {
      hashed_[i] = 0;
      if (!use(i)) continue;
      const SelfCellRange r = SelfRangeOf(boxes[i].lo, boxes[i].hi, inv_cell);
      const int64_t cells = r.count();
      if (cells > max_cells_ || total + cells > max_entries_) {
        oversized_.push_back(i);  // reserved for every primitive: never reallocates
        continue;
      }
      hashed_[i] = 1;
      total += cells;
      SelfForEachCell(r, [&](int32_t cx, int32_t cy, int32_t cz) {
        ++bucket_start_[SelfHashCell(cx, cy, cz, table_size_) + 1];
      });
    }
    std::partial_sum(bucket_start_.begin(), bucket_start_.end(), bucket_start_.begin());
    for (int32_t b = 0; b < table_size_; ++b) bucket_fill_[b] = bucket_start_[b];
    for (int32_t i = 0; i < n; ++i) {
      if (!hashed_[i]) continue;
      const SelfCellRange r = SelfRangeOf(boxes[i].lo, boxes[i].hi, inv_cell);
      SelfForEachCell(r, [&](int32_t cx, int32_t cy, int32_t cz) {
        entries_[bucket_fill_[SelfHashCell(cx, cy, cz, table_size_)]++] = {i, {cx, cy, cz}};
      });
    }
    stats.oversized += static_cast<int32_t>(oversized_.size());
  };

  // Visits the hashed primitives j whose boxes overlap `box` and whose overlap's low corner lies
  // in a cell of `range` (so each once): f(j).
  const auto query = [&](const Box& box, const std::vector<Box>& boxes, auto&& f) {
    const SelfCellRange r = SelfRangeOf(box.lo, box.hi, inv_cell);
    SelfForEachCell(r, [&](int32_t cx, int32_t cy, int32_t cz) {
      const int32_t bucket = SelfHashCell(cx, cy, cz, table_size_);
      for (int32_t k = bucket_start_[bucket]; k < bucket_start_[bucket + 1]; ++k) {
        const Entry& en = entries_[k];
        if (en.cell[0] != cx || en.cell[1] != cy || en.cell[2] != cz) continue;
        const Box& o = boxes[en.id];
        if (!SelfBoxesOverlap(box.lo, box.hi, o.lo, o.hi)) continue;
        // Report in the cell of the low corner of the intersection only.
        const Vec3 corner = box.lo.cwiseMax(o.lo);
        if (SelfCellOf(corner.x(), inv_cell) != cx || SelfCellOf(corner.y(), inv_cell) != cy ||
            SelfCellOf(corner.z(), inv_cell) != cz) {
          continue;
        }
        f(en.id);
      }
    });
  };

  // Vertex-triangle: vertices (those some triangle uses) hashed, triangles looked up.
  build(num_vertices_, vertex_box_, [&](int32_t v) { return vertex_owner_[v] >= 0; });
  const int32_t nt = static_cast<int32_t>(triangles_.size());
  for (int32_t ti = 0; ti < nt; ++ti) {
    const Triangle& t = triangles_[ti];
    const Box& tb = triangle_box_[ti];
    if (SelfRangeOf(tb.lo, tb.hi, inv_cell).count() <= max_cells_) {
      query(tb, vertex_box_, [&](int32_t v) {
        if (!SelfHasCorner(t, v)) Emit(Kind::kVertexTriangle, v, ti, &stats);
      });
    } else {
      // A large triangle: every hashed vertex by box.
      for (int32_t v = 0; v < num_vertices_; ++v) {
        if (!hashed_[v] || SelfHasCorner(t, v)) continue;
        const Box& vb = vertex_box_[v];
        if (SelfBoxesOverlap(vb.lo, vb.hi, tb.lo, tb.hi))
          Emit(Kind::kVertexTriangle, v, ti, &stats);
      }
    }
  }
  // Vertices not in the table: every triangle by box.
  for (int32_t v : oversized_) {
    const Box& vb = vertex_box_[v];
    for (int32_t ti = 0; ti < nt; ++ti) {
      const Box& tb = triangle_box_[ti];
      if (!SelfHasCorner(triangles_[ti], v) && SelfBoxesOverlap(vb.lo, vb.hi, tb.lo, tb.hi)) {
        Emit(Kind::kVertexTriangle, v, ti, &stats);
      }
    }
  }

  // Edge-edge: edges hashed, each hashed edge looks up the edges of higher index.
  const int32_t ne = static_cast<int32_t>(edges_.size());
  build(ne, edge_box_, [](int32_t) { return true; });
  for (int32_t e = 0; e < ne; ++e) {
    if (!hashed_[e]) continue;
    query(edge_box_[e], edge_box_, [&](int32_t f) {
      if (f > e && !SelfEdgesTouch(edges_[e], edges_[f])) Emit(Kind::kEdgeEdge, e, f, &stats);
    });
  }
  // Edges not in the table: every hashed edge, and every other such edge of higher index.
  for (int32_t e : oversized_) {
    const Box& eb = edge_box_[e];
    for (int32_t f = 0; f < ne; ++f) {
      if (f == e || (!hashed_[f] && f < e) || SelfEdgesTouch(edges_[e], edges_[f])) continue;
      const Box& fb = edge_box_[f];
      if (SelfBoxesOverlap(eb.lo, eb.hi, fb.lo, fb.hi)) {
        Emit(Kind::kEdgeEdge, std::min(e, f), std::max(e, f), &stats);
      }
    }
  }
  return stats;
}

// ---------------------------------------------------------------------------------------------
// SelfTriangleTree

SelfTriangleTree::SelfTriangleTree(std::span<const Triangle> triangles, std::span<const Vec3> x,
                                   const SelfBroadPhaseOptions& options)
    : SelfBroadPhase(triangles, static_cast<int32_t>(x.size()), options) {
  const int32_t nt = static_cast<int32_t>(triangles_.size());
  // Each triangle's owned vertices and edges (-1 padded).
  owned_vertices_.assign(triangles_.size(), {-1, -1, -1});
  owned_edges_.assign(triangles_.size(), {-1, -1, -1});
  for (int32_t ti = 0; ti < nt; ++ti) {
    int32_t nv = 0, nedge = 0;
    for (int32_t k = 0; k < 3; ++k) {
      const int32_t v = triangles_[ti][k];
      if (vertex_owner_[v] == ti &&
          std::find(owned_vertices_[ti].begin(), owned_vertices_[ti].end(), v) ==
              owned_vertices_[ti].end()) {
        owned_vertices_[ti][nv++] = v;
      }
      const int32_t e = triangle_edges_[ti][k];
      if (e >= 0 && edge_owner_[e] == ti &&
          std::find(owned_edges_[ti].begin(), owned_edges_[ti].end(), e) ==
              owned_edges_[ti].end()) {
        owned_edges_[ti][nedge++] = e;
      }
    }
  }
  vertex_lo_.resize(x.size());
  vertex_hi_.resize(x.size());
  edge_lo_.resize(edges_.size());
  edge_hi_.resize(edges_.size());
  edge_stamp_.assign(edges_.size(), 0);
}

double SelfTriangleTree::BoxPadding(double thickness_m) { return SelfBroadPadding(thickness_m); }

bool SelfTriangleTree::BoxesOverlap(const Vec3& alo, const Vec3& ahi, const Vec3& blo,
                                    const Vec3& bhi) {
  return SelfBoxesOverlap(alo, ahi, blo, bhi);
}

void SelfTriangleTree::VertexBox(int32_t v, std::span<const Vec3> x0, std::span<const Vec3> x1,
                                 double pad, double start_pad) {
  vertex_lo_[v] = x0[v].cwiseMin(x1[v]).array() - pad;
  vertex_hi_[v] = x0[v].cwiseMax(x1[v]).array() + pad;
  if (start_pad > pad) {
    vertex_lo_[v] = vertex_lo_[v].cwiseMin(Vec3(x0[v].array() - start_pad));
    vertex_hi_[v] = vertex_hi_[v].cwiseMax(Vec3(x0[v].array() + start_pad));
  }
}

void SelfTriangleTree::NewBoxStamp() {
  if (++box_stamp_ == 0) {  // wrapped: no edge may keep a stale stamp
    std::fill(edge_stamp_.begin(), edge_stamp_.end(), 0u);
    box_stamp_ = 1;
  }
}

void SelfTriangleTree::EdgeBox(int32_t e) {
  if (edge_stamp_[e] == box_stamp_) return;
  edge_stamp_[e] = box_stamp_;
  const MeshEdge& m = edges_[e];
  edge_lo_[e] = vertex_lo_[m[0]].cwiseMin(vertex_lo_[m[1]]);
  edge_hi_[e] = vertex_hi_[m[0]].cwiseMax(vertex_hi_[m[1]]);
}

void SelfTriangleTree::PairTriangles(int32_t ta, int32_t tb, const Vec3& alo, const Vec3& ahi,
                                     const Vec3& blo, const Vec3& bhi,
                                     SelfBroadPhaseStats* stats) {
  using Kind = CcdPairHit::Kind;
  // Vertices owned by one triangle against the other triangle.
  for (int32_t side = 0; side < 2; ++side) {
    const int32_t owner = side == 0 ? ta : tb;
    const int32_t other = side == 0 ? tb : ta;
    const Vec3& olo = side == 0 ? blo : alo;
    const Vec3& ohi = side == 0 ? bhi : ahi;
    for (int32_t v : owned_vertices_[owner]) {
      if (v < 0) break;
      if (SelfHasCorner(triangles_[other], v)) continue;
      if (SelfBoxesOverlap(vertex_lo_[v], vertex_hi_[v], olo, ohi)) {
        Emit(Kind::kVertexTriangle, v, other, stats);
      }
    }
  }
  // Edges owned by one against edges owned by the other (EdgeBox: each edge's swept box made
  // once a broad phase, when a pair first needs it; most edges are in none).
  for (int32_t e : owned_edges_[ta]) {
    if (e < 0) break;
    EdgeBox(e);
    for (int32_t f : owned_edges_[tb]) {
      if (f < 0) break;
      if (SelfEdgesTouch(edges_[e], edges_[f])) continue;
      EdgeBox(f);
      if (SelfBoxesOverlap(edge_lo_[e], edge_hi_[e], edge_lo_[f], edge_hi_[f])) {
        Emit(Kind::kEdgeEdge, std::min(e, f), std::max(e, f), stats);
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// SelfBvh

SelfBvh::SelfBvh(std::span<const Triangle> triangles, std::span<const Vec3> x,
                 const SelfBroadPhaseOptions& options)
    : SelfTriangleTree(triangles, x, options) {
  const int32_t nt = static_cast<int32_t>(triangles_.size());
  if (nt == 0) return;

  // Top-down median split of the centroids along the longest axis of their box; nodes in
  // pre-order (a parent before its children).
  std::vector<Vec3> centroid(triangles_.size());
  for (int32_t ti = 0; ti < nt; ++ti) {
    const Triangle& t = triangles_[ti];
    centroid[ti] = (x[t[0]] + x[t[1]] + x[t[2]]) / 3.0;
  }
  if (options.normal_cones) {
    // Normal cones want patches with straight sides (star-shaped contours): two triangles that
    // share their longest edge (a quad's halves) are split on their common centroid, so that no
    // split runs along a quad's diagonal and leaves a sawtooth contour.
    std::vector<std::array<int32_t, 2>> longest(triangles_.size(), {-1, -1});
    std::vector<std::array<int32_t, 3>> keyed;  // (edge lo, edge hi, triangle)
    for (int32_t ti = 0; ti < nt; ++ti) {
      const Triangle& t = triangles_[ti];
      int32_t best = 0;
      for (int32_t k = 1; k < 3; ++k) {
        if ((x[t[(k + 1) % 3]] - x[t[k]]).squaredNorm() >
            (x[t[(best + 1) % 3]] - x[t[best]]).squaredNorm()) {
          best = k;
        }
      }
      const int32_t a = t[best], b = t[(best + 1) % 3];
      keyed.push_back({std::min(a, b), std::max(a, b), ti});
    }
    std::sort(keyed.begin(), keyed.end());
    std::vector<Vec3> paired = centroid;
    for (size_t i = 0; i + 1 < keyed.size(); ++i) {
      if (keyed[i][0] == keyed[i + 1][0] && keyed[i][1] == keyed[i + 1][1] &&
          (i + 2 == keyed.size() || keyed[i + 2][0] != keyed[i][0] ||
           keyed[i + 2][1] != keyed[i][1])) {
        const Vec3 mid_point = 0.5 * (centroid[keyed[i][2]] + centroid[keyed[i + 1][2]]);
        paired[keyed[i][2]] = mid_point;
        paired[keyed[i + 1][2]] = mid_point;
        ++i;
      }
    }
    centroid = paired;
  }
  std::vector<int32_t> order(triangles_.size());
  std::iota(order.begin(), order.end(), 0);
  std::vector<std::array<int32_t, 2>> range;  // [nodes] the node's triangles: order[begin, end)
  const auto build = [&](auto&& self, int32_t begin, int32_t end) -> int32_t {
    const int32_t node = static_cast<int32_t>(left_.size());
    left_.push_back(-1);
    right_.push_back(-1);
    range.push_back({begin, end});
    if (end - begin == 1) {
      right_[node] = order[begin];
      return node;
    }
    Vec3 lo = centroid[order[begin]], hi = lo;
    for (int32_t i = begin; i < end; ++i) {
      lo = lo.cwiseMin(centroid[order[i]]);
      hi = hi.cwiseMax(centroid[order[i]]);
    }
    int32_t axis = 0;
    (hi - lo).maxCoeff(&axis);
    int32_t mid = begin + (end - begin) / 2;
    const auto less = [&](int32_t a, int32_t b) {
      if (centroid[a][axis] != centroid[b][axis]) return centroid[a][axis] < centroid[b][axis];
      return a < b;
    };
    if (!options.normal_cones) {
      std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end, less);
    } else {
      // Normal cones want patches with straight sides (star-shaped contours): split where the
      // centroid coordinate changes, not inside a run of equal ones (a grid's row or column,
      // which a split by index would notch), at the change nearest the median.
      std::sort(order.begin() + begin, order.begin() + end, less);
      int32_t run_lo = mid, run_hi = mid;
      const double m = centroid[order[mid]][axis];
      while (run_lo > begin && centroid[order[run_lo - 1]][axis] == m) --run_lo;
      while (run_hi < end && centroid[order[run_hi]][axis] == m) ++run_hi;
      if (run_lo > begin && (run_hi == end || mid - run_lo <= run_hi - mid)) {
        mid = run_lo;
      } else if (run_hi < end) {
        mid = run_hi;
      }
    }
    const int32_t l = self(self, begin, mid);
    const int32_t r = self(self, mid, end);
    left_[node] = l;
    right_[node] = r;
    return node;
  };
  build(build, 0, nt);
  node_lo_.resize(left_.size());
  node_hi_.resize(left_.size());
  node_dirty_.assign(left_.size(), 0);
  triangle_dirty_.assign(triangles_.size(), 0);
  kept_from_.reserve(static_cast<size_t>(max_candidates_));
  // Pre-order reversed: children before parents.
  refit_order_.resize(left_.size());
  std::iota(refit_order_.rbegin(), refit_order_.rend(), 0);
  // The parents deepest level first (children before parents too): in reversed pre-order each
  // parent comes right after its left child, so every merge waits for the one before it (a chain
  // of square roots); within a level none depends on another.
  std::vector<int32_t> depth(left_.size(), 0);
  for (size_t node = 0; node < left_.size(); ++node) {
    if (left_[node] < 0) continue;
    depth[static_cast<size_t>(left_[node])] = depth[node] + 1;
    depth[static_cast<size_t>(right_[node])] = depth[node] + 1;
  }
  for (int32_t node : refit_order_) {
    if (left_[node] >= 0) parent_order_.push_back(node);
  }
  std::stable_sort(parent_order_.begin(), parent_order_.end(),
                   [&](int32_t a, int32_t b) { return depth[a] > depth[b]; });
  for (size_t i = 0; i < parent_order_.size(); ++i) {
    if (i == 0 || depth[parent_order_[i]] != depth[parent_order_[i - 1]]) {
      level_start_.push_back(static_cast<int32_t>(i));
    }
  }
  level_start_.push_back(static_cast<int32_t>(parent_order_.size()));
  normal_cones_ = options.normal_cones;
  if (normal_cones_) {
    BuildContours(x, order, range);
    // The leaves in the refit's order, for the batched cones (FindCandidates).
    leaf_slot_.assign(left_.size(), -1);
    for (int32_t node : refit_order_) {
      if (left_[node] >= 0) continue;
      leaf_slot_[node] = static_cast<int32_t>(leaf_tri_.size());
      leaf_tri_.push_back(right_[node]);
    }
    leaf_out_.assign(7 * leaf_tri_.size(), 0.0);
    merge_in_.assign(10 * parent_order_.size(), 0.0);
    merge_out_.assign(5 * parent_order_.size(), 0.0);
  }
}

// Set-up of the normal-cone test: for every node of at least kSelfConeMinTriangles triangles
// whose triangles form a consistently oriented manifold patch (each edge used once, or twice in
// opposite directions, never degenerate), its contour (the directed edges used once, the patch on
// their left) and a center triangle (the one whose centroid is nearest the patch's mean at x).
// Other nodes get center -1 and are never skipped.
void SelfBvh::BuildContours(std::span<const Vec3> x, const std::vector<int32_t>& order,
                            const std::vector<std::array<int32_t, 2>>& range) {
  constexpr int32_t kSelfConeMinTriangles = 2;
  const size_t nodes = left_.size();
  cone_.assign(nodes, Cone{});
  fat_.assign(nodes, FatBound{});
  center_.assign(nodes, -1);
  contour_begin_.assign(nodes + 1, 0);
  contour_.clear();
  struct DirectedEdge {
    int32_t lo, hi, from, to;
  };
  std::vector<DirectedEdge> es;
  for (size_t node = 0; node < nodes; ++node) {
    contour_begin_[node] = static_cast<int32_t>(contour_.size());
    const auto [begin, end] = range[node];
    if (end - begin < kSelfConeMinTriangles) continue;
    es.clear();
    bool ok = true;
    for (int32_t i = begin; i < end && ok; ++i) {
      const Triangle& t = triangles_[order[i]];
      for (int32_t k = 0; k < 3; ++k) {
        const int32_t a = t[k], b = t[(k + 1) % 3];
        if (a == b) ok = false;
        es.push_back({std::min(a, b), std::max(a, b), a, b});
      }
    }
    if (!ok) continue;
    std::sort(es.begin(), es.end(), [](const DirectedEdge& p, const DirectedEdge& q) {
      return p.lo != q.lo ? p.lo < q.lo : p.hi < q.hi;
    });
    const size_t first = contour_.size();
    for (size_t i = 0; i < es.size() && ok;) {
      size_t j = i + 1;
      while (j < es.size() && es[j].lo == es[i].lo && es[j].hi == es[i].hi) ++j;
      if (j - i == 1) {
        contour_.push_back({es[i].from, es[i].to});
      } else if (j - i != 2 || es[i].from == es[i + 1].from) {
        ok = false;  // non-manifold or inconsistently oriented
      }
      i = j;
    }
    if (!ok || contour_.size() == first) {
      contour_.resize(first);
      continue;
    }
    // The center: the centroid of the patch's triangle whose centroid is nearest the patch's
    // mean (strictly inside that triangle, so on no contour edge, and off the grid's lines).
    Vec3 mean = Vec3::Zero();
    for (int32_t i = begin; i < end; ++i) {
      const Triangle& t = triangles_[order[i]];
      mean += (x[t[0]] + x[t[1]] + x[t[2]]) / 3.0;
    }
    mean /= static_cast<double>(end - begin);
    double best = std::numeric_limits<double>::infinity();
    for (int32_t i = begin; i < end; ++i) {
      const Triangle& t = triangles_[order[i]];
      const double d = ((x[t[0]] + x[t[1]] + x[t[2]]) / 3.0 - mean).squaredNorm();
      if (d < best) {
        best = d;
        center_[node] = order[i];
      }
    }
    if (center_[node] < 0) contour_.resize(first);
  }
  contour_begin_[nodes] = static_cast<int32_t>(contour_.size());
}

namespace {

// The cone of a triangle's normal over the step (Tang, Curtis, Yoon & Manocha 2009, continuous
// normal cones): with A(t) = b(t) - a(t), B(t) = c(t) - a(t) linear in t, the normal
// n(t) = A(t) x B(t) = (1-t)^2 N0 + 2 t (1-t) Nm + t^2 N1 (Bernstein form), N0 = A0 x B0,
// N1 = A1 x B1, Nm = (A0 x B1 + A1 x B0) / 2, so n(t) is a non-negative combination of the three
// and lies in any cone holding them. Axis: the sum of their directions; cos_half <= 0: no cone
// (a degenerate triangle at an end of the step). At rest (x1 = x0) the three are one (Nm = N0
// exactly: 0.5 (N0 + N0)).
//
// With it, SelfBvh::FatBound: at one time the distance from a corner to the opposite edge is at
// least the altitude |n| / |opposite edge| >= h = |n| / (longest edge), n the doubled-area normal,
// so h^2 = |n|^2 / (longest edge)^2, the smaller of the step's ends. A translation common to the
// three corners changes no distance, so take the corners' moves less their mean, m_k; over the
// step a corner's distance then changes by at most L |t - s| between times t and s, L = 2 m, m
// the largest |m_k| (the corner moves by its own motion, the opposite segment by at most its
// farther end's), so at every time it is at least min(h0, h1) - m. A parent keeps the least h^2
// and the largest m^2 of its children.
//
// Written once for a lane type V (one triangle: double; four: __m256d) with the lane operations
// of L, every operation in the same order for both, so that every SIMD level gives the same bits
// (base/simd.h). In: the corners' coordinates at the step's ends, in[0..8] = a0, b0, c0 (x, y, z
// each), in[9..17] = a1, b1, c1. Out: axis x, y, z, cos_half, sin_half, h2, move2.
#pragma GCC push_options
#pragma GCC optimize("fp-contract=off")
namespace self_portable {
#include "collision/self_leaf_cone.inc"
}  // namespace self_portable
// SelfLeafConeLanes' lane operations on one double (the portable level).
struct SelfScalarLanes {
  static double Set(double v) { return v; }
  static double Sqrt(double v) { return std::sqrt(v); }
  static double Min(double a, double b) { return a < b ? a : b; }  // as MINPD
  static double Max(double a, double b) { return a > b ? a : b; }  // as MAXPD
  static bool Gt(double a, double b) { return a > b; }
  static bool Le(double a, double b) { return a <= b; }
  static bool And(bool a, bool b) { return a && b; }
  static double Select(bool m, double a, double b) { return m ? a : b; }
};

// Triangle t's corners at the step's ends as SelfLeafConeLanes reads them, input k into
// in[k stride], k < 18.
void SelfGatherLeaf(const Triangle& t, std::span<const Vec3> x0, std::span<const Vec3> x1,
                    double* in, size_t stride) {
  for (int32_t k = 0; k < 3; ++k) {
    for (int32_t a = 0; a < 3; ++a) {
      in[(3 * k + a) * stride] = x0[t[k]][a];
      in[(9 + 3 * k + a) * stride] = x1[t[k]][a];
    }
  }
}

// The leaves of one refit: leaf i's triangle triangles[leaf_tri[i]] over x0 -> x1.
struct SelfLeafInputs {
  std::span<const Vec3> x0, x1;
  const Triangle* triangles = nullptr;
  const int32_t* leaf_tri = nullptr;
};

// Item i's input k into in[k stride]: a leaf's corners (SelfLeafInputs), or a parent's
// children's cones, 10 doubles each in a flat array.
void SelfLoadLeaf(const void* ctx, size_t i, double* in, size_t stride) {
  const auto& leaves = *static_cast<const SelfLeafInputs*>(ctx);
  SelfGatherLeaf(leaves.triangles[leaves.leaf_tri[i]], leaves.x0, leaves.x1, in, stride);
}
void SelfLoadMerge(const void* ctx, size_t i, double* in, size_t stride) {
  const double* flat = static_cast<const double*>(ctx) + 10 * i;
  for (int32_t k = 0; k < 10; ++k) in[k * stride] = flat[k];
}

// One leaf, one parent: SelfLeafConeLanes (18 in, 7 out) and SelfMergeConeLanes (10 in, 5 out)
// on one double.
void SelfLeafConeOne(const double* in, double* out) {
  self_portable::SelfLeafConeLanes<double, SelfScalarLanes>(in, out);
}
void SelfMergeConeOne(const double* in, double* out) {
  self_portable::SelfMergeConeLanes<double, SelfScalarLanes>(in, out);
}

// `count` items one by one: item i's NIn inputs from Load(ctx, i), its NOut outputs to
// out[NOut i].
template <int NIn, int NOut, void (*Load)(const void*, size_t, double*, size_t),
          void (*One)(const double*, double*)>
void SelfBatchPortable(const void* ctx, double* out, size_t count) {
  double in[NIn];
  for (size_t i = 0; i < count; ++i) {
    Load(ctx, i, in, 1);
    One(in, out + NOut * i);
  }
}

#if defined(__x86_64__)
#pragma GCC target("avx2")
namespace self_avx2 {
#include "collision/self_leaf_cone.inc"
}  // namespace self_avx2

// SelfLeafConeLanes' lane operations on four doubles (AVX2), as SelfScalarLanes lane by lane.
struct SelfAvx2Lanes {
  static __m256d Set(double v) { return _mm256_set1_pd(v); }
  static __m256d Sqrt(__m256d v) { return _mm256_sqrt_pd(v); }
  static __m256d Min(__m256d a, __m256d b) { return _mm256_min_pd(a, b); }
  static __m256d Max(__m256d a, __m256d b) { return _mm256_max_pd(a, b); }
  static __m256d Gt(__m256d a, __m256d b) { return _mm256_cmp_pd(a, b, _CMP_GT_OQ); }
  static __m256d Le(__m256d a, __m256d b) { return _mm256_cmp_pd(a, b, _CMP_LE_OQ); }
  static __m256d And(__m256d a, __m256d b) { return _mm256_and_pd(a, b); }
  static __m256d Select(__m256d m, __m256d a, __m256d b) { return _mm256_blendv_pd(b, a, m); }
};

void SelfLeafConeFour(const __m256d* in, __m256d* out) {
  self_avx2::SelfLeafConeLanes<__m256d, SelfAvx2Lanes>(in, out);
}
void SelfMergeConeFour(const __m256d* in, __m256d* out) {
  self_avx2::SelfMergeConeLanes<__m256d, SelfAvx2Lanes>(in, out);
}

// SelfBatchPortable four items at a time (Four on their inputs as lanes, the same bits as One),
// the rest one by one.
template <int NIn, int NOut, void (*Load)(const void*, size_t, double*, size_t),
          void (*Four)(const __m256d*, __m256d*), void (*One)(const double*, double*)>
void SelfBatchAvx2(const void* ctx, double* out, size_t count) {
  size_t i = 0;
  for (; i + 4 <= count; i += 4) {
    alignas(32) double lanes[NIn][4];
    for (int32_t l = 0; l < 4; ++l) Load(ctx, i + l, &lanes[0][l], 4);
    __m256d lanes_in[NIn], lanes_out[NOut];
    for (int32_t k = 0; k < NIn; ++k) lanes_in[k] = _mm256_load_pd(lanes[k]);
    Four(lanes_in, lanes_out);
    alignas(32) double res[NOut][4];
    for (int32_t k = 0; k < NOut; ++k) _mm256_store_pd(res[k], lanes_out[k]);
    for (int32_t l = 0; l < 4; ++l) {
      for (int32_t k = 0; k < NOut; ++k) out[NOut * (i + l) + k] = res[k][l];
    }
  }
  double row[NIn];
  for (; i < count; ++i) {
    Load(ctx, i, row, 1);
    One(row, out + NOut * i);
  }
}
#endif
#pragma GCC pop_options

// The batched cones of one refit (inputs, out, count), per SIMD level: the leaves'
// (SelfLeafInputs) and the parents' (the flat merge inputs).
using SelfConeBatchKernel = void (*)(const void*, double*, size_t);
#if defined(__x86_64__)
constexpr SimdTable<SelfConeBatchKernel> kSelfLeafConesKernels{
    SelfBatchPortable<18, 7, SelfLoadLeaf, SelfLeafConeOne>,
    SelfBatchAvx2<18, 7, SelfLoadLeaf, SelfLeafConeFour, SelfLeafConeOne>,
    SelfBatchAvx2<18, 7, SelfLoadLeaf, SelfLeafConeFour, SelfLeafConeOne>};
constexpr SimdTable<SelfConeBatchKernel> kSelfMergeConesKernels{
    SelfBatchPortable<10, 5, SelfLoadMerge, SelfMergeConeOne>,
    SelfBatchAvx2<10, 5, SelfLoadMerge, SelfMergeConeFour, SelfMergeConeOne>,
    SelfBatchAvx2<10, 5, SelfLoadMerge, SelfMergeConeFour, SelfMergeConeOne>};
#else
constexpr SimdTable<SelfConeBatchKernel> kSelfLeafConesKernels{
    SelfBatchPortable<18, 7, SelfLoadLeaf, SelfLeafConeOne>,
    SelfBatchPortable<18, 7, SelfLoadLeaf, SelfLeafConeOne>,
    SelfBatchPortable<18, 7, SelfLoadLeaf, SelfLeafConeOne>};
constexpr SimdTable<SelfConeBatchKernel> kSelfMergeConesKernels{
    SelfBatchPortable<10, 5, SelfLoadMerge, SelfMergeConeOne>,
    SelfBatchPortable<10, 5, SelfLoadMerge, SelfMergeConeOne>,
    SelfBatchPortable<10, 5, SelfLoadMerge, SelfMergeConeOne>};
#endif

}  // namespace

// True when the patch of node a (with b >= 0: of nodes a and b together) is certified free of
// contact between non-incident primitives over the step, `cone` (axis V, below pi/2) holding
// every normal of the patch over the step:
// projected along V every triangle keeps its orientation, so a generic point of the plane has as
// many preimages in the patch as the projected contour's winding number around it; the contour
// is star-shaped about the center point c at every t (each directed contour edge (p, q) has
// V . ((p - c) x (q - c)) > 0, a quadratic in t checked by its three Bernstein coefficients) and
// winds once around it (counted at t = 0; constant over the step since c never meets the
// contour; c is the centroid of the center triangle, moving linearly with it), so the projection is
// one-to-one and no two non-incident primitives of the patch touch (Volino & Magnenat-Thalmann
// 1994; Schvartzman, Perez & Otaduy 2010, star-contours).
bool SelfBvh::SelfContactFree(int32_t a, int32_t b, const Cone& cone) const {
  const std::span<const Vec3> x0 = step_x0_, x1 = step_x1_;
  const Triangle& ct = triangles_[center_[a]];
  const Vec3 c0 = (x0[ct[0]] + x0[ct[1]] + x0[ct[2]]) / 3.0;
  const Vec3 c1 = still_ ? c0 : Vec3((x1[ct[0]] + x1[ct[1]] + x1[ct[2]]) / 3.0);
  const Vec3& V = cone.axis;
  // A unit u normal to V, and w = V x u: (u, w, V) is right-handed.
  int32_t k = 0;
  V.cwiseAbs().minCoeff(&k);
  const Vec3 u = V.cross(Vec3::Unit(k)).normalized();
  const Vec3 w = V.cross(u);
  int32_t winding = 0;
  // One contour edge p -> q: counter-clockwise about c over the whole step, and its crossing of
  // the ray from c along u at t = 0 counted.
  const auto edge_ok = [&](const std::array<int32_t, 2>& e) {
    if (still_) {
      // At rest the three Bernstein coefficients are one: V . ((p - c) x (q - c)).
      const Vec3 a0 = x0[e[0]] - c0, b0 = x0[e[1]] - c0;
      const double g0 = V.dot(a0.cross(b0));
      const double sa = a0.squaredNorm(), sb = b0.squaredNorm();
      if (!(g0 > 1e-12 * (sa + sa + sb + sb))) return false;
      if (a0.dot(w) < 0.0 && b0.dot(w) >= 0.0) ++winding;
      return true;
    }
    const Vec3 a0 = x0[e[0]] - c0, a1 = x1[e[0]] - c1;
    const Vec3 b0 = x0[e[1]] - c0, b1 = x1[e[1]] - c1;
    const double g0 = V.dot(a0.cross(b0));
    const double g2 = V.dot(a1.cross(b1));
    const double g1 = 0.5 * (V.dot(a0.cross(b1)) + V.dot(a1.cross(b0)));
    const double tol =
        1e-12 * (a0.squaredNorm() + a1.squaredNorm() + b0.squaredNorm() + b1.squaredNorm());
    if (!(g0 > tol && g1 > tol && g2 > tol)) return false;
    if (a0.dot(w) < 0.0 && b0.dot(w) >= 0.0) ++winding;
    return true;
  };
  const auto key_less = [](const std::array<int32_t, 2>& e, const std::array<int32_t, 2>& f) {
    const int32_t elo = std::min(e[0], e[1]), flo = std::min(f[0], f[1]);
    if (elo != flo) return elo < flo;
    return std::max(e[0], e[1]) < std::max(f[0], f[1]);
  };
  int32_t i = contour_begin_[a];
  const int32_t i_end = contour_begin_[a + 1];
  int32_t j = b >= 0 ? contour_begin_[b] : 0;
  const int32_t j_end = b >= 0 ? contour_begin_[b + 1] : 0;
  // The union's contour: both contours (each sorted by undirected edge) merged, an edge that one
  // patch has in each direction being interior to the union.
  while (i < i_end || j < j_end) {
    if (j == j_end || (i < i_end && key_less(contour_[i], contour_[j]))) {
      if (!edge_ok(contour_[i++])) return false;
    } else if (i == i_end || key_less(contour_[j], contour_[i])) {
      if (!edge_ok(contour_[j++])) return false;
    } else {
      if (contour_[i][0] == contour_[j][0]) return false;  // same direction: not a surface
      ++i;
      ++j;
    }
  }
  return winding == 1;
}

bool SelfBvh::SelfFat(const Cone& cone, const FatBound& fat) const {
  // Every corner of the patch stays at least min(h0, h1) - m from its opposite edge over the step
  // (FatBound); projected along the cone's axis, at least cos(half-angle) times that.
  return cone.cos_half * (std::sqrt(fat.h2) - std::sqrt(fat.move2)) >= 2.0 * certify_m_;
}

void SelfBvh::PackCone(const Cone& cone, double* out) {
  out[0] = cone.axis.x();
  out[1] = cone.axis.y();
  out[2] = cone.axis.z();
  out[3] = cone.cos_half;
  out[4] = cone.sin_half;
}

SelfBvh::Cone SelfBvh::UnpackCone(const double* in) {
  Cone cone;
  cone.axis = Vec3(in[0], in[1], in[2]);
  cone.cos_half = in[3];
  cone.sin_half = in[4];
  return cone;
}

SelfBvh::Cone SelfBvh::MergeCones(const Cone& l, const Cone& r) {
  double in[10], out[5];
  PackCone(l, in);
  PackCone(r, in + 5);
  SelfMergeConeOne(in, out);
  return UnpackCone(out);
}

SelfBvh::FatBound SelfBvh::MergeFat(const FatBound& l, const FatBound& r) {
  return {std::min(l.h2, r.h2), std::max(l.move2, r.move2)};
}

void SelfBvh::RefitParentBounds(int32_t node) {
  const int32_t l = left_[node], r = right_[node];
  node_lo_[node] = node_lo_[l].cwiseMin(node_lo_[r]);
  node_hi_[node] = node_hi_[l].cwiseMax(node_hi_[r]);
  if (normal_cones_) fat_[node] = MergeFat(fat_[l], fat_[r]);
}

void SelfBvh::RefitParents() {
  for (int32_t node : parent_order_) RefitParentBounds(node);
  if (!normal_cones_) return;
  // The cones a level at a time from the deepest (children before parents), each level's merges
  // at once (four a step with AVX2; MergeCones' bits).
  const auto merge = PickSimd(kSelfMergeConesKernels);
  for (size_t level = 0; level + 1 < level_start_.size(); ++level) {
    const int32_t first = level_start_[level], last = level_start_[level + 1];
    for (int32_t i = first; i < last; ++i) {
      const int32_t node = parent_order_[i];
      PackCone(cone_[left_[node]], merge_in_.data() + 10 * i);
      PackCone(cone_[right_[node]], merge_in_.data() + 10 * i + 5);
    }
    merge(merge_in_.data() + 10 * first, merge_out_.data() + 5 * first,
          static_cast<size_t>(last - first));
    for (int32_t i = first; i < last; ++i) {
      cone_[parent_order_[i]] = UnpackCone(merge_out_.data() + 5 * i);
    }
  }
}

bool SelfBvh::Overlap(int32_t a, int32_t b) const {
  return SelfBoxesOverlap(node_lo_[a], node_hi_[a], node_lo_[b], node_hi_[b]);
}

SelfBroadPhaseStats SelfBvh::FindCandidates(std::span<const Vec3> x0, std::span<const Vec3> x1,
                                            double thickness_m) {
  return FindCandidates(x0, x1, thickness_m, 0.0);
}

SelfBroadPhaseStats SelfBvh::FindCandidates(std::span<const Vec3> x0, std::span<const Vec3> x1,
                                            double thickness_m, double start_thickness_m) {
  BeginStep(x0, x1, thickness_m);
  candidates_.clear();
  SelfBroadPhaseStats stats;
  if (left_.empty()) return stats;
  const double pad = SelfBroadPadding(thickness_m);
  const double start_pad = start_thickness_m > 0.0 ? SelfBroadPadding(start_thickness_m) : 0.0;

  // A broad phase at rest (x1 is x0, the proximity pass's): cheaper cones and star tests.
  still_ = x0.data() == x1.data();
  // Swept, padded boxes of the vertices (an edge's box is made from its ends' where a leaf pair
  // first needs it: EdgeBox).
  for (int32_t v = 0; v < num_vertices_; ++v) VertexBox(v, x0, x1, pad, start_pad);
  NewBoxStamp();
  // Bottom-up refit (children before parents): a leaf's box (and cone) from its triangle, a
  // parent's from its children. The leaves' cones first, all at once (four a step with AVX2;
  // the same bits as RefitLeaf's), in the refit's order.
  if (normal_cones_) {
    const SelfLeafInputs leaves{x0, x1, triangles_.data(), leaf_tri_.data()};
    PickSimd(kSelfLeafConesKernels)(&leaves, leaf_out_.data(), leaf_tri_.size());
  }
  for (int32_t node : refit_order_) {
    if (left_[node] >= 0) continue;
    LeafBox(node);
    if (normal_cones_) TakeLeafCone(node, leaf_out_.data() + 7 * leaf_slot_[node]);
  }
  RefitParents();
  cone_culled_ = 0;
  union_culled_ = 0;
  step_x0_ = x0;
  step_x1_ = x1;
  certify_m_ = thickness_m;
  incremental_ = false;
  kept_from_.clear();
  Traverse(0, 0, &stats);
  return stats;
}

// A leaf's swept box from its triangle's vertex boxes and, with normal cones, its triangle's
// cone over the step x0 -> x1 (SelfLeafConeLanes; cos_half <= 1e-9: no cone below pi/2).
void SelfBvh::RefitLeaf(int32_t node, std::span<const Vec3> x0, std::span<const Vec3> x1) {
  LeafBox(node);
  if (!normal_cones_) return;
  double in[18], out[7];
  SelfGatherLeaf(triangles_[right_[node]], x0, x1, in, 1);
  SelfLeafConeOne(in, out);
  TakeLeafCone(node, out);
}

void SelfBvh::LeafBox(int32_t node) {
  const Triangle& t = triangles_[right_[node]];
  node_lo_[node] = vertex_lo_[t[0]].cwiseMin(vertex_lo_[t[1]]).cwiseMin(vertex_lo_[t[2]]);
  node_hi_[node] = vertex_hi_[t[0]].cwiseMax(vertex_hi_[t[1]]).cwiseMax(vertex_hi_[t[2]]);
}

void SelfBvh::TakeLeafCone(int32_t node, const double* out) {
  cone_[node] = UnpackCone(out);
  fat_[node].h2 = out[5];
  fat_[node].move2 = out[6];
}

// A parent's box from its children's and, with normal cones, its cone around the bisector of
// its children's axes, wide enough for both (half-angle max(angle(axis, child axis) + child
// half-angle), by cos(x + y) = cos x cos y - sin x sin y; 1e-12 kept back per level for
// rounding).
void SelfBvh::RefitParent(int32_t node) {
  RefitParentBounds(node);
  if (normal_cones_) cone_[node] = MergeCones(cone_[left_[node]], cone_[right_[node]]);
}

SelfBroadPhaseStats SelfBvh::UpdateCandidates(std::span<const Vec3> x0, std::span<const Vec3> x1,
                                              double thickness_m, double start_thickness_m,
                                              std::span<const uint8_t> moved) {
  BeginStep(x0, x1, thickness_m);
  FELT_CHECK(std::ssize(moved) == num_vertices_);
  still_ = x0.data() == x1.data();
  SelfBroadPhaseStats stats;
  kept_from_.clear();
  if (left_.empty()) {
    candidates_.clear();
    return stats;
  }
  const double pad = SelfBroadPadding(thickness_m);
  const double start_pad = start_thickness_m > 0.0 ? SelfBroadPadding(start_thickness_m) : 0.0;
  // The moved vertices' boxes (every edge's box made again where needed: EdgeBox), and the
  // triangles holding one.
  for (int32_t v = 0; v < num_vertices_; ++v) {
    if (moved[v]) VertexBox(v, x0, x1, pad, start_pad);
  }
  NewBoxStamp();
  for (size_t ti = 0; ti < triangles_.size(); ++ti) {
    const Triangle& t = triangles_[ti];
    triangle_dirty_[ti] = moved[t[0]] | moved[t[1]] | moved[t[2]];
  }
  // Dirty nodes refitted bottom-up; the others keep their boxes and cones (same vertices).
  for (int32_t node : refit_order_) {
    if (left_[node] < 0) {
      node_dirty_[node] = triangle_dirty_[right_[node]];
      if (node_dirty_[node]) RefitLeaf(node, x0, x1);
    } else {
      node_dirty_[node] = node_dirty_[left_[node]] | node_dirty_[right_[node]];
      if (node_dirty_[node]) RefitParent(node);
    }
  }
  // Keep the candidates found in a pair of clean leaves (a vertex's or an edge's leaf is its
  // owner's; the other side's leaf is the triangle, or the other edge's owner), in order.
  using Kind = CcdPairHit::Kind;
  const int32_t count = static_cast<int32_t>(candidates_.size());
  int32_t kept = 0;
  for (int32_t i = 0; i < count; ++i) {
    const SelfCandidate c = candidates_[i];
    const bool dirty =
        c.kind == Kind::kVertexTriangle
            ? (triangle_dirty_[vertex_owner_[c.first]] | triangle_dirty_[c.second])
            : (triangle_dirty_[edge_owner_[c.first]] | triangle_dirty_[edge_owner_[c.second]]);
    if (dirty) continue;
    if (c.kind == Kind::kVertexTriangle) {
      ++stats.vertex_triangle;
    } else {
      ++stats.edge_edge;
    }
    candidates_[kept] = c;
    kept_from_.push_back(i);  // reserved for max_candidates: never reallocates
    ++kept;
  }
  candidates_.resize(static_cast<size_t>(kept));
  // The pairs with a dirty leaf, found again on the new motion.
  cone_culled_ = 0;
  union_culled_ = 0;
  step_x0_ = x0;
  step_x1_ = x1;
  certify_m_ = thickness_m;
  incremental_ = true;
  Traverse(0, 0, &stats);
  incremental_ = false;
  return stats;
}

namespace {
// The union test of two patches is tried only when their contours have this many edges together
// (for smaller patches, descending to the leaf pairs is as cheap as the test).
constexpr int32_t kSelfUnionMinContour = 16;
}  // namespace

void SelfBvh::Traverse(int32_t a, int32_t b, SelfBroadPhaseStats* stats) {
  // UpdateCandidates: the pairs of two clean nodes are already in the kept candidates.
  if (incremental_ && !(node_dirty_[a] | node_dirty_[b])) return;
  // A node against itself: its children against themselves and each other.
  if (a == b) {
    if (left_[a] < 0) return;  // one triangle: its own features are all incident
    // A patch certified free of self-contact over the step is not traversed against itself.
    if (normal_cones_ && center_[a] >= 0 && cone_[a].cos_half > 1e-9 &&
        SelfFat(cone_[a], fat_[a]) && SelfContactFree(a, -1, cone_[a])) {
      ++cone_culled_;
      return;
    }
    Traverse(left_[a], left_[a], stats);
    Traverse(right_[a], right_[a], stats);
    Traverse(left_[a], right_[a], stats);
    return;
  }
  if (!Overlap(a, b)) return;
  // Two patches certified together (their union's cone below pi/2, its contour star-shaped):
  // no pair between them (Tang et al. 2009's adjacent-patch test).
  if (normal_cones_ && center_[a] >= 0 && center_[b] >= 0 &&
      contour_begin_[a + 1] - contour_begin_[a] + contour_begin_[b + 1] - contour_begin_[b] >=
          kSelfUnionMinContour) {
    const Cone both = MergeCones(cone_[a], cone_[b]);
    if (both.cos_half > 1e-9 && SelfFat(both, MergeFat(fat_[a], fat_[b])) &&
        SelfContactFree(a, b, both)) {
      ++union_culled_;
      return;
    }
  }
  const bool leaf_a = left_[a] < 0, leaf_b = left_[b] < 0;
  if (leaf_a && leaf_b) {
    LeafPair(a, b, stats);
  } else if (leaf_a) {
    Traverse(a, left_[b], stats);
    Traverse(a, right_[b], stats);
  } else if (leaf_b) {
    Traverse(left_[a], b, stats);
    Traverse(right_[a], b, stats);
  } else {
    Traverse(left_[a], left_[b], stats);
    Traverse(left_[a], right_[b], stats);
    Traverse(right_[a], left_[b], stats);
    Traverse(right_[a], right_[b], stats);
  }
}

void SelfBvh::LeafPair(int32_t na, int32_t nb, SelfBroadPhaseStats* stats) {
  PairTriangles(right_[na], right_[nb], node_lo_[na], node_hi_[na], node_lo_[nb], node_hi_[nb],
                stats);
}

// ---------------------------------------------------------------------------------------------
// SelfCcd

SelfCcdStats SelfCcd(SelfBroadPhase* broad, std::span<const Vec3> x0, std::span<const Vec3> x1,
                     const AllPairsCcdOptions& options, std::vector<CcdPairHit>* hits) {
  SelfCcdStats stats;
  hits->clear();
  stats.broad = broad->FindCandidates(x0, x1, options.ccd.thickness_m);
  if (stats.broad.overflow) {
    stats.overflow = true;
    return stats;
  }
  const std::span<const Triangle> triangles = broad->triangles();
  const std::span<const MeshEdge> edges = broad->edges();
  // Narrow phase over every candidate (collision/ccd_all_pairs.h's per-pair tests).
  for (const SelfCandidate& c : broad->candidates()) {
    CcdPairHit h;
    const bool hit =
        c.kind == CcdPairHit::Kind::kVertexTriangle
            ? VertexTrianglePairHit(x0, x1, c.first, c.second, triangles[c.second], options, &h)
            : EdgeEdgePairHit(x0, x1, c.first, edges[c.first], c.second, edges[c.second],
                              options, &h);
    if (!hit) continue;
    ++stats.hits;
    if (hits->size() < hits->capacity()) {
      hits->push_back(h);
    } else {
      stats.overflow = true;
    }
  }
  // AllPairsCcd's order: kind, then (first, second).
  std::sort(hits->begin(), hits->end(), [](const CcdPairHit& a, const CcdPairHit& b) {
    if (a.kind != b.kind) return a.kind < b.kind;
    if (a.first != b.first) return a.first < b.first;
    return a.second < b.second;
  });
  return stats;
}

}  // namespace felt
