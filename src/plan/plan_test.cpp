// xgauge plan at small size: the prediction against a measurement of
// independently rendered shots, the plan's best set against the translated
// pair, and bad plan jobs refused before anything is written.
#include "xgauge/plan/plan.h"

#include "core/expect_error.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/image/tiff.h"
#include "xgauge/lab/random.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/material/transmission_table.h"
#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"
#include "xgauge/xray/renderer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>

#include <fmt/format.h>

namespace xgauge {
namespace {

namespace fs = std::filesystem;

const std::string kRoot = XGAUGE_SOURCE_DIR;

class PlanViews : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("xgauge_plan_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    writeMachine(96, 0.8);
    ExponentialSum material({{0.6, 0.03}, {0.3, 0.07}, {0.1, 0.25}});
    // A curve known to 1 %: a face-on view's depth, seen only through
    // the intensity, is then as uncertain as the tolerance.
    nlohmann::json curve = material.toJson();
    curve["uncertainty"]["transmission"] = 0.01;
    std::ofstream(dir_ / "material.json") << curve.dump();
  }
  void TearDown() override { fs::remove_all(dir_); }

  // machine.json: a square panel of `pixels` of `pitch_mm`, 1000 mm from the source.
  void writeMachine(int pixels, double pitch_mm) {
    Machine machine;
    machine.source_detector_distance_mm = 1000.0;
    machine.columns = machine.rows = pixels;
    machine.pitch_u_mm = machine.pitch_v_mm = pitch_mm;
    machine.cx_px = machine.cy_px = 0.5 * pixels;
    std::ofstream(dir_ / "machine.json") << machine.toJson().dump();
  }

  // A plan of the cuboid: three fixture rotations about the vertical, two
  // stage positions 12 mm apart; `change` edits the plan's JSON.
  fs::path writePlan(const std::function<void(nlohmann::json&)>& change = {}) {
    nlohmann::json plan = nlohmann::json::parse(R"({
      "job": {
        "part": ")" + kRoot + R"(/parts/cuboid.json",
        "machine": "machine.json", "material": "material.json",
        "dimensions": {"bounds": {"size_x": [19, 21], "size_y": [29, 31], "size_z": [9, 11]}},
        "tolerances": {"size_x": {"lower": -0.05, "upper": 0.05},
                       "size_y": {"lower": -0.05, "upper": 0.05},
                       "size_z": {"lower": -0.05, "upper": 0.05}},
        "pose_bounds": {"rotation_deg": [[-5, 5], [-10, 70], [-5, 5]],
                        "centre_mm": [[-30, 30], [-20, 20], [470, 530]]},
        "loss": "l2"
      },
      "exposure": {"open_beam_noise": 0.01},
      "views": {"centre_mm": [-6, 0, 500], "rotations_deg": [[0, 0, 0], [0, 30, 0], [0, 60, 0]],
                "stage": {"axis": [1, 0, 0], "positions_mm": [0, 12], "travel_mm": [0, 20]}},
      "radiographs": 2,
      "compare": [["v00", "v01"]],
      "budgeted": 2
    })");
    if (change) change(plan);
    std::ofstream(dir_ / "plan.json") << plan.dump(2);
    return dir_ / "plan.json";
  }

  fs::path dir_;
};

// The shot of `pose` rendered independently of the planner (the renderer
// itself, as measure_test's self-rendered pairs), with the plan's noise.
void writeShot(const fs::path& file, const PlanJob& plan, const Pose& pose, uint64_t seed) {
  const ExponentialSum& material = *plan.inputs.material;
  const PartModel& part = *plan.inputs.part;
  const TriangleMesh mesh = part.mesh(part.nominalValues());
  std::vector<Vec3> world;
  poseVertices(pose, mesh.vertices, world);
  RenderOptions options;
  options.samples_per_axis = 2;
  options.edge_samples_per_axis = 8;
  Image image;
  renderIntensity(plan.inputs.machine, {world, mesh.triangles},
                  TransmissionTable::forMaterial(material, 200.0), options, image);
  for (int y = 0; y < image.height(); ++y) {
    SplitMix64 stream = SplitMix64::stream(seed, static_cast<uint64_t>(y));
    std::normal_distribution<double> normal;
    for (int x = 0; x < image.width(); ++x) {
      const double i = static_cast<double>(image(x, y));
      image(x, y) = static_cast<float>(i + plan.open_beam_noise * std::sqrt(std::max(0.0, i)) * normal(stream));
    }
  }
  writeTiff(file, image, TiffFormat::kFloat32);
}

TEST_F(PlanViews, ThePredictedUIsWhatMeasuringTheViewsGives) {
  const PlanJob plan = PlanJob::load(writePlan());
  ASSERT_EQ(plan.views.size(), 6u);
  const PlanResult result = planViews(plan);
  ASSERT_EQ(result.screened, 15);
  // Measure the compared pair (v00, then v01 translated by 12 mm) from
  // shots rendered apart from the planner, three times.
  const PredictedSet& compared = result.compared.at(0);
  ASSERT_EQ(compared.patterns, (std::vector<std::string>{"free", "translated"}));
  std::map<std::string, double> sum;
  constexpr int kRuns = 3;
  for (int run = 0; run < kRuns; ++run) {
    nlohmann::json job = measurementJobFor(plan, result, compared.views);
    for (auto& r : job["radiographs"]) {
      const std::string name = r["name"];
      const int v = name == "v00" ? 0 : 1;
      const fs::path image = dir_ / fmt::format("{}_{}.tif", name, run);
      writeShot(image, plan, plan.views[static_cast<size_t>(v)].pose, 100 + 10 * run + v);
      r["image"] = image.string();
    }
    job["machine"] = (dir_ / "machine.json").string();
    job["material"] = (dir_ / "material.json").string();
    std::ofstream(dir_ / "job.json") << job.dump(2);
    const MeasurementInputs inputs = loadMeasurementInputs(dir_ / "job.json");
    ForwardModel model(inputs);
    const MeasurementResult measured = measure(model, model.start());
    ASSERT_EQ(measured.status, MeasurementStatus::kMeasured);
    for (const DimensionUncertainty& d : measured.uncertainty.dimensions) sum[d.name] += d.expanded;
  }
  for (const PredictedDimension& d : compared.dimensions) {
    ASSERT_TRUE(d.identifiable) << d.name;
    const double measured = sum.at(d.name) / kRuns;
    EXPECT_NEAR(d.expanded / measured, 1.0, 0.25) << d.name << ": predicted " << d.expanded
                                                  << ", measured " << measured;
  }
}

TEST_F(PlanViews, TheBudgetedSetsLeadTheRankingAndNoComparedSetBeatsThem) {
  const PlanJob plan = PlanJob::load(writePlan());
  const PlanResult result = planViews(plan);
  // The two best screened sets were budgeted and lead, in order; the
  // compared pair is among the screened sets, so none of its budget beats
  // the best (screening that missed a better set would fail this).
  ASSERT_TRUE(result.ranked.at(0).budgeted && result.ranked.at(1).budgeted);
  EXPECT_FALSE(result.ranked.at(2).budgeted);
  EXPECT_LE(result.ranked[0].score, result.ranked[1].score);
  EXPECT_LE(result.ranked[0].score, result.compared.at(0).score);
  EXPECT_TRUE(std::isfinite(result.ranked[0].score));
  // Written: plan.json, job.json (the best set's), report.html.
  xgauge::writePlan(plan, result, dir_ / "out");
  const nlohmann::json written = nlohmann::json::parse(std::ifstream(dir_ / "out/plan.json"));
  EXPECT_EQ(written["ranked"][0]["predicted_by"], "budget");
  EXPECT_EQ(written["screened"], 15);
  const nlohmann::json job = nlohmann::json::parse(std::ifstream(dir_ / "out/job.json"));
  EXPECT_EQ(job["radiographs"].size(), 2u);
  EXPECT_TRUE(fs::exists(dir_ / "out/report.html"));
}

// Prism A at 128^2 (1.6 mm pixels) on a curve known to 0.3 %: the face-on
// pair, 15 mm apart, sees the thickness along the beam only through the
// curve; the plan's best pair turns the jaw and sees it across (xgauge
// plan examples/view_plan_prism_a_small.json gives the same at 1024^2).
TEST_F(PlanViews, ThePlansBestPairBeatsTheFaceOnPairWhereTheDepthIsToleranced) {
  writeMachine(128, 1.6);
  const PlanJob plan = PlanJob::load(writePlan([](nlohmann::json& p) {
    nlohmann::json& job = p["job"];
    job["part"] = kRoot + "/parts/prism_jaw.json";
    job["dimensions"] = nlohmann::json::object();
    job["tolerances"] = nlohmann::json::object();
    for (const char* d : {"width", "thickness"})
      job["tolerances"][d] = {{"lower", -0.05}, {"upper", 0.05}};
    for (const char* d : {"groove_center", "groove_depth", "groove_left", "groove_right",
                          "slot_width", "slot_depth"})
      job["tolerances"][d] = {{"lower", -0.1}, {"upper", 0.1}};
    job["pose_bounds"] = nlohmann::json::parse(
        R"({"rotation_deg": [[-5, 5], [-90, 90], [-5, 5]], "centre_mm": [[-60, 60], [-30, 30], [690, 750]]})");
    p["exposure"]["open_beam_noise"] = 0.005;
    p["views"] = nlohmann::json::parse(
        R"({"centre_mm": [-8, 0, 720], "rotations_deg": [[0, 0, 0], [0, 30, 0], [0, 60, 0]],
            "stage": {"axis": [1, 0, 0], "positions_mm": [0, 15], "travel_mm": [0, 20]}})");
  }));
  const PlanResult result = planViews(plan);
  const PredictedSet& best = result.ranked.front();
  const PredictedSet& face_on = result.compared.at(0);
  ASSERT_EQ(face_on.patterns, (std::vector<std::string>{"free", "translated"}));
  EXPECT_LT(1.5 * best.score, face_on.score) << best.score << " vs " << face_on.score;
  EXPECT_NE(plan.views[static_cast<size_t>(best.views[0])].rotation_deg,
            plan.views[static_cast<size_t>(best.views[1])].rotation_deg);
  const auto thickness = [](const PredictedSet& s) {
    return std::find_if(s.dimensions.begin(), s.dimensions.end(),
                        [](const PredictedDimension& d) { return d.name == "thickness"; })
        ->expanded;
  };
  EXPECT_LT(2.0 * thickness(best), thickness(face_on));
}

// The wedge block with its eight edges free: measured from a centre line
// the part does not show, the pocket's edges move with the part's pose and
// are not determined (the walls are: their width shows). The plan says so
// for a translated pair, and so does the measurement of shots rendered
// apart from the planner.
TEST_F(PlanViews, WhatThePlanCannotDetermineTheMeasurementCannotEither) {
  writeMachine(128, 3.2);
  const PlanJob plan = PlanJob::load(writePlan([](nlohmann::json& p) {
    nlohmann::json& job = p["job"];
    job["part"] = kRoot + "/parts/wedge_block.json";
    job["dimensions"] = nlohmann::json::parse(
        R"({"free": ["pocket_left_top", "pocket_right_top", "wall_left_top", "wall_right_top",
                     "pocket_left_mid", "pocket_right_mid", "wall_left_mid", "wall_right_mid"]})");
    job.erase("tolerances");
    job["pose_bounds"] = nlohmann::json::parse(
        R"({"rotation_deg": [[-5, 5], [-10, 40], [-5, 5]], "centre_mm": [[-30, 30], [-20, 20], [600, 800]]})");
    p["criterion"] = {{"dimension", "wall_left_top"}};
    p["views"] = nlohmann::json::parse(
        R"({"centre_mm": [0, 0, 700], "rotations_deg": [[0, 0, 0], [0, 30, 0]],
            "stage": {"axis": [1, 0, 0], "positions_mm": [0, 12]}})");
    p["budgeted"] = 1;
  }));
  const PlanResult result = planViews(plan);
  const PredictedSet& pair = result.compared.at(0);
  std::map<std::string, bool> planned;
  for (const PredictedDimension& d : pair.dimensions) planned[d.name] = d.identifiable;
  EXPECT_FALSE(planned.at("pocket_left_top"));
  EXPECT_TRUE(planned.at("wall_left_top"));
  nlohmann::json job = measurementJobFor(plan, result, pair.views);
  for (auto& r : job["radiographs"]) {
    const std::string name = r["name"];
    const int v = name == "v00" ? 0 : 1;
    const fs::path image = dir_ / (name + ".tif");
    writeShot(image, plan, plan.views[static_cast<size_t>(v)].pose, 7 + v);
    r["image"] = image.string();
  }
  std::ofstream(dir_ / "job.json") << job.dump(2);
  const MeasurementInputs inputs = loadMeasurementInputs(dir_ / "job.json");
  ForwardModel model(inputs);
  const MeasurementResult measured = measure(model, model.start());
  ASSERT_EQ(measured.uncertainty.dimensions.size(), planned.size());
  for (const DimensionUncertainty& d : measured.uncertainty.dimensions)
    EXPECT_EQ(d.identifiable, planned.at(d.name)) << d.name;
}

// Where the grid is too large to screen every set, local exchange from
// seeded starts finds the best set every set's screening finds, on a grid
// small enough to check.
// "sets": "known_moves" keeps only sets whose later views are stage moves of
// the first: the cuboid's three rotations at two stage positions give 3.
TEST_F(PlanViews, KnownMovesOnlyKeepsTheStagesPairs) {
  const PlanResult result = planViews(PlanJob::load(writePlan([](nlohmann::json& p) {
    p["sets"] = "known_moves";
  })));
  EXPECT_EQ(result.screened, 3);
  for (const PredictedSet& s : result.ranked) {
    EXPECT_EQ(s.patterns, (std::vector<std::string>{"free", "translated"}));
    EXPECT_FALSE(s.scale_from_curve());
  }
}

TEST_F(PlanViews, LocalExchangeFindsWhatScreeningEverySetFinds) {
  const PlanResult every = planViews(PlanJob::load(writePlan([](nlohmann::json& p) {
    p["radiographs"] = 3;
    p.erase("compare");
  })));
  const PlanResult exchanged = planViews(PlanJob::load(writePlan([](nlohmann::json& p) {
    p["radiographs"] = 3;
    p.erase("compare");
    p["exhaustive_up_to"] = 4;
  })));
  EXPECT_EQ(every.screened, 20);
  EXPECT_NE(exchanged.search.find("local exchange"), std::string::npos) << exchanged.search;
  EXPECT_EQ(exchanged.ranked.front().views, every.ranked.front().views);
  EXPECT_DOUBLE_EQ(exchanged.ranked.front().score, every.ranked.front().score);
}

TEST_F(PlanViews, BadPlansAreRefusedNamingTheKey) {
  const auto refused = [&](const std::function<void(nlohmann::json&)>& change,
                           const std::string& expected) {
    const fs::path file = writePlan(change);
    expectErrorMentioning([&] { PlanJob::load(file); }, expected);
  };
  refused([](nlohmann::json& p) { p["views"]["rotations_deg"] = nlohmann::json::array(); },
          "/views/rotations_deg");
  refused([](nlohmann::json& p) { p["views"]["stage"]["positions_mm"] = {0, 25}; },
          "outside the stage's travel_mm");
  refused([](nlohmann::json& p) { p["job"]["tolerances"]["size_w"] = nlohmann::json::parse(R"({"lower": -0.1, "upper": 0.1})"); },
          "size_w");
  refused([](nlohmann::json& p) { p["views"]["rotations_deg"] = nlohmann::json::parse("[[0, 80, 0]]"); },
          "outside the job's pose_bounds");
  // On a bound's edge: the measurement's fit would end at the bound.
  refused([](nlohmann::json& p) { p["views"]["rotations_deg"] = nlohmann::json::parse("[[5, 0, 0]]"); },
          "within 2 % of their range from an edge");
  refused([](nlohmann::json& p) { p["job"]["dimensions"]["bounds"]["size_x"] = {20, 21}; },
          "size_x's value 20");
  refused([](nlohmann::json& p) { p["radiographs"] = 4; }, "/radiographs");
  refused([](nlohmann::json& p) { p["compare"] = nlohmann::json::parse(R"([["v00", "v99"]])"); }, "no candidate view named 'v99'");
  refused([](nlohmann::json& p) { p["job"]["radiographs"] = nlohmann::json::array(); },
          "a plan's job names no radiographs");
  refused([](nlohmann::json& p) { p["views"]["turntable"] = nlohmann::json::parse(R"({"angles_deg": [0, 10]})"); },
          "states no turntable axis");
  refused([](nlohmann::json& p) { p.erase("exposure"); }, "exposure");
  refused([](nlohmann::json& p) { p["criterion"] = "best"; }, "unknown criterion 'best'");
  refused([](nlohmann::json& p) { p["sets"] = "known"; }, "unknown sets 'known'");
}

}  // namespace
}  // namespace xgauge
