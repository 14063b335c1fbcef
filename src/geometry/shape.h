// The shapes a part model file describes (its "shape" object): how they are
// read, how their fixed topology is built from the nominal values, and how
// their vertices are placed for other values. Keys are documented in
// xgauge/geometry/part_model.h.
#pragma once

#include "expression.h"

#include "xgauge/core/config.h"
#include "xgauge/geometry/mesh.h"

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <span>
#include <string_view>
#include <vector>

namespace xgauge {

enum class ShapeType { kExtrusion, kRevolution, kMesh, kFixed, kFaced };

struct FacedStep;

// A shape as read from the file. Its scalars are the expressions whose values
// place the vertices:
//   extrusion:  a_0, b_0, a_1, b_1, ... (profile), then from, to
//   revolution: r_0, h_0, r_1, h_1, ... (profile: radius, axial position)
//   mesh:       x_0, y_0, z_0, x_1, ...
//   stl, step:  none (the vertices are fixed)
//   faced:      a STEP solid with dimensions on its faces (face_moves.h):
//               the dimensions that move faces, then the "surfaces" entries'
//               expressions
struct ShapeSpec {
  ShapeType type = ShapeType::kMesh;
  SourceLocation where;  // the "shape" object
  SourceLocation profile_where;  // extrusion, revolution: where the profile was written
  std::vector<ExpressionSource> scalars;
  // extrusion: the profile's two axes, then the extrusion axis;
  // revolution: (u, v, axis), right-handed, angle measured from u towards v.
  std::array<int, 3> axes{0, 1, 2};
  int segments = 0;                 // revolution; 0: enough for a 0.001 mm chord error
  std::vector<Triangle> triangles;  // mesh
  TriangleMesh fixed;               // stl, step: the mesh read from the file
  std::filesystem::path file;       // stl, step, faced: the file read
  std::string file_sha256;          // ... and the SHA-256 of its bytes
  std::shared_ptr<const FacedStep> faced;  // faced: the solid and its moves
};

struct FaceMoveSources;

// Reads one primitive solid: "extrusion" (without holes), "revolution",
// "box", "cylinder", "mesh", "stl" or "step" (boxes become extrusions,
// cylinders revolutions; STL and STEP files fixed meshes, or, for the STEP
// solid that `faces` moves, a faced shape). Relative STL and STEP paths are
// taken from `directory`. Placement keys and holes are read by the solid
// (solid.h). `faces` (may be null) is consumed by the first "step" shape:
// a second one with face moves pending is refused.
ShapeSpec readShapeSpec(const ConfigNode& shape, const std::filesystem::path& directory,
                        const FaceMoveSources* faces, bool& faces_taken);

// Segments that keep an inscribed polygon of this radius (mm) within
// `chord_error_mm` of its circle (the sagitta r (1 - cos(pi / N))), at least 8.
int segmentsForChordError(double radius_mm, double chord_error_mm);

// A shape with its topology fixed. Vertex count and order never change.
class Shape {
 public:
  virtual ~Shape() = default;

  const std::vector<Triangle>& triangles() const { return triangles_; }
  size_t vertexCount() const { return vertex_count_; }

  // Vertex positions (mm, part frame) from the evaluated scalars; `out` has
  // vertexCount() elements. Allocates nothing.
  virtual void place(std::span<const double> scalars, std::span<Vec3> out) const = 0;

  // Why these scalars would turn part of the surface inside out, or empty.
  // Extrusions: a cap triangle turning over, because the profile folds over
  // itself or moved so far from nominal that the caps' triangulation (fixed
  // at nominal values) no longer fits it. Revolutions: a profile point
  // reaching the axis. Cheap and allocation-free; it catches folds, not
  // every self-intersection.
  virtual std::string_view fold(std::span<const double> /*scalars*/) const { return {}; }

  // The same for the vertices place() made from these scalars (in the
  // shape's own frame), for shapes whose folds show only in the vertices
  // (a faced STEP solid: a face turning over, faces that no longer meet).
  virtual std::optional<std::string> placementProblem(std::span<const double> /*scalars*/,
                                                      std::span<const Vec3> /*vertices*/) const {
    return std::nullopt;
  }

 protected:
  std::vector<Triangle> triangles_;
  size_t vertex_count_ = 0;
};

// Builds the topology from the nominal scalars, orients extrusions and
// revolutions outward, and checks the nominal mesh is closed and outward.
// Throws Error located in the shape object.
std::unique_ptr<const Shape> buildShape(const ShapeSpec& spec,
                                        std::span<const double> nominal_scalars);

}  // namespace xgauge
