// The measurement pipeline on radiographs rendered by xgauge's own renderer:
// with no noise and no model error, it must find the dimensions exactly.
#include "xgauge/measure/measure.h"

#include "xgauge/core/config.h"
#include "xgauge/core/progress.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/image/stats.h"
#include "xgauge/image/tiff.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/measure/model.h"
#include "xgauge/xray/renderer.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

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
  fs::path dir_;
};

// Renders two noise-free radiographs of `part_file` with `truth` (the second
// translated by 30 mm), measures them with the default schedule and returns
// the result; `a` is the first pose.
MeasurementResult measureSelfRender(const fs::path& dir, const std::string& part_file,
                                    const std::map<std::string, double>& truth, const Pose& a,
                                    const Vec3& axis, const std::string& bounds) {
  Machine machine;
  machine.source_detector_distance_mm = 1000.0;
  machine.columns = machine.rows = 320;
  machine.pitch_u_mm = machine.pitch_v_mm = 0.4;
  machine.cx_px = 161.3, machine.cy_px = 158.9;
  std::ofstream(dir / "machine.json") << machine.toJson().dump();
  const ExponentialSum material({{0.6, 0.03}, {0.3, 0.07}, {0.1, 0.25}});
  std::ofstream(dir / "material.json") << material.toJson().dump();
  const PartModel part = PartModel::load(part_file);
  const TriangleMesh mesh = part.mesh(part.values(truth));
  Pose b = a;
  b.translation_mm += 30.0 * axis;

  // Noise-free radiographs with 2 x 2 samples, as the fit's stages.
  const auto table = TransmissionTable::forMaterial(material, 200.0);
  RenderOptions options;
  options.samples_per_axis = 2;
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
      {"name": "a", "image": "a.tif", "white_region": [4, 4, 30, 30], "pattern": "free"},
      {"name": "b", "image": "b.tif", "white_region": [4, 4, 30, 30], "pattern": "translated",
       "reference": "a", "distance_mm": 30.0}],
    "pose_bounds": )" + bounds + R"(,
    "loss": "l2"})";
  const MeasurementJob job = MeasurementJob::load(dir / "job.json");
  MeasurementResult result = measure(job);
  writeMeasurementOutputs(job, result, dir / "out");
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
  for (const auto& d : result.dimensions) {
    ASSERT_TRUE(d.free) << d.name;
    EXPECT_NEAR(d.value, truth.at(d.name), 1e-4) << d.name;
  }
  // The translated pose keeps the known distance exactly, along the found axis.
  const Vec3 moved =
      result.radiographs[1].pose.translation_mm - result.radiographs[0].pose.translation_mm;
  EXPECT_NEAR(moved.norm(), 30.0, 1e-9);
  EXPECT_LT((moved.normalized() - axis).norm(), 1e-4);
  EXPECT_LT((result.radiographs[0].pose.translation_mm - a.translation_mm).norm(), 1e-3);
  for (const char* file :
       {"result.json", "simulated_a.tif", "difference_b.tif", "difference_b.png"})
    EXPECT_TRUE(fs::exists(dir_ / "out" / file)) << file;
}

TEST_F(Measure, RecoversTheDimensionsOfANoiseFreePrismJaw) {
  // Seen through its thickness, the jaw's groove and slot depths trade against
  // each other along a narrow valley of the loss: the least-squares stage
  // that ends the default schedule with the L2 loss is what reaches 1e-4 mm.
  const std::map<std::string, double> truth = {
      {"width", 21.05},      {"groove_center", 10.39}, {"thickness", 12.96}, {"groove_depth", 6.98},
      {"groove_left", 6.80}, {"groove_right", 7.01},   {"slot_width", 4.05}, {"slot_depth", 3.99}};
  const Pose a = Pose::fromEulerDeg({1.5, 12.0, -0.8}, {-25.0, -20.0, 494.0});
  const Vec3 axis = Vec3(1.0, 0.03, 0.05).normalized();
  const MeasurementResult result = measureSelfRender(
      dir_, kRoot + "/parts/prism_jaw.json", truth, a, axis,
      R"({"rotation_deg": [[-5, 5], [-30, 30], [-5, 5]], "centre_mm": [[-40, 40], [-30, 30], [470, 530]]})");
  for (const auto& d : result.dimensions) EXPECT_NEAR(d.value, truth.at(d.name), 1e-4) << d.name;
  const Vec3 moved =
      result.radiographs[1].pose.translation_mm - result.radiographs[0].pose.translation_mm;
  EXPECT_NEAR(moved.norm(), 30.0, 1e-9);
}

TEST_F(Measure, FreeMaterialParametersStandForTheMaterial) {
  Machine machine;
  machine.columns = machine.rows = 64;
  machine.pitch_u_mm = machine.pitch_v_mm = 0.5;
  machine.cx_px = machine.cy_px = 32.0;
  std::ofstream(dir_ / "machine.json") << machine.toJson().dump();
  writeTiff(dir_ / "a.tif", Image(64, 64, 1.0f), TiffFormat::kFloat32);
  std::ofstream(dir_ / "job.json") << R"({"part": ")" + kRoot + R"(/parts/cuboid.json",
    "machine": "machine.json",
    "radiographs": [{"name": "a", "image": "a.tif", "white_region": [0, 0, 8, 8], "roi": [8, 8, 40, 40]}],
    "pose_bounds": {"rotation_deg": [[-5, 5], [-5, 5], [-5, 5]], "centre_mm": [[-9, 9], [-9, 9], [390, 410]]}})";
  const MeasurementJob job = [&] {
    const ConfigNode root = ConfigNode::loadFile(dir_ / "job.json");
    MeasurementJob j = MeasurementJob::fromConfig(root, dir_ / "job.json", false);
    root.finish();
    return j;
  }();
  EXPECT_TRUE(job.material_file.empty());
  const ExponentialSum material({{0.5, 0.02}, {0.3, 0.1}, {0.2, 0.7}});
  ForwardModel model(job, ExponentialSum({{1.0, 0.05}}));
  std::vector<double> theta = model.start();
  const size_t before = theta.size();
  model.freeMaterial(material, theta);
  // M - 1 fractions and M rates, inside their bounds, standing for the material.
  ASSERT_EQ(theta.size(), before + 5);
  EXPECT_EQ(model.materialIndices().size(), 5u);
  for (int i : model.materialIndices()) {
    EXPECT_EQ(model.kind(i), ForwardModel::Kind::kMaterial);
    EXPECT_GE(theta[static_cast<size_t>(i)], model.lower()[static_cast<size_t>(i)]);
    EXPECT_LE(theta[static_cast<size_t>(i)], model.upper()[static_cast<size_t>(i)]);
  }
  const ExponentialSum back = model.materialOf(theta);
  ASSERT_EQ(back.terms().size(), 3u);
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_NEAR(back.terms()[k].weight, material.terms()[k].weight, 1e-15);
    EXPECT_EQ(back.terms()[k].mu_per_mm, material.terms()[k].mu_per_mm);
  }
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

}  // namespace
}  // namespace xgauge
