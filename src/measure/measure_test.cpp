// The measurement pipeline on radiographs rendered by xgauge's own renderer:
// with no noise and no model error, it must find the dimensions exactly.
#include "xgauge/measure/measure.h"

#include "core/expect_error.h"
#include "xgauge/core/config.h"
#include "xgauge/core/digest.h"
#include "xgauge/core/progress.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/image/blur.h"
#include "xgauge/image/stats.h"
#include "xgauge/image/tiff.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/measure/model.h"
#include "xgauge/report/measurement.h"
#include "xgauge/xray/renderer.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

namespace xgauge {
namespace {

namespace fs = std::filesystem;
const std::string kRoot = XGAUGE_SOURCE_DIR;

class Measure : public ::testing::Test {
 protected:
  void SetUp() override {
    setProgressEnabled(false);
    dir_ = fs::temp_directory_path() /
           ("xgauge_measure_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }
  // machine.json, a 64 x 64 detector of 0.5 mm pixels, and a.tif, an open
  // beam on it: what a job needs to load without measuring.
  void writeOpenBeamShot() const {
    Machine machine;
    machine.columns = machine.rows = 64;
    machine.pitch_u_mm = machine.pitch_v_mm = 0.5;
    machine.cx_px = machine.cy_px = 32.0;
    std::ofstream(dir_ / "machine.json") << machine.toJson().dump();
    writeTiff(dir_ / "a.tif", Image(64, 64, 1.0f), TiffFormat::kFloat32);
  }
  fs::path dir_;
};

// Renders two noise-free radiographs of `part_file` with `truth` (the second
// translated by 30 mm), measures them with the default schedule and returns
// the result; `a` is the first pose.
// A square detector of `detector_px` pixels seeing about 128 mm.
Machine squareDetector(int detector_px) {
  Machine machine;
  machine.source_detector_distance_mm = 1000.0;
  machine.columns = machine.rows = detector_px;
  machine.pitch_u_mm = machine.pitch_v_mm = 0.4 * 320 / detector_px;
  machine.cx_px = 161.3 * detector_px / 320, machine.cy_px = 158.9 * detector_px / 320;
  return machine;
}

// The same on any machine, with the second shot `b` at its pose and with
// its pattern's keys `b_keys`, `extra` keys of the job (its "dimensions" or
// "schedule") and the white region given.
MeasurementResult measureSelfRenderedPair(const fs::path& dir, const Machine& machine,
                                          const std::string& part_file,
                                          const std::map<std::string, double>& truth, const Pose& a,
                                          const Pose& b, const std::string& b_keys,
                                          const std::string& bounds, const std::string& extra,
                                          const std::string& white);

// ... with b translated from a by 30 mm along `axis`, `b_extra` keys of
// the translated radiograph added.
MeasurementResult measureSelfRender(const fs::path& dir, const Machine& machine,
                                    const std::string& part_file,
                                    const std::map<std::string, double>& truth, const Pose& a,
                                    const Vec3& axis, const std::string& bounds,
                                    const std::string& extra, const std::string& white,
                                    const std::string& b_extra = "") {
  Pose b = a;
  b.translation_mm += 30.0 * axis;
  return measureSelfRenderedPair(
      dir, machine, part_file, truth, a, b,
      R"("pattern": "translated", "reference": "a", "distance_mm": 30.0)" + b_extra, bounds, extra,
      white);
}

MeasurementResult measureSelfRender(const fs::path& dir, const std::string& part_file,
                                    const std::map<std::string, double>& truth, const Pose& a,
                                    const Vec3& axis, const std::string& bounds,
                                    const std::string& schedule = "default",
                                    int detector_px = 320) {
  return measureSelfRender(dir, squareDetector(detector_px), part_file, truth, a, axis, bounds,
                           R"("schedule": ")" + schedule + R"(")", "[4, 4, 30, 30]");
}

MeasurementResult measureSelfRenderedPair(const fs::path& dir, const Machine& machine,
                                          const std::string& part_file,
                                          const std::map<std::string, double>& truth, const Pose& a,
                                          const Pose& b, const std::string& b_keys,
                                          const std::string& bounds, const std::string& extra,
                                          const std::string& white) {
  std::ofstream(dir / "machine.json") << machine.toJson().dump();
  const ExponentialSum material({{0.6, 0.03}, {0.3, 0.07}, {0.1, 0.25}});
  std::ofstream(dir / "material.json") << material.toJson().dump();
  const PartModel part = PartModel::load(part_file);
  const TriangleMesh mesh = part.mesh(part.values(truth));

  // Noise-free radiographs as the fit's final stage renders them: 2 x 2
  // samples, the edges 8 x 8 where its schedule refines them (schedule.h).
  const auto table = TransmissionTable::forMaterial(material, 200.0);
  RenderOptions options;
  options.samples_per_axis = 2;
  std::string schedule = "default";
  if (const size_t at = extra.find(R"("schedule": ")"); at != std::string::npos) {
    const size_t from = at + std::string_view(R"("schedule": ")").size();
    schedule = extra.substr(from, extra.find('"', from) - from);
  }
  const auto kind = scheduleKindFromName(schedule);
  options.edge_samples_per_axis =
      scheduleFor(kind.value_or(ScheduleKind::kDefault)).least_squares.edge_samples;
  std::vector<Vec3> world;
  for (const auto& [name, pose] : {std::pair{"a", a}, std::pair{"b", b}}) {
    poseVertices(pose, mesh.vertices, world);
    Image image;
    renderIntensity(machine, {world, mesh.triangles}, table, options, image);
    writeTiff(dir / (std::string(name) + ".tif"), image, TiffFormat::kFloat32);
  }
  std::ofstream(dir / "job.json") << R"({
    "part": ")" + part_file + R"(",
    "machine": "machine.json", "material": "material.json",
    "radiographs": [
      {"name": "a", "image": "a.tif", "white_region": )" +
                                         white + R"(, "pattern": "free"},
      {"name": "b", "image": "b.tif", "white_region": )" +
                                         white + ", " + b_keys + R"(}],
    "pose_bounds": )" + bounds + R"(,
    )" + extra + R"(,
    "loss": "l2"})";
  const MeasurementInputs inputs = loadMeasurementInputs(dir / "job.json");
  ForwardModel model(inputs);
  MeasurementResult result = measure(model, model.start());
  // The losses from the full-size simulation (as `xgauge measure` takes
  // them) are measure()'s own to the bit.
  std::vector<Image> simulated = simulateRadiographs(model, result.theta);
  MeasurementResult from_outputs = result;
  takeFullSizeLosses(model, simulated, from_outputs);
  for (size_t r = 0; r < result.radiographs.size(); ++r)
    EXPECT_EQ(from_outputs.radiographs[r].loss, result.radiographs[r].loss);
  EXPECT_EQ(from_outputs.total_loss, result.total_loss);
  writeMeasurementOutputs(model, result, dir / "out", true, nullptr, std::move(simulated));
  return result;
}

TEST_F(Measure, RecoversTheDimensionsOfANoiseFreeCuboid) {
  const std::map<std::string, double> truth = {
      {"size_x", 20.734}, {"size_y", 29.381}, {"size_z", 10.517}};
  // Near frontal: a box turned by +-ry looks nearly the same, so the bounds
  // leave out the mirror solution.
  const Pose a = Pose::fromEulerDeg({2.0, 4.0, -1.5}, {-12.0, 1.0, 500.0});
  const Vec3 axis = Vec3(1.0, 0.03, 0.05).normalized();
  const MeasurementResult result = measureSelfRender(
      dir_, kRoot + "/parts/cuboid.json", truth, a, axis,
      R"({"rotation_deg": [[-5, 5], [0, 10], [-5, 5]], "centre_mm": [[-40, 40], [-30, 30], [470, 530]]})");
  // With -march=native the fit reaches the truth to 1e-4 mm; the portable
  // build (other rounding in Eigen's kernels) stops in the shallow valley
  // where the box's size trades against its depth and the translation's
  // axis, about 0.01 mm and 0.5 mm off, where the finite-difference
  // least-squares stage finds no decreasing step. Analytic derivatives
  // (the Gauss-Newton issue) are the cure; until then the bounds below hold
  // for both builds.
  for (const auto& d : result.dimensions) {
    ASSERT_TRUE(d.free) << d.name;
    EXPECT_NEAR(d.value, truth.at(d.name), 0.02) << d.name;
  }
  // The translated pose keeps the known distance exactly, along the found axis.
  const Vec3 moved =
      result.radiographs[1].pose.translation_mm - result.radiographs[0].pose.translation_mm;
  EXPECT_NEAR(moved.norm(), 30.0, 1e-9);
  EXPECT_LT((moved.normalized() - axis).norm(), 0.1);
  EXPECT_LT((result.radiographs[0].pose.translation_mm - a.translation_mm).norm(), 1.0);
  for (const char* file :
       {"result.json", "simulated_a.tif", "difference_b.tif", "difference_b.png"})
    EXPECT_TRUE(fs::exists(dir_ / "out" / file)) << file;
}

TEST_F(Measure, ALineDetectorRecoversACylindersDiameter) {
  // One row of 2048 pixels of 0.1 mm (a line scanner's fan beam) across a
  // cylinder whose axis runs along the rows' normal: the row sees one
  // circular section, so the height is held and the orientation bounded as a
  // fixture holds it; the diameter comes from the two shots. A move along the
  // cylinder's axis is invisible to the row, so the conveyor's move is
  // bounded to the row's plane (without that bound the fit puts part of the
  // known 30 mm out of the plane and the magnification, and with it the
  // diameter, goes wrong: 0.06 mm here).
  Machine line;
  line.source_detector_distance_mm = 1000.0;
  line.columns = 2048, line.rows = 1;
  line.pitch_u_mm = line.pitch_v_mm = 0.1;
  line.cx_px = 1031.4, line.cy_px = 0.5;
  const std::map<std::string, double> truth = {{"diameter", 20.137}, {"height", 30.0}};
  const Pose a = Pose::fromEulerDeg({0.0, 0.0, 0.0}, {-25.0, 0.3, 500.0});
  const Vec3 axis = Vec3(1.0, 0.0, 0.05).normalized();
  const MeasurementResult result = measureSelfRender(
      dir_, line, kRoot + "/parts/cylinder.json", truth, a, axis,
      R"({"rotation_deg": [[-0.5, 0.5], [-0.5, 0.5], [-0.5, 0.5]], "centre_mm": [[-60, 60], [-5, 5], [450, 550]]})",
      R"("dimensions": {"fixed": {"height": 30.0}, "start": {"diameter": 20.0}})",
      "[40, 0, 100, 1]", R"(, "axis_elevation_bounds_deg": [-0.5, 0.5])");
  ASSERT_EQ(result.dimensions[0].name, "diameter");
  EXPECT_NEAR(result.dimensions[0].value, 20.137, 0.005);
  EXPECT_NEAR(result.radiographs[0].pose.translation_mm.z(), 500.0, 1.0)
      << result.radiographs[0].pose.translation_mm.transpose() << " / "
      << result.radiographs[1].pose.translation_mm.transpose();
}

// The jaw seen as a translated pair, measured from the drawing's round values.
const std::map<std::string, double> kJawTruth = {
    {"width", 21.05},      {"groove_center", 10.39}, {"thickness", 12.96}, {"groove_depth", 6.98},
    {"groove_left", 6.80}, {"groove_right", 7.01},   {"slot_width", 4.05}, {"slot_depth", 3.99}};

MeasurementResult measureJaw(const fs::path& dir, const std::string& schedule) {
  const Pose a = Pose::fromEulerDeg({1.5, 12.0, -0.8}, {-25.0, -20.0, 494.0});
  const Vec3 axis = Vec3(1.0, 0.03, 0.05).normalized();
  return measureSelfRender(
      dir, kRoot + "/parts/prism_jaw.json", kJawTruth, a, axis,
      R"({"rotation_deg": [[-5, 5], [-30, 30], [-5, 5]], "centre_mm": [[-40, 40], [-30, 30], [470, 530]]})",
      schedule);
}

TEST_F(Measure, ATurnedPairNeedsNoLinearStage) {
  // The jaw on a turntable: the second shot is the first turned by 12 deg
  // about the machine's vertical axis, which passes 4 mm beside the part's
  // centre. The turn alone fixes the scale: no distance is known, and the
  // second pose has no parameters of its own.
  Machine machine = squareDetector(320);
  Turntable axis;
  axis.point_mm = {-21.0, 0.0, 497.0};
  axis.direction = Vec3(0.002, 1.0, -0.003).normalized();
  machine.turntable = axis;
  const Pose a = Pose::fromEulerDeg({1.5, 12.0, -0.8}, {-25.0, -20.0, 494.0});
  const Pose b = axis.turn(a, 12.0);
  const MeasurementResult result = measureSelfRenderedPair(
      dir_, machine, kRoot + "/parts/prism_jaw.json", kJawTruth, a, b,
      R"("pattern": "turned", "reference": "a", "angle_deg": 12.0)",
      R"({"rotation_deg": [[-5, 5], [-30, 30], [-5, 5]], "centre_mm": [[-40, 40], [-30, 30], [470, 530]]})",
      R"("schedule": "default")", "[4, 4, 30, 30]");
  for (const auto& d : result.dimensions)
    EXPECT_NEAR(d.value, kJawTruth.at(d.name), 1e-3) << d.name;
  // The second pose is the first turned, to rounding.
  const Pose turned = axis.turn(result.radiographs[0].pose, 12.0);
  EXPECT_LT((result.radiographs[1].pose.translation_mm - turned.translation_mm).norm(), 1e-9);
  EXPECT_LT((result.radiographs[1].pose.rotation - turned.rotation).norm(), 1e-12);
  EXPECT_LT((result.radiographs[0].pose.translation_mm - a.translation_mm).norm(), 0.01);
}

TEST_F(Measure, ATurnedRadiographNeedsTheMachinesTurntable) {
  writeOpenBeamShot();
  std::ofstream(dir_ / "material.json") << ExponentialSum({{1.0, 0.05}}).toJson().dump();
  std::ofstream(dir_ / "job.json") << R"({
    "part": ")" + kRoot + R"(/parts/cuboid.json",
    "machine": "machine.json", "material": "material.json",
    "radiographs": [
      {"name": "a", "image": "a.tif", "white_region": [0, 0, 4, 4], "roi": [8, 8, 48, 48]},
      {"name": "b", "image": "a.tif", "white_region": [0, 0, 4, 4], "roi": [8, 8, 48, 48],
       "pattern": "turned",
       "reference": "a", "angle_deg": 10}],
    "pose_bounds": {"rotation_deg": [[-5, 5], [-5, 5], [-5, 5]],
                    "centre_mm": [[-5, 5], [-5, 5], [480, 520]]}})";
  const MeasurementInputs inputs = loadMeasurementInputs(dir_ / "job.json");
  expectErrorMentioning([&] { ForwardModel model(inputs); },
                        "/radiographs/1/pattern: radiograph b is turned, but the machine file");
}

// The methods, renders with derivatives and renders of a result's joint
// stages on pyramid levels ("joint, 512 px, ..."; not the final stage).
struct JointStages {
  std::vector<std::string> methods;
  int with_derivatives = 0;
  int renders = 0;
};
JointStages jointStages(const MeasurementResult& result) {
  JointStages j;
  for (const StageReport& s : result.stages) {
    if (!s.name.starts_with("joint") || s.name.find(" px") == std::string::npos) continue;
    j.methods.push_back(s.method);
    j.with_derivatives += s.with_derivatives;
    j.renders += s.evaluations;
  }
  return j;
}

TEST_F(Measure, RecoversTheDimensionsOfANoiseFreePrismJaw) {
  // Seen through its thickness, the jaw's groove and slot depths trade against
  // each other along a narrow valley of the loss: the least-squares stage
  // that ends the default schedule with the L2 loss is what reaches 1e-4 mm.
  // The default's joint fit runs on the render's derivatives, and so does
  // its final stage, on the refined render's.
  const MeasurementResult result = measureJaw(dir_, "default");
  for (const auto& d : result.dimensions)
    EXPECT_NEAR(d.value, kJawTruth.at(d.name), 1e-4) << d.name;
  const Vec3 moved =
      result.radiographs[1].pose.translation_mm - result.radiographs[0].pose.translation_mm;
  EXPECT_NEAR(moved.norm(), 30.0, 1e-9);
  const JointStages joint = jointStages(result);
  ASSERT_EQ(joint.methods.size(), 2u);
  for (const std::string& m : joint.methods) EXPECT_EQ(m, "ceres_levenberg_marquardt");
  EXPECT_GT(joint.with_derivatives, 0);
  EXPECT_LT(joint.renders, 400);
  const StageReport& last = result.stages.back();
  EXPECT_EQ(last.name.find(" px"), std::string::npos) << last.name;
  EXPECT_GT(last.with_derivatives, 0) << last.name;
  EXPECT_LT(last.evaluations, 60) << last.name;
  // The stages reuse their derivatives (least_squares.cpp): taken at a
  // stage's start and at most once more near its end, plain renders in
  // between (measured: 3 in the joint stages and 1 in the final one; 6 and
  // 2 when every iteration takes them).
  EXPECT_LE(last.with_derivatives, 2) << last.name;
  EXPECT_LE(joint.with_derivatives, 4);
}

TEST_F(Measure, TheBobyqaScheduleRecoversANoiseFreePrismJaw) {
  // The default before the derivatives, kept for comparison: BOBYQA on
  // three levels, then least squares by forward differences, to the same
  // 1e-4 mm, without a single render with derivatives.
  const MeasurementResult result = measureJaw(dir_, "bobyqa");
  for (const auto& d : result.dimensions)
    EXPECT_NEAR(d.value, kJawTruth.at(d.name), 1e-4) << d.name;
  const JointStages joint = jointStages(result);
  ASSERT_EQ(joint.methods.size(), 3u);
  for (const std::string& m : joint.methods) EXPECT_EQ(m, "bobyqa");
  int with_derivatives = 0;
  for (const StageReport& s : result.stages) with_derivatives += s.with_derivatives;
  EXPECT_EQ(with_derivatives, 0);
}

TEST_F(Measure, TheGaussNewtonScheduleRecoversANoiseFreePrismJaw) {
  // The same jaw by the `gauss-newton` schedule: the default's stages on
  // point samples alone (no edge refinement), to 1e-3 mm.
  const MeasurementResult result = measureJaw(dir_, "gauss-newton");
  for (const auto& d : result.dimensions)
    EXPECT_NEAR(d.value, kJawTruth.at(d.name), 1e-3) << d.name;
  const StageReport& last = result.stages.back();
  EXPECT_EQ(last.name.find(" px"), std::string::npos) << last.name;
  EXPECT_GT(last.with_derivatives, 0) << last.name;
}

// A material.json from a wedge calibration carries the detector's scatter;
// a job without a "scatter" of its own uses it, a job with one keeps its own.
TEST_F(Measure, AJobWithoutScatterUsesTheOneItsMaterialCarries) {
  writeOpenBeamShot();
  std::ofstream(dir_ / "material.json") << R"({"model": "exponential_sum",
    "terms": [{"weight": 1, "mu_per_mm": 0.05}],
    "scatter": {"weight": 0.12, "sigma_mm": 40, "weight_uncertainty": 0.01, "sigma_uncertainty_mm": 5}})";
  auto load = [&](const std::string& scatter) {
    std::ofstream(dir_ / "job.json") << R"({"part": ")" + kRoot + R"(/parts/cuboid.json",
      "machine": "machine.json", "material": "material.json", )" +
                                            scatter + R"(
      "radiographs": [{"name": "a", "image": "a.tif", "white_region": [0, 0, 8, 8], "roi": [8, 8, 40, 40]}],
      "pose_bounds": {"rotation_deg": [[-5, 5], [-5, 5], [-5, 5]], "centre_mm": [[-9, 9], [-9, 9], [390, 410]]}})";
    const ConfigNode root = ConfigNode::loadFile(dir_ / "job.json");
    MeasurementInputs in = loadMeasurementInputs(root, dir_ / "job.json", true);
    root.finish();
    return in.job.scatter;
  };
  const ScatterModel found = load("");
  EXPECT_EQ(found.weight, 0.12);
  EXPECT_EQ(found.sigma_mm, 40.0);
  EXPECT_EQ(found.weight_uncertainty, 0.01);
  EXPECT_EQ(found.sigma_uncertainty_mm, 5.0);
  const ScatterModel own = load(R"("scatter": {"weight": 0, "sigma_mm": 1},)");
  EXPECT_FALSE(own.enabled());
  // The curve itself reads the same file without complaint.
  EXPECT_EQ(ExponentialSum::load(dir_ / "material.json").terms().size(), 1u);
}

TEST_F(Measure, FreeMaterialParametersStandForTheMaterial) {
  writeOpenBeamShot();
  std::ofstream(dir_ / "job.json") << R"({"part": ")" + kRoot + R"(/parts/cuboid.json",
    "machine": "machine.json",
    "radiographs": [{"name": "a", "image": "a.tif", "white_region": [0, 0, 8, 8], "roi": [8, 8, 40, 40]}],
    "pose_bounds": {"rotation_deg": [[-5, 5], [-5, 5], [-5, 5]], "centre_mm": [[-9, 9], [-9, 9], [390, 410]]}})";
  const MeasurementInputs inputs = [&] {
    const ConfigNode root = ConfigNode::loadFile(dir_ / "job.json");
    MeasurementInputs in = loadMeasurementInputs(root, dir_ / "job.json", false);
    root.finish();
    return in;
  }();
  EXPECT_TRUE(inputs.job.material_file.empty());
  EXPECT_FALSE(inputs.material.has_value());
  const ExponentialSum material({{0.5, 0.02}, {0.3, 0.1}, {0.2, 0.7}});
  ForwardModel model(inputs, ExponentialSum({{1.0, 0.05}}));
  std::vector<double> theta = model.start();
  const size_t before = theta.size();
  model.freeMaterial(material, theta);
  // M - 1 fractions and M rates, inside their bounds, standing for the material.
  ASSERT_EQ(theta.size(), before + 5);
  EXPECT_EQ(model.materialIndices().size(), 5u);
  for (int i : model.materialIndices()) {
    EXPECT_EQ(model.kind(i), ParameterKind::kMaterial);
    EXPECT_GE(theta[static_cast<size_t>(i)], model.lower()[static_cast<size_t>(i)]);
    EXPECT_LE(theta[static_cast<size_t>(i)], model.upper()[static_cast<size_t>(i)]);
  }
  const ExponentialSum back = model.materialOf(theta);
  ASSERT_EQ(back.terms().size(), 3u);
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_NEAR(back.terms()[k].weight, material.terms()[k].weight, 1e-15);
    EXPECT_EQ(back.terms()[k].mu_per_mm, material.terms()[k].mu_per_mm);
  }
  EXPECT_EQ(model.parameters().index("material/rate1"), model.materialIndices()[2]);
  // Any point of the box is a valid material; a fraction of 1 leaves one term.
  theta[static_cast<size_t>(model.materialIndices()[0])] = 1.0;
  const ExponentialSum one = model.materialOf(theta);
  ASSERT_EQ(one.terms().size(), 1u);
  EXPECT_EQ(one.terms()[0].weight, 1.0);
  // The simulation follows theta's material: a darker material, a darker image.
  theta[static_cast<size_t>(model.materialIndices()[2])] = 0.5;  // mu_1 from 0.02 to 0.5
  const PixelRect all{0, 0, 64, 64};
  const double bright = meanOf(model.simulate(model.start(), 0, 0, 1, all), all);
  const double darker = meanOf(model.simulate(theta, 0, 0, 1, all), all);
  EXPECT_LT(bright, 0.99);  // the part is in view
  EXPECT_LT(darker, bright - 0.05);
}

TEST_F(Measure, TheThesisScheduleRecoversANoiseFreeCuboid) {
  // The thesis's schedule (uniform sampling, Nelder-Mead, a joint Nelder-Mead
  // at full size) on small radiographs: it runs its stages and gets near the
  // truth from the drawing's round values (20, 30, 10 mm, 0.3-0.7 mm off),
  // though Nelder-Mead over 11 parameters stops short of the exact answer.
  const std::map<std::string, double> truth = {
      {"size_x", 20.734}, {"size_y", 29.381}, {"size_z", 10.517}};
  const Pose a = Pose::fromEulerDeg({1.0, 4.0, -1.0}, {-12.0, 1.0, 500.0});
  const Vec3 axis = Vec3(1.0, 0.03, 0.05).normalized();
  const MeasurementResult result = measureSelfRender(
      dir_, kRoot + "/parts/cuboid.json", truth, a, axis,
      R"({"rotation_deg": [[-3, 3], [0, 8], [-3, 3]], "centre_mm": [[-20, 20], [-10, 10], [480, 520]]})",
      "thesis", 128);
  for (const auto& d : result.dimensions) EXPECT_NEAR(d.value, truth.at(d.name), 0.25) << d.name;
  EXPECT_LT(result.stages.back().loss_after, 0.1 * result.stages.back().loss_before);
  // Its stages, by name, as the table in measure/schedule.h says.
  std::vector<std::string> names;
  for (const auto& s : result.stages) names.push_back(s.name);
  EXPECT_EQ(names, (std::vector<std::string>{"a: pose search", "a: pose", "b: axis search",
                                             "b: axis", "joint"}));
  EXPECT_EQ(result.stages.back().level, 0);
  EXPECT_EQ(result.stages.back().method, "nelder_mead");
}

// A cuboid job on a blank 64^2 detector, loaded through the one loader.
MeasurementInputs cuboidInputs(const fs::path& dir, const std::string& pose_bounds) {
  Machine machine;
  machine.columns = machine.rows = 64;
  machine.pitch_u_mm = machine.pitch_v_mm = 0.5;
  machine.cx_px = machine.cy_px = 32.0;
  std::ofstream(dir / "machine.json") << machine.toJson().dump();
  std::ofstream(dir / "material.json") << ExponentialSum({{1.0, 0.05}}).toJson().dump();
  writeTiff(dir / "a.tif", Image(64, 64, 1.0f), TiffFormat::kFloat32);
  std::ofstream(dir / "job.json") << R"({"part": ")" + kRoot + R"(/parts/cuboid.json",
    "machine": "machine.json", "material": "material.json",
    "radiographs": [{"name": "a", "image": "a.tif", "white_region": [0, 0, 8, 8], "roi": [8, 8, 40, 40]},
                    {"name": "b", "image": "a.tif", "white_region": [0, 0, 8, 8], "roi": [8, 8, 40, 40],
                     "pattern": "translated", "reference": "a", "distance_mm": 5}],
    "pose_bounds": )" + pose_bounds + "}";
  return loadMeasurementInputs(dir / "job.json");
}

// The final stage's level follows the part's shadow, not the detector alone:
// on a 2048^2 detector the default fits at 1024 px when the roi keeps 128
// px or more across there, and at full size when it would not; the bobyqa
// schedule stays at 2048 px; a line detector's row stays at full size.
TEST_F(Measure, TheFinalStagesLevelKeepsASmallShadowsPixels) {
  Machine machine;
  machine.columns = machine.rows = 2048;
  machine.pitch_u_mm = machine.pitch_v_mm = 0.1;
  machine.cx_px = machine.cy_px = 1024.0;
  std::ofstream(dir_ / "machine.json") << machine.toJson().dump();
  std::ofstream(dir_ / "material.json") << ExponentialSum({{1.0, 0.05}}).toJson().dump();
  writeTiff(dir_ / "a.tif", Image(2048, 2048, 1.0f), TiffFormat::kFloat32);
  const auto levelFor = [&](const std::string& roi, ScheduleKind kind) {
    std::ofstream(dir_ / "job.json") << R"({"part": ")" + kRoot + R"(/parts/cuboid.json",
      "machine": "machine.json", "material": "material.json",
      "radiographs": [{"name": "a", "image": "a.tif", "white_region": [0, 0, 64, 64], "roi": )" +
                                            roi + R"(}],
      "pose_bounds": {"rotation_deg": [[-5, 5], [-5, 5], [-5, 5]],
                      "centre_mm": [[-9, 9], [-9, 9], [390, 410]]}})";
    const MeasurementInputs inputs = loadMeasurementInputs(dir_ / "job.json");
    const ForwardModel model(inputs);
    return leastSquaresLevel(model, scheduleFor(kind));
  };
  EXPECT_EQ(levelFor("[700, 600, 600, 900]", ScheduleKind::kDefault), 1);  // 300 px across
  EXPECT_EQ(levelFor("[900, 900, 240, 900]", ScheduleKind::kDefault), 0);  // 120 px there
  EXPECT_EQ(levelFor("[700, 600, 600, 900]", ScheduleKind::kBobyqa), 0);
  // A row of 2048 pixels: full size, its only level.
  machine.rows = 1;
  machine.cy_px = 0.5;
  std::ofstream(dir_ / "machine.json") << machine.toJson().dump();
  writeTiff(dir_ / "a.tif", Image(2048, 1, 1.0f), TiffFormat::kFloat32);
  std::ofstream(dir_ / "job.json") << R"({"part": ")" + kRoot + R"(/parts/cuboid.json",
    "machine": "machine.json", "material": "material.json",
    "radiographs": [{"name": "a", "image": "a.tif", "white_region": [0, 0, 64, 1],
                     "roi": [700, 0, 600, 1]}],
    "pose_bounds": {"rotation_deg": [[-5, 5], [-5, 5], [-5, 5]],
                    "centre_mm": [[-9, 9], [-9, 9], [390, 410]]}})";
  const MeasurementInputs line_inputs = loadMeasurementInputs(dir_ / "job.json");
  const ForwardModel line(line_inputs);
  EXPECT_EQ(line.levels(), 1);
  EXPECT_EQ(leastSquaresLevel(line, scheduleFor(ScheduleKind::kDefault)), 0);
}

TEST_F(Measure, ParametersAreNamedByBlock) {
  const MeasurementInputs inputs = cuboidInputs(
      dir_,
      R"({"rotation_deg": [[-5, 5], [-5, 5], [-5, 5]], "centre_mm": [[-9, 9], [-9, 9], [390, 410]]})");
  ForwardModel model(inputs);
  const ParameterLayout& p = model.parameters();
  ASSERT_EQ(p.size(), 3 + 6 + 2);
  EXPECT_EQ(p[p.index("dim/size_y")].name, "dim/size_y");
  EXPECT_EQ(p.block("dim"), (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(model.poseIndices(0), (std::vector<int>{3, 4, 5, 6, 7, 8}));
  EXPECT_EQ(p.block("a/position"), (std::vector<int>{6, 7, 8}));
  EXPECT_EQ(model.poseIndices(1), p.block("b/axis"));
  EXPECT_EQ(p[p.index("b/axis/elevation")].kind, ParameterKind::kAxis);
  EXPECT_EQ(p[p.index("a/rotation/ry")].lower, -5.0);
  EXPECT_TRUE(p.block("material").empty());
  // The pose parameters mean what model.h says: the centre's world position.
  std::vector<double> theta = model.start();
  theta[static_cast<size_t>(p.index("a/position/z"))] = 401.5;
  const Vec3 centre = model.pose(theta, 0).apply(model.referenceCentre());
  EXPECT_NEAR(centre.z(), 401.5, 1e-12);
  // The translated pose is the reference moved by exactly the known distance.
  const Vec3 moved = model.pose(theta, 1).translation_mm - model.pose(theta, 0).translation_mm;
  EXPECT_NEAR(moved.norm(), 5.0, 1e-12);
}

TEST_F(Measure, InfeasibleParametersAreAStatusNotAnError) {
  // Position bounds that reach past the source (z = 1000 mm): the fit's
  // model reports such points as infeasible with the reason.
  const MeasurementInputs inputs = cuboidInputs(
      dir_,
      R"({"rotation_deg": [[-5, 5], [-5, 5], [-5, 5]], "centre_mm": [[-9, 9], [-9, 9], [390, 1200]]})");
  ForwardModel model(inputs);
  const int only[] = {0};
  std::vector<double> theta = model.start();
  theta[static_cast<size_t>(model.parameters().index("a/position/z"))] = 400.0;
  ASSERT_FALSE(model.infeasibility(theta).has_value());
  ASSERT_TRUE(model.loss(theta, 0, 1, only).has_value());
  theta[static_cast<size_t>(model.parameters().index("a/position/z"))] = 1100.0;
  const auto why = model.infeasibility(theta);
  ASSERT_TRUE(why.has_value());
  EXPECT_NE(why->find("source"), std::string::npos) << *why;
  EXPECT_FALSE(model.loss(theta, 0, 1, only).has_value());
  std::vector<double> residuals{1.0};
  EXPECT_FALSE(model.residuals(theta, 0, 1, only, residuals));
  EXPECT_TRUE(residuals.empty());
  // Dimensions outside the part model's bounds: infeasible, named.
  theta[static_cast<size_t>(model.parameters().index("a/position/z"))] = 400.0;
  theta[static_cast<size_t>(model.parameters().index("dim/size_x"))] = -1.0;
  const auto bad = model.infeasibility(theta);
  ASSERT_TRUE(bad.has_value());
  EXPECT_NE(bad->find("size_x"), std::string::npos) << *bad;
  EXPECT_FALSE(model.loss(theta, 0, 1, only).has_value());
}

TEST_F(Measure, TheLoaderReadsEachFileOnceAndRecordsWhatItRead) {
  const MeasurementInputs inputs = cuboidInputs(
      dir_,
      R"({"rotation_deg": [[-5, 5], [-5, 5], [-5, 5]], "centre_mm": [[-9, 9], [-9, 9], [390, 410]]})");
  // Two radiographs of one file: one image shared, one digest.
  ASSERT_EQ(inputs.radiographs.size(), 2u);
  ASSERT_EQ(inputs.sha256.size(), 5u);  // job, part, machine, material, a.tif
  auto digestOf = [](const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream bytes;
    bytes << in.rdbuf();
    return sha256Hex(bytes.str());
  };
  for (const auto& [file, digest] : inputs.sha256) EXPECT_EQ(digest, digestOf(file)) << file;
  // The known answer of SHA-256 (FIPS 180-2, "abc").
  EXPECT_EQ(sha256Hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

// The scatter the model adds is the lab's: the scintillator's Gaussian of
// the exactly area-sampled image (blur.h), over the whole detector. The
// model blurs a coarse render of the whole detector (a kernel hundreds of
// pixels wide needs no finer one), whose pixels must be the area means of
// the fine image: a render that samples each coarse pixel at its centre
// moves an edge's share of the halo by up to half a coarse pixel, a
// different amount for each position of the part on the detector, which
// reads as one transmission error per shot (a few 1e-4 on a 4096^2 panel,
// 0.01 mm of thickness).
TEST_F(Measure, TheModelsScatterIsTheAreaSampledImagesAtAnyPosition) {
  const Machine machine = squareDetector(512);  // 0.25 mm pixels; coarse pixels of 4
  std::ofstream(dir_ / "machine.json") << machine.toJson().dump();
  const ExponentialSum material({{0.6, 0.03}, {0.3, 0.07}, {0.1, 0.25}});
  std::ofstream(dir_ / "material.json") << material.toJson().dump();
  const std::string part_file = kRoot + "/parts/prism_jaw.json";
  const PartModel part = PartModel::load(part_file);
  const TriangleMesh mesh = part.mesh(part.values({}));
  const auto table = TransmissionTable::forMaterial(material, 200.0);
  const double weight = 0.139, sigma_mm = 15.0;  // 60 px, 15 coarse pixels
  const PixelRect white{8, 8, 40, 40};
  // Shifts of a quarter of a coarse pixel (1 mm on the detector, 0.7 mm at
  // the part) and one of several.
  double worst_mean = 0.0, worst_pixel = 0.0;
  for (const double shift_mm : {0.0, 0.175, 0.35, 0.525, 3.1}) {
    const Pose pose = Pose::fromEulerDeg({90.0, 0.0, 0.0}, {-10.0 + shift_mm, -8.0, 700.0});
    std::vector<Vec3> world;
    poseVertices(pose, mesh.vertices, world);
    RenderOptions fine;
    fine.samples_per_axis = 4;
    fine.edge_samples_per_axis = 24;
    Image lab;
    renderIntensity(machine, {world, mesh.triangles}, table, fine, lab);
    lab = scatterBlur(std::move(lab), weight, sigma_mm / machine.pitch_u_mm);
    const double open = meanOf(lab, white);
    for (float& p : lab.pixels()) p = static_cast<float>(static_cast<double>(p) / open);
    writeTiff(dir_ / "a.tif", lab, TiffFormat::kFloat32);
    const nlohmann::json job = {
        {"part", part_file},
        {"machine", "machine.json"},
        {"material", "material.json"},
        {"scatter", {{"weight", weight}, {"sigma_mm", sigma_mm}}},
        {"pose_bounds",
         {{"rotation_deg", {{85, 95}, {-5, 5}, {-5, 5}}},
          {"centre_mm", {{-20, 20}, {-20, 20}, {680, 740}}}}},
        {"radiographs",
         {{{"name", "a"},
           {"image", "a.tif"},
           {"white_region", {white.x, white.y, white.width, white.height}},
           {"pattern", "known"},
           {"pose",
            {{"rotation_deg", {90.0, 0.0, 0.0}},
             {"translation_mm", {-10.0 + shift_mm, -8.0, 700.0}}}}}}}};
    std::ofstream(dir_ / "job.json") << job.dump();
    const MeasurementInputs inputs = loadMeasurementInputs(dir_ / "job.json");
    ForwardModel model(inputs);
    model.setEdgeSamples(24);
    const PixelRect all = machine.detectorRect();
    const Image simulated = model.simulate(model.start(), 0, 0, 4, all);
    // The part's shadow, where the transmission is set by the path.
    double sum = 0.0;
    long count = 0;
    for (int v = 0; v < all.height; ++v)
      for (int u = 0; u < all.width; ++u)
        if (lab(u, v) < 0.9f) {
          const double d = static_cast<double>(simulated(u, v)) - static_cast<double>(lab(u, v));
          sum += d, ++count;
          worst_pixel = std::max(worst_pixel, std::abs(d));
        }
    ASSERT_GT(count, 2000) << "the part is in view";
    worst_mean = std::max(worst_mean, std::abs(sum / static_cast<double>(count)));
  }
  // Both agree to 1e-6. A coarse render sampled at pixel centres gave a mean
  // off by 0.7e-5 to 6e-5 depending on the position, 1.7e-4 at a pixel; the
  // kernel widened by the coarse pixels and the interpolation (1/4 coarse
  // pixel^2 of variance) gave 1.6e-5 at every position.
  EXPECT_LT(worst_mean, 5e-6);
  EXPECT_LT(worst_pixel, 1e-5);
}

}  // namespace
}  // namespace xgauge
