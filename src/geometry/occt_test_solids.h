// Test helpers for STEP parts: solids modelled with OpenCASCADE's own API
// from the drawings (docs/conventions.md), written as STEP files in the
// test's folder, and path-length renders to compare parts pixel by pixel.
#pragma once

#include "test_files.h"
#include "xray/test_machines.h"

#include "xgauge/geometry/part_model.h"
#include "xgauge/xray/renderer.h"

#include <BRepAlgoAPI_Cut.hxx>
#include <BRepAlgoAPI_Fuse.hxx>
#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepBuilderAPI_MakePolygon.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepPrimAPI_MakeCylinder.hxx>
#include <BRepPrimAPI_MakePrism.hxx>
#include <IFSelect_ReturnStatus.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <Message_PrinterOStream.hxx>
#include <STEPControl_Writer.hxx>
#include <TopoDS_Shape.hxx>
#include <gp.hxx>
#include <gp_Ax2.hxx>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace xgauge::testing {

// Writes `shape` as a STEP file (AP214, mm) in the test's folder.
inline std::filesystem::path writeStep(const std::string& name, const TopoDS_Shape& shape) {
  // The writer reports to OCCT's default messenger: keep the test's output clean.
  Message::DefaultMessenger()->RemovePrinters(STANDARD_TYPE(Message_PrinterOStream));
  const std::filesystem::path path = testFile(name);
  STEPControl_Writer writer;
  EXPECT_EQ(writer.Transfer(shape, STEPControl_AsIs), IFSelect_RetDone);
  EXPECT_EQ(writer.Write(path.string().c_str()), IFSelect_RetDone);
  return path;
}

// A part's dimension values by name.
inline std::map<std::string, double> valuesByName(const PartModel& part,
                                                  const std::vector<double>& values) {
  std::map<std::string, double> named;
  for (size_t i = 0; i < values.size(); ++i) named[part.dimensions()[i].name] = values[i];
  return named;
}

// The bracket of parts/bracket.json (docs/conventions.md, part 5) as
// bracket.json describes it: the union of the plates minus three true
// cylinders, 1 mm beyond the plates. `v`: its dimensions by name.
inline TopoDS_Shape bracketSolid(const std::map<std::string, double>& v) {
  const double L = v.at("base_length"), H = v.at("height"), W = v.at("width"),
               T = v.at("thickness"), d = v.at("hole_diameter"), c = v.at("hole_position"),
               s = v.at("hole_spacing"), du = v.at("upright_hole_diameter"),
               hu = v.at("upright_hole_height");
  TopoDS_Shape body = BRepAlgoAPI_Fuse(BRepPrimAPI_MakeBox(gp_Pnt(0, 0, 0), gp_Pnt(L, W, T)).Shape(),
                                       BRepPrimAPI_MakeBox(gp_Pnt(0, 0, 0), gp_Pnt(T, W, H)).Shape())
                          .Shape();
  for (const double x : {c, c + s})
    body = BRepAlgoAPI_Cut(
               body,
               BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(x, W / 2, -1), gp::DZ()), d / 2, T + 2).Shape())
               .Shape();
  return BRepAlgoAPI_Cut(
             body,
             BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(-1, W / 2, hu), gp::DX()), du / 2, T + 2).Shape())
      .Shape();
}

// The prism jaw of parts/prism_jaw.json (docs/conventions.md, part 1): its
// profile P0 .. P9 in (x, z) extruded along y over L = 40 mm.
struct PrismJawProfile {
  std::vector<std::array<double, 2>> points;  // (x, z), counter-clockwise
  explicit PrismJawProfile(const std::map<std::string, double>& v) {
    const double W = v.at("width"), c = v.at("groove_center"), T = v.at("thickness"),
                 g = v.at("groove_depth"), al = v.at("groove_left"), ar = v.at("groove_right"),
                 sw = v.at("slot_width"), sd = v.at("slot_depth");
    points = {{0, 0},
              {W, 0},
              {W, T},
              {c + ar, T},
              {c + sw / 2, T - g * (1 - sw / (2 * ar))},
              {c + sw / 2, T - g - sd},
              {c - sw / 2, T - g - sd},
              {c - sw / 2, T - g * (1 - sw / (2 * al))},
              {c - al, T},
              {0, T}};
  }
  // The midpoint of the side from P_i to P_(i+1), at y.
  std::array<double, 3> side(size_t i, double y) const {
    const auto& a = points[i];
    const auto& b = points[(i + 1) % points.size()];
    return {0.5 * (a[0] + b[0]), y, 0.5 * (a[1] + b[1])};
  }
};
inline constexpr double kPrismJawLength = 40.0;

inline TopoDS_Shape prismJawSolid(const std::map<std::string, double>& v) {
  const PrismJawProfile profile(v);
  BRepBuilderAPI_MakePolygon polygon;
  for (const auto& p : profile.points) polygon.Add(gp_Pnt(p[0], 0, p[1]));
  polygon.Close();
  const TopoDS_Face face = BRepBuilderAPI_MakeFace(polygon.Wire()).Face();
  return BRepPrimAPI_MakePrism(face, gp_Vec(0, kPrismJawLength, 0)).Shape();
}

inline double maxAbsDifference(const ImageT<double>& a, const ImageT<double>& b) {
  double worst = 0.0;
  for (size_t i = 0; i < a.size(); ++i)
    worst = std::max(worst, std::abs(a.pixels()[i] - b.pixels()[i]));
  return worst;
}

// Path lengths (mm) through `mesh` at `pose`, n x n samples per pixel.
inline ImageT<double> renderPaths(const Machine& machine, const TriangleMesh& mesh,
                                  const Pose& pose, int n) {
  std::vector<Vec3> world;
  RenderOptions options;
  options.samples_per_axis = n;
  ImageT<double> image;
  renderPathLength(machine, posed(mesh, pose, world), options, image);
  return image;
}

// Places `centre` (part frame) at `at` after rotating by Euler angles (deg).
inline Pose poseAbout(const Vec3& angles_deg, const Vec3& centre, const Vec3& at) {
  Pose pose = Pose::fromEulerDeg(angles_deg, Vec3::Zero());
  pose.translation_mm = at - pose.rotation * centre;
  return pose;
}

}  // namespace xgauge::testing
