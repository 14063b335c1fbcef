#include "xgauge/xray/machine.h"

#include <gtest/gtest.h>

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
