#pragma once
// Exact orientation predicates on double coordinates, for the exact triangle-triangle test
// (collision/self_intersection.h): the sign of a determinant is computed in floating point and
// trusted when it exceeds Shewchuk's error bound, and otherwise recomputed exactly with expansion
// arithmetic (J. R. Shewchuk, "Adaptive Precision Floating-Point Arithmetic and Fast Robust
// Geometric Predicates", Discrete & Computational Geometry 18, 1997). Exact for finite inputs
// whose products neither overflow nor underflow (coordinates of magnitude 1e-100..1e100 or 0).
// No allocation, no exceptions (real-time safe); the exact path costs about a microsecond.

#include "collision/mesh.h"

namespace felt {

/// Sign (-1, 0 or +1) of the exact value of ((b - a) x (c - a)) . (d - a) for positions a, b, c, d
/// [m, one frame]: +1 when d lies on the side of the plane (a, b, c) that its normal
/// (b - a) x (c - a) points to, 0 when the four points are exactly coplanar (also when a, b, c
/// are collinear). Real-time safe.
int Orient3D(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

/// Sign (-1, 0 or +1) of the exact value of ((b - a) x (c - a))[axis] (axis 0, 1 or 2): the
/// orientation of a, b, c [m] projected onto the coordinate plane orthogonal to `axis`, its two
/// axes taken in cyclic order (axis 2: (x, y); axis 0: (y, z); axis 1: (z, x)), +1 when
/// counter-clockwise. Real-time safe.
int Orient2D(const Vec3& a, const Vec3& b, const Vec3& c, int axis);

/// True when a, b, c [m] are exactly collinear (including repeated points): (b - a) x (c - a) is
/// exactly the zero vector. Real-time safe.
bool ExactlyCollinear(const Vec3& a, const Vec3& b, const Vec3& c);

}  // namespace felt
