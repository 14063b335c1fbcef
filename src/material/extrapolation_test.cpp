// The curve's extrapolation envelope (material/extrapolation.h) and its
// place in material.json (ExponentialSum::extrapolation).
#include "xgauge/material/extrapolation.h"

#include "core/expect_error.h"
#include "xgauge/material/exponential_fit.h"
#include "xgauge/material/exponential_sum.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace xgauge {
namespace {

ExponentialSum threeTerms() { return ExponentialSum({{0.5, 0.02}, {0.3, 0.08}, {0.2, 0.4}}); }

// The envelope comes back from material.json as written, and survives a
// scaling of the rates; a file written before it (no "extrapolation") still
// loads, with no extrapolation and e(x) = 0 everywhere.
TEST(CurveExtrapolation, RoundTripsThroughTheMaterialFile) {
  ExponentialSum m = threeTerms();
  m.setCalibratedRange(std::array<double, 2>{0.3, 20.0});
  m.setExtrapolation({{20.0, 0.0}, {30.0, 0.002}, {40.0, 0.005}});
  const auto root = ConfigNode::parse(m.toJson().dump(), "material.json");
  const ExponentialSum back = ExponentialSum::fromConfig(root);
  EXPECT_NO_THROW(root.finish());
  ASSERT_EQ(back.extrapolation().size(), 3u);
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_EQ(back.extrapolation()[k].path_mm, m.extrapolation()[k].path_mm);
    EXPECT_EQ(back.extrapolation()[k].half_width, m.extrapolation()[k].half_width);
  }
  EXPECT_EQ(back.withScaledRates(0.01).extrapolation().size(), 3u);

  // e(x): 0 up to the first point, linear between, the last's share of the
  // curve beyond.
  for (double x : {0.0, 10.0, 19.999, 20.0}) EXPECT_EQ(back.extrapolationHalfWidth(x), 0.0) << x;
  EXPECT_DOUBLE_EQ(back.extrapolationHalfWidth(25.0), 0.001);
  EXPECT_DOUBLE_EQ(back.extrapolationHalfWidth(35.0), 0.0035);
  EXPECT_DOUBLE_EQ(back.extrapolationHalfWidth(60.0),
                   0.005 * m.transmission(60.0) / m.transmission(40.0));

  const auto old = ConfigNode::parse(
      R"({"model": "exponential_sum", "terms": [{"weight": 1, "mu_per_mm": 0.1}],
          "uncertainty": {"transmission": 0.001}, "calibrated_range_mm": [0.3, 19.5]})",
      "old.json");
  const ExponentialSum before = ExponentialSum::fromConfig(old);
  EXPECT_NO_THROW(old.finish());
  EXPECT_TRUE(before.extrapolation().empty());
  EXPECT_EQ(before.extrapolationHalfWidth(40.0), 0.0);
  EXPECT_FALSE(before.toJson().contains("extrapolation"));

  nlohmann::json bad = m.toJson();
  bad["extrapolation"]["path_mm"] = {20.0, 40.0, 30.0};
  expectErrorMentioning(
      [&] { ExponentialSum::fromConfig(ConfigNode::parse(bad.dump(), "material.json")); },
      "extrapolation");
  bad = m.toJson();
  bad["extrapolation"]["half_width"] = {0.0, 0.001};
  expectErrorMentioning(
      [&] { ExponentialSum::fromConfig(ConfigNode::parse(bad.dump(), "material.json")); },
      "extrapolation");
  expectErrorMentioning([&] { m.setExtrapolation({{20.0, 0.0}, {30.0, -0.001}}); }, "half-width");
}

// A spectrum's curve (40 exponentials, rates 0.04 to 1.5 / mm, at least the
// floor 0.04) read as a table of 250 values up to 20 mm with noise 1e-4, and
// fitted with 3 terms: beyond 20 mm the fit and the spectrum part (the fit
// hardens less), and the envelope of the sums the table admits covers the
// difference at 1.25, 1.5 and 2 times the table's length, is 0 at its end
// and grows, relative to the curve, with the distance beyond it.
TEST(CurveExtrapolation, TheEnvelopeCoversASpectrumsCurveBeyondItsTable) {
  constexpr double kFloor = 0.04, kNoise = 1e-4, kLength = 20.0;
  std::vector<ExponentialTerm> spectrum;
  double total = 0.0;
  for (int k = 0; k < 40; ++k) {
    const double u = k / 39.0;
    spectrum.push_back(
        {std::exp(-0.5 * std::pow((u - 0.25) / 0.25, 2.0)), kFloor * std::pow(1.5 / kFloor, u)});
    total += spectrum.back().weight;
  }
  auto truth = [&](double x) {
    double sum = 0.0;
    for (const ExponentialTerm& t : spectrum) sum += t.weight / total * std::exp(-t.mu_per_mm * x);
    return sum;
  };
  std::vector<double> path, value;
  std::mt19937_64 rng(62);
  std::normal_distribution<double> gauss(0.0, kNoise);
  for (int i = 0; i < 250; ++i) {
    path.push_back(0.25 + (kLength - 0.25) * i / 249.0);
    value.push_back(truth(path.back()) + gauss(rng));
  }
  ExponentialFitOptions options;
  options.min_mu_per_mm = kFloor;
  options.max_transmission = 2.0;
  const ExponentialSum fitted = fitExponentialSum(path, value, 3, options);
  const ExtrapolationEnvelope envelope = extrapolationEnvelope(path, value, kNoise, kFloor, fitted);
  ASSERT_EQ(envelope.points.size(), 8u);
  EXPECT_EQ(envelope.points.front().path_mm, kLength);
  EXPECT_EQ(envelope.points.front().half_width, 0.0);
  // The best admitted sum fits within the noise.
  EXPECT_LT(envelope.chi2_min / 250.0, 1.3);
  EXPECT_GE(envelope.birge, 1.0);
  for (size_t k = 1; k < envelope.points.size(); ++k) {
    const ExtrapolationPoint& p = envelope.points[k];
    const ExtrapolationPoint& before = envelope.points[k - 1];
    EXPECT_GT(p.half_width / fitted.transmission(p.path_mm),
              before.half_width / fitted.transmission(before.path_mm))
        << p.path_mm;
    EXPECT_LE(envelope.lower[k], envelope.upper[k]);
  }
  for (double factor : {1.25, 1.5, 2.0}) {
    const double x = factor * kLength;
    double e = 0.0;
    for (const ExtrapolationPoint& p : envelope.points)
      if (p.path_mm == x) e = p.half_width;
    const double deviation = std::abs(truth(x) - fitted.transmission(x));
    EXPECT_GT(deviation, 1e-5) << factor;  // the fit does part from the spectrum there
    EXPECT_LE(deviation, e) << factor;
    EXPECT_LT(e, 0.2 * fitted.transmission(x)) << factor;  // and the envelope says something
  }
}

// Inputs the envelope cannot work from are refused.
TEST(CurveExtrapolation, RefusesATableItCannotUse) {
  const std::vector<double> path{1.0, 2.0, 3.0}, value{0.9, 0.8, 0.7};
  expectErrorMentioning([&] { extrapolationEnvelope(path, value, 1e-4, 0.0, threeTerms()); },
                        "at least 4");
  const std::vector<double> p4{1.0, 2.0, 3.0, 4.0}, v4{0.9, 0.8, 0.7, 0.6};
  expectErrorMentioning([&] { extrapolationEnvelope(p4, v4, 0.0, 0.0, threeTerms()); }, "noise");
}

}  // namespace
}  // namespace xgauge
