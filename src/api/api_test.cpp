// The front door (xgauge/xgauge.h): a cuboid measured from one rendered
// radiograph through measure(options), its summary against the truth and
// against the result.json it writes, the stage callback, and bad options and
// bad jobs as a failure with the reason, never an exception.
#include "xgauge/xgauge.h"

#include "xgauge/lab.h"
#include "xgauge/production.h"

#include "xgauge/geometry/part_model.h"
#include "xgauge/image/tiff.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/material/transmission_table.h"
#include "xgauge/xray/machine.h"
#include "xgauge/xray/renderer.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

namespace fs = std::filesystem;

namespace xgauge {
namespace {

const char* kMachine = R"({"source_detector_distance_mm": 1000,
  "detector": {"columns": 128, "rows": 96, "pixel_pitch_mm": [0.5, 0.5]}})";
const char* kMaterial =
    R"({"model": "exponential_sum", "terms": [{"weight": 1, "mu_per_mm": 0.05}]})";

class FrontDoor : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("xgauge_api_test_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
            "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    write("machine.json", kMachine);
    write("material.json", kMaterial);
    // The cuboid 20 x 30 x 10 mm turned a little, 400 mm from the detector,
    // 3 x 3 samples a pixel, with Gaussian noise of 0.002: a at x = 5 mm,
    // b moved 8 mm along -x.
    render(dir_ / "a.tif", 5.0, 11);
    render(dir_ / "b.tif", -3.0, 12);
  }
  void render(const fs::path& file, double x_mm, uint64_t seed) {
    const PartModel part = PartModel::load(fs::path(XGAUGE_SOURCE_DIR) / "parts/cuboid.json");
    const Machine machine = Machine::load(dir_ / "machine.json");
    std::vector<Vec3> world;
    poseVertices(Pose::fromEulerDeg({1, -2, 0.5}, {x_mm, -2, 400}),
                 part.mesh(part.values({{"size_x", 20}, {"size_y", 30}, {"size_z", 10}})).vertices,
                 world);
    RenderOptions options;
    options.samples_per_axis = 3;
    Image image;
    renderIntensity(
        machine, WorldMesh{world, part.triangles(), part.csg().get()},
        TransmissionTable::forMaterial(ExponentialSum::load(dir_ / "material.json"), 100), options,
        image);
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> gauss(0.0, 0.002);
    for (int y = 0; y < image.height(); ++y)
      for (int x = 0; x < image.width(); ++x)
        image(x, y) = static_cast<float>(static_cast<double>(image(x, y)) + gauss(rng));
    writeTiff(file, image, TiffFormat::kFloat32);
  }
  void TearDown() override { fs::remove_all(dir_); }

  void write(const std::string& name, const std::string& text) {
    std::ofstream(dir_ / name) << text;
  }
  static std::string read(const fs::path& file) {
    std::ifstream in(file);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }
  // The job, its paths relative to the test's folder; `extra` at its end.
  std::string job(const std::string& extra = "") const {
    return std::string(R"({"part": ")") + XGAUGE_SOURCE_DIR + R"(/parts/cuboid.json",
      "machine": "machine.json", "material": "material.json",
      "radiographs": [{"name": "a", "image": "a.tif", "white_region": [0, 0, 8, 8]},
                      {"name": "b", "image": "b.tif", "pattern": "translated", "reference": "a",
                       "distance_mm": 8, "white_region": [0, 0, 8, 8]}],
      "dimensions": {"fixed": {"size_z": 10}},
      "pose_bounds": {"rotation_deg": [[-5, 5], [-5, 5], [-5, 5]],
                      "centre_mm": [[-10, 10], [-10, 10], [390, 410]]},
      "unverified_verdicts": true,
      "tolerances": {"size_x": {"nominal": 20, "lower": -0.5, "upper": 0.5},
                     "size_y": {"nominal": 29, "lower": -0.2, "upper": 0.2}})" +
           extra + "}";
  }

  fs::path dir_;
};

TEST_F(FrontDoor, MeasuresACuboidAndWritesTheResultItSummarizes) {
  MeasurementOptions options;
  options.job_json = job();
  options.base_folder = dir_;
  options.output_folder = dir_ / "out";
  options.write_report = false;
  std::vector<std::string> seen;
  options.on_stage = [&seen](const StageSummary& s) { seen.push_back(s.name); };
  std::string why;
  ASSERT_TRUE(options.IsValid(&why)) << why;

  const MeasurementSummary summary = measure(options);
  ASSERT_EQ(summary.termination, TerminationType::kMeasured) << summary.BriefReport();
  ASSERT_EQ(summary.dimensions.size(), 3u);
  const DimensionSummary& x = summary.dimensions[0];
  const DimensionSummary& y = summary.dimensions[1];
  const DimensionSummary& z = summary.dimensions[2];
  EXPECT_EQ(x.name, "size_x");
  EXPECT_NEAR(x.value, 20.0, 0.05);
  EXPECT_NEAR(y.value, 30.0, 0.05);
  EXPECT_TRUE(x.free && y.free && !z.free);
  EXPECT_DOUBLE_EQ(z.value, 10.0);
  ASSERT_TRUE(x.expanded_uncertainty.has_value());
  EXPECT_GT(*x.expanded_uncertainty, 0.0);
  // size_x inside [19.5, 20.5] by far; size_y 30 outside [28.8, 29.2].
  EXPECT_EQ(x.verdict, VerdictType::kConforms);
  EXPECT_EQ(y.verdict, VerdictType::kDoesNotConform);
  EXPECT_EQ(z.verdict, VerdictType::kNone);
  ASSERT_TRUE(x.lower_limit && x.upper_limit);
  EXPECT_DOUBLE_EQ(*x.lower_limit, 19.5);
  EXPECT_EQ(summary.exit_status, 3);

  // The callback saw every stage as it ended: the kept fit's, which the
  // summary lists, in their order, and those of fits tried and set aside
  // (other pose candidates, retries).
  size_t next = 0;
  for (const std::string& name : seen)
    if (next < summary.stages.size() && name == summary.stages[next].name) ++next;
  EXPECT_EQ(next, summary.stages.size());
  EXPECT_GE(summary.stages.size(), 2u);

  // ToJson is result.json, to the byte; its values are the summary's.
  EXPECT_EQ(summary.ToJson(), read(dir_ / "out" / "result.json"));
  const nlohmann::json json = nlohmann::json::parse(summary.ToJson());
  EXPECT_EQ(json.at("status"), "measured");
  EXPECT_EQ(json.at("dimensions").at(0).at("value_mm").get<double>(), x.value);
  EXPECT_TRUE(fs::exists(dir_ / "out" / "measure.log"));
  EXPECT_FALSE(fs::exists(dir_ / "out" / "report.html"));
  EXPECT_NE(summary.FullReport().find("size_y"), std::string::npos);
  EXPECT_NE(summary.FullReport().find("does not conform"), std::string::npos);
  EXPECT_EQ(summary.BriefReport().rfind("measured: 3 dimension(s)", 0), 0u)
      << summary.BriefReport();
}

TEST_F(FrontDoor, TheSameJobFromItsFileGivesTheSameResult) {
  MeasurementOptions text;
  text.job_json = job();
  text.base_folder = dir_;
  write("job.json", job());
  MeasurementOptions file;
  file.job_file = dir_ / "job.json";
  const MeasurementSummary a = measure(text), b = measure(file);
  ASSERT_EQ(a.termination, TerminationType::kMeasured) << a.BriefReport();
  ASSERT_EQ(b.termination, TerminationType::kMeasured) << b.BriefReport();
  for (size_t k = 0; k < a.dimensions.size(); ++k)
    EXPECT_EQ(a.dimensions[k].value, b.dimensions[k].value) << a.dimensions[k].name;
  EXPECT_FALSE(fs::exists(dir_ / "out"));  // no output folder: nothing written
}

TEST_F(FrontDoor, InconsistentOptionsAreRefusedWithTheReason) {
  MeasurementOptions options;
  std::string why;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("job_file or as job_json"), std::string::npos) << why;
  EXPECT_FALSE(options.IsValid(nullptr));
  options.job_file = dir_ / "job.json";
  options.job_json = job();
  EXPECT_FALSE(options.IsValid(&why));
  const MeasurementSummary summary = measure(options);
  EXPECT_EQ(summary.termination, TerminationType::kFailure);
  EXPECT_EQ(summary.exit_status, 1);
  EXPECT_EQ(summary.BriefReport(), "failure: " + why);
  EXPECT_TRUE(summary.ToJson().empty());
}

TEST_F(FrontDoor, ABadJobIsAFailureNamingTheKeyAndWritesNothing) {
  MeasurementOptions options;
  options.job_json = job(R"(, "shedule": "default")");
  options.base_folder = dir_;
  options.output_folder = dir_ / "out";
  const MeasurementSummary summary = measure(options);
  EXPECT_EQ(summary.termination, TerminationType::kFailure);
  EXPECT_NE(summary.message.find("unknown key 'shedule'"), std::string::npos) << summary.message;
  EXPECT_NE(summary.message.find("did you mean 'schedule'"), std::string::npos) << summary.message;
  EXPECT_TRUE(summary.dimensions.empty());
  EXPECT_FALSE(fs::exists(dir_ / "out" / "result.json"));
  // A missing image is named.
  options.job_json = job();
  fs::remove(dir_ / "a.tif");
  const MeasurementSummary missing = measure(options);
  EXPECT_EQ(missing.termination, TerminationType::kFailure);
  EXPECT_NE(missing.message.find("a.tif"), std::string::npos) << missing.message;
}

}  // namespace
}  // namespace xgauge

namespace xgauge {
namespace {

// A wedge's radiograph (tests/cli_test.cpp's): a ramp of 0.2 .. 20 mm over
// rows 40 .. 260 of a two-term material, whose curve the calibration gives
// back; an open beam, which has no ramp.
class FrontDoorCalibration : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("xgauge_api_cal_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    std::ofstream(dir_ / "machine.json") << R"({"source_detector_distance_mm": 1000,
      "detector": {"columns": 200, "rows": 300, "pixel_pitch_mm": [1.0, 1.0]}})";
    Image image(200, 300, 1.0f);
    for (int y = 40; y < 260; ++y)
      for (int x = 50; x < 150; ++x)
        image(x, y) = static_cast<float>(curve(0.2 + 19.8 * (y + 0.5 - 40) / 220));
    writeTiff(dir_ / "wedge.tif", image, TiffFormat::kFloat32);
    writeTiff(dir_ / "open.tif", Image(200, 300, 1.0f), TiffFormat::kFloat32);
  }
  void TearDown() override { fs::remove_all(dir_); }
  static double curve(double path) {
    return 0.6 * std::exp(-0.05 * path) + 0.4 * std::exp(-0.3 * path);
  }
  fs::path job(const std::string& image) {
    const fs::path file = dir_ / ("job_" + image + ".json");
    std::ofstream(file) << R"({"machine": "machine.json",
      "radiograph": {"image": ")" +
                               image + R"(", "white_region": [5, 5, 30, 30]},
      "wedge": {"max_thickness_mm": 20.0, "ramp_length_mm": 90.0}})";
    return file;
  }
  fs::path dir_;
};

TEST_F(FrontDoorCalibration, AWedgeGivesBackItsCurve) {
  CalibrationOptions options;
  options.job_file = job("wedge.tif");
  options.output_folder = dir_ / "cal";
  options.write_report = false;
  std::string why;
  ASSERT_TRUE(options.IsValid(&why)) << why;
  const CalibrationSummary summary = calibrate(options);
  ASSERT_EQ(summary.termination, CalibrationTermination::kCalibrated) << summary.BriefReport();
  ASSERT_FALSE(summary.terms.empty());
  ASSERT_TRUE(summary.calibrated_range_mm.has_value());
  // The summary's curve is the drawn one within 0.015 (the synthetic ramp's
  // rows are not a wedge's exact projection: its thin end, 0.2 mm, reads
  // as about 0 by eq. 3.7, which shifts the paths by up to 0.2 mm).
  double previous = 2.0;
  for (double x : {0.0, 1.0, 5.0, 10.0, 15.0}) {
    double fitted = 0.0;
    for (const auto& t : summary.terms) fitted += t.weight * std::exp(-t.mu_per_mm * x);
    EXPECT_NEAR(fitted, curve(x), 0.015) << x << " mm";
    EXPECT_LT(fitted, previous) << x << " mm";
    previous = fitted;
  }
  EXPECT_EQ(summary.ToJson(), [&] {
    std::ifstream in(dir_ / "cal" / "material.json");
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }());
  EXPECT_NE(summary.FullReport().find("thin end at row"), std::string::npos);
  EXPECT_EQ(summary.BriefReport().rfind("calibrated: ", 0), 0u) << summary.BriefReport();
}

TEST_F(FrontDoorCalibration, AFailedStepIsNamedAndLeavesOnlyItsDiagnostic) {
  CalibrationOptions options;
  options.job_file = job("open.tif");
  options.output_folder = dir_ / "cal";
  const CalibrationSummary summary = calibrate(options);
  EXPECT_EQ(summary.termination, CalibrationTermination::kStepFailed);
  EXPECT_EQ(summary.step, "find the ramp");
  EXPECT_NE(summary.message.find("no ramp found"), std::string::npos) << summary.message;
  EXPECT_TRUE(summary.ToJson().empty());
  EXPECT_TRUE(fs::exists(dir_ / "cal" / "failed_calibration.json"));
  EXPECT_FALSE(fs::exists(dir_ / "cal" / "material.json"));
  // Options without an output folder are refused before anything runs.
  CalibrationOptions incomplete;
  incomplete.job_file = options.job_file;
  std::string why;
  EXPECT_FALSE(incomplete.IsValid(&why));
  EXPECT_NE(why.find("output_folder"), std::string::npos) << why;
  EXPECT_EQ(calibrate(incomplete).termination, CalibrationTermination::kFailure);
}

}  // namespace
}  // namespace xgauge

namespace xgauge {
namespace {

// The rest of the front door (xgauge/runtime.h, radiographs.h, lab.h,
// production.h, characterize and verify): bad input is a failure with the
// CLI's message, never an exception.
TEST(FrontDoorRest, BadInputIsAFailureWithItsReason) {
  const fs::path missing = fs::temp_directory_path() / "xgauge_api_missing.json";
  EXPECT_EQ(characterize({missing, fs::temp_directory_path() / "xgauge_api_c"}).termination,
            RunTermination::kFailure);
  const VerificationSummary verified =
      verify({missing, fs::temp_directory_path() / "xgauge_api_v"});
  EXPECT_EQ(verified.termination, RunTermination::kFailure);
  EXPECT_NE(verified.message.find("xgauge_api_missing.json"), std::string::npos);
  MeasurementStudyOptions study_options;
  study_options.output_folder = fs::temp_directory_path() / "xgauge_api_study";
  study_options.shard = "0/2";
  const MeasurementStudySummary studied = study(study_options);
  EXPECT_EQ(studied.termination, RunTermination::kFailure);
  EXPECT_EQ(studied.message, "--shard 0/2: expected i/N with 1 <= i <= N");
  InspectionOptions inspection;
  inspection.source = "a", inspection.watch = "b";
  EXPECT_EQ(inspect(inspection).message, "inspect: give a source folder or --watch, not both");
  EXPECT_EQ(exportLot({}).message, "export: give --dfq FILE, --csv FILE or both");
  EXPECT_STREQ(RunTerminationToString(RunTermination::kDone), "done");
}

TEST(FrontDoorRest, GeometryCalibrationIsACalibrationKind) {
  CalibrationOptions options;
  options.kind = CalibrationKind::kGeometry;
  options.job_file = "job.json";
  options.output_folder = "out";
  std::string why;
  EXPECT_TRUE(options.IsValid(&why)) << why;
  options.reach_deg = 0.0;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("reach_deg"), std::string::npos);
  options.reach_deg = 2.0;
  options.job_file = fs::temp_directory_path() / "xgauge_api_missing.json";
  const CalibrationSummary summary = calibrate(options);
  EXPECT_EQ(summary.termination, CalibrationTermination::kFailure);
  EXPECT_FALSE(summary.message.empty());
}

}  // namespace
}  // namespace xgauge
