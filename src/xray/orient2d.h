// Exact 2-D orientation test with a consistent tie-break, the predicate that
// makes the rasterizer watertight.
//
// orientSign(a, b, p) is the sign of det[a - p, b - p] =
// (ax - px)(by - py) - (ay - py)(bx - px), computed exactly for any double
// inputs: positive when p lies left of the directed line a -> b (in a frame
// whose y axis points up; the rasterizer only relies on consistency). When
// p lies exactly on the line, the tie is broken by simulation of simplicity,
// as if p were moved by (eps, eps^2): the sign of (ay - by), then of
// (bx - ax). The result is therefore never 0 for a != b, and
// orientSign(a, b, p) == -orientSign(b, a, p) exactly. Every sample point is
// then inside exactly one of the triangles that tile a region around it,
// whatever the rounding of the vertex coordinates: no cracks, no double hits.
//
// Written by hand (after Shewchuk, "Adaptive precision floating-point
// arithmetic and fast robust geometric predicates", 1997): no Debian package
// ships these predicates as a small library (CGAL's kernels would pull in
// GMP, MPFR and Boost for one function).
#pragma once

#include <cmath>

namespace xgauge::raster {

// Exact sign of the determinant, 0 when p is exactly on the line (slow path).
int exactOrientSign(double ax, double ay, double bx, double by, double px, double py);

inline int orientSign(double ax, double ay, double bx, double by, double px, double py) {
  // Fast filter: Shewchuk's error bound for this exact expression.
  constexpr double kEpsilon = 0x1p-53;
  constexpr double kBound = (3.0 + 16.0 * kEpsilon) * kEpsilon;
  const double left = (ax - px) * (by - py);
  const double right = (ay - py) * (bx - px);
  const double det = left - right;
  if (std::abs(det) > kBound * (std::abs(left) + std::abs(right))) return det > 0 ? 1 : -1;
  const int exact = exactOrientSign(ax, ay, bx, by, px, py);
  if (exact != 0) return exact;
  if (ay != by) return ay > by ? 1 : -1;
  if (bx != ax) return bx > ax ? 1 : -1;
  return 0;  // a == b: a degenerate edge
}

}  // namespace xgauge::raster
