// Reading STEP files (ISO 10303-21: AP203, AP214, AP242 B-rep solids) into
// the closed, outward, indexed mesh the STL reader makes (stl.h), so that a
// "step" shape is used exactly as an "stl" one: a fixed mesh.
//
// OpenCASCADE (OCCT, Debian's libocct-* packages) is the maintained tool for
// reading STEP, checking B-rep solids and tessellating them; xgauge parses no
// STEP itself. Lengths are converted from the file's unit to mm (OCCT's
// default); coordinates are in the part frame.
//
// Steps, each refusing with an Error located in the STEP file:
// - read and transfer every root (STEPControl_Reader); a file that is not
//   STEP, or holds no face, is refused;
// - closed solid: every edge of every face (degenerate edges aside) must be
//   shared by exactly two face sides (a seam counts twice in its face); the
//   first face bounded by a free or a non-manifold edge is named, as
//   "face 3 of 6 (#42 'name')": its place in OCCT's face order, the STEP
//   entity and its name where the file gives them; then the shape must pass
//   OCCT's BRepCheck_Analyzer, the first failing face named the same way;
// - tessellate (BRepMesh_IncrementalMesh, absolute deflection), triangles
//   taken with each face's orientation (reversed faces reversed) and
//   location; triangles with two equal corners (at a degenerate edge) are
//   left out;
// - weld the triangles and check the mesh closed and outward
//   (closedMeshFromSoup, mesh.h: the same code as for STL).
//
// Thread safety: OCCT's STEP reader keeps global state, so calls are
// serialised by a mutex. OCCT's default messenger printer (standard output)
// is removed from the process on first use, so that OCCT never prints.
#pragma once

#include "xgauge/geometry/mesh.h"
#include "xgauge/geometry/surface.h"

#include <filesystem>
#include <string>
#include <vector>

namespace xgauge {

// How finely a B-rep is tessellated. The keys of a "step" shape
// (docs/formats.md): chord_tolerance_mm, angular_tolerance_deg.
struct StepTessellation {
  // OCCT's linear deflection t, mm: curved edges are divided within t / 2
  // (planar, cylindrical and conical faces follow them); inside doubly
  // curved faces triangles stray up to about 2 t (measured on a sphere).
  double chord_tolerance_mm = 0.001;
  // OCCT's angular deflection, degrees: the largest angle between the
  // normals along a triangle's side.
  double angular_tolerance_deg = 20.0;
};

inline constexpr double kMinStepChordToleranceMm = 1e-5;
inline constexpr double kMaxStepChordToleranceMm = 1.0;
inline constexpr double kMinStepAngularToleranceDeg = 0.5;
inline constexpr double kMaxStepAngularToleranceDeg = 60.0;
// More triangles than this is refused (as for any shape of a part).
inline constexpr size_t kMaxStepTriangles = size_t{1} << 24;

// Throws Error (located in `path`) for a missing or unreadable file, a file
// that is not STEP, a shape that is not a closed valid solid, a tolerance out
// of the ranges above (or not finite), or a tessellation of more than
// kMaxStepTriangles triangles.
TriangleMesh readStep(const std::filesystem::path& path, const StepTessellation& tessellation);

// One face of a STEP solid: what `xgauge part faces` lists, and what a
// dimension's face selector matches (part_model.h).
struct StepFace {
  int index = 0;             // 1-based, OpenCASCADE's face order ("face 3 of 6")
  int entity = 0;            // the STEP entity it was read from (#42); 0 when unknown
  std::string name;          // the name the file gives it; may be empty
  Surface surface;           // kind kOther for a freeform surface
  std::string surface_type;  // "plane", ..., "torus", or "B-spline", "Bezier", ...
  // Analytic kinds: +1 when the solid's outward normal is
  // surface.gradient(), -1 when it is the opposite (a hole's cylinder).
  int outward = 1;
  double area_mm2 = 0.0;                // of its triangles
  Vec3 centroid_mm = Vec3::Zero();      // of its triangles, area-weighted
  Vec3 normal = Vec3::Zero();           // mean outward normal of its triangles (unit or zero)
};

// A STEP solid with its faces: the mesh readStep makes, and for each of its
// triangles the face it tessellates.
struct StepSolid {
  TriangleMesh mesh;
  std::vector<StepFace> faces;          // faces[i].index == i + 1
  std::vector<uint32_t> triangle_face;  // per mesh triangle, the face's position in `faces`
  std::string sha256;                   // of the file's bytes
  double chord_tolerance_mm = 0.0;      // the tessellation's (StepTessellation)
  // "face 3 of 6 (#42 'top', plane)".
  std::string describe(size_t face) const;
};

// readStep, keeping the faces. Throws as readStep.
StepSolid readStepSolid(const std::filesystem::path& path, const StepTessellation& tessellation);

}  // namespace xgauge
