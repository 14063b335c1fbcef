// The part model file format: shapes, expressions, and the errors bad files
// give. The shipped parts are tested in parts_test.cpp.
#include "xgauge/geometry/part_model.h"

#include "test_files.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace xgauge {
namespace {

using testing::expectLoadError;
using testing::kTetrahedronStl;
using testing::loadText;
using testing::writeTestFile;

// A square with a notch: the profile (0,0) (w,0) (w,10) (p,5) (0,10) in the
// x-z plane, extruded along y over L = 4. For 0 < p < w its area is 7.5 w
// whatever p (the notch is a triangle of base w and height 5).
constexpr const char* kNotchedBar = R"({
  "description": "test part",
  "dimensions": [
    {"name": "width", "nominal": 10, "min": 5, "max": 20, "unit": "mm", "thesis": "θ1"},
    {"name": "p", "nominal": 3, "min": -20, "max": 20, "unit": "mm"}
  ],
  "constants": [{"name": "L", "value": 4, "unit": "mm"}],
  "derived": [{"name": "top", "expr": "10"}],
  "constraints": [{"expr": "width - p", "message": "the notch must stay inside"}],
  "shape": {
    "type": "extrusion", "plane": ["x", "z"], "axis": "y",
    "profile": [[0, 0], ["width", "0"], ["width", "top"], ["p", "top / 2"], ["0", "top"]],
    "from": "0", "to": "L"
  }
})";

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

TEST(PartModel, ReadsDimensionsInDeclarationOrder) {
  const PartModel model = loadText(kNotchedBar, "notched_bar.json");
  EXPECT_EQ(model.name(), "notched_bar");
  EXPECT_EQ(model.description(), "test part");
  ASSERT_EQ(model.dimensions().size(), 2u);
  EXPECT_EQ(model.dimensions()[0].name, "width");
  EXPECT_EQ(model.dimensions()[0].thesis, "θ1");
  EXPECT_EQ(model.dimensions()[1].name, "p");
  EXPECT_EQ(model.dimensionIndex("p"), 1);
  EXPECT_EQ(model.nominalValues(), (std::vector<double>{10, 3}));
  EXPECT_EQ(model.vertexCount(), 10u);
  EXPECT_EQ(model.triangles().size(), 2u * 3 + 2u * 5);
}

TEST(PartModel, ExtrusionPlacesProfileAndIsOutward) {
  const PartModel model = loadText(kNotchedBar);
  for (double width : {8.0, 10.0, 17.0}) {
    const TriangleMesh mesh = model.mesh(model.values({{"width", width}}));
    const MeshCheck check = checkClosedMesh(mesh);
    EXPECT_TRUE(check.ok()) << check.message;
    EXPECT_NEAR(check.volume_mm3, 7.5 * width * 4.0, 1e-12 * width);
    // Profile point 3 is (p, 5) at y = 0 and y = L.
    EXPECT_EQ(mesh.vertices[3], Vec3(3, 0, 5));
    EXPECT_EQ(mesh.vertices[8], Vec3(3, 4, 5));
    EXPECT_EQ(mesh.vertices[1], Vec3(width, 0, 0));
  }
}

TEST(PartModel, ExtrusionOrientationIsAutomaticForAnyWindingAndAxes) {
  // Clockwise profile, plane (z, x), extruded along y downwards.
  const std::string text = replaced(
      replaced(replaced(kNotchedBar, R"("plane": ["x", "z"])", R"("plane": ["z", "x"])"),
               R"([[0, 0], ["width", "0"], ["width", "top"], ["p", "top / 2"], ["0", "top"]])",
               R"([["0", "top"], ["p", "top / 2"], ["width", "top"], ["width", "0"], [0, 0]])"),
      R"("from": "0", "to": "L")", R"("from": "L", "to": "-1")");
  const PartModel model = loadText(text);
  const TriangleMesh mesh = model.mesh(model.nominalValues());
  const MeshCheck check = checkClosedMesh(mesh);
  EXPECT_TRUE(check.ok()) << check.message;
  EXPECT_NEAR(check.volume_mm3, 7.5 * 10 * 5, 1e-11);
  EXPECT_EQ(mesh.vertices[0], Vec3(10, 4, 0));  // (z, x) = ("0", "top")
}

TEST(PartModel, EvaluateChangesOnlyTheVerticesThatDependOnAValue) {
  const PartModel model = loadText(kNotchedBar);
  std::vector<Vec3> nominal, moved;
  model.evaluate(model.nominalValues(), nominal);
  model.evaluate(model.values({{"p", 4.5}}), moved);
  ASSERT_EQ(moved.size(), nominal.size());
  for (size_t i = 0; i < nominal.size(); ++i) {
    if (i == 3 || i == 8)
      EXPECT_EQ(moved[i], nominal[i] + Vec3(1.5, 0, 0)) << i;
    else
      EXPECT_EQ(moved[i], nominal[i]) << i;
  }
  // The hot path reuses the caller's storage.
  const Vec3* storage = moved.data();
  model.evaluate(model.nominalValues(), moved);
  EXPECT_EQ(moved.data(), storage);
}

TEST(PartModel, FoldingProfileIsCaughtByEvaluate) {
  // p = -5 puts the notch apex outside the left face: the profile crosses
  // itself, which no constraint of this file forbids.
  const PartModel model = loadText(kNotchedBar);
  std::vector<Vec3> out;
  try {
    model.evaluate(model.values({{"p", -5}}), out);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.message(),
              "a cap triangle turned over: the profile folds over itself, or moved too far from "
              "nominal for the caps' triangulation at width=10 mm, p=-5 mm");
    EXPECT_EQ(e.where().key_path, "/shape");
  }
  EXPECT_NO_THROW(model.evaluate(model.values({{"p", 1}}), out));
}

TEST(PartModel, ValuesCheckNamesAndBounds) {
  const PartModel model = loadText(kNotchedBar, "bar.json");
  EXPECT_EQ(model.values({{"p", 1.25}}), (std::vector<double>{10, 1.25}));
  try {
    model.values({{"width", 30}});
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.message(), "width = 30 mm is outside its bounds [5, 20] mm (part 'bar')");
  }
  try {
    model.values({{"wdth", 12}});
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.message(), "unknown dimension 'wdth' of part 'bar' (known: width, p)");
  }
}

TEST(PartModel, ValidateNamesTheViolatedConstraint) {
  const PartModel model = loadText(kNotchedBar);
  const std::vector<double> values = {10, 12};
  try {
    model.validate(values);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.message(),
              "constraint violated: the notch must stay inside (width - p = -2, must be > 0) at "
              "width=10 mm, p=12 mm");
    EXPECT_EQ(e.where().key_path, "/constraints/0/expr");
  }
  EXPECT_THROW(model.mesh(values), Error);
  EXPECT_THROW(model.validate(std::vector<double>{4, 3}), Error);  // width below its bounds
}

TEST(PartModel, NominalValuesMustSatisfyTheConstraints) {
  expectLoadError(replaced(kNotchedBar, R"("width - p")", R"("p - width")"),
                  "the nominal values are not valid: constraint violated: the notch must stay "
                  "inside (p - width = -7, must be > 0) at width=10 mm, p=3 mm",
                  "/constraints/0/expr");
}

TEST(PartModel, CombinationsAreNamedSumsOfItsDimensions) {
  const std::string with = R"("constraints": [{"expr": "width - p", "message": "the notch must stay inside"}],)";
  const auto declaring = [&](const std::string& combinations) {
    return replaced(kNotchedBar, with, with + R"( "combinations": )" + combinations + ",");
  };
  const PartModel model = loadText(
      declaring(R"([{"name": "span", "terms": {"width": 1, "p": -0.5}, "description": "d"}])"));
  ASSERT_EQ(model.combinations().size(), 1u);
  EXPECT_EQ(model.combinations()[0].name, "span");
  EXPECT_EQ(model.combinations()[0].description, "d");
  ASSERT_EQ(model.combinations()[0].terms.size(), 2u);
  EXPECT_TRUE(loadText(kNotchedBar).combinations().empty());

  expectLoadError(declaring(R"([{"name": "span", "terms": {"width": 1, "depth": 1}}])"),
                  "not a dimension of the part", "/combinations/0/terms/depth");
  expectLoadError(declaring(R"([{"name": "span", "terms": {"width": 1}}])"),
                  "a combination needs at least two dimensions", "/combinations/0/terms");
  expectLoadError(declaring(R"([{"name": "span", "terms": {"width": 1, "p": 0}}])"),
                  "a coefficient must be finite and not 0", "/combinations/0/terms/p");
  expectLoadError(declaring(R"([{"name": "top", "terms": {"width": 1, "p": 1}}])"), "'top' is defined twice",
                  "/combinations/0/name");
  expectLoadError(declaring(R"([{"name": "span", "terms": {"width": 1, "p": 1}, "typo": 1}])"),
                  "unknown key 'typo'", "/combinations/0/typo");
}

TEST(PartModel, CopiesEvaluateOnTheirOwn) {
  auto original = std::make_unique<PartModel>(loadText(kNotchedBar));
  const PartModel copy = *original;
  original.reset();
  const TriangleMesh mesh = copy.mesh(copy.values({{"width", 12}}));
  EXPECT_NEAR(signedVolume(mesh), 7.5 * 12 * 4, 1e-11);
}

TEST(PartModel, DegreeHelpersAndDerivedValues) {
  const std::string text = replaced(kNotchedBar, R"({"name": "top", "expr": "10"})",
                                    R"j({"name": "half", "expr": "5 / cosd(60) / 2"},
                                       {"name": "top", "expr": "2 * half * sind(90)"})j");
  const PartModel model = loadText(text);
  const TriangleMesh mesh = model.mesh(model.nominalValues());
  EXPECT_NEAR(mesh.vertices[4].z(), 10.0, 1e-14);
}

TEST(PartModel, UnknownNameInExpression) {
  expectLoadError(replaced(kNotchedBar, R"(["width", "0"])", R"(["wdth", "0"])"),
                  "bad expression 'wdth': Unexpected token \"wdth\" found at position 0. (known "
                  "names: width, p, top, L)",
                  "/shape/profile/1/0");
}

TEST(PartModel, SyntaxErrorGivesMuparsersMessageAndPosition) {
  expectLoadError(replaced(kNotchedBar, R"("top / 2")", R"("top / ")"),
                  "bad expression 'top / ': Unexpected end of expression at position 7",
                  "/shape/profile/3/1");
}

TEST(PartModel, DerivedValuesSeeOnlyEarlierOnes) {
  expectLoadError(replaced(kNotchedBar, R"({"name": "top", "expr": "10"})",
                           R"({"name": "top", "expr": "2 * half"}, {"name": "half", "expr": "5"})"),
                  "bad expression '2 * half': Unexpected token \"half\" found at position 4. "
                  "(known names: width, p, L)",
                  "/derived/0/expr");
}

TEST(PartModel, AnExpressionReadsOneValue) {
  expectLoadError(replaced(kNotchedBar, R"("width - p")", R"("width = p")"),
                  "bad expression 'width = p': '=' assigns; compare with '==' or remove it",
                  "/constraints/0/expr");
  expectLoadError(replaced(kNotchedBar, R"("width - p")", R"("width, p")"),
                  "bad expression 'width, p': it gives 2 values separated by ',', not one",
                  "/constraints/0/expr");
}

TEST(PartModel, MalformedJsonGivesLineAndColumn) {
  try {
    loadText("{\n  \"description\": \"x\",\n  \"dimensions\": [,]\n}");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.where().line, 3);
    EXPECT_NE(e.message().find("malformed JSON"), std::string::npos) << e.what();
  }
}

TEST(PartModel, MissingKey) {
  expectLoadError(replaced(kNotchedBar, R"("max": 20, )", ""), "missing key 'max'",
                  "/dimensions/0");
}

TEST(PartModel, MisspelledKey) {
  expectLoadError(replaced(kNotchedBar, R"("thesis": "θ1")", R"("theses": "θ1")"),
                  "unknown key 'theses'; did you mean 'thesis'?", "/dimensions/0/theses");
  // A required key misspelled: the unknown key is named, not the missing one.
  expectLoadError(replaced(kNotchedBar, R"("from": "0")", R"("form": "0")"),
                  "unknown key 'form'; did you mean 'from'?", "/shape/form");
}

TEST(PartModel, BadDeclarations) {
  expectLoadError(replaced(kNotchedBar, R"("nominal": 10)", R"("nominal": 25)"),
                  "nominal 25 lies outside [min, max] = [5, 20]", "/dimensions/0");
  expectLoadError(replaced(kNotchedBar, R"("unit": "mm", "thesis")", R"("unit": "cm", "thesis")"),
                  "unknown unit 'cm' (known: mm, deg)", "/dimensions/0/unit");
  expectLoadError(replaced(kNotchedBar, R"({"name": "L")", R"({"name": "p")"),
                  "'p' is defined twice", "/constants/0/name");
  expectLoadError(replaced(kNotchedBar, R"({"name": "L")", R"({"name": "sin")"),
                  "'sin' is the name of a built-in function or constant", "/constants/0/name");
  expectLoadError(replaced(kNotchedBar, R"("type": "extrusion")", R"("type": "sweep")"),
                  "unknown shape type 'sweep' (known: union, difference, intersection, extrusion, "
                  "revolution, box, cylinder, mesh, stl, step)",
                  "/shape/type");
  expectLoadError(replaced(kNotchedBar, R"("axis": "y")", R"("axis": "x")"),
                  "the extrusion axis must be the one not in the plane, 'y'", "/shape/axis");
}

// The drawing's default tolerance of a dimension (measure/tolerance.h).
std::string withWidthTolerance(const std::string& tolerance) {
  return replaced(kNotchedBar, R"("thesis": "θ1")", R"("thesis": "θ1", "tolerance": )" + tolerance);
}

TEST(PartModel, ReadsAnOptionalTolerancePerDimension) {
  const PartModel model = loadText(withWidthTolerance(R"({"lower": -0.05, "upper": 0.125})"));
  ASSERT_TRUE(model.dimensions()[0].tolerance.has_value());
  EXPECT_EQ(model.dimensions()[0].tolerance->lower, -0.05);
  EXPECT_EQ(model.dimensions()[0].tolerance->upper, 0.125);
  EXPECT_FALSE(model.dimensions()[1].tolerance.has_value());
  // Asymmetric zones on one side of the nominal are specifications too.
  const PartModel above = loadText(withWidthTolerance(R"({"lower": 0.25, "upper": 0.5})"));
  EXPECT_EQ(above.dimensions()[0].tolerance->lower, 0.25);
}

TEST(PartModel, BadTolerancesNameTheirKey) {
  expectLoadError(withWidthTolerance(R"({"lower": 0.05, "upper": -0.05})"),
                  "lower (0.05) must be below upper (-0.05)", "/dimensions/0/tolerance");
  expectLoadError(withWidthTolerance(R"({"lower": 0.05, "upper": 0.05})"),
                  "lower (0.05) must be below upper (0.05)", "/dimensions/0/tolerance");
  expectLoadError(withWidthTolerance(R"({"lower": -0.05})"), "missing key 'upper'",
                  "/dimensions/0/tolerance");
  expectLoadError(withWidthTolerance(R"({"lower": -0.05, "upper": 0.05, "uper": 0.05})"),
                  "unknown key 'uper'; did you mean 'upper'?", "/dimensions/0/tolerance/uper");
  // The part model's nominal is the dimension's: a tolerance here takes none.
  expectLoadError(withWidthTolerance(R"({"nominal": 10, "lower": -0.05, "upper": 0.05})"),
                  "unknown key 'nominal'", "/dimensions/0/tolerance/nominal");
  expectLoadError(withWidthTolerance("0.05"), "expected an object", "/dimensions/0/tolerance");
  expectLoadError(withWidthTolerance(R"({"lower": "-0.05", "upper": 0.05})"),
                  "expected a number, got \"-0.05\"", "/dimensions/0/tolerance/lower");
  // Width 10 in [5, 20]: a zone [25, 30] (a slip of unit or sign) cannot be met.
  expectLoadError(
      withWidthTolerance(R"({"lower": 15, "upper": 20})"),
      "the tolerance zone [25, 30] mm lies outside the dimension's [min, max] = [5, 20]",
      "/dimensions/0/tolerance");
}

TEST(PartModel, ANonFiniteToleranceIsRefused) {
  // JSON text cannot hold a NaN; a document built in memory can.
  nlohmann::json document =
      nlohmann::json::parse(withWidthTolerance(R"({"lower": -0.05, "upper": 0.05})"));
  document["dimensions"][0]["tolerance"]["lower"] = std::nan("");
  try {
    PartModel::fromConfig(ConfigNode::fromJson(document, "part.json"), "part.json");
    FAIL() << "a NaN tolerance was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.message(), "expected a finite number");
    EXPECT_EQ(e.where().key_path, "/dimensions/0/tolerance/lower");
  }
}

TEST(PartModel, SelfIntersectingNominalProfile) {
  expectLoadError(replaced(kNotchedBar, R"("nominal": 3)", R"("nominal": -3)"),
                  "at nominal values the profile is not a simple polygon: edges 2-3 and 4-0 "
                  "touch or cross",
                  "/shape/profile");
}

TEST(PartModel, NonFiniteExpression) {
  const std::string text = replaced(kNotchedBar, R"({"name": "top", "expr": "10"})",
                                    R"j({"name": "top", "expr": "10 + 1 / (width - 12)"})j");
  const PartModel model = loadText(text);
  std::vector<Vec3> out;
  try {
    model.evaluate(model.values({{"width", 12}}), out);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.message(),
              "expression '10 + 1 / (width - 12)' is not finite at width=12 mm, p=3 mm");
    EXPECT_EQ(e.where().key_path, "/derived/0/expr");
  }
}

// A tetrahedron as a raw mesh; `triangles` replaces its triangle list.
std::string tetrahedron(const std::string& triangles) {
  return R"({
    "description": "tetrahedron",
    "dimensions": [{"name": "a", "nominal": 2, "min": 1, "max": 3, "unit": "mm"}],
    "shape": {"type": "mesh",
              "vertices": [[0, 0, 0], ["a", 0, 0], [0, "a", 0], [0, 0, "a"]],
              "triangles": )" +
         triangles + "}}";
}

TEST(PartModel, RawMeshMustBeClosedAndOutward) {
  const PartModel model = loadText(tetrahedron("[[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]"));
  EXPECT_NEAR(signedVolume(model.mesh(model.values({{"a", 3}}))), 27.0 / 6.0, 1e-14);

  expectLoadError(tetrahedron("[[0, 2, 1], [0, 1, 3], [0, 3, 2]]"),
                  "at nominal values: edge (1, 2) is used by 1 triangle (triangle 0): the mesh "
                  "is open",
                  "/shape");
  expectLoadError(tetrahedron("[[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]]"),
                  "at nominal values: triangles are oriented inward (negative volume, "
                  "-1.3333333333333333 mm^3)",
                  "/shape");
  expectLoadError(tetrahedron("[[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 2]]"),
                  "at nominal values: triangle 3 is degenerate: it repeats a vertex (1, 2, 2)",
                  "/shape");
  expectLoadError(tetrahedron("[[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 4]]"),
                  "vertex index 4 out of range (the mesh has 4 vertices)", "/shape/triangles/3/2");
}

// The connectivity is checked at load; the orientation can break at other
// values, and is checked wherever vertices are made (issue: hostile input).
TEST(PartModel, TurningInsideOutInsideTheBoundsIsRefusedWithTheValues) {
  const PartModel model =
      PartModel::load(std::string(XGAUGE_SOURCE_DIR) + "/tests/data/box_turning_inside_out.json");
  std::vector<Vec3> vertices;
  EXPECT_FALSE(model.tryEvaluate(std::vector<double>{8.0}, vertices));
  const auto inverted = model.tryEvaluate(std::vector<double>{4.0}, vertices);
  ASSERT_TRUE(inverted);
  EXPECT_NE(inverted->find("the surface turns inside out (signed volume -48 mm^3) at s=4 mm"),
            std::string::npos)
      << *inverted;
  const auto flat = model.tryEvaluate(std::vector<double>{5.0}, vertices);
  ASSERT_TRUE(flat);
  EXPECT_NE(flat->find("encloses no volume"), std::string::npos) << *flat;
  EXPECT_THROW(model.mesh(std::vector<double>{4.0}), Error);
}

TEST(PartModel, RevolutionWithTooManyTrianglesIsRefusedBeforeBuilding) {
  // Found by fuzzing: 64 points x 1e6 segments asked for 1.5 GB.
  std::string profile;
  for (int i = 0; i < 10; ++i)
    profile += fmt::format("{}[{}, {}]", i ? ", " : "", 5 + std::cos(0.6 * i), std::sin(0.6 * i));
  expectLoadError(R"({"description": "ring", "dimensions": [],
      "shape": {"type": "revolution", "axis": "z", "segments": 1000000, "profile": [)" +
                      profile + "]}}",
                  "10 profile points x 1000000 segments make 20000000 triangles; at most "
                  "16777216 are supported",
                  "/shape/segments");
}

TEST(PartModel, RevolutionWithPolesAndWithout) {
  constexpr int kSegments = 12;
  const double sector = kSegments / 2.0 * std::sin(2 * std::numbers::pi / kSegments);
  auto revolution = [](const std::string& profile) {
    return std::string(R"({"description": "solid of revolution",
      "dimensions": [{"name": "r", "nominal": 3, "min": 1, "max": 5, "unit": "mm"}],
      "shape": {"type": "revolution", "axis": "z", "segments": 12, "profile": )") +
           profile + "}}";
  };
  // Cone: apex and base centre on the axis.
  const PartModel cone = loadText(revolution(R"([[0, 0], ["r", 0], [0, 4]])"));
  EXPECT_EQ(cone.vertexCount(), 2u + kSegments);
  EXPECT_EQ(cone.triangles().size(), 2u * kSegments);
  MeshCheck check = checkClosedMesh(cone.mesh(cone.nominalValues()));
  EXPECT_TRUE(check.ok()) << check.message;
  EXPECT_NEAR(check.volume_mm3, sector * 9 * 4 / 3, 1e-12);
  // Tube, profile clockwise: rings only, inner radius 1.
  const PartModel tube = loadText(revolution(R"([[1, 0], [1, 2], ["r", 2], ["r", 0]])"));
  EXPECT_EQ(tube.vertexCount(), 4u * kSegments);
  const TriangleMesh mesh = tube.mesh(tube.values({{"r", 4}}));
  check = checkClosedMesh(mesh);
  EXPECT_TRUE(check.ok()) << check.message;
  EXPECT_NEAR(check.volume_mm3, sector * (16 - 1) * 2, 1e-12);
  // Ring vertices lie on the true circle, the first on +x for axis z.
  EXPECT_NEAR(mesh.vertices[2 * kSegments].x(), 4.0, 1e-15);
  EXPECT_EQ(mesh.vertices[2 * kSegments].y(), 0.0);
  for (int k = 0; k < kSegments; ++k)
    EXPECT_NEAR(mesh.vertices[2 * kSegments + k].head<2>().norm(), 4.0, 1e-14);

  expectLoadError(revolution(R"([[0, 0], ["r", 0], [0, 2], ["r", 4], [0, 4]])"),
                  "at nominal values 3 profile points lie on the axis; there must be none, or "
                  "two neighbours whose segment closes the profile",
                  "/shape/profile");
}

TEST(PartModel, StlShapeIsRelativeToThePartFile) {
  // An ASCII tetrahedron beside the part file.
  writeTestFile("tetra.stl", kTetrahedronStl);
  const PartModel model =
      loadText(R"({"description": "fixed", "shape": {"type": "stl", "file": "tetra.stl"}})");
  EXPECT_TRUE(model.dimensions().empty());
  EXPECT_NEAR(signedVolume(model.mesh({})), 1.0 / 6.0, 1e-16);
  expectLoadError(
      R"({"description": "fixed", "dimensions": [], "shape": {"type": "stl", "file": "tetra.stl"}})",
      "a part with an \"stl\" shape has no dimensions, constants, derived values or constraints",
      "/dimensions");
}

}  // namespace
}  // namespace xgauge
