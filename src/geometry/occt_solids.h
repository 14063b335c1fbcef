// Solids modelled with OpenCASCADE's own API from the drawings
// (docs/conventions.md) and from what a sample CAD file shows, at any
// dimension values: references for the STEP parts' tests, and the true
// solids of the CAD study (bench/screw_solid.cpp), made without xgauge's
// vertex placement.
#pragma once

#include <BRepAlgoAPI_Cut.hxx>
#include <BRepAlgoAPI_Fuse.hxx>
#include <BRepBuilderAPI_MakeEdge.hxx>
#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepBuilderAPI_MakePolygon.hxx>
#include <BRepBuilderAPI_MakeWire.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepPrimAPI_MakeCylinder.hxx>
#include <BRepPrimAPI_MakePrism.hxx>
#include <BRepPrimAPI_MakeRevol.hxx>
#include <GC_MakeArcOfCircle.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Shape.hxx>
#include <gp.hxx>
#include <gp_Ax1.hxx>
#include <gp_Ax2.hxx>

#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <string>
#include <vector>

namespace xgauge::testing {

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

// Debian's screw.step (occt-misc; examples/screw/screw.json) rebuilt from
// what its faces say, at any values of examples/screw/screw.json's
// dimensions: a head (the dome, an arc of the circle of radius 54.8737 mm
// about (rho, z) = (-8.25, -46.31367), and the 45-degree countersink down to
// its apex) and a shank (radius D / 2 from inside the head down to the
// tip's 45-degree chamfer and face), turned about the axis, the shank's
// moved by shank_offset along y (across the slot), united; the slot cut
// across the head.
struct ScrewGeometry {
  static constexpr double kAxisX = -17.89811369191, kAxisY = -0.826297072243;
  static constexpr double kTop = 7.93633;           // the dome's apex on the axis
  static constexpr double kDomeCentreRho = -8.25;   // the dome's circle, in (rho, z)
  static constexpr double kDomeCentreZ = -46.31367;
  static constexpr double kDomeRadius = 54.873718663856;
  static constexpr double kRimRho = 10.0, kRimZ = 5.43633;  // dome meets countersink
  static constexpr double kApexZ = -4.56367;       // the countersink's apex: rho = z - kApexZ
  static constexpr double kTipChamferRho = 4.07990;  // the chamfer at the tip's face (nominal)
  static constexpr double kShankTopZ = 2.0;         // inside the head
};

inline TopoDS_Shape screwSolid(const std::map<std::string, double>& v) {
  using G = ScrewGeometry;
  const double w = v.at("slot_width"), depth = v.at("slot_depth"), r = v.at("shank_diameter") / 2,
               length = v.at("length"), offset = v.at("shank_offset");
  const gp_Ax1 axis(gp_Pnt(G::kAxisX, G::kAxisY, 0), gp::DZ());
  // A point of the profile plane at `y`, at radius rho from the axis's x.
  const auto at = [&](double y, double rho, double z) { return gp_Pnt(G::kAxisX + rho, y, z); };
  // Head: the dome's arc, the countersink, the axis.
  const double mid_rho = 5.0;
  const double mid_z = G::kDomeCentreZ + std::sqrt(G::kDomeRadius * G::kDomeRadius -
                                                   std::pow(mid_rho - G::kDomeCentreRho, 2));
  const double y = G::kAxisY;
  const Handle(Geom_TrimmedCurve) dome =
      GC_MakeArcOfCircle(at(y, 0, G::kTop), at(y, mid_rho, mid_z), at(y, G::kRimRho, G::kRimZ))
          .Value();
  const TopoDS_Wire head_wire =
      BRepBuilderAPI_MakeWire(
          BRepBuilderAPI_MakeEdge(dome).Edge(),
          BRepBuilderAPI_MakeEdge(at(y, G::kRimRho, G::kRimZ), at(y, 0, G::kApexZ)).Edge(),
          BRepBuilderAPI_MakeEdge(at(y, 0, G::kApexZ), at(y, 0, G::kTop)).Edge())
          .Wire();
  const TopoDS_Shape head =
      BRepPrimAPI_MakeRevol(BRepBuilderAPI_MakeFace(head_wire).Face(), axis).Shape();
  // Shank: its own axis moved by `offset` along y.
  const double shank_y = G::kAxisY + offset;
  const double tip_z = G::kTop - length;
  const double chamfer_z = tip_z + (r - G::kTipChamferRho);
  BRepBuilderAPI_MakePolygon shank_profile;
  for (const gp_Pnt& p :
       {at(shank_y, 0, G::kShankTopZ), at(shank_y, r, G::kShankTopZ), at(shank_y, r, chamfer_z),
        at(shank_y, G::kTipChamferRho, tip_z), at(shank_y, 0, tip_z)})
    shank_profile.Add(p);
  shank_profile.Close();
  const TopoDS_Shape shank =
      BRepPrimAPI_MakeRevol(BRepBuilderAPI_MakeFace(shank_profile.Wire()).Face(),
                            gp_Ax1(gp_Pnt(G::kAxisX, shank_y, 0), gp::DZ()))
          .Shape();
  const TopoDS_Shape body = BRepAlgoAPI_Fuse(head, shank).Shape();
  const TopoDS_Shape slot =
      BRepPrimAPI_MakeBox(gp_Pnt(G::kAxisX - 12, G::kAxisY - w / 2, G::kTop - depth),
                          gp_Pnt(G::kAxisX + 12, G::kAxisY + w / 2, G::kTop + 5))
          .Shape();
  return BRepAlgoAPI_Cut(body, slot).Shape();
}

}  // namespace xgauge::testing
