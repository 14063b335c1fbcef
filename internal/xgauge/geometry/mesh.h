// Triangle meshes of closed solids, and the checks that make them safe to
// render: a watertight ray caster needs every edge shared by exactly two
// triangles with opposite directions and every normal pointing outward.
#pragma once

#include "xgauge/core/error.h"
#include "xgauge/core/transform.h"
#include "xgauge/geometry/csg.h"

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace xgauge {

// Three vertex indices, counter-clockwise seen from outside the solid: the
// outward normal is (b - a) x (c - a) (right-hand rule).
using Triangle = std::array<uint32_t, 3>;

// A closed surface in part coordinates (mm). Vertices are shared between the
// triangles that meet there (indexed, not a triangle soup).
// A CSG part (csg.h) is several closed surfaces, one per piece, in
// consecutive triangle ranges, with `csg` saying how they combine.
struct TriangleMesh {
  std::vector<Vec3> vertices;
  std::vector<Triangle> triangles;
  std::shared_ptr<const Csg> csg;  // null: the mesh is one solid
};

// Axis-aligned box, mm. An empty mesh gives min = +inf, max = -inf.
struct BoundingBox {
  Vec3 min_mm;
  Vec3 max_mm;
  double diagonal() const { return (max_mm - min_mm).norm(); }  // mm
};

// Signed enclosed volume in mm^3 by the divergence theorem: positive when the
// triangles face outward. Meaningful for a closed mesh only.
double signedVolume(const TriangleMesh& mesh);
double signedVolume(std::span<const Vec3> vertices, std::span<const Triangle> triangles);

// Box of all vertices (referenced by a triangle or not).
BoundingBox boundingBox(const TriangleMesh& mesh);

// Reverses every triangle (outward <-> inward).
void flipOrientation(TriangleMesh& mesh);

// Outcome of checkClosedMesh: the first problem found, checked in this order.
struct MeshCheck {
  enum class Problem {
    kNone,
    kEmpty,                    // no triangles
    kBadIndex,                 // a vertex index out of range
    kDegenerateTriangle,       // repeated vertex index
    kOpenEdge,                 // an edge used by one triangle only
    kNonManifoldEdge,          // an edge used by more than two triangles
    kInconsistentOrientation,  // two triangles run along their edge the same way
    kNoVolume,                 // closed and consistent, but encloses nothing
    kInward,                   // closed and consistent, negative volume
  };
  Problem problem = Problem::kNone;
  std::string message;      // names the first problem; empty when ok()
  double volume_mm3 = 0.0;  // signed volume, set when the edges passed
  // Triangles of (almost) zero area with three distinct vertices: accepted,
  // since they add nothing to any path; counted for a note.
  size_t zero_area_triangles = 0;

  bool ok() const { return problem == Problem::kNone; }
};

// Relative tolerance of the zero-area and zero-volume tests: a triangle is
// degenerate when twice its area is at most kZeroAreaTolerance * d^2, d the
// bounding box diagonal (rounding noise of collinear points is ~1e-16 d^2).
inline constexpr double kZeroAreaTolerance = 1e-12;

// Checks that the mesh bounds a solid: no degenerate triangle, every
// undirected edge used by exactly two triangles in opposite directions
// (closed, manifold, consistently oriented) and positive volume (outward).
MeshCheck checkClosedMesh(const TriangleMesh& mesh);

// An info message when the check accepted zero-area triangles.
void noteZeroAreaTriangles(const MeshCheck& check, const std::string& source);

// checkClosedMesh, throwing Error(message, where) on the first problem.
void requireClosedMesh(const TriangleMesh& mesh, const SourceLocation& where);

// Three corners per triangle, as a file gives them: an STL's facets (stl.h),
// the triangles of a tessellated STEP solid (step.h).
using TriangleSoup = std::vector<std::array<Vec3, 3>>;

// Relative tolerance of the second welding pass of closedMeshFromSoup.
inline constexpr double kWeldTolerance = 1e-9;

// The common end of the readers of fixed meshes (STL, STEP): the soup as a
// closed, outward, indexed mesh. Welding: vertices with identical
// coordinates become one vertex; then vertices whose coordinates all differ
// by at most kWeldTolerance times the bounding box diagonal are merged as
// well (writers that rounded one point two ways). Triangles that collapse in
// welding (a repeated vertex) are dropped with a warning. The welded mesh
// must pass checkClosedMesh; one that is closed and consistent but faces
// inward is flipped with a warning. Every other problem throws Error located
// in the file `source`. `kept`, when given, receives for every triangle of
// the result the index of the soup triangle it came from (in order).
TriangleMesh closedMeshFromSoup(const TriangleSoup& soup, const std::string& source,
                                std::vector<uint32_t>* kept = nullptr);

}  // namespace xgauge
