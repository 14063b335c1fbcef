#include "xgauge/xray/contour.h"

#include <algorithm>
#include <cstdint>
#include <utility>

namespace xgauge {

std::vector<Segment2> projectedContour(const Machine& machine, const WorldMesh& mesh) {
  const Vec3 source = machine.sourceWorld();
  // Each directed edge (a, b) of a triangle, keyed by its sorted vertex pair,
  // with whether that triangle faces the source.
  struct Edge {
    uint32_t lo, hi;
    bool front;
  };
  std::vector<Edge> edges;
  edges.reserve(mesh.triangles.size() * 3);
  for (const auto& t : mesh.triangles) {
    const Vec3& a = mesh.vertices_mm[t[0]];
    const Vec3& b = mesh.vertices_mm[t[1]];
    const Vec3& c = mesh.vertices_mm[t[2]];
    const bool front = (b - a).cross(c - a).dot(source - a) > 0.0;
    for (int k = 0; k < 3; ++k) {
      const uint32_t u = t[static_cast<size_t>(k)], v = t[static_cast<size_t>((k + 1) % 3)];
      edges.push_back({std::min(u, v), std::max(u, v), front});
    }
  }
  std::stable_sort(edges.begin(), edges.end(), [](const Edge& x, const Edge& y) {
    return std::pair(x.lo, x.hi) < std::pair(y.lo, y.hi);
  });
  std::vector<Segment2> out;
  for (size_t i = 0; i < edges.size();) {
    size_t j = i;
    bool front = false, back = false;
    for (; j < edges.size() && edges[j].lo == edges[i].lo && edges[j].hi == edges[i].hi; ++j)
      (edges[j].front ? front : back) = true;
    if ((front && back) || j - i == 1)
      out.push_back({machine.project(mesh.vertices_mm[edges[i].lo]),
                     machine.project(mesh.vertices_mm[edges[i].hi])});
    i = j;
  }
  return out;
}

}  // namespace xgauge
