#include "collision/bvh.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "base/simd.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__)
#include <immintrin.h>
#endif

namespace felt {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Fixed traversal stack: a depth-first walk holds at most (arity - 1) * depth + 1 nodes.
constexpr int32_t kMaxStack = 256;

// Outward rounding to float32 (PackedAabb). RoundDown(x) <= x for every double x: the nearest
// float f of x is within half an ulp of x, and f - max(|f|, 2^-80) 2^-23 lies at least one ulp
// below f (an ulp of a normal float is at most |f| 2^-23; 2^-103 covers the subnormals and the
// doubles that round to zero); overflow to +inf is clamped to FLT_MAX first so the result stays
// finite, -inf stays -inf (below x). Rounding is monotone, so RoundDown(min(a, b)) =
// min(RoundDown(a), RoundDown(b)): a box built from per-vertex bounds equals the rounded box of
// the exact one. NaN maps to FLT_MAX - pad (the box then holds nothing and prunes, as before).
constexpr float kPadFloor = 0x1p-80f;  // |f| below this pads by kPadFloor 2^-23 = 2^-103
constexpr float kPadRel = 0x1p-23f;    // one float ulp relative to |f|, rounded up
float RoundDown(double x) {
  float f = static_cast<float>(x);
  if (!(f <= std::numeric_limits<float>::max())) f = std::numeric_limits<float>::max();
  return f - std::max(std::fabs(f), kPadFloor) * kPadRel;
}

#if defined(__SSE2__)
// RoundDown on four lanes, the same operations (min(f, FLT_MAX) takes FLT_MAX for NaN, as the
// scalar test does).
__m128 RoundDown4(__m128 f) {
  f = _mm_min_ps(f, _mm_set1_ps(std::numeric_limits<float>::max()));
  const __m128 abs = _mm_and_ps(f, _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff)));
  return _mm_sub_ps(f, _mm_mul_ps(_mm_max_ps(abs, _mm_set1_ps(kPadFloor)), _mm_set1_ps(kPadRel)));
}
#endif

// The box of one point: lo = RoundDown(v), neg_hi = RoundDown(-v) (= -RoundUp(v)); padding
// lanes RoundDown(0) in both halves.
PackedAabb VertexBox(const Vec3& v) {
  PackedAabb b;
#if defined(__SSE2__)
  const __m128 f =
      _mm_movelh_ps(_mm_cvtpd_ps(_mm_loadu_pd(v.data())), _mm_cvtpd_ps(_mm_load_sd(v.data() + 2)));
  _mm_store_ps(b.lo, RoundDown4(f));
  _mm_store_ps(b.neg_hi, RoundDown4(_mm_xor_ps(f, _mm_set1_ps(-0.0f))));
#else
  for (int i = 0; i < 3; ++i) {
    b.lo[i] = RoundDown(v[i]);
    b.neg_hi[i] = RoundDown(-v[i]);
  }
  b.lo[3] = b.neg_hi[3] = RoundDown(0.0);
#endif
  return b;
}

// Lanewise minimum, a < b ? a : b per lane (MINPS's rule, also for NaN): merging two boxes.
PackedAabb MinBox(const PackedAabb& a, const PackedAabb& b) {
  PackedAabb m;
#if defined(__SSE2__)
  _mm_store_ps(m.lo, _mm_min_ps(_mm_load_ps(a.lo), _mm_load_ps(b.lo)));
  _mm_store_ps(m.neg_hi, _mm_min_ps(_mm_load_ps(a.neg_hi), _mm_load_ps(b.neg_hi)));
#else
  for (int i = 0; i < 4; ++i) {
    m.lo[i] = a.lo[i] < b.lo[i] ? a.lo[i] : b.lo[i];
    m.neg_hi[i] = a.neg_hi[i] < b.neg_hi[i] ? a.neg_hi[i] : b.neg_hi[i];
  }
#endif
  return m;
}

// 1 if any lane differs (NaN differs).
uint8_t DifferBox(const PackedAabb& a, const PackedAabb& b) {
#if defined(__SSE2__)
  const __m128 ne = _mm_or_ps(_mm_cmpneq_ps(_mm_load_ps(a.lo), _mm_load_ps(b.lo)),
                              _mm_cmpneq_ps(_mm_load_ps(a.neg_hi), _mm_load_ps(b.neg_hi)));
  return _mm_movemask_ps(ne) != 0;
#else
  uint8_t d = 0;
  for (int i = 0; i < 4; ++i) d |= (a.lo[i] != b.lo[i]) | (a.neg_hi[i] != b.neg_hi[i]);
  return d;
#endif
}

// AABB volume operations (van den Bergen 1997 for refitting boxes from children), on boxes
// stored as PackedAabb; the query tests convert them to double (exactly) and work as before.
struct AabbOps {
  using BV = PackedAabb;
  // Leaf box: the per-vertex boxes merged in the order SweepAabbExact's kernels use.
  static PackedAabb Leaf(const Vec3& a, const Vec3& b, const Vec3& c) {
    return MinBox(MinBox(VertexBox(a), VertexBox(b)), VertexBox(c));
  }
  static PackedAabb Merge(const PackedAabb& x, const PackedAabb& y) { return MinBox(x, y); }
  static bool Contains(const PackedAabb& outer, const PackedAabb& inner) {
    bool in = true;
    for (int i = 0; i < 4; ++i)
      in &= (outer.lo[i] <= inner.lo[i]) & (outer.neg_hi[i] <= inner.neg_hi[i]);
    return in;
  }
  static bool Equal(const PackedAabb& x, const PackedAabb& y) { return DifferBox(x, y) == 0; }
  static bool Differ(const PackedAabb& x, const PackedAabb& y) { return DifferBox(x, y) != 0; }
  // Enlarged by d on every side, rounded outward again (-(hi + d) = neg_hi - d).
  static PackedAabb Inflate(const PackedAabb& x, double d) {
    PackedAabb o = x;
    for (int i = 0; i < 3; ++i) {
      o.lo[i] = RoundDown(static_cast<double>(x.lo[i]) - d);
      o.neg_hi[i] = RoundDown(static_cast<double>(x.neg_hi[i]) - d);
    }
    return o;
  }
  // Is p within `reach` of the box?
  static bool Near(const PackedAabb& packed, const Vec3& p, double reach) {
    const Aabb x = packed.ToAabb();
    const Vec3 excess = (x.lo - p).cwiseMax(p - x.hi).cwiseMax(0.0);
    return excess.squaredNorm() <= reach * reach;
  }
  // First t in [0, t_max] at which p0 + t d is within `reach` of the box (the box enlarged by
  // reach on every side, a superset of its Minkowski sum with the sphere), or +inf; slab test,
  // Ericson §5.3.3.
  static double Entry(const PackedAabb& packed, const Vec3& p0, const Vec3& d, double reach,
                      double t_max) {
    const Aabb x = packed.ToAabb();
    double t0 = 0.0;
    double t1 = t_max;
    for (int i = 0; i < 3; ++i) {
      const double lo = x.lo[i] - reach;
      const double hi = x.hi[i] + reach;
      if (d[i] == 0.0) {
        if (p0[i] < lo || p0[i] > hi) return kInf;
        continue;
      }
      const double inv = 1.0 / d[i];
      double ta = (lo - p0[i]) * inv;
      double tb = (hi - p0[i]) * inv;
      if (ta > tb) std::swap(ta, tb);
      t0 = std::max(t0, ta);
      t1 = std::min(t1, tb);
      if (t0 > t1) return kInf;
    }
    return t0;
  }
};

// Sphere volume operations.
struct SphereOps {
  using BV = BoundingSphere;
  // The smallest sphere around a triangle: on the longest edge's midpoint when the triangle is
  // right or obtuse, else its circumcentre (Ericson §4.3.1 for minimum spheres; circumcentre by
  // the cross-product formula). The radius is the largest vertex distance, so it always encloses.
  static BoundingSphere Leaf(const Vec3& a, const Vec3& b, const Vec3& c) {
    const Vec3 ab = b - a;
    const Vec3 ac = c - a;
    Vec3 center;
    if (ab.dot(ac) <= 0.0) {
      center = 0.5 * (b + c);
    } else if ((a - b).dot(c - b) <= 0.0) {
      center = 0.5 * (a + c);
    } else if ((a - c).dot(b - c) <= 0.0) {
      center = 0.5 * (a + b);
    } else {
      const Vec3 n = ab.cross(ac);
      center = a + (ac.squaredNorm() * n.cross(ab) + ab.squaredNorm() * ac.cross(n)) /
                       (2.0 * n.squaredNorm());
    }
    const double r_sq = std::max(
        {(a - center).squaredNorm(), (b - center).squaredNorm(), (c - center).squaredNorm()});
    return {center, std::sqrt(r_sq)};
  }
  // The smallest sphere enclosing two spheres.
  static BoundingSphere Merge(const BoundingSphere& x, const BoundingSphere& y) {
    const Vec3 d = y.center - x.center;
    const double dist = d.norm();
    if (dist + y.radius <= x.radius) return x;
    if (dist + x.radius <= y.radius) return y;
    const double r = 0.5 * (dist + x.radius + y.radius);
    return {x.center + ((r - x.radius) / dist) * d, r};
  }
  static bool Contains(const BoundingSphere& outer, const BoundingSphere& inner) {
    return (outer.center - inner.center).norm() + inner.radius <= outer.radius;
  }
  static bool Equal(const BoundingSphere& x, const BoundingSphere& y) {
    return x.center == y.center && x.radius == y.radius;
  }
  static bool Differ(const BoundingSphere& x, const BoundingSphere& y) { return !Equal(x, y); }
  static BoundingSphere Inflate(const BoundingSphere& x, double d) {
    return {x.center, x.radius + d};
  }
  static bool Near(const BoundingSphere& x, const Vec3& p, double reach) {
    const double r = x.radius + reach;
    return (p - x.center).squaredNorm() <= r * r;
  }
  // Entry time of the ray into the sphere enlarged by reach (Ericson §5.3.2).
  static double Entry(const BoundingSphere& x, const Vec3& p0, const Vec3& d, double reach,
                      double t_max) {
    const Vec3 m = p0 - x.center;
    const double r = x.radius + reach;
    const double c = m.squaredNorm() - r * r;
    if (c <= 0.0) return 0.0;
    const double b = m.dot(d);
    if (b >= 0.0) return kInf;
    const double a = d.squaredNorm();
    const double disc = b * b - a * c;
    if (disc < 0.0) return kInf;
    const double t = (-b - std::sqrt(disc)) / a;
    return t <= t_max ? t : kInf;
  }
};

// The leaf and internal passes of the exact AABB repair (SweepAabbExact), on the per-vertex
// boxes of the current positions: what they read and write.
struct AabbSweepArgs {
  const Vec3* x;                  // [vertices] the positions, m
  int32_t num_vertices;           // how many of them the triangles use
  PackedAabb* vertex_box;         // [vertices] set to VertexBox of each position
  const Triangle* slot_vertices;  // [slots] the vertices of each leaf slot's triangle
  const int32_t* leaf_of_slot;    // [slots]
  int32_t num_slots;
  const int32_t* first_child;    // [nodes]
  const int32_t* num_children;   // [nodes]
  const int32_t* internal_desc;  // [internal nodes] decreasing ids
  int32_t num_internal;
  PackedAabb* box;   // [nodes] the stored boxes, rewritten
  uint8_t* changed;  // [nodes] 1 if the node's box changed
};

// Stored boxes that changed, and internal nodes with a changed child (001 §6.3's invalidated).
struct AabbSweepCounts {
  int32_t updates = 0;
  int32_t invalidated = 0;
};

// Portable passes: MinBox (SSE2 where available) and a lanewise comparison per node.
AabbSweepCounts SweepAabbPortable(const AabbSweepArgs& args) {
  // A local copy: the byte stores to `changed` may alias anything, and would make the fields be
  // reloaded through a reference on every iteration.
  const AabbSweepArgs a = args;
  AabbSweepCounts n;
  for (int32_t v = 0; v < a.num_vertices; ++v) a.vertex_box[v] = VertexBox(a.x[v]);
  for (int32_t s = 0; s < a.num_slots; ++s) {
    const Triangle& tr = a.slot_vertices[s];
    const PackedAabb fit =
        MinBox(MinBox(a.vertex_box[tr[0]], a.vertex_box[tr[1]]), a.vertex_box[tr[2]]);
    const int32_t node = a.leaf_of_slot[s];
    const uint8_t ch = DifferBox(a.box[node], fit);
    a.box[node] = fit;
    a.changed[node] = ch;
    n.updates += ch;
  }
  for (int32_t i = 0; i < a.num_internal; ++i) {
    const int32_t node = a.internal_desc[i];
    const int32_t first = a.first_child[node];
    PackedAabb fit = a.box[first];
    uint8_t need = a.changed[first];
    for (int32_t j = 1; j < a.num_children[node]; ++j) {
      fit = MinBox(fit, a.box[first + j]);
      need |= a.changed[first + j];
    }
    const uint8_t ch = need & DifferBox(a.box[node], fit);
    a.box[node] = fit;
    a.changed[node] = ch;
    n.updates += ch;
    n.invalidated += need;
  }
  return n;
}

#if defined(__x86_64__)
// The same passes with a box in one AVX register: a leaf is two VMINPS over its vertices' boxes,
// a parent of four one VMINPS per child, in MinBox's operand order (same bits as the portable
// passes, NaN included).
__attribute__((target("avx2"))) AabbSweepCounts SweepAabbAvx2(const AabbSweepArgs& a) {
  // Every field in a local: the byte stores to `changed` may alias anything, so reading the
  // fields through `a` would reload them on every iteration.
  int32_t updates = 0;
  int32_t invalidated = 0;
  PackedAabb* const vb = a.vertex_box;
  const Vec3* const x = a.x;
  const int32_t num_vertices = a.num_vertices;
  const Triangle* const slot_vertices = a.slot_vertices;
  const int32_t* const leaf_of_slot = a.leaf_of_slot;
  const int32_t num_slots = a.num_slots;
  const int32_t* const first_child = a.first_child;
  const int32_t* const num_children = a.num_children;
  const int32_t* const internal_desc = a.internal_desc;
  const int32_t num_internal = a.num_internal;
  uint8_t* const changed = a.changed;
  float* const box = a.box[0].lo;  // node i at box + 8 i
  for (int32_t v = 0; v < num_vertices; ++v) vb[v] = VertexBox(x[v]);
  for (int32_t s = 0; s < num_slots; ++s) {
    const Triangle& tr = slot_vertices[s];
    const __m256 fit =
        _mm256_min_ps(_mm256_min_ps(_mm256_load_ps(vb[tr[0]].lo), _mm256_load_ps(vb[tr[1]].lo)),
                      _mm256_load_ps(vb[tr[2]].lo));
    const int32_t node = leaf_of_slot[s];
    float* const o = box + 8 * static_cast<ptrdiff_t>(node);
    const __m256 ne = _mm256_cmp_ps(fit, _mm256_load_ps(o), _CMP_NEQ_UQ);
    _mm256_store_ps(o, fit);
    const uint8_t ch = _mm256_movemask_ps(ne) != 0;
    changed[node] = ch;
    updates += ch;
  }
  for (int32_t i = 0; i < num_internal; ++i) {
    const int32_t node = internal_desc[i];
    const int32_t first = first_child[node];
    const int32_t k = num_children[node];
    const float* const c = box + 8 * static_cast<ptrdiff_t>(first);
    __m256 fit = _mm256_load_ps(c);
    uint8_t need;
    if (k == 4) {  // the common case of a quad tree: no loop, the four flags in one load
      fit = _mm256_min_ps(fit, _mm256_load_ps(c + 8));
      fit = _mm256_min_ps(fit, _mm256_load_ps(c + 16));
      fit = _mm256_min_ps(fit, _mm256_load_ps(c + 24));
      uint32_t flags;
      std::memcpy(&flags, changed + first, sizeof flags);
      need = flags != 0;
    } else {
      need = changed[first];
      for (int32_t j = 1; j < k; ++j) {
        fit = _mm256_min_ps(fit, _mm256_load_ps(c + 8 * j));
        need |= changed[first + j];
      }
    }
    float* const o = box + 8 * static_cast<ptrdiff_t>(node);
    const __m256 ne = _mm256_cmp_ps(fit, _mm256_load_ps(o), _CMP_NEQ_UQ);
    _mm256_store_ps(o, fit);
    const uint8_t ch = need & static_cast<uint8_t>(_mm256_movemask_ps(ne) != 0);
    changed[node] = ch;
    updates += ch;
    invalidated += need;
  }
  return {updates, invalidated};
}
#endif

// The exact AABB repair's passes at each level (SimdTable): AVX2 from the AVX2 level up (AVX-512
// has no kernel of its own here), else the portable passes; the same bits (simd_kernels_test.cc).
using AabbSweepKernel = AabbSweepCounts (*)(const AabbSweepArgs& a);
#if defined(__x86_64__)
constexpr SimdTable<AabbSweepKernel> kAabbSweepKernels{SweepAabbPortable, SweepAabbAvx2,
                                                       SweepAabbAvx2};
#else
constexpr SimdTable<AabbSweepKernel> kAabbSweepKernels{SweepAabbPortable, SweepAabbPortable,
                                                       SweepAabbPortable};
#endif

}  // namespace

BvhTopology BvhTopology::Make(int32_t num_triangles, int32_t arity) {
  if (arity != 2 && arity != 4) {
    throw std::invalid_argument("BvhOptions.arity: must be 2 or 4, got " + std::to_string(arity));
  }
  if (num_triangles < 0) throw std::invalid_argument("BvhTopology: negative triangle count");
  BvhTopology t;
  t.arity = arity;
  if (num_triangles == 0) return t;
  const auto add = [&t](int32_t b, int32_t e, int32_t parent) {
    t.first_child.push_back(-1);
    t.num_children.push_back(0);
    t.parent.push_back(parent);
    t.begin.push_back(b);
    t.end.push_back(e);
  };
  add(0, num_triangles, -1);
  std::vector<int32_t> depth(1, 0);
  // Breadth-first: children are appended after every node already numbered, so parent < child.
  for (int32_t i = 0; i < static_cast<int32_t>(t.parent.size()); ++i) {
    const int64_t b = t.begin[i];
    const int64_t m = t.end[i] - t.begin[i];
    if (m == 1) continue;
    const int64_t k = std::min<int64_t>(arity, m);
    t.first_child[i] = static_cast<int32_t>(t.parent.size());
    t.num_children[i] = static_cast<int32_t>(k);
    ++t.num_internal;
    for (int64_t j = 0; j < k; ++j) {
      add(static_cast<int32_t>(b + m * j / k), static_cast<int32_t>(b + m * (j + 1) / k), i);
      depth.push_back(depth[i] + 1);
    }
  }
  t.leaf_of_slot.assign(static_cast<size_t>(num_triangles), -1);
  for (int32_t i = t.num_nodes() - 1; i >= 0; --i) {
    if (t.first_child[i] < 0) {
      t.leaves_desc.push_back(i);
      t.leaf_of_slot[static_cast<size_t>(t.begin[i])] = i;
    } else {
      t.internal_desc.push_back(i);
    }
  }
  t.depth = *std::max_element(depth.begin(), depth.end());
  if ((arity - 1) * t.depth + 1 > kMaxStack) {
    throw std::invalid_argument("BvhTopology: too many triangles for the traversal stack");
  }
  return t;
}

// The volume-type-specific work of a Bvh; one instantiation per volume kind, chosen once per call.
template <class Ops>
struct BvhImpl {
  using BV = typename Ops::BV;

  static std::vector<BV>& Bounds(Bvh& h) {
    if constexpr (std::is_same_v<BV, PackedAabb>) {
      return h.aabb_;
    } else {
      return h.sphere_;
    }
  }
  static const std::vector<BV>& Bounds(const Bvh& h) {
    if constexpr (std::is_same_v<BV, PackedAabb>) {
      return h.aabb_;
    } else {
      return h.sphere_;
    }
  }

  // Stores `fit` in `stored` if needed; returns whether the stored volume changed. Exact mode:
  // whenever it differs. Inflated mode: only when fit escapes it, and then enlarged by d.
  static bool Store(double d, BV* stored, const BV& fit) {
    if (d > 0.0) {
      if (Ops::Contains(*stored, fit)) return false;
      *stored = Ops::Inflate(fit, d);
      return true;
    }
    if (Ops::Equal(*stored, fit)) return false;
    *stored = fit;
    return true;
  }

  static BV MergeChildren(const BvhTopology& t, const std::vector<BV>& bv, int32_t node) {
    const int32_t first = t.first_child[node];
    BV merged = bv[first];
    for (int32_t k = 1; k < t.num_children[node]; ++k) merged = Ops::Merge(merged, bv[first + k]);
    return merged;
  }

  // Tight leaf volume of the triangle in leaf slot `slot` at one snapshot, or over two.
  struct LeafFit {
    const Triangle* slot_vertices;  // [triangles] Bvh::slot_vertices_
    std::span<const Vec3> x0;
    std::span<const Vec3> x1;  // empty: one snapshot
    BV operator()(int32_t slot) const {
      const Triangle& t = slot_vertices[slot];
      const BV fit0 = Ops::Leaf(x0[t[0]], x0[t[1]], x0[t[2]]);
      if (x1.empty()) return fit0;
      return Ops::Merge(fit0, Ops::Leaf(x1[t[0]], x1[t[1]], x1[t[2]]));
    }
  };

  // kBottomUp and kRebuild: one pass over the leaf slots, then one over the internal nodes in
  // decreasing id order (children before parents, since breadth-first ids put every parent before
  // its children: 001 §6.3). No queue and no branch on which node is invalidated: changed_[node]
  // records whether the node's stored volume changed, and a parent is "invalidated" (001 §6.3)
  // when one of its children changed. Exact mode (d = 0) stores every fit unconditionally: a
  // parent none of whose children changed merges the same stored volumes into the same result,
  // so the volumes and the counters equal those of kBottomUpQueue. `kAll`: kRebuild, every
  // volume rewritten and counted.
  template <bool kAll, bool kSwept>
  static RepairStats Sweep(Bvh& h, std::span<const Vec3> x0, std::span<const Vec3> x1) {
    const BvhTopology& t = *h.topology_;
    BV* bv = Bounds(h).data();
    uint8_t* changed = h.changed_.data();
    const double d = h.options_.inflation_m;
    const int32_t num_slots = static_cast<int32_t>(h.slot_vertices_.size());
    const Triangle* sv = h.slot_vertices_.data();
    const int32_t* leaf_of_slot = t.leaf_of_slot.data();
    const Vec3* p0 = x0.data();
    const Vec3* p1 = x1.data();
    int32_t updates = 0;
    // Leaves: every triangle's tight volume (over both snapshots when swept).
    for (int32_t s = 0; s < num_slots; ++s) {
      const Triangle& tr = sv[s];
      BV fit = Ops::Leaf(p0[tr[0]], p0[tr[1]], p0[tr[2]]);
      if constexpr (kSwept) fit = Ops::Merge(fit, Ops::Leaf(p1[tr[0]], p1[tr[1]], p1[tr[2]]));
      const int32_t node = leaf_of_slot[s];
      const uint8_t c = StoreFlat<kAll>(d, true, &bv[node], fit);
      changed[node] = c;
      updates += c;
    }
    // Internal nodes, deepest first.
    const int32_t* first_child = t.first_child.data();
    const int32_t* num_children = t.num_children.data();
    int32_t invalidated = 0;
    for (const int32_t node : t.internal_desc) {
      const int32_t first = first_child[node];
      const int32_t k = num_children[node];
      BV fit = bv[first];
      uint8_t need = changed[first];
      for (int32_t j = 1; j < k; ++j) {
        fit = Ops::Merge(fit, bv[first + j]);
        need |= changed[first + j];
      }
      const uint8_t c = StoreFlat<kAll>(d, need != 0, &bv[node], fit);
      changed[node] = c;
      updates += c;
      invalidated += need;
    }
    RepairStats stats;
    stats.leaves_refit = num_slots;
    stats.parents_refit = kAll ? t.num_internal : invalidated;
    stats.node_updates = updates;
    return stats;
  }

  // Sweep for exact AABB trees over one snapshot, the case the sim runs every frame: one pass
  // over the positions makes each vertex's rounded-outward float box (VertexBox), then a leaf is
  // the lanewise minimum of its three vertices' boxes and a parent that of its children's
  // (PackedAabb stores -hi, so min merges both bounds), each compared with the stored box and
  // stored. With the kernel of base/simd.h's level in use (AVX2 or the portable passes): the
  // same bits. Same volumes and counters as Sweep<false, false> (whose AabbOps::Leaf and Merge are
  // those minimums).
  static RepairStats SweepAabbExact(Bvh& h, std::span<const Vec3> x) {
    const BvhTopology& t = *h.topology_;
    const AabbSweepArgs args{x.data(),
                             static_cast<int32_t>(std::min(h.vertex_box_.size(), x.size())),
                             h.vertex_box_.data(),
                             h.slot_vertices_.data(),
                             t.leaf_of_slot.data(),
                             static_cast<int32_t>(h.slot_vertices_.size()),
                             t.first_child.data(),
                             t.num_children.data(),
                             t.internal_desc.data(),
                             static_cast<int32_t>(t.internal_desc.size()),
                             h.aabb_.data(),
                             h.changed_.data()};
    const AabbSweepCounts n = PickSimd(kAabbSweepKernels)(args);
    RepairStats stats;
    stats.leaves_refit = args.num_slots;
    stats.parents_refit = n.invalidated;
    stats.node_updates = n.updates;
    return stats;
  }

  // Sweep's store: returns 1 if the stored volume changed. Exact mode writes the fit whatever
  // `need` says (it equals the stored volume when no child changed); inflated mode writes only an
  // invalidated node whose fit escapes its stored volume, as Store does.
  template <bool kAll>
  static uint8_t StoreFlat(double d, bool need, BV* stored, const BV& fit) {
    if constexpr (kAll) {
      *stored = d > 0.0 ? Ops::Inflate(fit, d) : fit;
      return 1;
    } else {
      if (d > 0.0) {
        if (!need || Ops::Contains(*stored, fit)) return 0;
        *stored = Ops::Inflate(fit, d);
        return 1;
      }
      const uint8_t c = need & Ops::Differ(*stored, fit);
      *stored = fit;
      return c;
    }
  }

  // 001 §6.3: the leaves sit in an array in decreasing id order; a changed node queues its
  // parent. Nodes are taken in decreasing id order from the merge of the leaf array and the
  // queue; since a breadth-first parent id never increases as the child id decreases, the queue
  // fills in decreasing order and a parent already queued is always the last one added ("last
  // added parent" test), so each parent is refitted at most once, after all its children.
  static RepairStats BottomUpQueue(Bvh& h, const LeafFit& fit) {
    const BvhTopology& t = *h.topology_;
    std::vector<BV>& bv = Bounds(h);
    const double d = h.options_.inflation_m;
    RepairStats stats;
    int32_t* queue = h.queue_.data();
    int32_t head = 0;
    int32_t tail = 0;
    int32_t last_added = -1;
    size_t next_leaf = 0;
    const size_t num_leaves = t.leaves_desc.size();
    while (true) {
      // The larger id of the next leaf and the queue's head.
      int32_t node;
      const bool have_leaf = next_leaf < num_leaves;
      if (have_leaf && (head == tail || t.leaves_desc[next_leaf] > queue[head])) {
        node = t.leaves_desc[next_leaf++];
      } else if (head < tail) {
        node = queue[head++];
      } else {
        break;
      }
      // Refit it from its triangle or its children.
      bool changed;
      if (t.is_leaf(node)) {
        changed = Store(d, &bv[node], fit(t.begin[node]));
        ++stats.leaves_refit;
      } else {
        changed = Store(d, &bv[node], MergeChildren(t, bv, node));
        ++stats.parents_refit;
      }
      if (!changed) continue;
      ++stats.node_updates;
      const int32_t parent = t.parent[node];
      if (parent >= 0 && parent != last_added) {
        queue[tail++] = parent;
        last_added = parent;
      }
    }
    return stats;
  }

  // Recursive top-down refit: every child first, then the parent if any child changed.
  static bool TopDownNode(Bvh& h, const LeafFit& fit, int32_t node, RepairStats* stats) {
    const BvhTopology& t = *h.topology_;
    std::vector<BV>& bv = Bounds(h);
    const double d = h.options_.inflation_m;
    bool changed;
    if (t.is_leaf(node)) {
      changed = Store(d, &bv[node], fit(t.begin[node]));
      ++stats->leaves_refit;
    } else {
      bool any_child = false;
      for (int32_t k = 0; k < t.num_children[node]; ++k) {
        any_child = TopDownNode(h, fit, t.first_child[node] + k, stats) || any_child;
      }
      if (!any_child) return false;
      changed = Store(d, &bv[node], MergeChildren(t, bv, node));
      ++stats->parents_refit;
    }
    if (changed) ++stats->node_updates;
    return changed;
  }

  // Every volume recomputed from scratch in decreasing id order (children before parents).
  static RepairStats All(Bvh& h, const LeafFit& fit) {
    const BvhTopology& t = *h.topology_;
    std::vector<BV>& bv = Bounds(h);
    const double d = h.options_.inflation_m;
    RepairStats stats;
    for (int32_t node = t.num_nodes() - 1; node >= 0; --node) {
      BV v;
      if (t.is_leaf(node)) {
        v = fit(t.begin[node]);
        ++stats.leaves_refit;
      } else {
        v = MergeChildren(t, bv, node);
        ++stats.parents_refit;
      }
      bv[node] = d > 0.0 ? Ops::Inflate(v, d) : v;
      ++stats.node_updates;
    }
    return stats;
  }

  static RepairStats Run(Bvh& h, std::span<const Vec3> x0, std::span<const Vec3> x1) {
    const LeafFit fit{h.slot_vertices_.data(), x0, x1};
    if (h.topology_->num_nodes() == 0) return {};
    const bool swept = !x1.empty();
    switch (h.options_.repair) {
      case BvhRepair::kBottomUp:
        if (swept) return Sweep<false, true>(h, x0, x1);
        if constexpr (std::is_same_v<BV, PackedAabb>) {
          if (h.options_.inflation_m == 0.0) return SweepAabbExact(h, x0);
        }
        return Sweep<false, false>(h, x0, x1);
      case BvhRepair::kBottomUpQueue:
        return BottomUpQueue(h, fit);
      case BvhRepair::kTopDown: {
        RepairStats stats;
        TopDownNode(h, fit, 0, &stats);
        return stats;
      }
      case BvhRepair::kRebuild:
        break;
    }
    Partition(h, swept ? x1 : x0);
    return swept ? Sweep<true, true>(h, x0, x1) : Sweep<true, false>(h, x0, x1);
  }

  // Top-down median split (001 §4.1, "top-down ... using heuristics"): each internal node's range
  // of the leaf order is partitioned along the longest axis of its centroids' box so that every
  // child gets the triangles of its rank range. nth_element works in place (no allocation).
  static void Partition(Bvh& h, std::span<const Vec3> x) {
    const BvhTopology& t = *h.topology_;
    const std::vector<Triangle>& tris = *h.triangles_;
    for (size_t i = 0; i < tris.size(); ++i) {
      h.centroid_[i] = (x[tris[i][0]] + x[tris[i][1]] + x[tris[i][2]]) / 3.0;
    }
    int32_t* order = h.order_.data();
    const Vec3* centroid = h.centroid_.data();
    for (int32_t node = 0; node < t.num_nodes(); ++node) {
      if (t.is_leaf(node)) continue;
      const int32_t b = t.begin[node];
      const int32_t e = t.end[node];
      // Longest axis of the centroids' bounding box.
      Vec3 lo = centroid[order[b]];
      Vec3 hi = lo;
      for (int32_t s = b + 1; s < e; ++s) {
        lo = lo.cwiseMin(centroid[order[s]]);
        hi = hi.cwiseMax(centroid[order[s]]);
      }
      int axis;
      (hi - lo).maxCoeff(&axis);
      const auto less = [centroid, axis](int32_t i, int32_t j) {
        const double ci = centroid[i][axis];
        const double cj = centroid[j][axis];
        return ci < cj || (ci == cj && i < j);
      };
      // Split at each child's first slot, left to right.
      int32_t from = b;
      for (int32_t k = 1; k < t.num_children[node]; ++k) {
        const int32_t at = t.begin[t.first_child[node] + k];
        std::nth_element(order + from, order + at, order + e, less);
        from = at;
      }
    }
    // The leaf pass reads each slot's vertices directly.
    for (size_t slot = 0; slot < tris.size(); ++slot) h.slot_vertices_[slot] = tris[order[slot]];
  }

  // Query 1: depth-first walk of the volumes within r (+ slack) of p.
  static void Within(const Bvh& h, std::span<const Vec3> x, WithinAccumulator* acc) {
    const BvhTopology& t = *h.topology_;
    if (t.num_nodes() == 0) return;
    const std::vector<BV>& bv = Bounds(h);
    const std::vector<Triangle>& tris = *h.triangles_;
    const double reach = acc->r + CullSlack(acc->p, acc->p, acc->r);
    std::array<int32_t, kMaxStack> stack;
    int32_t top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const int32_t node = stack[--top];
      if (!Ops::Near(bv[node], acc->p, reach)) continue;
      if (t.is_leaf(node)) {
        const int32_t tri = h.order_[t.begin[node]];
        acc->Test(tri, tris[tri], x);
        continue;
      }
      for (int32_t k = t.num_children[node] - 1; k >= 0; --k) {
        stack[top++] = t.first_child[node] + k;
      }
    }
  }

  // Queries 2 and 3: depth-first along the segment p0 -> p1, nearest entry first, skipping
  // nodes entered after the best toi so far. `test(tri)` runs the per-triangle test.
  template <class Acc, class Test>
  static void Segment(const Bvh& h, const Vec3& p0, const Vec3& p1, double r, const Acc& acc,
                      Test&& test) {
    const BvhTopology& t = *h.topology_;
    if (t.num_nodes() == 0) return;
    const std::vector<BV>& bv = Bounds(h);
    const Vec3 d = p1 - p0;
    const double reach = r + CullSlack(p0, p1, r);
    struct Entry {
      int32_t node;
      double t;
    };
    std::array<Entry, kMaxStack> stack;
    int32_t top = 0;
    const double t_root = Ops::Entry(bv[0], p0, d, reach, 1.0);
    if (t_root == kInf) return;
    stack[top++] = {0, t_root};
    while (top > 0) {
      const Entry e = stack[--top];
      const double bound = std::min(1.0, acc.bound());
      if (e.t > bound) continue;
      if (t.is_leaf(e.node)) {
        test(h.order_[t.begin[e.node]]);
        continue;
      }
      // Children's entry times, pushed latest first so the earliest is popped next.
      std::array<Entry, 4> kids;
      int32_t n = 0;
      for (int32_t k = 0; k < t.num_children[e.node]; ++k) {
        const int32_t child = t.first_child[e.node] + k;
        const double tc = Ops::Entry(bv[child], p0, d, reach, bound);
        if (tc == kInf) continue;
        int32_t j = n++;
        while (j > 0 && kids[j - 1].t < tc) {
          kids[j] = kids[j - 1];
          --j;
        }
        kids[j] = {child, tc};
      }
      for (int32_t k = 0; k < n; ++k) stack[top++] = kids[k];
    }
  }
};

Bvh::Bvh(std::shared_ptr<const std::vector<Triangle>> triangles, std::span<const Vec3> x,
         const BvhOptions& options)
    : options_(options), triangles_(std::move(triangles)) {
  if (!triangles_) throw std::invalid_argument("Bvh: triangles must not be null");
  if (!(options_.inflation_m >= 0.0) || !std::isfinite(options_.inflation_m)) {
    throw std::invalid_argument("BvhOptions.inflation_m: must be finite and >= 0, got " +
                                std::to_string(options_.inflation_m));
  }
  const std::vector<Triangle>& tris = *triangles_;
  for (size_t i = 0; i < tris.size(); ++i) {
    for (int32_t v : tris[i]) {
      if (v < 0 || static_cast<size_t>(v) >= x.size()) {
        throw std::invalid_argument("Bvh: triangle " + std::to_string(i) + " has vertex index " +
                                    std::to_string(v) + " outside [0, " + std::to_string(x.size()) +
                                    ")");
      }
    }
  }
  topology_ = std::make_shared<const BvhTopology>(
      BvhTopology::Make(static_cast<int32_t>(tris.size()), options_.arity));
  // Sized once: nothing below or in any repair or query allocates.
  order_.resize(tris.size());
  std::iota(order_.begin(), order_.end(), 0);
  centroid_.resize(tris.size());
  slot_vertices_.resize(tris.size());
  changed_.resize(static_cast<size_t>(topology_->num_nodes()));
  queue_.resize(static_cast<size_t>(std::max(topology_->num_internal, 1)));
  if (options_.volume == BoundingVolume::kAabb) {
    aabb_.resize(static_cast<size_t>(topology_->num_nodes()));
    int32_t num_vertices = 0;
    for (const Triangle& tr : tris)
      num_vertices = std::max({num_vertices, tr[0] + 1, tr[1] + 1, tr[2] + 1});
    vertex_box_.resize(static_cast<size_t>(num_vertices));
    BvhImpl<AabbOps>::Partition(*this, x);
  } else {
    sphere_.resize(static_cast<size_t>(topology_->num_nodes()));
    BvhImpl<SphereOps>::Partition(*this, x);
  }
  RefitAll(x);
}

RepairStats Bvh::Repair(std::span<const Vec3> x) {
  covers_motion_ = false;
  return options_.volume == BoundingVolume::kAabb ? BvhImpl<AabbOps>::Run(*this, x, {})
                                                  : BvhImpl<SphereOps>::Run(*this, x, {});
}

RepairStats Bvh::RepairSwept(std::span<const Vec3> x_old, std::span<const Vec3> x_new) {
  covers_motion_ = true;
  return options_.volume == BoundingVolume::kAabb ? BvhImpl<AabbOps>::Run(*this, x_old, x_new)
                                                  : BvhImpl<SphereOps>::Run(*this, x_old, x_new);
}

RepairStats Bvh::RefitAll(std::span<const Vec3> x) {
  covers_motion_ = false;
  if (options_.volume == BoundingVolume::kAabb) {
    return BvhImpl<AabbOps>::All(*this, {slot_vertices_.data(), x, {}});
  }
  return BvhImpl<SphereOps>::All(*this, {slot_vertices_.data(), x, {}});
}

WithinResult Bvh::TrianglesWithin(std::span<const Vec3> x, const Vec3& p, double r,
                                  std::span<PointContact> out, bool ids_only) const {
  WithinAccumulator acc{p, r, out, {}, ids_only};
  if (options_.volume == BoundingVolume::kAabb) {
    BvhImpl<AabbOps>::Within(*this, x, &acc);
  } else {
    BvhImpl<SphereOps>::Within(*this, x, &acc);
  }
  return acc.result;
}

SweepHit Bvh::SweepSphere(std::span<const Vec3> x, const Vec3& p0, const Vec3& p1, double r) const {
  SweepAccumulator acc{p0, p1, r, {}};
  const std::vector<Triangle>& tris = *triangles_;
  const auto test = [&](int32_t tri) { acc.Test(tri, tris[tri], x); };
  if (options_.volume == BoundingVolume::kAabb) {
    BvhImpl<AabbOps>::Segment(*this, p0, p1, r, acc, test);
  } else {
    BvhImpl<SphereOps>::Segment(*this, p0, p1, r, acc, test);
  }
  return acc.best;
}

SweepHit Bvh::SweepSphereMoving(std::span<const Vec3> x_old, std::span<const Vec3> x_new,
                                const Vec3& c0, const Vec3& c1, double r,
                                const MovingContactOptions& options) const {
  // Without covers_motion_ the volumes do not bound the motion: every triangle (correct, O(n)).
  return SweepMovingOver(*triangles_, x_old, x_new, c0, c1, r, options, covers_motion_,
                         [&](const auto& test, const MovingAccumulator& acc) {
                           if (options_.volume == BoundingVolume::kAabb) {
                             BvhImpl<AabbOps>::Segment(*this, c0, c1, r, acc, test);
                           } else {
                             BvhImpl<SphereOps>::Segment(*this, c0, c1, r, acc, test);
                           }
                         });
}

}  // namespace felt
