// Simple polygons in a plane: area, simplicity and triangulation (the caps of
// extruded profiles). Coordinates in any one unit; the predicates use plain
// double arithmetic, which is exact enough for profiles whose features are far
// above rounding (parts of millimetres, not 1e-12 mm).
#pragma once

#include "xgauge/core/transform.h"
#include "xgauge/geometry/mesh.h"

#include <span>
#include <string>
#include <vector>

namespace xgauge {

// Twice the triangle's signed area: > 0 when a, b, c turn counter-clockwise
// (x right, y up).
inline double orient2d(const Vec2& a, const Vec2& b, const Vec2& c) {
  return (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
}

// Shoelace formula: > 0 when the vertices run counter-clockwise.
double signedArea(std::span<const Vec2> polygon);

// Why the closed polygon (last vertex joined to the first) is not simple, or
// an empty string when it is: fewer than 3 vertices, a zero-length edge, two
// edges that touch or cross other than neighbours at their shared vertex, or
// an edge folding back onto its predecessor. Names vertices by index.
std::string simplePolygonProblem(std::span<const Vec2> polygon);

// Ear clipping, written here: Debian ships Mapbox's earcut only as a Python
// module (no C++ headers), and CGAL would be a large dependency for polygons
// of ten vertices. Cuts the best-shaped ear first (no slivers). The polygon
// must be simple; collinear vertices are allowed and never produce zero-area
// triangles. Returns n - 2 triangles indexing `polygon`, with the polygon's
// own winding. O(n^3): meant for profiles of tens of vertices. Throws Error
// if no ear is found (the polygon was not simple).
std::vector<Triangle> triangulatePolygon(std::span<const Vec2> polygon);

}  // namespace xgauge
