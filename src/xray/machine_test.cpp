#include "xgauge/xray/machine.h"

#include <gtest/gtest.h>
#include <unistd.h>
#include <filesystem>
#include <fstream>
#include "core/expect_error.h"
#include "xgauge/core/error.h"

namespace xgauge {
namespace {

TEST(Machine, ProjectionFollowsPartsConventions) {
  auto root = ConfigNode::parse(R"({
    "source_detector_distance_mm": 1000,
    "detector": {"columns": 200, "rows": 100, "pixel_pitch_mm": [0.2, 0.1],
                 "principal_point_px": [90.5, 40.25]}})", "m.json");
  const Machine m = Machine::fromConfig(root);
  EXPECT_NO_THROW(root.finish());
  // The foot of the perpendicular projects onto the principal point.
  EXPECT_EQ(m.project(Vec3(0, 0, 300)), Vec2(90.5, 40.25));
  // A point halfway to the source is magnified twice; +x right, +y up (row decreases).
  const Vec2 p = m.project(Vec3(1.0, 2.0, 500.0));
  EXPECT_DOUBLE_EQ(p.x(), 90.5 + 2.0 * 1.0 / 0.2);
  EXPECT_DOUBLE_EQ(p.y(), 40.25 - 2.0 * 2.0 / 0.1);
  // detectorPoint inverts project on the detector plane.
  const Vec3 q = m.detectorPoint(p.x(), p.y());
  EXPECT_NEAR(q.x(), 2.0, 1e-12);
  EXPECT_NEAR(q.y(), 4.0, 1e-12);
  // JSON round trip.
  const Machine again = Machine::fromConfig(ConfigNode::fromJson(m.toJson(), "x"));
  EXPECT_EQ(again.toJson(), m.toJson());
}

TEST(Machine, ATiltedDetectorProjectsOntoItsOwnPoints) {
  const ConfigNode node = ConfigNode::fromJson(nlohmann::json::parse(R"({
    "source_detector_distance_mm": 900.0,
    "detector": {"columns": 400, "rows": 300, "pixel_pitch_mm": [0.2, 0.25],
                 "principal_point_px": [210.5, 140.25], "tilt_deg": [0.4, -0.3],
                 "rotation_deg": 0.2},
    "uncertainty": {"detector_pose_deg": [0.01, 0.02, 0.005]}})"),
                                               "machine.json");
  const Machine m = Machine::fromConfig(node);
  node.finish();
  ASSERT_TRUE(m.tilted());
  // The panel is turned about the world origin, where pixel (cx, cy) stays.
  EXPECT_LT(m.detectorPoint(210.5, 140.25).norm(), 1e-12);
  // Any point on the ray from the source to a pixel's detector point
  // projects back to that pixel; its magnification is |P - S| / |W - S|.
  for (const Vec2& pixel : {Vec2(3.5, 7.25), Vec2(399.0, 0.5), Vec2(120.0, 290.0)}) {
    const Vec3 p = m.detectorPoint(pixel.x(), pixel.y());
    for (double s : {0.2, 0.5, 0.9}) {
      const Vec3 w = m.sourceWorld() + s * (p - m.sourceWorld());
      EXPECT_LT((m.project(w) - pixel).norm(), 1e-9) << pixel.transpose() << " at " << s;
      EXPECT_NEAR(m.magnificationAt(w), 1.0 / s, 1e-12);
    }
  }
  // Tilted by 0.4 deg about u, the panel's top row is nearer the source.
  EXPECT_GT(m.detectorPoint(210.5, 0.0).z(), 0.0);
  // Written and read back the same.
  const ConfigNode again = ConfigNode::fromJson(m.toJson(), "again");
  const Machine back = Machine::fromConfig(again);
  EXPECT_LT((back.detector_rotation - m.detector_rotation).norm(), 1e-15);
  EXPECT_EQ(back.detector_pose_uncertainty_deg[1], 0.02);
  // An untilted machine keeps the plain projection.
  Machine plain = m;
  plain.setDetectorPose(0.0, 0.0, 0.0);
  EXPECT_FALSE(plain.tilted());
  EXPECT_EQ(plain.detectorPoint(3.5, 7.25).z(), 0.0);
}

TEST(Machine, ADetectorTiltOutOfRangeNamesTheKey) {
  const ConfigNode node = ConfigNode::fromJson(nlohmann::json::parse(R"({
    "source_detector_distance_mm": 900.0,
    "detector": {"columns": 4, "rows": 4, "pixel_pitch_mm": [0.2, 0.2], "tilt_deg": [0.4, 30]}})"),
                                               "machine.json");
  expectErrorMentioning([&] { Machine::fromConfig(node); }, "machine.json: /detector/tilt_deg/1");
}

TEST(Machine, DefaultPrincipalPointIsTheCentre) {
  auto root = ConfigNode::parse(R"({"source_detector_distance_mm": 500,
    "detector": {"columns": 64, "rows": 32, "pixel_pitch_mm": [0.1, 0.1]}})", "m.json");
  const Machine m = Machine::fromConfig(root);
  EXPECT_EQ(m.cx_px, 32.0);
  EXPECT_EQ(m.cy_px, 16.0);
}

TEST(Machine, BadValuesNameTheKey) {
  auto root = ConfigNode::parse(R"({"source_detector_distance_mm": 500,
    "detector": {"columns": 64, "rows": 32, "pixel_pitch_mm": [0.1, -0.1]}})", "m.json");
  try {
    Machine::fromConfig(root);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.where().key_path, "/detector/pixel_pitch_mm/1");
  }
  auto fractional = ConfigNode::parse(R"({"source_detector_distance_mm": 500,
    "detector": {"columns": 64.5, "rows": 32, "pixel_pitch_mm": [0.1, 0.1]}})", "m.json");
  EXPECT_THROW(Machine::fromConfig(fractional), Error);
}

// A stated lag fraction carries a standard uncertainty: the machine's, or a
// tenth of the fraction; none without a fraction, and an uncertainty
// without a fraction is refused naming its key.
TEST(Machine, AStatedLagHasAnUncertainty) {
  const std::string base = R"("source_detector_distance_mm": 500,
    "detector": {"columns": 64, "rows": 32, "pixel_pitch_mm": [0.1, 0.1])";
  const Machine none = Machine::fromConfig(ConfigNode::parse("{" + base + "}}", "m.json"));
  EXPECT_EQ(none.lagFractionUncertainty(), 0.0);
  const Machine stated = Machine::fromConfig(
      ConfigNode::parse("{" + base + R"(, "lag_fraction": 0.004}})", "m.json"));
  EXPECT_DOUBLE_EQ(stated.lagFractionUncertainty(), 0.0004);
  auto given = ConfigNode::parse(
      "{" + base + R"(, "lag_fraction": 0.004}, "uncertainty": {"lag_fraction": 0.0002}})",
      "m.json");
  const Machine known = Machine::fromConfig(given);
  EXPECT_NO_THROW(given.finish());
  EXPECT_EQ(known.lagFractionUncertainty(), 0.0002);
  const Machine again = Machine::fromConfig(ConfigNode::fromJson(known.toJson(), "x"));
  EXPECT_EQ(again.lagFractionUncertainty(), 0.0002);
  try {
    Machine::fromConfig(
        ConfigNode::parse("{" + base + R"(}, "uncertainty": {"lag_fraction": 0.001}})", "m.json"));
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.where().key_path, "/uncertainty/lag_fraction");
  }
}

// A characterised machine: its detector file's crosstalk and bad-pixel map
// come with it; a map of another size, or a pixel off the panel, names the
// file and key.
TEST(Machine, ACharacterisedDetectorBringsItsCrosstalkAndBadPixels) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("xgauge_machine_detector_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  auto put = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
    return (dir / name).string();
  };
  put("bad_pixels.json",
      R"({"columns": 8, "rows": 6, "dead": [[1, 2]], "hot": [[7, 5]], "noisy": []})");
  put("detector.json", R"({"crosstalk": {"value": 0.004, "uncertainty": 0.0002},
    "lag_fraction": {"value": 0.003, "uncertainty": 0.0001},
    "bad_pixels": {"file": "bad_pixels.json", "dead": 1, "hot": 1, "noisy": 0}})");
  const std::string machine = put("machine.json", R"({"source_detector_distance_mm": 1000,
    "detector": {"columns": 8, "rows": 6, "pixel_pitch_mm": [0.1, 0.1],
                 "characterization": "detector.json"}})");
  const Machine m = Machine::load(machine);
  EXPECT_EQ(m.column_crosstalk, 0.004);
  EXPECT_EQ(m.column_crosstalk_uncertainty, 0.0002);
  EXPECT_EQ(m.lag_fraction, 0.003);
  ASSERT_TRUE(m.bad_pixels);
  int bad = 0;
  for (const uint8_t b : m.bad_pixels->pixels()) bad += b;
  EXPECT_EQ(bad, 2);
  EXPECT_EQ((*m.bad_pixels)(1, 2), 1);
  EXPECT_EQ((*m.bad_pixels)(7, 5), 1);
  put("bad_pixels.json", R"({"columns": 8, "rows": 6, "dead": [[8, 2]], "hot": [], "noisy": []})");
  try {
    Machine::load(machine);
    ADD_FAILURE() << "a pixel off the panel was taken";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("bad_pixels.json"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("/dead/0/0"), std::string::npos) << e.what();
  }
  put("bad_pixels.json", R"({"columns": 9, "rows": 6, "dead": [], "hot": [], "noisy": []})");
  EXPECT_THROW(Machine::load(machine), Error);
  std::filesystem::remove_all(dir);
}

TEST(PoseConfig, EulerAndMatrixAgree) {
  auto euler = ConfigNode::parse(
      R"({"rotation_deg": [10, 20, 30], "translation_mm": [1, 2, 300]})", "p.json");
  const Pose a = poseFromConfig(euler);
  EXPECT_NO_THROW(euler.finish());
  const Pose b = poseFromConfig(ConfigNode::fromJson({{"matrix", a.rowMajor()}}, "q.json"));
  EXPECT_LT((a.matrix() - b.matrix()).cwiseAbs().maxCoeff(), 1e-15);
  const auto json = poseToJson(a);
  EXPECT_NEAR(json["rotation_deg"][2].get<double>(), 30.0, 1e-12);
  EXPECT_EQ(json["matrix"].size(), 16u);
}

TEST(PoseConfig, RejectsBadPoses) {
  EXPECT_THROW(poseFromConfig(ConfigNode::parse(R"({"translation_mm": [1, 2]})", "p")), Error);
  EXPECT_THROW(poseFromConfig(ConfigNode::parse(R"({"rotation_deg": [0, 0, 0]})", "p")), Error);
  auto misspelled = ConfigNode::parse(R"({"rotaton_deg": [0,0,0], "translation_mm": [0,0,1]})", "p");
  poseFromConfig(misspelled);
  EXPECT_THROW(misspelled.finish(), Error);
}

}  // namespace
}  // namespace xgauge
