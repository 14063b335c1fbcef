// STEP parts (geometry/step.h): solids modelled with OpenCASCADE's own API,
// written as STEP by the test, loaded as "step" shapes and rendered beside
// the JSON parts (the reference bracket, parts/bracket.json; the same CSG
// tree with an "stl" operand), and the refusals (open shells, files that are
// missing or not STEP, tolerances).
#include "xgauge/geometry/step.h"

#include "occt_test_solids.h"

#include "xgauge/core/config.h"
#include "xgauge/core/file.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/geometry/stl.h"
#include "xgauge/xray/renderer.h"

#include <BRepAlgoAPI_Cut.hxx>
#include <BRepAlgoAPI_Fuse.hxx>
#include <BRepBuilderAPI_MakeEdge.hxx>
#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepPrimAPI_MakeCylinder.hxx>
#include <BRepPrimAPI_MakeSphere.hxx>
#include <BRep_Builder.hxx>
#include <IFSelect_ReturnStatus.hxx>
#include <Interface_Static.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <Message_PrinterOStream.hxx>
#include <STEPControl_Writer.hxx>
#include <TopExp_Explorer.hxx>
#include <TopLoc_Location.hxx>
#include <TopoDS_Compound.hxx>
#include <TopoDS_Shape.hxx>
#include <TopoDS_Shell.hxx>
#include <gp.hxx>
#include <gp_Ax2.hxx>
#include <gp_Pln.hxx>
#include <gp_Trsf.hxx>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>
#include <optional>
#include <vector>

namespace xgauge {
namespace {

using testing::bracketSolid;
using testing::expectLoadError;
using testing::kParts;
using testing::maxAbsDifference;
using testing::poseAbout;
using testing::renderPaths;
using testing::valuesByName;
using testing::writeStep;
using testing::loadText;
using testing::posed;
using testing::squareMachine;
using testing::testFile;
using testing::writeTestFile;
constexpr double kPi = std::numbers::pi;

// readStep's Error: its message, and that it is located in `path`.
std::string stepError(const std::filesystem::path& path, const StepTessellation& t = {}) {
  try {
    readStep(path, t);
  } catch (const Error& e) {
    EXPECT_EQ(e.where().file, path.string()) << e.what();
    return e.message();
  }
  ADD_FAILURE() << "expected an Error reading " << path;
  return {};
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// ---------------------------------------------------------------------------
// Reading solids

TEST(Step, BoxIsReadWithItsLocation) {
  // A 30 x 20 x 10 box turned 90 degrees about z and moved, written as an
  // assembly (a placed instance of the box): OCCT reads it back as the box
  // with a location, which the triangles must follow.
  gp_Trsf turn, move;
  turn.SetRotation(gp::OZ(), kPi / 2);
  move.SetTranslation(gp_Vec(5, -3, 2));
  BRep_Builder builder;
  TopoDS_Compound assembly;
  builder.MakeCompound(assembly);
  builder.Add(assembly,
              BRepPrimAPI_MakeBox(30, 20, 10).Shape().Moved(TopLoc_Location(move * turn)));
  { STEPControl_Writer define_the_writers_parameters; }
  ASSERT_TRUE(Interface_Static::SetIVal("write.step.assembly", 1));
  const std::filesystem::path path = writeStep("box.step", assembly);
  Interface_Static::SetIVal("write.step.assembly", 0);
  ASSERT_TRUE(contains(readFileContents(path, 1 << 20, "STEP"), "NEXT_ASSEMBLY_USAGE_OCCURRENCE"));

  const TriangleMesh mesh = readStep(path, {});
  EXPECT_EQ(mesh.vertices.size(), 8u);
  EXPECT_EQ(mesh.triangles.size(), 12u);
  EXPECT_TRUE(checkClosedMesh(mesh).ok());
  EXPECT_NEAR(signedVolume(mesh), 6000.0, 1e-9);
  const BoundingBox b = boundingBox(mesh);
  // (x, y) -> (-y, x), then + (5, -3, 2).
  EXPECT_NEAR(b.min_mm.x(), -15.0, 1e-9);
  EXPECT_NEAR(b.max_mm.x(), 5.0, 1e-9);
  EXPECT_NEAR(b.min_mm.y(), -3.0, 1e-9);
  EXPECT_NEAR(b.max_mm.y(), 27.0, 1e-9);
  EXPECT_NEAR(b.min_mm.z(), 2.0, 1e-9);
  EXPECT_NEAR(b.max_mm.z(), 12.0, 1e-9);
}

TEST(Step, AStepFileIsAPartByItsExtension) {
  // PartModel::fromFile (xgauge render, the Python module): .step and .stp
  // in any case are fixed meshes, as an "stl" file is.
  const std::filesystem::path path =
      writeStep("Block.STP", BRepPrimAPI_MakeBox(30, 20, 10).Shape());
  const PartModel part = PartModel::fromFile(path);
  EXPECT_TRUE(part.dimensions().empty());
  const TriangleMesh mesh = part.mesh({});
  EXPECT_NEAR(signedVolume(mesh), 6000.0, 1e-9);
  EXPECT_EQ(mesh.triangles.size(), 12u);
}

TEST(Step, SphereIsTessellatedNearTheChordTolerance) {
  // A seam and two degenerate pole edges. Every vertex lies on the sphere.
  // The chord tolerance is OCCT's linear deflection. OCCT divides curves at
  // half of it, but inside a doubly curved face a triangle strays further:
  // on this 5 mm sphere, 1.3 and 0.75 times it at 0.05 and 0.01 mm, 2.06 to
  // 2.08 times it from 0.005 down to 0.0005 mm, beside the seam
  // (docs/formats.md: up to about twice).
  const double r = 5.0;
  const Vec3 centre(1, 2, 3);
  const auto path = writeStep("sphere.step", BRepPrimAPI_MakeSphere(gp_Pnt(1, 2, 3), r).Shape());
  for (const double chord : {0.01, 0.002}) {
    const TriangleMesh mesh = readStep(path, {chord, 20.0});
    EXPECT_TRUE(checkClosedMesh(mesh).ok());
    double worst_vertex = 0.0, worst_inside = 0.0;
    for (const Vec3& v : mesh.vertices)
      worst_vertex = std::max(worst_vertex, std::abs((v - centre).norm() - r));
    // The deepest point of each triangle, on a barycentric grid.
    constexpr int kSteps = 12;
    for (const Triangle& t : mesh.triangles)
      for (int i = 0; i <= kSteps; ++i)
        for (int j = 0; i + j <= kSteps; ++j) {
          const Vec3 p = (mesh.vertices[t[0]] * i + mesh.vertices[t[1]] * j +
                          mesh.vertices[t[2]] * (kSteps - i - j)) /
                         kSteps;
          worst_inside = std::max(worst_inside, r - (p - centre).norm());
        }
    std::printf("chord %g mm: %zu triangles, deepest point %.5f mm inside the sphere\n", chord,
                mesh.triangles.size(), worst_inside);
    EXPECT_LT(worst_vertex, 1e-9);
    EXPECT_LE(worst_inside, 2.1 * chord);
    const double volume = 4.0 / 3.0 * kPi * r * r * r;
    EXPECT_LT(signedVolume(mesh), volume);
    EXPECT_GT(signedVolume(mesh), volume - 4 * kPi * r * r * 2.1 * chord);
  }
}

// ---------------------------------------------------------------------------
// Refusals

TEST(Step, OpenShellIsRefusedNamingTheFace) {
  // A box with its last face left out.
  const TopoDS_Shape box = BRepPrimAPI_MakeBox(10, 20, 30).Shape();
  BRep_Builder builder;
  TopoDS_Shell shell;
  builder.MakeShell(shell);
  int faces = 0;
  for (TopExp_Explorer e(box, TopAbs_FACE); e.More(); e.Next())
    if (++faces < 6) builder.Add(shell, e.Current());
  const std::string message = stepError(writeStep("open.step", shell));
  EXPECT_TRUE(message.starts_with("face 1 of 5")) << message;
  EXPECT_TRUE(contains(message,
                       "is bounded by a free edge (one no other face shares): not a "
                       "closed solid"))
      << message;

  const TopoDS_Shape face = BRepBuilderAPI_MakeFace(gp_Pln(gp::XOY()), 0, 10, 0, 10).Shape();
  const std::string single = stepError(writeStep("face.step", face));
  EXPECT_TRUE(single.starts_with("face 1 of 1")) << single;
  EXPECT_TRUE(contains(single, "free edge")) << single;
}

TEST(Step, ShapeWithoutFacesIsRefused) {
  const TopoDS_Shape edge = BRepBuilderAPI_MakeEdge(gp_Pnt(0, 0, 0), gp_Pnt(1, 2, 3)).Shape();
  const std::filesystem::path path = writeStep("edge.step", edge);
  const std::string message = stepError(path);
  EXPECT_TRUE(contains(message, "not a solid") || contains(message, "holds no shape")) << message;
}

TEST(Step, MissingEmptyAndOtherFilesAreRefusedNamingTheFile) {
  EXPECT_EQ(stepError(testFile("missing.step")), "file does not exist");
  EXPECT_EQ(stepError(writeTestFile("empty.step", "")),
            "not a STEP file: it does not start with 'ISO-10303-21;' (ISO 10303-21)");
  EXPECT_EQ(stepError(writeTestFile("tetra.stl", testing::kTetrahedronStl)),
            "not a STEP file: it does not start with 'ISO-10303-21;' (ISO 10303-21)");
  const std::string broken = stepError(writeTestFile(
      "broken.step", "ISO-10303-21;\nHEADER;\nthis is not STEP\nENDSEC;\nDATA;\n#1=FOO(;\n"));
  EXPECT_TRUE(contains(broken, "OpenCASCADE cannot read") || contains(broken, "holds no shape"))
      << broken;
  EXPECT_EQ(stepError(testFile("folder.step").parent_path()), "is a folder, not a file");
}

TEST(Step, TolerancesOutOfRangeAreRefused) {
  const auto path = writeStep("box.step", BRepPrimAPI_MakeBox(1, 2, 3).Shape());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(stepError(path, {nan, 20.0}), "chord_tolerance_mm nan out of range [1e-05, 1]");
  EXPECT_EQ(stepError(path, {0.0, 20.0}), "chord_tolerance_mm 0 out of range [1e-05, 1]");
  EXPECT_EQ(stepError(path, {0.001, 90.0}), "angular_tolerance_deg 90 out of range [0.5, 60]");

  // In a part file: the part file and the key are named.
  writeStep("block.step", BRepPrimAPI_MakeBox(1, 2, 3).Shape());
  expectLoadError(R"({"description": "d", "shape": {"type": "step", "file": "block.step",
                      "chord_tolerance_mm": 2}})",
                  "value 2 out of range [1e-05, 1]", "/shape/chord_tolerance_mm");
  expectLoadError(R"({"description": "d", "shape": {"type": "step", "file": "block.step",
                      "angular_tolerance_deg": 0.1}})",
                  "value 0.1 out of range [0.5, 60]", "/shape/angular_tolerance_deg");
  expectLoadError(R"({"description": "d", "shape": {"type": "step", "file": "block.step",
                      "chord_tolerance_nm": 0.01}})",
                  "unknown key 'chord_tolerance_nm'; did you mean 'chord_tolerance_mm'?",
                  "/shape/chord_tolerance_nm");
  expectLoadError(R"({"description": "d", "dimensions": [],
                      "shape": {"type": "step", "file": "block.step"}})",
                  "a part with a \"step\" shape has dimensions only where they name the faces "
                  "they move (\"offset\", \"diameter\", \"position\" or \"surfaces\"; "
                  "docs/your-part.md)",
                  "/dimensions");
  // NaN cannot be written in JSON; a document built in memory can hold it.
  nlohmann::json document = nlohmann::json::parse(
      R"({"description": "d", "shape": {"type": "step", "file": "block.step"}})");
  document["shape"]["chord_tolerance_mm"] = nan;
  const std::filesystem::path part = testFile("part.json");
  try {
    PartModel::fromConfig(ConfigNode::fromJson(document, part.string()), part);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.message(), "expected a finite number");
    EXPECT_EQ(e.where().key_path, "/shape/chord_tolerance_mm");
  }
  // Missing from a part file: the STEP file is named.
  try {
    loadText(R"({"description": "d", "shape": {"type": "step", "file": "nothing.step"}})");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.message(), "file does not exist");
    EXPECT_EQ(e.where().file, testFile("nothing.step").string());
  }
}

// ---------------------------------------------------------------------------
// Rendering

TEST(Step, OperandOfACsgTreeRendersAsTheSameTreeWithAnStlOperand) {
  // A 30 x 20 x 10 block from CAD with a parametric hole of diameter d at x.
  writeStep("block.step", BRepPrimAPI_MakeBox(gp_Pnt(0, 0, 0), gp_Pnt(30, 20, 10)).Shape());
  std::string stl = "solid block\n";
  const auto corner = [](int i) { return Vec3(i & 1 ? 30 : 0, i & 2 ? 20 : 0, i & 4 ? 10 : 0); };
  for (const Triangle& t : std::vector<Triangle>{{0, 2, 3},
                                                 {0, 3, 1},
                                                 {4, 5, 7},
                                                 {4, 7, 6},
                                                 {0, 1, 5},
                                                 {0, 5, 4},
                                                 {2, 6, 7},
                                                 {2, 7, 3},
                                                 {0, 4, 6},
                                                 {0, 6, 2},
                                                 {1, 3, 7},
                                                 {1, 7, 5}}) {
    stl += "facet normal 0 0 0 outer loop\n";
    for (uint32_t v : t)
      stl += fmt::format("vertex {} {} {}\n", corner(v).x(), corner(v).y(), corner(v).z());
    stl += "endloop endfacet\n";
  }
  writeTestFile("block.stl", stl + "endsolid block\n");
  const std::string part = R"({"description": "a block from CAD with a drilled hole",
    "dimensions": [
      {"name": "d", "nominal": 6, "min": 3, "max": 10, "unit": "mm"},
      {"name": "x", "nominal": 15, "min": 10, "max": 20, "unit": "mm"}],
    "shape": {"type": "difference", "solids": [
      {"type": "FIXED", "file": "block.FIXED"},
      {"type": "cylinder", "axis": "z", "diameter": "d", "from": -1, "to": 11,
       "translate": ["x", 10, 0]}]}})";
  const auto replaced = [&](const std::string& type) {
    std::string text = part;
    for (size_t at; (at = text.find("FIXED")) != std::string::npos;) text.replace(at, 5, type);
    return text;
  };
  const PartModel from_step = loadText(replaced("step"), "step_part.json");
  const PartModel from_stl = loadText(replaced("stl"), "stl_part.json");
  EXPECT_EQ(from_step.triangles().size(), from_stl.triangles().size());
  ASSERT_TRUE(from_step.csg());

  const Machine machine = squareMachine(96, 0.5);
  const Pose pose = poseAbout({25, -35, 10}, {15, 10, 5}, {0, 0, 200});
  ImageT<double> previous;
  for (const std::map<std::string, double>& values :
       {std::map<std::string, double>{}, {{"d", 8.5}, {"x", 12.0}}}) {
    const ImageT<double> a = renderPaths(machine, from_step.mesh(from_step.values(values)), pose, 2);
    const ImageT<double> b = renderPaths(machine, from_stl.mesh(from_stl.values(values)), pose, 2);
    EXPECT_LT(maxAbsDifference(a, b), 1e-9);
    if (!previous.empty()) {
      EXPECT_GT(maxAbsDifference(a, previous), 1.0);  // the hole moved
    }
    previous = a;
  }
}

// The bracket of parts/bracket.json at nominal size, in part coordinates.
struct Bracket {
  double L, H, W, T, d, c, s, du, hu;
  explicit Bracket(const PartModel& part) {
    const std::vector<double> v = part.nominalValues();
    const auto at = [&](const char* name) {
      return v[static_cast<size_t>(part.dimensionIndex(name))];
    };
    L = at("base_length"), H = at("height"), W = at("width"), T = at("thickness");
    d = at("hole_diameter"), c = at("hole_position"), s = at("hole_spacing");
    du = at("upright_hole_diameter"), hu = at("upright_hole_height");
  }

  // Modelled as bracket.json describes it, with OpenCASCADE's own API.
  static TopoDS_Shape occt(const PartModel& part) {
    return bracketSolid(valuesByName(part, part.nominalValues()));
  }

  // The exact path length (mm) of the segment p + t (q - p), t in [0, 1],
  // through the true bracket (round holes): the booleans evaluated between
  // the sorted ends of each solid's interval.
  double pathLength(const Vec3& p, const Vec3& q) const {
    const Vec3 dir = q - p;
    struct Interval {
      double t0 = 1, t1 = 0;  // empty unless t0 < t1
      bool contains(double t) const { return t0 < t && t < t1; }
    };
    const auto slab = [&](int axis, double lo, double hi, Interval& in) {
      if (dir[axis] == 0.0) {
        if (p[axis] <= lo || p[axis] >= hi) in = {};
        return;
      }
      double a = (lo - p[axis]) / dir[axis], b = (hi - p[axis]) / dir[axis];
      if (a > b) std::swap(a, b);
      in.t0 = std::max(in.t0, a), in.t1 = std::min(in.t1, b);
    };
    const auto box = [&](const Vec3& lo, const Vec3& hi) {
      Interval in{0, 1};
      for (int axis = 0; axis < 3; ++axis) slab(axis, lo[axis], hi[axis], in);
      return in;
    };
    // A cylinder about `axis` through (centre u, centre v) of the other two.
    const auto cylinder = [&](int axis, double cu, double cv, double r, double from, double to) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      const double du_ = dir[u], dv_ = dir[v], pu = p[u] - cu, pv = p[v] - cv;
      const double a = du_ * du_ + dv_ * dv_, b = 2 * (pu * du_ + pv * dv_);
      const double disc = b * b - 4 * a * (pu * pu + pv * pv - r * r);
      if (a == 0.0 || disc <= 0.0) return Interval{};
      Interval in{(-b - std::sqrt(disc)) / (2 * a), (-b + std::sqrt(disc)) / (2 * a)};
      in.t0 = std::max(in.t0, 0.0), in.t1 = std::min(in.t1, 1.0);
      slab(axis, from, to, in);
      return in;
    };
    const Interval base = box({0, 0, 0}, {L, W, T}), upright = box({0, 0, 0}, {T, W, H});
    const Interval holes[3] = {cylinder(2, c, W / 2, d / 2, -1, T + 1),
                               cylinder(2, c + s, W / 2, d / 2, -1, T + 1),
                               cylinder(0, W / 2, hu, du / 2, -1, T + 1)};
    std::vector<double> ends{0.0, 1.0};
    for (const Interval& in : {base, upright, holes[0], holes[1], holes[2]})
      if (in.t0 < in.t1)
        ends.insert(ends.end(), {std::clamp(in.t0, 0.0, 1.0), std::clamp(in.t1, 0.0, 1.0)});
    std::sort(ends.begin(), ends.end());
    double inside = 0.0;
    for (size_t i = 0; i + 1 < ends.size(); ++i) {
      const double mid = 0.5 * (ends[i] + ends[i + 1]);
      if ((base.contains(mid) || upright.contains(mid)) &&
          !std::any_of(std::begin(holes), std::end(holes),
                       [&](const Interval& h) { return h.contains(mid); }))
        inside += ends[i + 1] - ends[i];
    }
    return inside * dir.norm();
  }
};

// The renderer's pixel value for the true bracket: the mean over the same
// n x n samples (renderer.h).
ImageT<double> renderExact(const Machine& machine, const Bracket& bracket, const Pose& pose,
                           int n) {
  const Mat3 back = pose.rotation.transpose();
  const Vec3 source = back * (machine.sourceWorld() - pose.translation_mm);
  ImageT<double> image(machine.columns, machine.rows);
  for (int v = 0; v < machine.rows; ++v)
    for (int u = 0; u < machine.columns; ++u) {
      double sum = 0.0;
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          const Vec3 pixel = back * (machine.detectorPoint(u + (i + 0.5) / n, v + (j + 0.5) / n) -
                                     pose.translation_mm);
          sum += bracket.pathLength(source, pixel);
        }
      image(u, v) = sum / (n * n);
    }
  return image;
}

TEST(Step, BracketFromOpenCascadeRendersAsPartsBracketJson) {
  const PartModel json_part = PartModel::load(kParts + "bracket.json");
  const Bracket bracket(json_part);
  writeStep("bracket.step", Bracket::occt(json_part));
  const auto step_part = [](const char* chord) {
    return loadText(fmt::format(R"({{"description": "parts/bracket.json from OpenCASCADE",
      "shape": {{"type": "step", "file": "bracket.step", "chord_tolerance_mm": {}}}}})",
                                chord),
                    fmt::format("bracket_{}.json", chord));
  };

  // The bracket covers 41 % of a 160 x 160 detector of 0.4 mm pixels (4 x 4
  // samples each), seen obliquely: no hole's axis lies along a ray.
  const Machine machine = squareMachine(160, 0.4);
  const Pose pose = poseAbout({35, -25, 15}, {20, 12.5, 15}, {0, 0, 150});
  const int n = 4;
  const ImageT<double> json = renderPaths(machine, json_part.mesh(json_part.nominalValues()), pose, n);
  const ImageT<double> exact = renderExact(machine, bracket, pose, n);
  int covered = 0;
  for (double x : json.pixels()) covered += x > 0;
  EXPECT_GT(covered, static_cast<int>(json.size() / 3));

  // bracket.json's holes are inscribed polygons within 0.001 mm of their
  // circles (N >= pi / acos(1 - 0.001 / r): 128 and 144 sides). OCCT divides
  // a circle the same way at half its linear deflection, from the same
  // starting direction (the cylinder's x axis, as bracket.json's u axis),
  // so at a chord tolerance of 0.002 mm the STEP part's holes are the same
  // polygons and the two parts render alike.
  const ImageT<double> coarse = renderPaths(machine, step_part("0.002").mesh({}), pose, n);
  const double coarse_json = maxAbsDifference(coarse, json);
  EXPECT_LT(coarse_json, 0.002);

  // Finer, the STEP part approaches the true bracket (round holes), computed
  // along the same sample rays: within 0.0006 mm at 0.0001 mm. bracket.json
  // itself differs from the true bracket by up to 0.0135 mm, at some 135
  // pixels where rays graze a hole's wall (a polygon's side cuts up to 0.001
  // mm into the circle), so the fine STEP part is that far from it there.
  const ImageT<double> fine = renderPaths(machine, step_part("0.0001").mesh({}), pose, n);
  const double fine_exact = maxAbsDifference(fine, exact);
  EXPECT_LT(fine_exact, 0.002);
  std::printf(
      "max |path difference| over %d covered pixels: STEP at 0.002 mm vs bracket.json "
      "%.3g mm; STEP at 0.0001 mm vs the true bracket %.3g mm, vs bracket.json %.3g mm; "
      "bracket.json vs the true bracket %.3g mm\n",
      covered, coarse_json, fine_exact, maxAbsDifference(fine, json),
      maxAbsDifference(json, exact));
}

}  // namespace
}  // namespace xgauge
