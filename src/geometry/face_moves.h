// Dimensions named on the faces of a STEP solid (docs/formats.md,
// "Dimensions on faces"): which faces each dimension moves and how, read
// from the part file and resolved against the solid's faces once, at load.
//
// A dimension may carry the keys "offset", "diameter" and "position" (each
// one object or a list of them); the part may carry "surfaces", face sets
// whose surface is given by expressions of the dimensions. Faces are chosen
// by selectors: {"at": [x, y, z]} (the face within kFaceSelectionMm of the
// point, in the STEP file's frame), "#42" (the STEP entity), "name" (the
// face's name in the file) or a face's number (1-based, `xgauge part
// faces`).
//
// Faces that lie on one surface and share an edge (a cylinder split at its
// seam) form one group, which moves as one: a selector that names one of
// them moves them all. A group's surface after the moves is its nominal
// surface translated by the sum of its position moves' (and, for planes,
// offsets') displacements and grown along its normal by the sum of its
// offsets and diameter changes (geometry/surface.h); or, for a "surfaces"
// entry, the surface its expressions give.
#pragma once

#include "expression.h"

#include "xgauge/core/config.h"
#include "xgauge/geometry/step.h"
#include "xgauge/geometry/surface.h"

#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace xgauge {

// A selector "at" matches the faces within this distance of its point.
inline constexpr double kFaceSelectionMm = 0.01;
// A datum, a "diameter" or a "surfaces" entry must agree with the solid at
// nominal values within this (mm): it catches a face picked by mistake.
inline constexpr double kNominalAgreementMm = 0.001;

// The face keys of a part file, before its STEP file is read.
struct FaceMoveSources {
  struct Dimension {
    std::string name;
    double nominal = 0.0;
    double min = 0.0, max = 0.0;
    std::string unit;
  };
  struct Move {
    size_t dimension = 0;  // in `dimensions`
    std::string kind;      // "offset", "diameter" or "position"
    ConfigNode node;
  };
  std::vector<Dimension> dimensions;
  std::vector<Move> moves;
  std::optional<ConfigNode> surfaces;  // the part's "surfaces" list
  SourceLocation where;                // the part file

  bool empty() const { return moves.empty() && !surfaces; }
};

// The "offset", "diameter" and "position" keys of a dimension entry (the
// caller has read its name, nominal and unit), appended to `sources`.
void readFaceMoves(const ConfigNode& dimension_entry, FaceMoveSources& sources);

// One surface of the solid and how it moves.
struct FaceGroup {
  Surface surface;              // nominal
  int outward = 1;              // +1: the outward normal is surface.gradient()
  std::vector<uint32_t> faces;  // positions in StepSolid::faces, ascending

  // Moves: per unit of (scalar - its nominal), a translation and a growth
  // along the surface's gradient (geometry/surface.h).
  struct Term {
    uint32_t scalar = 0;  // the dimension's scalar, in the shape's scalars
    Vec3 translation = Vec3::Zero();
    double growth = 0.0;
  };
  std::vector<Term> terms;

  // A "surfaces" entry: the surface is given by scalars from `first_scalar`:
  // kPlaneThrough three points (9), kPlaneNormal a point and a normal (6),
  // kCylinder a point, an axis and a diameter (7).
  enum class Expressed { kNone, kPlaneThrough, kPlaneNormal, kCylinder };
  Expressed expressed = Expressed::kNone;
  uint32_t first_scalar = 0;
  SourceLocation where;  // the "surfaces" entry

  bool moves() const { return !terms.empty() || expressed != Expressed::kNone; }
  // The surface for these scalars (`nominal` the shape's nominal scalars).
  Surface at(std::span<const double> scalars, std::span<const double> nominal) const;
};

// A STEP solid with its faces grouped into surfaces and the part's moves
// resolved: what a "step" shape with dimensions on its faces is built from.
struct FacedStep {
  StepSolid solid;
  std::vector<FaceGroup> groups;
  std::vector<uint32_t> face_group;  // per face
  // Per scalar of the shape: the dimension it is ("thickness"), or, for a
  // "surfaces" entry's scalars, the entry ("surfaces[2]").
  std::vector<std::string> scalar_names;
  // Per scalar of the shape: the dimension's [min, max]; NaN for a
  // "surfaces" entry's expressions (whose range is not known).
  std::vector<std::pair<double, double>> scalar_ranges;
  double size_mm = 0.0;             // the solid's bounding box diagonal
  double chord_tolerance_mm = 0.0;  // of its tessellation
  // Per group: the dimensions and "surfaces" entries that move it.
  std::vector<std::vector<std::string>> group_movers;

  // "face 3 of 6 (#42, plane)" and, when it moves, " moved by thickness, width".
  std::string describeFace(size_t face) const;
  // The dimensions and "surfaces" entries that move a group, "thickness, width".
  std::string movers(size_t group) const;
};

// Groups the faces and resolves every selector and move against `solid`.
// The scalars the moves need (each dimension that moves a face, as an
// expression of its name; each "surfaces" entry's expressions) are appended
// to `scalars`. Throws Error, located at the key, naming the dimension and
// the face: a selector that matches no face or several, an unknown entity or
// name, a move on the wrong kind of surface ("diameter" on a plane), a datum
// or "surfaces" entry that disagrees with the solid at nominal values, a
// face moved both by a dimension and by a "surfaces" entry.
std::shared_ptr<const FacedStep> resolveFaceMoves(StepSolid solid, double chord_tolerance_mm,
                                                  const FaceMoveSources& sources,
                                                  std::vector<ExpressionSource>& scalars);

}  // namespace xgauge
