// Why along-the-ray booleans and not a boolean mesh (issue: CSG parts).
// Built only where CGAL is installed (Debian libcgal-dev; not a dependency of
// xgauge itself). Run: build/bench/csg_bench
//
// For Part 5 (parts/bracket.json, two boxes and three holes) at its nominal
// values, prints the median time of
//   - one CGAL corefinement into a single closed mesh (union of the plates,
//     then each hole subtracted; Surface_mesh, exact predicates, inexact
//     constructions): what a fit would pay per evaluation, before rendering;
//   - one render of the CSG part by xgauge's along-the-ray booleans at 256^2
//     (the coarse pyramid level where a fit spends most evaluations) and
//     1024^2, and of the corefined mesh with the plain renderer;
// and the largest path difference between the two renders.
#include "xgauge/core/memory.h"
#include "xgauge/core/parallel.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/xray/renderer.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/corefinement.h>
#include <CGAL/Polygon_mesh_processing/triangulate_faces.h>
#include <CGAL/Surface_mesh.h>

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <functional>

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Mesh = CGAL::Surface_mesh<Kernel::Point_3>;
namespace PMP = CGAL::Polygon_mesh_processing;
using namespace xgauge;

double medianMs(int repeats, const std::function<void()>& work) {
  std::vector<double> ms;
  for (int i = 0; i < repeats; ++i) {
    const auto start = std::chrono::steady_clock::now();
    work();
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
  }
  std::nth_element(ms.begin(), ms.begin() + repeats / 2, ms.end());
  return ms[static_cast<size_t>(repeats / 2)];
}

// Piece `p` of a CSG mesh as a CGAL surface mesh.
Mesh pieceMesh(const TriangleMesh& mesh, uint32_t first, uint32_t end) {
  Mesh out;
  std::vector<Mesh::Vertex_index> map(mesh.vertices.size());
  std::vector<bool> used(mesh.vertices.size(), false);
  for (uint32_t t = first; t < end; ++t)
    for (uint32_t v : mesh.triangles[t]) used[v] = true;
  for (size_t v = 0; v < mesh.vertices.size(); ++v)
    if (used[v])
      map[v] = out.add_vertex({mesh.vertices[v].x(), mesh.vertices[v].y(), mesh.vertices[v].z()});
  for (uint32_t t = first; t < end; ++t)
    out.add_face(map[mesh.triangles[t][0]], map[mesh.triangles[t][1]], map[mesh.triangles[t][2]]);
  return out;
}

TriangleMesh fromCgal(const Mesh& mesh) {
  TriangleMesh out;
  std::vector<uint32_t> index(mesh.number_of_vertices() + mesh.number_of_removed_vertices());
  for (auto v : mesh.vertices()) {
    index[v] = static_cast<uint32_t>(out.vertices.size());
    const auto& p = mesh.point(v);
    out.vertices.emplace_back(p.x(), p.y(), p.z());
  }
  for (auto f : mesh.faces()) {
    std::array<uint32_t, 3> t{};
    int k = 0;
    for (auto v : vertices_around_face(mesh.halfedge(f), mesh)) t[static_cast<size_t>(k++)] = index[v];
    out.triangles.push_back(t);
  }
  return out;
}

}  // namespace

int main() {
  keepLargeBlocksInHeap();  // as the command line does (core/memory.h)
  ThreadLimit limit(2);
  const PartModel part = PartModel::load(std::string(XGAUGE_SOURCE_DIR) + "/parts/bracket.json");
  const TriangleMesh csg = part.mesh(part.nominalValues());
  const auto ends = csg.csg->pieceTriangleEnds();

  Mesh result;
  const double corefine_ms = medianMs(9, [&] {
    std::vector<Mesh> pieces;
    uint32_t begin = 0;
    for (uint32_t end : ends) {
      pieces.push_back(pieceMesh(csg, begin, end));
      begin = end;
    }
    Mesh plates;
    PMP::corefine_and_compute_union(pieces[0], pieces[1], plates);
    for (size_t h = 2; h < pieces.size(); ++h) {
      Mesh cut;
      PMP::corefine_and_compute_difference(plates, pieces[h], cut);
      plates = std::move(cut);
    }
    PMP::triangulate_faces(plates);
    result = std::move(plates);
  });
  const TriangleMesh boolean_mesh = fromCgal(result);

  const Pose pose = Pose::fromEulerDeg({10, -35, 0}, {-12.0, -12.0, 713.0});
  const TransmissionTable table = TransmissionTable::forMaterial(
      ExponentialSum({{0.55, 0.035}, {0.35, 0.075}, {0.10, 0.25}}), 120.0);
  fmt::print("Part 5 (bracket), nominal values, 2 threads\n");
  fmt::print("  CGAL corefinement into one mesh: {:.2f} ms ({} triangles)\n", corefine_ms,
             boolean_mesh.triangles.size());
  for (int size : {256, 1024}) {
    Machine m;
    m.source_detector_distance_mm = 1000.0;
    m.columns = m.rows = size;
    m.pitch_u_mm = m.pitch_v_mm = 409.6 / size;
    m.cx_px = m.cy_px = 0.5 * size;
    std::vector<Vec3> world_csg, world_bool;
    poseVertices(pose, csg.vertices, world_csg);
    poseVertices(pose, boolean_mesh.vertices, world_bool);
    Image a(size, size), b(size, size);
    const double csg_ms = medianMs(15, [&] {
      renderIntensity(m, {world_csg, csg.triangles, csg.csg.get()}, table, {}, a);
    });
    const double mesh_ms =
        medianMs(15, [&] { renderIntensity(m, {world_bool, boolean_mesh.triangles}, table, {}, b); });
    ImageT<double> pa, pb;
    renderPathLength(m, {world_csg, csg.triangles, csg.csg.get()}, {}, pa);
    renderPathLength(m, {world_bool, boolean_mesh.triangles}, {}, pb);
    double worst = 0.0;
    for (int y = 0; y < size; ++y)
      for (int x = 0; x < size; ++x) worst = std::max(worst, std::abs(pa(x, y) - pb(x, y)));
    fmt::print(
        "  {}^2: along-the-ray CSG render {:.2f} ms; corefined mesh render {:.2f} ms "
        "(+ corefinement {:.2f} ms = {:.2f} ms); largest path difference {:.3g} mm\n",
        size, csg_ms, mesh_ms, corefine_ms, mesh_ms + corefine_ms, worst);
  }
  return 0;
}
