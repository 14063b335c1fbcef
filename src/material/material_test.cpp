#include "core/expect_error.h"
#include "xgauge/material/attenuation.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/material/transmission_table.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>

namespace xgauge {
namespace {

ExponentialSum threeTerms() { return ExponentialSum({{0.5, 0.02}, {0.3, 0.08}, {0.2, 0.4}}); }

TEST(ExponentialSum, ClosedForm) {
  const auto m = threeTerms();
  EXPECT_DOUBLE_EQ(m.transmission(0.0), 1.0);
  const double x = 7.5;
  const double expected = 0.5 * std::exp(-0.15) + 0.3 * std::exp(-0.6) + 0.2 * std::exp(-3.0);
  EXPECT_DOUBLE_EQ(m.transmission(x), expected);
  const double h = 1e-6;
  EXPECT_NEAR(m.derivative(x), (m.transmission(x + h) - m.transmission(x - h)) / (2 * h), 1e-9);
}

TEST(ExponentialSum, RejectsInvalidTerms) {
  EXPECT_THROW(ExponentialSum({{0.5, 0.1}, {0.4, 0.2}}), Error);   // sum 0.9
  EXPECT_THROW(ExponentialSum({{1.2, 0.1}, {-0.2, 0.2}}), Error);  // negative weight
  EXPECT_THROW(ExponentialSum({{1.0, -0.1}}), Error);              // negative mu
  EXPECT_THROW(ExponentialSum({{1.0, NAN}}), Error);
  EXPECT_THROW(ExponentialSum({}), Error);
}

TEST(ExponentialSum, JsonRoundTrip) {
  const auto m = threeTerms();
  const auto again = ExponentialSum::fromConfig(ConfigNode::fromJson(m.toJson(), "m.json"));
  ASSERT_EQ(again.terms().size(), 3u);
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_EQ(again.terms()[k].weight, m.terms()[k].weight);
    EXPECT_EQ(again.terms()[k].mu_per_mm, m.terms()[k].mu_per_mm);
  }
}

TEST(ExponentialSum, ErrorsNameTheFileAndKey) {
  auto root =
      ConfigNode::parse(R"({"model": "exponential_sum", "terms": [{"weight": 1}]})", "al.json");
  try {
    ExponentialSum::fromConfig(root);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.where().file, "al.json");
    EXPECT_EQ(e.where().key_path, "/terms/0");
  }
  auto unknown = ConfigNode::parse(R"({"model": "exp"})", "al.json");
  EXPECT_THROW(ExponentialSum::fromConfig(unknown), Error);
}

TEST(Attenuation, AluminiumFromXraylib) {
  // NIST XCOM: Al at 100 keV, total with coherent: 0.1704 cm^2/g.
  EXPECT_NEAR(massAttenuationCm2PerG("Al", 100.0), 0.1704, 0.002);
  EXPECT_NEAR(linearAttenuationPerMm("Al", 2.699, 100.0), 0.1704 * 2.699 * 0.1, 0.001);
  EXPECT_THROW(massAttenuationCm2PerG("Xx", 100.0), Error);
  EXPECT_THROW(linearAttenuationPerMm("Al", -1.0, 100.0), Error);
}

TEST(Attenuation, FloorIsTheLeastAttenuationOfTheSpectrum) {
  // Aluminium falls monotonically with energy up to well beyond 300 keV: its
  // floor is its attenuation at the tube voltage.
  EXPECT_DOUBLE_EQ(attenuationFloorPerMm("Al", 2.699, 220.0),
                   linearAttenuationPerMm("Al", 2.699, 220.0));
  // Lead's K edge (88.0 keV) lies inside a 100 kV spectrum: just below it
  // lead attenuates less than at 100 keV (NIST XCOM: 1.9 against 5.5
  // cm^2/g), so the floor is there, not at the tube voltage.
  const double at_kv = linearAttenuationPerMm("Pb", 11.35, 100.0);
  const double floor = attenuationFloorPerMm("Pb", 11.35, 100.0);
  EXPECT_LT(floor, 0.5 * at_kv);
  EXPECT_NEAR(floor, linearAttenuationPerMm("Pb", 11.35, 87.5), 0.1 * floor);
  EXPECT_THROW(attenuationFloorPerMm("Al", 2.699, 2.0), Error);
  EXPECT_THROW(attenuationFloorPerMm("Al", 2.699, NAN), Error);
}

TEST(ExponentialSum, CalibratedRangeRoundTrips) {
  auto root = ConfigNode::parse(
      R"({"model": "exponential_sum", "terms": [{"weight": 1, "mu_per_mm": 0.1}],
          "calibrated_range_mm": [0.3, 19.5]})",
      "al.json");
  const auto m = ExponentialSum::fromConfig(root);
  EXPECT_NO_THROW(root.finish());
  ASSERT_TRUE(m.calibratedRange());
  EXPECT_EQ((*m.calibratedRange())[1], 19.5);
  const auto back = ConfigNode::parse(m.toJson().dump(), "back.json");
  EXPECT_EQ(ExponentialSum::fromConfig(back).calibratedRange(), m.calibratedRange());
  // A range must be [low, high] with 0 <= low < high.
  for (const char* range : {"[5, 1]", "[-1, 3]", "[1]", "[0, \"a\"]"}) {
    auto bad = ConfigNode::parse(
        fmt::format(R"({{"model": "exponential_sum", "terms": [{{"weight": 1, "mu_per_mm": 0.1}}],
                        "calibrated_range_mm": {}}})",
                    range),
        "bad.json");
    expectErrorMentioning([&] { ExponentialSum::fromConfig(bad); }, "calibrated_range_mm");
  }
}

// A calibration's curve moves (one input moved by its u, and the curve it
// calibrates) come back from the file as written, survive a scaling of the
// rates, and a move that is not a valid curve or has no uncertainty is
// refused naming its key.
TEST(ExponentialSum, CurveMovesRoundTrip) {
  ExponentialSum m = threeTerms();
  m.setTransmissionUncertainty(0.0012);
  m.setCurveMoves({{"wedge thin_end", "mm", 0.2, 0.01, 0.001, m.withScaledRates(0.01)},
                   {"wedge thickness", "mm", 20.0, 0.01, 0.0002, m.withScaledRates(-0.002)}},
                  0.0006);
  const auto root = ConfigNode::parse(m.toJson().dump(), "material.json");
  const ExponentialSum back = ExponentialSum::fromConfig(root);
  EXPECT_NO_THROW(root.finish());
  ASSERT_EQ(back.curveMoves().size(), 2u);
  EXPECT_EQ(back.curveMovesBesides(), 0.0006);
  EXPECT_EQ(back.transmissionUncertainty(), 0.0012);
  const CurveMove& thin = back.curveMoves()[0];
  EXPECT_EQ(thin.name, "wedge thin_end");
  EXPECT_EQ(thin.unit, "mm");
  EXPECT_EQ(thin.value, 0.2);
  EXPECT_EQ(thin.standard_uncertainty, 0.01);
  EXPECT_EQ(thin.curve_change, 0.001);
  for (double x : {0.0, 3.0, 12.0})
    EXPECT_DOUBLE_EQ(thin.curve.transmission(x), m.withScaledRates(0.01).transmission(x));
  EXPECT_EQ(back.withScaledRates(0.1).curveMoves().size(), 2u);
  EXPECT_TRUE(threeTerms().curveMoves().empty());
  EXPECT_FALSE(threeTerms().toJson().at("uncertainty").contains("curve_moves"));

  nlohmann::json bad = m.toJson();
  bad["uncertainty"]["curve_moves"][1]["standard_uncertainty"] = 0.0;
  expectErrorMentioning(
      [&] { ExponentialSum::fromConfig(ConfigNode::parse(bad.dump(), "material.json")); },
      "/uncertainty/curve_moves/1/standard_uncertainty");
  bad = m.toJson();
  bad["uncertainty"]["curve_moves"][0]["curve"]["terms"][0]["weight"] = -1.0;
  expectErrorMentioning(
      [&] { ExponentialSum::fromConfig(ConfigNode::parse(bad.dump(), "material.json")); },
      "/uncertainty/curve_moves/0/curve");
  bad = m.toJson();
  bad["uncertainty"].erase("besides_curve_moves");
  expectErrorMentioning(
      [&] { ExponentialSum::fromConfig(ConfigNode::parse(bad.dump(), "material.json")); },
      "besides_curve_moves");
}

TEST(ExponentialSum, MonochromaticFromConfig) {
  auto root = ConfigNode::parse(
      R"({"model": "monochromatic", "compound": "Al", "density_g_cm3": 2.699, "energy_kev": 100})",
      "al.json");
  const auto m = ExponentialSum::fromConfig(root);
  EXPECT_NO_THROW(root.finish());
  ASSERT_EQ(m.terms().size(), 1u);
  EXPECT_DOUBLE_EQ(m.terms()[0].mu_per_mm, linearAttenuationPerMm("Al", 2.699, 100.0));
}

TEST(TransmissionTable, MatchesExactCurve) {
  const auto m = threeTerms();
  const auto table = TransmissionTable::forMaterial(m, 60.0);
  double worst = 0.0;
  for (int i = 0; i <= 600000; ++i) {
    const double x = i * 1e-4;
    worst = std::max(worst, std::abs(table(x) - m.transmission(x)));
  }
  EXPECT_LT(worst, 1e-10);
  EXPECT_DOUBLE_EQ(table(0.0), 1.0);
  EXPECT_DOUBLE_EQ(table(-1.0), 1.0);           // clamped
  EXPECT_DOUBLE_EQ(table(100.0), table(60.0));  // clamped
}

TEST(TransmissionTable, StrictlyDecreasing) {
  const auto table = TransmissionTable::forMaterial(threeTerms(), 60.0);
  double previous = table(0.0);
  for (int i = 1; i <= 60000; ++i) {
    const double value = table(i * 1e-3);
    ASSERT_LT(value, previous) << "at x = " << i * 1e-3;
    previous = value;
  }
}

}  // namespace
}  // namespace xgauge
