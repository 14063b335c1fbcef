// The geometry calibration (calibrate/geometry.h) on radiographs rendered
// with a tilted detector: it finds the panel's pose from a part of known
// dimensions, and refuses what it cannot stand behind.
#include "xgauge/calibrate/geometry.h"

#include "core/expect_error.h"
#include "xgauge/core/progress.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/image/tiff.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/xray/renderer.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

namespace xgauge {
namespace {

namespace fs = std::filesystem;
const std::string kRoot = XGAUGE_SOURCE_DIR;

const std::map<std::string, double> kJaw = {
    {"width", 21.05},      {"groove_center", 10.39}, {"thickness", 12.96}, {"groove_depth", 6.98},
    {"groove_left", 6.80}, {"groove_right", 7.01},   {"slot_width", 4.05}, {"slot_depth", 3.99}};

class GeometryCalibrationTest : public ::testing::Test {
 protected:
  void SetUp() override {
    setProgressEnabled(false);
    dir_ = fs::temp_directory_path() /
           ("xgauge_geometry_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }

  // Three shots (noise 0.003) of the jaw across a 400 x 400 panel of 0.4 mm
  // pixels that sits tilted (1.0, -0.8) deg and turned 0.5 deg; the job's
  // machine is the ideal one. `extra` job keys (its "dimensions").
  fs::path writeJob(const std::string& dimensions) const {
    Machine ideal;
    ideal.source_detector_distance_mm = 1000.0;
    ideal.columns = ideal.rows = 400;
    ideal.pitch_u_mm = ideal.pitch_v_mm = 0.4;
    ideal.cx_px = 203.1, ideal.cy_px = 197.4;
    std::ofstream(dir_ / "machine.json") << ideal.toJson().dump();
    Machine tilted = ideal;
    tilted.setDetectorPose(1.0, -0.8, 0.5);
    const ExponentialSum material({{0.6, 0.03}, {0.3, 0.07}, {0.1, 0.25}});
    std::ofstream(dir_ / "material.json") << material.toJson().dump();
    const PartModel part = PartModel::load(kRoot + "/parts/prism_jaw.json");
    const TriangleMesh mesh = part.mesh(part.values(kJaw));
    const auto table = TransmissionTable::forMaterial(material, 200.0);
    RenderOptions options;
    options.samples_per_axis = 2;
    options.edge_samples_per_axis = 8;
    std::string radiographs;
    const Vec3 places[] = {{-35.0, 12.0, 500.0}, {10.0, -30.0, 520.0}, {-15.0, -28.0, 480.0}};
    std::vector<Vec3> world;
    for (int k = 0; k < 3; ++k) {
      const Pose pose = Pose::fromEulerDeg({1.5, 12.0 + 20.0 * k, -0.8}, places[k]);
      poseVertices(pose, mesh.vertices, world);
      Image image;
      renderIntensity(tilted, {world, mesh.triangles}, table, options, image);
      // Photon noise of about 0.3 % of the open beam, the same for every run.
      std::mt19937_64 rng(17 + static_cast<uint64_t>(k));
      std::normal_distribution<float> noise(0.0f, 0.003f);
      for (float& pixel : image.pixels()) pixel += noise(rng);
      const std::string name = fmt::format("s{}", k);
      writeTiff(dir_ / (name + ".tif"), image, TiffFormat::kFloat32);
      radiographs +=
          fmt::format(R"({}{{"name": "{}", "image": "{}.tif", "white_region": [4, 4, 30, 30]}})",
                      k ? ", " : "", name, name);
    }
    const fs::path job = dir_ / "job.json";
    std::ofstream(job) << R"({"part": ")" + kRoot + R"(/parts/prism_jaw.json",
      "machine": "machine.json", "material": "material.json", )" +
                              dimensions + R"(,
      "radiographs": [)" + radiographs +
                              R"(],
      "pose_bounds": {"rotation_deg": [[-5, 5], [0, 60], [-5, 5]],
                      "centre_mm": [[-80, 80], [-80, 80], [450, 550]]},
      "loss": "l2"})";
    return job;
  }
  std::string fixedAt(const std::map<std::string, double>& values) const {
    nlohmann::json fixed = nlohmann::json::object();
    for (const auto& [name, value] : values) fixed[name] = value;
    return R"("dimensions": )" + nlohmann::json{{"fixed", fixed}}.dump();
  }
  fs::path dir_;
};

TEST_F(GeometryCalibrationTest, FindsTheTiltedPanelsPoseFromAKnownPart) {
  const GeometryCalibration g = calibrateGeometry(writeJob(fixedAt(kJaw)), 2.0);
  // Each tilt within three of its standard uncertainties. The turn in
  // the panel's plane the free poses take up: it is held as the machine
  // states it.
  for (int k : {0, 1}) {
    const double truth = k == 0 ? 1.0 : -0.8;
    EXPECT_GT(g.uncertainty_deg[k], 0.0);
    EXPECT_LT(g.uncertainty_deg[k], 0.05);
    EXPECT_NEAR(g.angles_deg[k], truth, 3.0 * g.uncertainty_deg[k]);
  }
  // The second estimate: each of the three shots left out in turn (none is
  // another's reference), each fit's tilts near the truth; the stated u the
  // larger of the least squares' and the jackknife's (n - 1)/n sum of squares.
  ASSERT_EQ(g.leave_one_out.size(), 3u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(g.leave_one_out[static_cast<size_t>(k)].radiograph, fmt::format("s{}", k));
    EXPECT_NEAR(g.leave_one_out[static_cast<size_t>(k)].angles_deg[0], 1.0, 0.1);
    EXPECT_NEAR(g.leave_one_out[static_cast<size_t>(k)].angles_deg[1], -0.8, 0.1);
  }
  for (size_t a : {0u, 1u}) {
    double mean = 0.0, squares = 0.0;
    for (const auto& l : g.leave_one_out) mean += l.angles_deg[a] / 3.0;
    for (const auto& l : g.leave_one_out) squares += std::pow(l.angles_deg[a] - mean, 2);
    EXPECT_NEAR(g.leave_one_out_uncertainty_deg[a], std::sqrt(2.0 / 3.0 * squares), 1e-12);
    EXPECT_EQ(g.uncertainty_deg[a],
              std::max(g.statistical_uncertainty_deg[a], g.leave_one_out_uncertainty_deg[a]));
    EXPECT_GT(g.statistical_uncertainty_deg[a], 0.0);
  }
  EXPECT_FALSE(g.rotation_fitted);
  EXPECT_EQ(g.angles_deg[2], 0.0);
  EXPECT_GT(g.misfit_ratio, 0.5);
  EXPECT_LT(g.misfit_ratio, 2.0);
  for (double u : g.uncertainty_deg) EXPECT_TRUE(std::isfinite(u) && u >= 0.0);
  writeGeometryCalibration(g, dir_ / "out");
  const Machine back = Machine::load(dir_ / "out" / "machine.json");
  EXPECT_TRUE(back.tilted());
  EXPECT_NEAR(back.detector_rotation_deg, g.angles_deg[2], 1e-12);
  EXPECT_EQ(back.detector_pose_uncertainty_deg, g.uncertainty_deg);
  const nlohmann::json written = nlohmann::json::parse(std::ifstream(dir_ / "out" / "geometry.json"));
  EXPECT_EQ(written["detector"]["leave_one_out"]["angles_deg"].size(), 3u);
  EXPECT_EQ(written["detector"]["leave_one_out"]["uncertainty_deg"][1].get<double>(),
            g.leave_one_out_uncertainty_deg[1]);
}

TEST_F(GeometryCalibrationTest, AFreeDimensionOrAWrongPartIsRefused) {
  std::map<std::string, double> some = kJaw;
  some.erase("width");
  expectErrorMentioning([&] { calibrateGeometry(writeJob(fixedAt(some)), 2.0); },
                        "/dimensions: a geometry calibration fits the detector to a part of known "
                        "dimensions");
  // The jaw stated 1 mm wider and its slot 1 mm deeper than it is: no pose
  // of the panel explains that.
  std::map<std::string, double> wrong = kJaw;
  wrong["width"] += 1.0;
  wrong["slot_depth"] += 1.0;
  expectErrorMentioning([&] { calibrateGeometry(writeJob(fixedAt(wrong)), 2.0); }, "not a result");
}

}  // namespace
}  // namespace xgauge
