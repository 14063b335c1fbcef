#include "xgauge/geometry/mesh.h"

#include "smallest_root_sets.h"

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <tuple>
#include <unordered_map>

namespace xgauge {

double signedVolume(std::span<const Vec3> vertices, std::span<const Triangle> triangles) {
  if (vertices.empty()) return 0.0;
  // Sum of signed tetrahedra (origin, a, b, c) / 6. Taking the origin at a
  // vertex keeps the terms small for parts far from the part origin. Summed
  // by fixed blocks of triangles, the blocks on every core and their sums
  // in order: the same number on any thread count (a fit checks every
  // evaluation's volume).
  constexpr size_t kBlock = 4096;
  const Vec3& origin = vertices.front();
  const size_t blocks = (triangles.size() + kBlock - 1) / kBlock;
  std::vector<double> six_volumes(blocks, 0.0);
  const auto sum_block = [&](size_t b) {
    double six_volume = 0.0;
    for (size_t i = b * kBlock; i < std::min(triangles.size(), (b + 1) * kBlock); ++i) {
      const Triangle& t = triangles[i];
      const Vec3 a = vertices[t[0]] - origin;
      const Vec3 bv = vertices[t[1]] - origin;
      const Vec3 c = vertices[t[2]] - origin;
      six_volume += a.dot(bv.cross(c));
    }
    six_volumes[b] = six_volume;
  };
  if (blocks > 1) {
    tbb::parallel_for(size_t{0}, blocks, sum_block);
  } else if (blocks == 1) {
    sum_block(0);
  }
  return std::accumulate(six_volumes.begin(), six_volumes.end(), 0.0) / 6.0;
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

namespace {

struct CellHash {
  size_t operator()(const std::array<int64_t, 3>& cell) const {
    uint64_t h = 1469598103934665603ull;
    for (int64_t c : cell) h = (h ^ static_cast<uint64_t>(c)) * 1099511628211ull;
    return static_cast<size_t>(h);
  }
};

// For each vertex, the smallest index of a vertex within `tolerance` of it in
// every coordinate (chains included). Vertices are bucketed in a grid of
// cells `tolerance` wide, so only the 27 surrounding cells need comparing.
std::vector<uint32_t> mergeClose(const std::vector<Vec3>& vertices, const Vec3& origin,
                                 double tolerance) {
  SmallestRootSets sets(vertices.size());
  std::unordered_map<std::array<int64_t, 3>, std::vector<uint32_t>, CellHash> cells;
  auto cellOf = [&](const Vec3& v) {
    const Vec3 scaled = ((v - origin) / tolerance).array().floor().matrix();
    return std::array<int64_t, 3>{static_cast<int64_t>(scaled.x()),
                                  static_cast<int64_t>(scaled.y()),
                                  static_cast<int64_t>(scaled.z())};
  };
  for (uint32_t i = 0; i < vertices.size(); ++i) cells[cellOf(vertices[i])].push_back(i);
  for (uint32_t i = 0; i < vertices.size(); ++i) {
    const auto cell = cellOf(vertices[i]);
    for (int64_t dx = -1; dx <= 1; ++dx)
      for (int64_t dy = -1; dy <= 1; ++dy)
        for (int64_t dz = -1; dz <= 1; ++dz) {
          const auto found = cells.find({cell[0] + dx, cell[1] + dy, cell[2] + dz});
          if (found == cells.end()) continue;
          for (uint32_t j : found->second)
            if (j > i && (vertices[i] - vertices[j]).cwiseAbs().maxCoeff() <= tolerance)
              sets.join(i, j);
        }
  }
  std::vector<uint32_t> representative(vertices.size());
  for (uint32_t i = 0; i < vertices.size(); ++i) representative[i] = sets.root(i);
  return representative;
}

struct PointHash {
  size_t operator()(const Vec3& p) const {  // +0.0 and -0.0 hash alike
    size_t h = std::hash<double>{}(p.x());
    h = h * 1000003u ^ std::hash<double>{}(p.y());
    return h * 1000003u ^ std::hash<double>{}(p.z());
  }
};

// `kept`, when given, receives the soup index of every triangle of the result.
TriangleMesh weld(const TriangleSoup& soup, const std::string& file, std::vector<uint32_t>* kept) {
  // Exact matches first.
  TriangleMesh mesh;
  std::unordered_map<Vec3, uint32_t, PointHash> index_of;
  mesh.triangles.reserve(soup.size());
  for (const auto& corners : soup) {
    Triangle& t = mesh.triangles.emplace_back();
    for (int c = 0; c < 3; ++c) {
      const auto [it, added] =
          index_of.try_emplace(corners[c], static_cast<uint32_t>(mesh.vertices.size()));
      if (added) mesh.vertices.push_back(corners[c]);
      t[c] = it->second;
    }
  }

  // Then near matches; keep the surviving vertices in their first-seen order.
  const BoundingBox box = boundingBox(mesh);
  const double tolerance = kWeldTolerance * box.diagonal();
  if (tolerance > 0) {
    const std::vector<uint32_t> representative = mergeClose(mesh.vertices, box.min_mm, tolerance);
    std::vector<uint32_t> new_index(mesh.vertices.size());
    std::vector<Vec3> survivors;
    for (uint32_t i = 0; i < mesh.vertices.size(); ++i) {
      if (representative[i] == i) {
        new_index[i] = static_cast<uint32_t>(survivors.size());
        survivors.push_back(mesh.vertices[i]);
      } else {
        new_index[i] = new_index[representative[i]];  // representative[i] < i
      }
    }
    mesh.vertices = std::move(survivors);
    for (Triangle& t : mesh.triangles)
      for (uint32_t& v : t) v = new_index[v];
  }

  // Triangles that lost a corner to welding cover no area: drop them.
  const size_t before = mesh.triangles.size();
  std::vector<Triangle> surviving;
  surviving.reserve(before);
  if (kept) kept->clear();
  for (size_t i = 0; i < before; ++i) {
    const Triangle& t = mesh.triangles[i];
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) continue;
    surviving.push_back(t);
    if (kept) kept->push_back(static_cast<uint32_t>(i));
  }
  mesh.triangles = std::move(surviving);
  if (mesh.triangles.size() != before)
    spdlog::warn("{}: dropped {} triangles that collapsed when welding vertices", file,
                 before - mesh.triangles.size());
  return mesh;
}

}  // namespace

TriangleMesh closedMeshFromSoup(const TriangleSoup& soup, const std::string& source,
                                std::vector<uint32_t>* kept) {
  TriangleMesh mesh = weld(soup, source, kept);
  const MeshCheck check = checkClosedMesh(mesh);
  if (check.problem == MeshCheck::Problem::kInward) {
    spdlog::warn("{}: triangles face inward; flipped them all", source);
    flipOrientation(mesh);
  } else if (!check.ok()) {
    throw Error(check.message, SourceLocation::inFile(source));
  }
  noteZeroAreaTriangles(check, source);
  return mesh;
}

}  // namespace xgauge
