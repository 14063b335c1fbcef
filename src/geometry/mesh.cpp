#include "xgauge/geometry/mesh.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>

namespace xgauge {

double signedVolume(std::span<const Vec3> vertices, std::span<const Triangle> triangles) {
  if (vertices.empty()) return 0.0;
  // Sum of signed tetrahedra (origin, a, b, c) / 6. Taking the origin at a
  // vertex keeps the terms small for parts far from the part origin.
  const Vec3& origin = vertices.front();
  double six_volume = 0.0;
  for (const Triangle& t : triangles) {
    const Vec3 a = vertices[t[0]] - origin;
    const Vec3 b = vertices[t[1]] - origin;
    const Vec3 c = vertices[t[2]] - origin;
    six_volume += a.dot(b.cross(c));
  }
  return six_volume / 6.0;
}

double signedVolume(const TriangleMesh& mesh) { return signedVolume(mesh.vertices, mesh.triangles); }

BoundingBox boundingBox(const TriangleMesh& mesh) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  BoundingBox box{Vec3::Constant(kInf), Vec3::Constant(-kInf)};
  for (const Vec3& v : mesh.vertices) {
    box.min_mm = box.min_mm.cwiseMin(v);
    box.max_mm = box.max_mm.cwiseMax(v);
  }
  return box;
}

void flipOrientation(TriangleMesh& mesh) {
  for (Triangle& t : mesh.triangles) std::swap(t[1], t[2]);
}

namespace {

MeshCheck problem(MeshCheck::Problem kind, std::string message) {
  MeshCheck check;
  check.problem = kind;
  check.message = std::move(message);
  return check;
}

// One directed edge of a triangle, keyed by its undirected vertex pair.
struct EdgeUse {
  uint32_t lo, hi;    // lo < hi
  uint32_t triangle;  // index of the triangle using it
  bool forward;       // the triangle runs lo -> hi

  auto key() const { return std::tie(lo, hi, triangle); }
  bool operator<(const EdgeUse& other) const { return key() < other.key(); }
};

}  // namespace

MeshCheck checkClosedMesh(const TriangleMesh& mesh) {
  using P = MeshCheck::Problem;
  if (mesh.triangles.empty()) return problem(P::kEmpty, "the mesh has no triangles");

  // Indices and degenerate triangles.
  size_t zero_area = 0;
  const size_t vertex_count = mesh.vertices.size();
  const double diagonal = boundingBox(mesh).diagonal();
  const double min_twice_area = kZeroAreaTolerance * diagonal * diagonal;
  for (size_t i = 0; i < mesh.triangles.size(); ++i) {
    const Triangle& t = mesh.triangles[i];
    for (uint32_t v : t) {
      if (v >= vertex_count)
        return problem(P::kBadIndex, fmt::format("triangle {} uses vertex {}, but there are {}", i,
                                                 v, vertex_count));
    }
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0])
      return problem(P::kDegenerateTriangle,
                     fmt::format("triangle {} is degenerate: it repeats a vertex ({}, {}, {})", i,
                                 t[0], t[1], t[2]));
    // A sliver of three distinct, collinear vertices (CAD exports are full
    // of them) adds nothing to any path; the edge checks below decide
    // whether the surface around it is still closed.
    const Vec3& a = mesh.vertices[t[0]];
    const double twice_area = (mesh.vertices[t[1]] - a).cross(mesh.vertices[t[2]] - a).norm();
    if (!(twice_area > min_twice_area)) ++zero_area;
  }

  // Every undirected edge: exactly two uses, in opposite directions.
  std::vector<EdgeUse> uses;
  uses.reserve(3 * mesh.triangles.size());
  for (uint32_t i = 0; i < mesh.triangles.size(); ++i) {
    const Triangle& t = mesh.triangles[i];
    for (int k = 0; k < 3; ++k) {
      const uint32_t from = t[k], to = t[(k + 1) % 3];
      uses.push_back({std::min(from, to), std::max(from, to), i, from < to});
    }
  }
  std::sort(uses.begin(), uses.end());
  for (size_t begin = 0; begin < uses.size();) {
    size_t end = begin + 1;
    while (end < uses.size() && uses[end].lo == uses[begin].lo && uses[end].hi == uses[begin].hi)
      ++end;
    const EdgeUse& first = uses[begin];
    const size_t count = end - begin;
    if (count == 1)
      return problem(P::kOpenEdge,
                     fmt::format("edge ({}, {}) is used by 1 triangle (triangle {}): the mesh is "
                                 "open",
                                 first.lo, first.hi, first.triangle));
    if (count > 2)
      return problem(P::kNonManifoldEdge,
                     fmt::format("edge ({}, {}) is used by {} triangles: the mesh is not manifold",
                                 first.lo, first.hi, count));
    if (first.forward == uses[begin + 1].forward)
      return problem(P::kInconsistentOrientation,
                     fmt::format("edge ({}, {}) runs the same way in triangles {} and {}: the "
                                 "orientation is inconsistent",
                                 first.lo, first.hi, first.triangle, uses[begin + 1].triangle));
    begin = end;
  }

  // Outward: positive volume, beyond rounding noise.
  MeshCheck check;
  check.zero_area_triangles = zero_area;
  check.volume_mm3 = signedVolume(mesh);
  const double min_volume = kZeroAreaTolerance * diagonal * diagonal * diagonal;
  if (std::abs(check.volume_mm3) <= min_volume) {
    check.problem = P::kNoVolume;
    check.message = fmt::format("the mesh encloses no volume ({} mm^3)", check.volume_mm3);
  } else if (check.volume_mm3 < 0) {
    check.problem = P::kInward;
    check.message =
        fmt::format("triangles are oriented inward (negative volume, {} mm^3)", check.volume_mm3);
  }
  return check;
}

void noteZeroAreaTriangles(const MeshCheck& check, const std::string& source) {
  if (check.zero_area_triangles > 0)
    spdlog::info("{}: {} triangles have zero area; the surface is closed without them, and they "
                 "add nothing to any path",
                 source, check.zero_area_triangles);
}

void requireClosedMesh(const TriangleMesh& mesh, const SourceLocation& where) {
  const MeshCheck check = checkClosedMesh(mesh);
  if (!check.ok()) throw Error(check.message, where);
  noteZeroAreaTriangles(check, where.str());
}

}  // namespace xgauge
