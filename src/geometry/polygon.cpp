#include "xgauge/geometry/polygon.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace xgauge {

double signedArea(std::span<const Vec2> polygon) {
  double twice_area = 0.0;
  for (size_t i = 0, n = polygon.size(); i < n; ++i) {
    const Vec2& a = polygon[i];
    const Vec2& b = polygon[(i + 1) % n];
    twice_area += a.x() * b.y() - b.x() * a.y();
  }
  return twice_area / 2.0;
}

namespace {

// p lies on the closed segment [a, b], given that the three are collinear.
bool withinSegment(const Vec2& a, const Vec2& b, const Vec2& p) {
  return p.x() >= std::min(a.x(), b.x()) && p.x() <= std::max(a.x(), b.x()) &&
         p.y() >= std::min(a.y(), b.y()) && p.y() <= std::max(a.y(), b.y());
}

// The closed segments [p1, p2] and [q1, q2] share at least one point.
bool segmentsTouch(const Vec2& p1, const Vec2& p2, const Vec2& q1, const Vec2& q2) {
  const double d1 = orient2d(q1, q2, p1), d2 = orient2d(q1, q2, p2);
  const double d3 = orient2d(p1, p2, q1), d4 = orient2d(p1, p2, q2);
  if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0)))
    return true;
  return (d1 == 0 && withinSegment(q1, q2, p1)) || (d2 == 0 && withinSegment(q1, q2, p2)) ||
         (d3 == 0 && withinSegment(p1, p2, q1)) || (d4 == 0 && withinSegment(p1, p2, q2));
}

}  // namespace

std::string simplePolygonProblem(std::span<const Vec2> polygon) {
  const size_t n = polygon.size();
  if (n < 3) return fmt::format("a polygon needs at least 3 vertices, this one has {}", n);
  for (size_t i = 0; i < n; ++i) {
    const size_t j = (i + 1) % n;
    if (polygon[i] == polygon[j])
      return fmt::format("vertices {} and {} coincide (zero-length edge)", i, j);
  }
  for (size_t i = 0; i < n; ++i) {
    // Neighbouring edges (i-1 -> i, i -> i+1) may only meet at vertex i.
    const Vec2& before = polygon[(i + n - 1) % n];
    const Vec2& at = polygon[i];
    const Vec2& after = polygon[(i + 1) % n];
    if (orient2d(before, at, after) == 0 && (at - before).dot(after - at) < 0)
      return fmt::format("the edges at vertex {} fold back onto each other", i);
  }
  for (size_t i = 0; i < n; ++i) {
    // Other edges must not touch at all.
    for (size_t j = i + 2; j < n; ++j) {
      if (i == 0 && j == n - 1) continue;  // neighbours through the closing edge
      if (segmentsTouch(polygon[i], polygon[i + 1], polygon[j], polygon[(j + 1) % n]))
        return fmt::format("edges {}-{} and {}-{} touch or cross", i, i + 1, j, (j + 1) % n);
    }
  }
  return {};
}

std::vector<Triangle> triangulatePolygon(std::span<const Vec2> polygon) {
  const size_t n = polygon.size();
  if (n < 3) fail("cannot triangulate a polygon of {} vertices", n);
  // Work as if counter-clockwise; `sign` folds the winding into every test.
  const double sign = signedArea(polygon) > 0 ? 1.0 : -1.0;
  auto turnsLeft = [&](uint32_t a, uint32_t b, uint32_t c) {
    return sign * orient2d(polygon[a], polygon[b], polygon[c]) > 0;
  };
  std::vector<uint32_t> ring(n);
  std::iota(ring.begin(), ring.end(), 0u);

  // An ear: a strictly convex corner whose triangle holds no other remaining
  // vertex, not even on its boundary (so a collinear vertex on the diagonal
  // keeps the corner from being cut, which would leave a zero-area triangle).
  auto isEar = [&](uint32_t a, uint32_t b, uint32_t c) {
    if (!turnsLeft(a, b, c)) return false;
    for (uint32_t v : ring) {
      if (v == a || v == b || v == c) continue;
      const Vec2& p = polygon[v];
      if (sign * orient2d(polygon[a], polygon[b], p) >= 0 &&
          sign * orient2d(polygon[b], polygon[c], p) >= 0 &&
          sign * orient2d(polygon[c], polygon[a], p) >= 0)
        return false;
    }
    return true;
  };
  // Shape quality in (0, 1], 1 for an equilateral triangle. Cutting the best
  // ear first avoids slivers, which keeps the triangulation valid over a
  // wider range of dimension values around the nominal ones.
  auto quality = [&](uint32_t a, uint32_t b, uint32_t c) {
    const Vec2 &pa = polygon[a], &pb = polygon[b], &pc = polygon[c];
    const double squares =
        (pb - pa).squaredNorm() + (pc - pb).squaredNorm() + (pa - pc).squaredNorm();
    return 2.0 * std::sqrt(3.0) * std::abs(orient2d(pa, pb, pc)) / squares;
  };

  std::vector<Triangle> triangles;
  triangles.reserve(n - 2);
  while (ring.size() > 3) {
    const size_t m = ring.size();
    size_t best = m;
    double best_quality = 0.0;
    for (size_t at = 0; at < m; ++at) {
      const uint32_t a = ring[(at + m - 1) % m], b = ring[at], c = ring[(at + 1) % m];
      if (!isEar(a, b, c)) continue;
      const double q = quality(a, b, c);
      if (best == m || q > best_quality) best = at, best_quality = q;
    }
    if (best == m) fail("cannot triangulate the polygon: no ear left (is it simple?)");
    triangles.push_back({ring[(best + m - 1) % m], ring[best], ring[(best + 1) % m]});
    ring.erase(ring.begin() + static_cast<std::ptrdiff_t>(best));
  }
  if (!turnsLeft(ring[0], ring[1], ring[2]))
    fail("cannot triangulate the polygon: the last triangle has zero area (is it simple?)");
  triangles.push_back({ring[0], ring[1], ring[2]});
  return triangles;
}

}  // namespace xgauge
