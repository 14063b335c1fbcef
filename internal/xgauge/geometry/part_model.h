// Parametric part models: a triangle mesh whose topology is fixed and whose
// vertex positions are functions of named dimensions, described in a JSON
// file so that a new part needs no recompilation (see parts/*.json and
// docs/conventions.md for the reference parts, docs/formats.md for the file).
//
// File format (lengths in mm, angles in degrees; every key is checked, a
// misspelled one is an error):
//
//   key            | contents
//   ---------------|-----------------------------------------------------------
//   description    | what the part is, its frame and anything a reader needs
//   dimensions     | array, in the order the model's values use:
//                  |   {"name", "nominal", "min", "max", "unit": "mm" | "deg",
//                  |    "description" (optional), "thesis" (optional, "θ8"),
//                  |    "tolerance" (optional): {"lower", "upper"}, the
//                  |    drawing's default deviation limits from nominal in
//                  |    the dimension's unit, lower < upper, the zone
//                  |    overlapping [min, max] (measure/tolerance.h)}
//                  | min <= nominal <= max, min < max. Absent for "stl"
//                  | and "step".
//   constants      | optional array of {"name", "value", "unit" (optional),
//                  |   "description" (optional)}: fixed values such as L = 40
//   derived        | optional array of {"name", "expr", "description"
//                  |   (optional)}, evaluated in order: each may use the
//                  |   dimensions, constants and earlier derived values
//   constraints    | optional array of {"expr", "message"}: a valid part has
//                  |   every expr > 0; message says what breaks otherwise
//   shape          | one of the objects below
//
//   shape "type"   | further keys
//   ---------------|-----------------------------------------------------------
//   "extrusion"    | "plane": two axes ["x", "z"]; "profile": [[a, b], ...],
//                  | a simple polygon in that plane (either winding);
//                  | "axis": the third axis; "from", "to": its extent. Caps
//                  | are ear-clipped once, at nominal values.
//   "revolution"   | "axis"; "profile": [[radius, axial], ...], a simple
//                  | polygon in the half-plane radius >= 0 (either winding);
//                  | "segments": N >= 3. A point with radius 0 at nominal is
//                  | one pole vertex; there must be none or exactly two such
//                  | neighbours (their segment on the axis closes the
//                  | profile). Other points become N vertices on the true
//                  | circle (inscribed polygon), the first on axis u of the
//                  | right-handed (u, v, axis): x -> (y, z), y -> (z, x),
//                  | z -> (x, y).
//   "mesh"         | "vertices": [[x, y, z], ...]; "triangles": [[i, j, k],
//                  | ...], counter-clockwise seen from outside (checked).
//   "stl"          | "file": an STL path, relative to the part file.
//   "step"         | "file": a STEP path, relative to the part file (a
//                  | closed B-rep solid, tessellated once: step.h);
//                  | optional "chord_tolerance_mm" (1e-5 .. 1, default
//                  | 0.001) and "angular_tolerance_deg" (0.5 .. 60,
//                  | default 20).
//
// Every coordinate, bound of an extrusion, derived value and constraint is an
// expression (a JSON string, or a plain number) in muparser syntax: + - * / ^,
// comparisons, "c ? a : b", and the functions min, max, sum, avg, abs, sqrt,
// exp, ln, log10, sin, cos, tan, asin, acos, atan, atan2 ... (radians), plus
// the degree helpers sind, cosd, tand (argument in degrees), asind, acosd,
// atand, atan2d (result in degrees), rad(deg) and deg(rad), and the constant
// pi. Vertex orientation of extrusions and revolutions is made outward
// automatically.
//
// Thread safety: evaluation runs precompiled muparser expressions that keep
// state inside the object, so one PartModel must not be evaluated (evaluate,
// mesh, validate, values) from several threads at once. A copy compiles its
// own expressions: give each thread its own copy.
#pragma once

#include "xgauge/core/config.h"
#include "xgauge/core/transform.h"
#include "xgauge/geometry/csg.h"
#include "xgauge/geometry/mesh.h"
#include "xgauge/geometry/step.h"

#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace xgauge {

// A drawing's tolerance of a dimension: the deviation limits from its
// nominal, in its unit (lower < upper; e.g. -0.05 and +0.05, or +0.02 and
// +0.08). Verdicts against it: measure/tolerance.h.
struct DimensionTolerance {
  double lower = 0.0;
  double upper = 0.0;
};

struct Dimension {
  std::string name;
  double nominal = 0.0;  // in `unit`
  double min = 0.0;      // valid values lie in [min, max]
  double max = 0.0;
  std::string unit;         // "mm" or "deg"
  std::string description;  // may be empty
  std::string thesis;       // the thesis's symbol, "θ8" (docs/conventions.md); may be empty
  std::optional<DimensionTolerance> tolerance;  // the drawing's default; none when not given
};

// A quantity of the drawing that is a sum of dimensions with coefficients,
// such as a pocket's width (its left and right edges from a centre line the
// part does not show): reported with its uncertainty beside the dimensions,
// even where the single terms are not identifiable.
struct DeclaredCombination {
  std::string name;
  std::string description;                             // may be empty
  std::vector<std::pair<std::string, double>> terms;  // (dimension, coefficient), declaration order
};

class PartModel {
 public:
  // Reads a part model file. Throws Error (file, key path, and for
  // expressions muparser's message and position) for bad input, and when
  // the nominal mesh is not closed and outward or the nominal values break a
  // constraint.
  static PartModel load(const std::filesystem::path& path);
  // The same from a file already read (ConfigNode::loadFile); `path` is the
  // file's, for its name and the folder of an STL or STEP shape.
  static PartModel fromConfig(const ConfigNode& root, const std::filesystem::path& path);
  // A fixed mesh without dimensions (see readStl).
  static PartModel fromStl(const std::filesystem::path& path);
  // Any part file by its extension: .stl (fromStl), .step or .stp (a fixed
  // mesh tessellated at the `step` shape's default tolerances), else a part
  // model (load).
  static PartModel fromFile(const std::filesystem::path& path);

  PartModel(const PartModel& other);
  PartModel& operator=(const PartModel& other);
  PartModel(PartModel&&) noexcept;
  PartModel& operator=(PartModel&&) noexcept;
  ~PartModel();

  const std::string& name() const;  // the file name without extension
  // The STL and STEP files its shape read and the SHA-256 of the bytes
  // read (part of the model: a result records them beside the part file's).
  const std::map<std::string, std::string>& shapeFileDigests() const;
  const std::string& description() const;
  const std::vector<Dimension>& dimensions() const;
  // Optional key "combinations" (docs/formats.md).
  const std::vector<DeclaredCombination>& combinations() const;
  std::vector<double> nominalValues() const;
  // Throws Error "unknown dimension 'x' (known: a, b, c)".
  int dimensionIndex(std::string_view name) const;

  // The nominal values with some replaced by name. Throws Error for an
  // unknown name or a value outside its dimension's bounds.
  std::vector<double> values(const std::map<std::string, double>& overrides) const;

  // Throws Error unless every value lies within its bounds and every
  // constraint holds, naming the dimension or the constraint and its message.
  // `values` has one entry per dimension, in declaration order.
  void validate(std::span<const double> values) const;
  // What validate() would throw, as a message; nullopt for valid values. For
  // a fit, where such values are an infeasible point, not an error.
  std::optional<std::string> invalidity(std::span<const double> values) const;

  // Vertex positions (mm, part frame) for these dimension values: always
  // vertexCount() vertices in the same order, matching triangles(). The hot
  // path of a fit: no allocation once `out` has the capacity, no lookups by
  // name. Does not check bounds or constraints (see validate). Throws Error
  // naming the values if an expression is not finite or the surface would
  // turn inside out: an extrusion cap triangle turning over (the profile
  // folds, or moved so far from nominal that the caps' triangulation, fixed
  // at nominal values, no longer fits it) or a revolution profile point
  // reaching the axis.
  void evaluate(std::span<const double> values, std::vector<Vec3>& out) const;
  // evaluate() that returns what it would throw instead (nullopt: `out` holds
  // the vertices).
  std::optional<std::string> tryEvaluate(std::span<const double> values,
                                         std::vector<Vec3>& out) const;

  // validate + evaluate + triangles.
  TriangleMesh mesh(std::span<const double> values) const;

  // The values dimension `index` can take with every other dimension at
  // nominal: the interval around nominal, within [min, max], where the
  // constraints hold and the part can be built (tryEvaluate), found on a
  // grid of kRangeGridSteps steps to each bound, then by bisection to 1e-9
  // of the bounds' span. Each end says why it is there: "its min", "its
  // max", a constraint's message or the fold.
  struct DimensionRange {
    double low = 0.0, high = 0.0;
    std::string low_reason, high_reason;
  };
  static constexpr int kRangeGridSteps = 16;
  DimensionRange buildableRange(int index) const;

  // For a part whose dimensions move a STEP solid's faces (docs/formats.md,
  // "Dimensions on faces"): that solid, its faces and which face each of its
  // triangles tessellates; its triangles are triangles()[first_triangle,
  // first_triangle + solid->mesh.triangles.size()). Null solid otherwise.
  struct StepFaces {
    const StepSolid* solid = nullptr;
    size_t first_triangle = 0;
  };
  StepFaces stepFaces() const;

  // Fixed when the model is loaded, outward at nominal values.
  const std::vector<Triangle>& triangles() const;
  size_t vertexCount() const;
  // How the pieces of a CSG part combine; null when the part is one solid.
  const std::shared_ptr<const Csg>& csg() const;

 private:
  struct Definition;
  class Evaluator;
  struct Invalidity;
  std::optional<Invalidity> findInvalidity(std::span<const double> values) const;
  std::optional<Invalidity> findFold(std::span<const double> values, std::vector<Vec3>& out) const;
  // invalidity(), then tryEvaluate().
  std::optional<std::string> whyNot(std::span<const double> values,
                                    std::vector<Vec3>& scratch) const;
  // For parts whose dimensions move a STEP solid's faces: throws Error,
  // located at the dimension in `path`, when a value on a grid over
  // [min, max] that the constraints allow cannot be built (a face turns
  // over), with the range that can (buildableRange).
  void requireBuildableWithinBounds(const std::filesystem::path& path) const;
  PartModel(std::shared_ptr<const Definition> definition, std::unique_ptr<Evaluator> evaluator);
  // A fixed mesh read from `path` (an "stl" or "step" file, `type`; its
  // bytes' SHA-256).
  static PartModel fromFixedMesh(const std::filesystem::path& path, const char* type,
                                 TriangleMesh mesh, const std::string& sha256);

  std::shared_ptr<const Definition> definition_;  // immutable, shared by copies
  std::unique_ptr<Evaluator> evaluator_;          // compiled expressions, per copy
};

}  // namespace xgauge
