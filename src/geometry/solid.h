// A part's solid as its file describes it (the "shape" object): one
// primitive, or a CSG tree of primitives (union, difference, intersection),
// each node optionally placed by a rotation and a translation that are
// expressions of the dimensions. Keys are documented in
// xgauge/geometry/part_model.h and docs/formats.md.
//
// The pieces' meshes are concatenated (vertices and triangles in tree order);
// a tree of more than one piece carries a Csg that tells the renderer how to
// combine them. An extrusion with holes becomes a difference of prisms.
#pragma once

#include "shape.h"

#include "xgauge/core/transform.h"
#include "xgauge/geometry/csg.h"

#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace xgauge {

struct SolidSpec {
  // A rotation (degrees, fixed axes x then y then z, as poses) then a
  // translation: six scalars from `first_scalar` (rx, ry, rz, tx, ty, tz).
  struct Placement {
    size_t first_scalar = 0;
  };
  struct Piece {
    ShapeSpec shape;
    size_t first_scalar = 0;           // its scalars in `scalars`
    std::vector<uint32_t> placements;  // innermost first
  };

  std::vector<Piece> pieces;
  std::vector<Csg::Node> program;  // postfix over pieces
  std::vector<Placement> placements;
  std::vector<ExpressionSource> scalars;  // every piece's, and every placement's
  SourceLocation where;                   // the root "shape" object
  // "stl" or "step" when the root is such a shape, a fixed mesh (a "step"
  // solid whose faces the dimensions move is not); empty otherwise.
  std::string fixed_root;
};

// Reads the "shape" object, recursively. `faces` (may be null): the part's
// dimensions on faces, which its one "step" solid takes (shape.h); Error
// when the shape has no "step" solid to take them.
SolidSpec readSolidSpec(const ConfigNode& shape, const std::filesystem::path& directory,
                        const FaceMoveSources* faces);

// The solid with its topology fixed at nominal values.
class Solid {
 public:
  // Builds every piece at the nominal scalars (Throws Error located in the
  // piece's object when one is not a closed outward surface).
  Solid(const SolidSpec& spec, std::span<const double> nominal_scalars);

  const std::vector<Triangle>& triangles() const { return triangles_; }
  size_t vertexCount() const { return vertex_count_; }
  // Null for a single piece: the part is that piece.
  const std::shared_ptr<const Csg>& csg() const { return csg_; }
  // The STEP solid whose faces the dimensions move, and its first triangle
  // in triangles(); null when there is none.
  std::pair<const FacedStep*, size_t> facedStep() const { return {faced_.get(), faced_first_triangle_}; }

  // Vertex positions (mm, part frame) from the evaluated scalars; `out` has
  // vertexCount() elements. Allocates nothing.
  void place(std::span<const double> scalars, std::span<Vec3> out) const;

  // Why these scalars (and the vertices place() made from them) do not give
  // every piece a solid: a piece's fold (Shape::fold) or its surface turned
  // inside out or flattened (signed volume). The message, and the piece's
  // place in the file.
  struct Problem {
    std::string message;
    SourceLocation where;
  };
  std::optional<Problem> problem(std::span<const double> scalars,
                                 std::span<const Vec3> vertices) const;

 private:
  struct Piece {
    std::unique_ptr<const Shape> shape;
    size_t first_scalar = 0, scalar_count = 0;
    uint32_t first_vertex = 0, first_triangle = 0, triangle_end = 0;
    std::vector<uint32_t> placements;
    SourceLocation where;
  };
  // Shape::placementProblem of the piece, given the part-frame vertices.
  std::optional<std::string> placementProblem(const Piece& piece, std::span<const double> scalars,
                                              std::span<const Vec3> vertices) const;

  std::vector<Piece> pieces_;
  std::vector<size_t> placement_scalars_;
  std::vector<Triangle> triangles_;
  size_t vertex_count_ = 0;
  std::shared_ptr<const Csg> csg_;
  std::shared_ptr<const FacedStep> faced_;
  size_t faced_first_triangle_ = 0;
};

}  // namespace xgauge
