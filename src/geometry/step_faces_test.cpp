// Dimensions named on the faces of STEP solids (face_moves.h,
// faced_shape.h): Prism A and the bracket modelled with OpenCASCADE at
// nominal size, their dimensions named on faces, against parts/prism_jaw.json
// and parts/bracket.json over random dimensions (paths pixel by pixel), their
// image derivatives against central differences, folds and the refusals.
#include "occt_test_solids.h"

#include "xgauge/core/error.h"
#include "xgauge/core/file.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/geometry/step.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/xray/derivatives.h"

#include <BRepBuilderAPI_MakeEdge.hxx>
#include <BRepBuilderAPI_MakeWire.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <TopoDS_Edge.hxx>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <gtest/gtest.h>

#include <cstdio>
#include <random>

namespace xgauge {
namespace {

using testing::bracketSolid;
using testing::kParts;
using testing::loadText;
using testing::maxAbsDifference;
using testing::poseAbout;
using testing::PrismJawProfile;
using testing::prismJawSolid;
using testing::renderPaths;
using testing::valuesByName;
using testing::writeStep;
using testing::writeTestFile;

std::string at(const std::array<double, 3>& p) {
  return fmt::format(R"({{"at": [{:.17g}, {:.17g}, {:.17g}]}})", p[0], p[1], p[2]);
}

// The dimension entries of `json` (a part model) with `moves` spliced into
// each: {"name": ..., <moves>}.
std::string dimension(const Dimension& d, const std::string& moves) {
  return fmt::format(
      R"({{"name": "{}", "nominal": {:.17g}, "min": {:.17g}, "max": {:.17g}, "unit": "mm"{}{}}})",
      d.name, d.nominal, d.min, d.max, moves.empty() ? "" : ", ", moves);
}

Dimension withMin(Dimension d, double min) {
  d.min = min;
  return d;
}

std::string constraintsOf(const std::string& part_file) {
  const nlohmann::json json =
      nlohmann::json::parse(readFileContents(kParts + part_file, 1 << 20, "part"));
  return json.at("constraints").dump();
}

// Prism A as parts/prism_jaw.json, from a STEP solid: the faces moved by
// offsets and positions, the groove's planes given through its apex line
// and its edges at the front face.
std::string prismJawStepPart(const PartModel& json) {
  const PrismJawProfile p(valuesByName(json, json.nominalValues()));
  const double y = 20.0;
  const auto face = [&](size_t side) { return at(p.side(side, y)); };
  const std::string back = face(0), right = face(1), front_right = face(2),
                    groove_right = face(3), slot_right = face(4), slot_bottom = face(5),
                    slot_left = face(6), groove_left = face(7), front_left = face(8),
                    left = face(9);
  const auto& d = json.dimensions();
  std::vector<std::string> entries = {
      dimension(d[0], fmt::format(R"("offset": {{"faces": [{}], "datum": [{}]}})", right, left)),
      dimension(d[1], fmt::format(R"("position": {{"faces": [{}, {}, {}], "direction": [1, 0, 0]}})",
                                  slot_left, slot_right, slot_bottom)),
      dimension(d[2],
                fmt::format(R"("offset": {{"faces": [{}, {}], "datum": {}}},
                   "position": {{"faces": [{}], "direction": [0, 0, 1]}})",
                            front_left, front_right, back, slot_bottom)),
      dimension(d[3], fmt::format(R"("position": {{"faces": {}, "direction": [0, 0, -1]}})",
                                  slot_bottom)),
      dimension(d[4], ""),
      dimension(d[5], ""),
      dimension(d[6], fmt::format(R"("offset": {{"faces": [{}], "datum": [{}], "split": true}})",
                                  slot_left, slot_right)),
      // The ends' triangles, fixed at nominal values, fold below 1.8 mm.
      dimension(withMin(d[7], 2.0), fmt::format(R"("position": {{"faces": [{}], "direction": [0, 0, -1]}})", slot_bottom))};
  std::string dimensions;
  for (const std::string& e : entries) dimensions += (dimensions.empty() ? "" : ",\n") + e;
  return fmt::format(R"({{
    "description": "Prism A from OpenCASCADE, its dimensions named on faces",
    "constants": [{{"name": "L", "value": 40}}],
    "dimensions": [{}],
    "surfaces": [
      {{"faces": [{}], "plane": {{"through": [
        ["groove_center", 0, "thickness - groove_depth"], ["groove_center", "L", "thickness - groove_depth"],
        ["groove_center - groove_left", 0, "thickness"]]}}}},
      {{"faces": [{}], "plane": {{"through": [
        ["groove_center", 0, "thickness - groove_depth"], ["groove_center + groove_right", 0, "thickness"],
        ["groove_center", "L", "thickness - groove_depth"]]}}}}],
    "constraints": {},
    "shape": {{"type": "step", "file": "prism_a.step"}}}})",
                     dimensions, groove_left, groove_right, constraintsOf("prism_jaw.json"));
}

// The bracket as parts/bracket.json, from a STEP solid. Its holes are
// tessellated as bracket.json's polygons at a chord tolerance of 0.002 mm
// (step_test.cpp, BracketFromOpenCascadeRendersAsPartsBracketJson).
std::string bracketStepPart(const PartModel& json) {
  const auto v = valuesByName(json, json.nominalValues());
  const double L = v.at("base_length"), H = v.at("height"), W = v.at("width"),
               T = v.at("thickness"), d = v.at("hole_diameter"), c = v.at("hole_position"),
               s = v.at("hole_spacing"), du = v.at("upright_hole_diameter"),
               hu = v.at("upright_hole_height");
  const std::string outer = at({0, 5, H / 2}), underside = at({(c + c + s) / 2, 5, 0}),
                    end = at({L, W / 2, T / 2}), top = at({T / 2, W / 2, H}),
                    near_side = at({L / 2, 0, T / 2}), far_side = at({L / 2, W, T / 2}),
                    base_top = at({L - 2, 5, T}), inner = at({T, 5, H - 2}),
                    hole1 = at({c + d / 2, W / 2, T / 2}), hole2 = at({c + s + d / 2, W / 2, T / 2}),
                    upright_hole = at({T / 2, W / 2 + du / 2, hu});
  const auto& dims = json.dimensions();
  const std::vector<std::string> entries = {
      dimension(dims[0], fmt::format(R"("offset": {{"faces": [{}], "datum": [{}]}})", end, outer)),
      dimension(dims[1], fmt::format(R"("offset": {{"faces": [{}], "datum": [{}]}})", top, underside)),
      dimension(dims[2], fmt::format(R"("offset": {{"faces": [{}], "datum": [{}]}},
        "position": {{"faces": [{}, {}, {}], "direction": [0, 1, 0], "ratio": 0.5}})",
                                     far_side, near_side, hole1, hole2, upright_hole)),
      dimension(dims[3], fmt::format(R"("offset": [{{"faces": [{}], "datum": [{}]}},
                                                  {{"faces": [{}], "datum": [{}]}}])",
                                     base_top, underside, inner, outer)),
      dimension(dims[4], fmt::format(R"("diameter": {{"faces": [{}, {}]}})", hole1, hole2)),
      dimension(dims[5], fmt::format(
                             R"("position": {{"faces": [{}, {}], "direction": [1, 0, 0], "datum": [{}]}})",
                             hole1, hole2, outer)),
      dimension(dims[6], fmt::format(
                             R"("position": {{"faces": [{}], "direction": [1, 0, 0], "datum": [{}]}})",
                             hole2, hole1)),
      dimension(dims[7], fmt::format(R"("diameter": {{"faces": [{}]}})", upright_hole)),
      dimension(dims[8], fmt::format(
                             R"("position": {{"faces": [{}], "direction": [0, 0, 1], "datum": [{}]}})",
                             upright_hole, underside))};
  std::string dimensions;
  for (const std::string& e : entries) dimensions += (dimensions.empty() ? "" : ",\n") + e;
  return fmt::format(R"({{
    "description": "The bracket from OpenCASCADE, its dimensions named on faces",
    "dimensions": [{}],
    "constraints": {},
    "shape": {{"type": "step", "file": "bracket.step", "chord_tolerance_mm": 0.002}}}})",
                     dimensions, constraintsOf("bracket.json"));
}

// `count` dimension sets within +-0.5 mm of nominal that `part` accepts.
std::vector<std::vector<double>> randomValues(const PartModel& part, int count, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> offset(-0.5, 0.5);
  std::vector<std::vector<double>> sets;
  while (static_cast<int>(sets.size()) < count) {
    std::vector<double> values = part.nominalValues();
    for (double& v : values) v += offset(rng);
    if (!part.invalidity(values)) sets.push_back(values);
  }
  return sets;
}

// Both parts' paths over `sets`, on one oblique view: the largest difference.
double largestPathDifference(const PartModel& json, const PartModel& step,
                             const std::vector<std::vector<double>>& sets, const Pose& pose) {
  const Machine machine = testing::squareMachine(120, 0.5);
  double worst = 0.0;
  for (const std::vector<double>& values : sets) {
    const ImageT<double> a = renderPaths(machine, json.mesh(values), pose, 2);
    const ImageT<double> b = renderPaths(machine, step.mesh(values), pose, 2);
    double covered = 0;
    for (double x : a.pixels()) covered += x > 0;
    EXPECT_GT(covered, 0.2 * static_cast<double>(a.size()));
    worst = std::max(worst, maxAbsDifference(a, b));
  }
  return worst;
}

TEST(StepFaces, PrismJawFromStepFollowsPartsPrismJawJson) {
  const PartModel json = PartModel::load(kParts + "prism_jaw.json");
  writeStep("prism_a.step", prismJawSolid(valuesByName(json, json.nominalValues())));
  const PartModel step = loadText(prismJawStepPart(json), "prism_a.json");
  ASSERT_EQ(step.dimensions().size(), json.dimensions().size());
  const auto sets = randomValues(json, 50, 58);
  const double worst = largestPathDifference(
      json, step, sets, poseAbout({30, -40, 15}, {10.5, 20, 6.5}, {0, 0, 150}));
  std::printf("Prism A, 50 dimension sets within 0.5 mm of nominal: largest path difference, "
              "STEP vs prism_jaw.json, %.3g mm\n",
              worst);
  EXPECT_LT(worst, 1e-6);
}

TEST(StepFaces, BracketFromStepFollowsPartsBracketJson) {
  const PartModel json = PartModel::load(kParts + "bracket.json");
  writeStep("bracket.step", bracketSolid(valuesByName(json, json.nominalValues())));
  const PartModel step = loadText(bracketStepPart(json), "bracket.json");
  ASSERT_EQ(step.dimensions().size(), json.dimensions().size());
  const auto sets = randomValues(json, 50, 59);
  const double worst = largestPathDifference(
      json, step, sets, poseAbout({35, -25, 15}, {20, 12.5, 15}, {0, 0, 150}));
  std::printf("bracket, 50 dimension sets within 0.5 mm of nominal: largest path difference, "
              "STEP vs bracket.json, %.3g mm\n",
              worst);
  EXPECT_LT(worst, 1e-6);
}

}  // namespace
}  // namespace xgauge
