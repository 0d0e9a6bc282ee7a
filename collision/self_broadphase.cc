#include "collision/self_broadphase.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

#include "base/check.h"

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
// SelfBvh

SelfBvh::SelfBvh(std::span<const Triangle> triangles, std::span<const Vec3> x,
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
  if (nt == 0) return;

  // Top-down median split of the centroids along the longest axis of their box; nodes in
  // pre-order (a parent before its children).
  std::vector<Vec3> centroid(triangles_.size());
  for (int32_t ti = 0; ti < nt; ++ti) {
    const Triangle& t = triangles_[ti];
    centroid[ti] = (x[t[0]] + x[t[1]] + x[t[2]]) / 3.0;
  }
  std::vector<int32_t> order(triangles_.size());
  std::iota(order.begin(), order.end(), 0);
  const auto build = [&](auto&& self, int32_t begin, int32_t end) -> int32_t {
    const int32_t node = static_cast<int32_t>(left_.size());
    left_.push_back(-1);
    right_.push_back(-1);
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
    const int32_t mid = begin + (end - begin) / 2;
    std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end,
                     [&](int32_t a, int32_t b) {
                       if (centroid[a][axis] != centroid[b][axis]) {
                         return centroid[a][axis] < centroid[b][axis];
                       }
                       return a < b;
                     });
    const int32_t l = self(self, begin, mid);
    const int32_t r = self(self, mid, end);
    left_[node] = l;
    right_[node] = r;
    return node;
  };
  build(build, 0, nt);
  node_lo_.resize(left_.size());
  node_hi_.resize(left_.size());
  // Pre-order reversed: children before parents.
  refit_order_.resize(left_.size());
  std::iota(refit_order_.rbegin(), refit_order_.rend(), 0);
}

bool SelfBvh::Overlap(int32_t a, int32_t b) const {
  return SelfBoxesOverlap(node_lo_[a], node_hi_[a], node_lo_[b], node_hi_[b]);
}

SelfBroadPhaseStats SelfBvh::FindCandidates(std::span<const Vec3> x0, std::span<const Vec3> x1,
                                            double thickness_m) {
  BeginStep(x0, x1, thickness_m);
  candidates_.clear();
  SelfBroadPhaseStats stats;
  if (left_.empty()) return stats;
  const double pad = SelfBroadPadding(thickness_m);

  // Swept, padded boxes of the vertices and edges.
  for (int32_t v = 0; v < num_vertices_; ++v) {
    vertex_lo_[v] = x0[v].cwiseMin(x1[v]).array() - pad;
    vertex_hi_[v] = x0[v].cwiseMax(x1[v]).array() + pad;
  }
  for (size_t i = 0; i < edges_.size(); ++i) {
    const MeshEdge& e = edges_[i];
    edge_lo_[i] = vertex_lo_[e[0]].cwiseMin(vertex_lo_[e[1]]);
    edge_hi_[i] = vertex_hi_[e[0]].cwiseMax(vertex_hi_[e[1]]);
  }
  // Bottom-up refit: leaves from their triangle's vertex boxes, then parents from children.
  for (int32_t node : refit_order_) {
    if (left_[node] < 0) {
      const Triangle& t = triangles_[right_[node]];
      node_lo_[node] = vertex_lo_[t[0]].cwiseMin(vertex_lo_[t[1]]).cwiseMin(vertex_lo_[t[2]]);
      node_hi_[node] = vertex_hi_[t[0]].cwiseMax(vertex_hi_[t[1]]).cwiseMax(vertex_hi_[t[2]]);
    } else {
      node_lo_[node] = node_lo_[left_[node]].cwiseMin(node_lo_[right_[node]]);
      node_hi_[node] = node_hi_[left_[node]].cwiseMax(node_hi_[right_[node]]);
    }
  }
  Traverse(0, 0, &stats);
  return stats;
}

void SelfBvh::Traverse(int32_t a, int32_t b, SelfBroadPhaseStats* stats) {
  // A node against itself: its children against themselves and each other.
  if (a == b) {
    if (left_[a] < 0) return;  // one triangle: its own features are all incident
    Traverse(left_[a], left_[a], stats);
    Traverse(right_[a], right_[a], stats);
    Traverse(left_[a], right_[a], stats);
    return;
  }
  if (!Overlap(a, b)) return;
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
  using Kind = CcdPairHit::Kind;
  const int32_t ta = right_[na], tb = right_[nb];
  // Vertices owned by one triangle against the other triangle.
  for (int32_t side = 0; side < 2; ++side) {
    const int32_t owner = side == 0 ? ta : tb;
    const int32_t other = side == 0 ? tb : ta;
    const int32_t other_node = side == 0 ? nb : na;
    for (int32_t v : owned_vertices_[owner]) {
      if (v < 0) break;
      if (SelfHasCorner(triangles_[other], v)) continue;
      if (SelfBoxesOverlap(vertex_lo_[v], vertex_hi_[v], node_lo_[other_node],
                           node_hi_[other_node])) {
        Emit(Kind::kVertexTriangle, v, other, stats);
      }
    }
  }
  // Edges owned by one against edges owned by the other.
  for (int32_t e : owned_edges_[ta]) {
    if (e < 0) break;
    for (int32_t f : owned_edges_[tb]) {
      if (f < 0) break;
      if (SelfEdgesTouch(edges_[e], edges_[f])) continue;
      if (SelfBoxesOverlap(edge_lo_[e], edge_hi_[e], edge_lo_[f], edge_hi_[f])) {
        Emit(Kind::kEdgeEdge, std::min(e, f), std::max(e, f), stats);
      }
    }
  }
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
