#include "xgauge/material/exponential_fit.h"

#include "core/expect_error.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

namespace xgauge {
namespace {

struct Curve {
  std::vector<double> path_mm;
  std::vector<double> transmission;
};

// `points` samples of a curve on [0, max_path_mm].
Curve sample(const std::function<double(double)>& curve_of_path, double max_path_mm = 60.0,
             int points = 601) {
  Curve curve;
  for (int i = 0; i < points; ++i) {
    const double x = max_path_mm * i / (points - 1);
    curve.path_mm.push_back(x);
    curve.transmission.push_back(curve_of_path(x));
  }
  return curve;
}
Curve sample(const ExponentialSum& model, double max_path_mm = 60.0, int points = 601) {
  return sample([&](double x) { return model.transmission(x); }, max_path_mm, points);
}

// A polychromatic-like curve: 50 exponentials whose rates run geometrically
// from 0.015 to 0.6 / mm with smooth (log-normal-like) weights, as a hardening
// spectrum through aluminium gives. Over 60 mm T falls from 1 to about 0.1.
Curve polychromatic() {
  std::vector<ExponentialTerm> terms;
  double total = 0.0;
  for (int k = 0; k < 50; ++k) {
    const double u = k / 49.0;
    const double mu = 0.015 * std::pow(0.6 / 0.015, u);
    const double weight = std::exp(-0.5 * std::pow((u - 0.3) / 0.2, 2.0));
    terms.push_back({weight, mu});
    total += weight;
  }
  return sample([&](double x) {
    double sum = 0.0;
    for (const auto& term : terms) sum += term.weight / total * std::exp(-term.mu_per_mm * x);
    return sum;
  });
}

void expectConstraints(const ExponentialSum& model) {
  double sum = 0.0;
  for (const auto& term : model.terms()) {
    EXPECT_GT(term.weight, 0.0);
    EXPECT_GE(term.mu_per_mm, 0.0);
    sum += term.weight;
  }
  EXPECT_NEAR(sum, 1.0, 1e-12);
  for (size_t k = 1; k < model.terms().size(); ++k)
    EXPECT_LT(model.terms()[k - 1].mu_per_mm, model.terms()[k].mu_per_mm);  // sorted
}

double maxCurveDifference(const ExponentialSum& a, const ExponentialSum& b, double max_path_mm) {
  double worst = 0.0;
  for (int i = 0; i <= 6000; ++i) {
    const double x = max_path_mm * i / 6000.0;
    worst = std::max(worst, std::abs(a.transmission(x) - b.transmission(x)));
  }
  return worst;
}

TEST(ExponentialFit, RecoversTwoSeparatedTerms) {
  const ExponentialSum truth({{0.6, 0.03}, {0.4, 0.3}});
  const Curve curve = sample(truth);
  for (auto weighting :
       {ExponentialFitOptions::Weighting::kRelative, ExponentialFitOptions::Weighting::kUniform}) {
    ExponentialFitOptions options;
    options.weighting = weighting;
    ExponentialFitReport report;
    const ExponentialSum fit =
        fitExponentialSum(curve.path_mm, curve.transmission, 2, options, &report);
    expectConstraints(fit);
    EXPECT_LT(report.max_abs_residual, 1e-7);
    EXPECT_LT(maxCurveDifference(fit, truth, 60.0), 1e-7);
    // Well separated rates are identifiable.
    ASSERT_EQ(fit.terms().size(), 2u);
    for (size_t k = 0; k < 2; ++k) {
      EXPECT_NEAR(fit.terms()[k].weight, truth.terms()[k].weight, 1e-5);
      EXPECT_NEAR(fit.terms()[k].mu_per_mm, truth.terms()[k].mu_per_mm,
                  1e-5 * truth.terms()[k].mu_per_mm);
    }
  }
}

TEST(ExponentialFit, RecoversThreeTerms) {
  const ExponentialSum truth({{0.5, 0.02}, {0.3, 0.08}, {0.2, 0.4}});
  const Curve curve = sample(truth);
  ExponentialFitReport report;
  const ExponentialSum fit = fitExponentialSum(curve.path_mm, curve.transmission, 3, {}, &report);
  expectConstraints(fit);
  EXPECT_LT(report.max_abs_residual, 1e-7);
  EXPECT_LE(report.rms_residual, report.max_abs_residual);
  EXPECT_LT(maxCurveDifference(fit, truth, 60.0), 1e-7);
  EXPECT_EQ(report.terms_used, static_cast<int>(fit.terms().size()));
  EXPECT_GT(report.evaluations, 0);
  // These rates are far enough apart to be identifiable.
  ASSERT_EQ(fit.terms().size(), 3u);
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_NEAR(fit.terms()[k].weight, truth.terms()[k].weight, 1e-6);
    EXPECT_NEAR(fit.terms()[k].mu_per_mm, truth.terms()[k].mu_per_mm,
                1e-6 * truth.terms()[k].mu_per_mm);
  }
}

TEST(ExponentialFit, RecoversRatesSpreadOverThreeDecades) {
  // Nearly constant, medium and nearly instant decay: the starts must reach
  // well outside the decay rates the chords see.
  const ExponentialSum truth({{0.3, 0.002}, {0.4, 0.05}, {0.3, 2.0}});
  const Curve curve = sample(truth);
  ExponentialFitReport report;
  const ExponentialSum fit = fitExponentialSum(curve.path_mm, curve.transmission, 3, {}, &report);
  expectConstraints(fit);
  EXPECT_LT(report.max_abs_residual, 1e-7);
  EXPECT_LT(maxCurveDifference(fit, truth, 60.0), 1e-7);
}

TEST(ExponentialFit, SingleTermIsExact) {
  const ExponentialSum truth({{1.0, 0.05}});
  const Curve curve = sample(truth);
  ExponentialFitReport report;
  const ExponentialSum fit = fitExponentialSum(curve.path_mm, curve.transmission, 1, {}, &report);
  ASSERT_EQ(fit.terms().size(), 1u);
  EXPECT_EQ(fit.terms()[0].weight, 1.0);
  EXPECT_NEAR(fit.terms()[0].mu_per_mm, 0.05, 1e-9);
  EXPECT_LT(report.max_abs_residual, 1e-9);
}

TEST(ExponentialFit, MoreTermsThanTheDataNeedStillFit) {
  // Two exponentials fitted with four: the extra freedom must not hurt.
  const ExponentialSum truth({{0.7, 0.025}, {0.3, 0.15}});
  const Curve curve = sample(truth);
  ExponentialFitReport report;
  const ExponentialSum fit = fitExponentialSum(curve.path_mm, curve.transmission, 4, {}, &report);
  expectConstraints(fit);
  EXPECT_LE(fit.terms().size(), 4u);
  EXPECT_LT(report.max_abs_residual, 1e-7);
}

TEST(ExponentialFit, PolychromaticCurveNeedsThreeTerms) {
  const Curve curve = polychromatic();
  ASSERT_LT(curve.transmission.back(), 0.2);
  ExponentialFitReport one, three;
  const ExponentialSum fit1 = fitExponentialSum(curve.path_mm, curve.transmission, 1, {}, &one);
  const ExponentialSum fit3 = fitExponentialSum(curve.path_mm, curve.transmission, 3, {}, &three);
  expectConstraints(fit1);
  expectConstraints(fit3);
  EXPECT_LT(three.max_abs_residual, 1e-3);
  EXPECT_LT(three.max_abs_residual, 0.01 * one.max_abs_residual);
  EXPECT_LT(three.rms_residual, one.rms_residual);
  // The report agrees with an independent evaluation.
  const ExponentialFitReport again =
      exponentialFitResiduals(fit3, curve.path_mm, curve.transmission);
  EXPECT_EQ(again.max_abs_residual, three.max_abs_residual);
  EXPECT_EQ(again.rms_residual, three.rms_residual);
}

TEST(ExponentialFit, UniformWeightingMinimisesAbsoluteError) {
  // Each weighting wins on its own measure.
  const Curve curve = polychromatic();
  ExponentialFitOptions uniform;
  uniform.weighting = ExponentialFitOptions::Weighting::kUniform;
  ExponentialFitReport by_uniform, by_relative;
  fitExponentialSum(curve.path_mm, curve.transmission, 2, uniform, &by_uniform);
  fitExponentialSum(curve.path_mm, curve.transmission, 2, {}, &by_relative);
  EXPECT_LE(by_uniform.rms_residual, by_relative.rms_residual);
  EXPECT_LE(by_relative.max_relative_residual, by_uniform.max_relative_residual);
}

TEST(ExponentialFit, IsDeterministic) {
  const Curve curve = polychromatic();
  const ExponentialSum a = fitExponentialSum(curve.path_mm, curve.transmission, 3);
  const ExponentialSum b = fitExponentialSum(curve.path_mm, curve.transmission, 3);
  ASSERT_EQ(a.terms().size(), b.terms().size());
  for (size_t k = 0; k < a.terms().size(); ++k) {
    EXPECT_EQ(a.terms()[k].weight, b.terms()[k].weight);
    EXPECT_EQ(a.terms()[k].mu_per_mm, b.terms()[k].mu_per_mm);
  }
}

TEST(ExponentialFit, DataNotStartingAtZero) {
  // A wedge table that starts at 5 mm: I(0) = 1 is still imposed.
  const ExponentialSum truth({{0.5, 0.02}, {0.3, 0.08}, {0.2, 0.4}});
  Curve curve;
  for (int i = 0; i < 200; ++i) {
    const double x = 5.0 + 0.25 * i;
    curve.path_mm.push_back(x);
    curve.transmission.push_back(truth.transmission(x));
  }
  ExponentialFitReport report;
  const ExponentialSum fit = fitExponentialSum(curve.path_mm, curve.transmission, 3, {}, &report);
  expectConstraints(fit);
  EXPECT_LT(report.max_abs_residual, 1e-6);
}

// The free-amplitude fit: weights summing to 0.9 (a curve seen from 1.3 mm on).
TEST(ExponentialFit, FreeAmplitudeRecoversKnownTerms) {
  const std::vector<ExponentialTerm> truth{{0.45, 0.02}, {0.27, 0.08}, {0.18, 0.4}};
  Curve curve;
  for (int i = 0; i <= 400; ++i) {
    const double x = 0.05 * i;
    double t = 0.0;
    for (const auto& term : truth) t += term.weight * std::exp(-term.mu_per_mm * x);
    curve.path_mm.push_back(x);
    curve.transmission.push_back(t);
  }
  ExponentialFitOptions options;
  options.free_amplitude = true;
  options.max_transmission = 2.0;
  ExponentialFitReport report;
  const std::vector<ExponentialTerm> fit =
      fitExponentialTerms(curve.path_mm, curve.transmission, 3, options, &report);
  ASSERT_EQ(fit.size(), 3u);
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_NEAR(fit[k].weight, truth[k].weight, 1e-5);
    EXPECT_NEAR(fit[k].mu_per_mm, truth[k].mu_per_mm, 1e-5 * truth[k].mu_per_mm);
  }
  EXPECT_LT(report.max_abs_residual, 1e-8);
  // The constrained fit cannot follow it: I(0) = 1 is forced.
  ExponentialFitReport constrained;
  fitExponentialSum(curve.path_mm, curve.transmission, 3, {}, &constrained);
  EXPECT_GT(constrained.max_abs_residual, 1e-3);
  // fitExponentialSum refuses a free amplitude (it returns a normalized material).
  EXPECT_THROW(fitExponentialSum(curve.path_mm, curve.transmission, 3, options), Error);
}

double evaluateTerms(const std::vector<ExponentialTerm>& terms, double x) {
  double sum = 0.0;
  for (const auto& term : terms) sum += term.weight * std::exp(-term.mu_per_mm * x);
  return sum;
}

TEST(ShiftAndScale, HoldsEquation37Exactly) {
  // I(0) < 1, as fitted to a wedge whose thin end was taken for 0 mm.
  const std::vector<ExponentialTerm> fitted{{0.52, 0.03}, {0.3, 0.11}, {0.15, 0.6}};
  const double x_max = 20.0;
  double x0 = 0.0;
  const ExponentialSum shifted = shiftAndScale(fitted, x_max, &x0);
  EXPECT_LT(x0, 0.0);
  EXPECT_NEAR(evaluateTerms(fitted, x0), 1.0, 1e-15);
  EXPECT_NEAR(shifted.transmission(0.0), 1.0, 1e-15);
  EXPECT_NEAR(shifted.transmission(x_max), evaluateTerms(fitted, x_max), 1e-15);
  // In between, I*(x) = I(x (x_max - x0) / x_max + x0).
  for (double x : {0.7, 3.3, 11.0, 19.9, 35.0})
    EXPECT_NEAR(shifted.transmission(x), evaluateTerms(fitted, x * (x_max - x0) / x_max + x0),
                1e-14);
  // A fit with I(0) > 1 shifts the other way.
  const std::vector<ExponentialTerm> above{{0.7, 0.05}, {0.4, 0.3}};
  const ExponentialSum down = shiftAndScale(above, x_max, &x0);
  EXPECT_GT(x0, 0.0);
  EXPECT_NEAR(down.transmission(0.0), 1.0, 1e-15);
  EXPECT_NEAR(down.transmission(x_max), evaluateTerms(above, x_max), 1e-15);
  // Already normalised: the identity.
  const ExponentialSum same = shiftAndScale({{0.6, 0.05}, {0.4, 0.2}}, x_max, &x0);
  EXPECT_NEAR(x0, 0.0, 1e-15);
  EXPECT_NEAR(same.terms()[1].mu_per_mm, 0.2, 1e-14);
}

TEST(ShiftAndScale, UndoesAThinEndTakenForZero) {
  // A wedge from 0.2 to 20 mm whose rows are mapped to 0 .. 20 mm (the thin
  // end taken for 0): fit with a free amplitude, then eq. 3.7 recovers the
  // true curve on 0 .. 20 mm.
  const ExponentialSum truth({{0.5, 0.04}, {0.35, 0.12}, {0.15, 0.5}});
  const double thin = 0.2, x_max = 20.0;
  Curve curve;
  for (int i = 0; i <= 500; ++i) {
    const double pretend = x_max * i / 500.0;
    curve.path_mm.push_back(pretend);
    curve.transmission.push_back(truth.transmission(thin + (x_max - thin) * pretend / x_max));
  }
  ExponentialFitOptions options;
  options.free_amplitude = true;
  const auto fitted = fitExponentialTerms(curve.path_mm, curve.transmission, 3, options);
  double x0 = 0.0;
  const ExponentialSum shifted = shiftAndScale(fitted, x_max, &x0);
  EXPECT_NEAR(x0, -thin * x_max / (x_max - thin), 1e-4);
  EXPECT_LT(maxCurveDifference(shifted, truth, x_max), 1e-5);
}

TEST(ShiftAndScale, RejectsCurvesItCannotShift) {
  expectErrorMentioning([] { shiftAndScale({{1.2, 0.0}}, 20.0); }, "does not fall below 1");
  expectErrorMentioning([] { shiftAndScale({{3.0, 0.01}}, 20.0); }, "does not fall below 1");
  expectErrorMentioning([] { shiftAndScale({{0.5, 0.1}}, 0.0); }, "x_max > 0");
  expectErrorMentioning([] { shiftAndScale({{-0.5, 0.1}}, 20.0); }, "term 0");
  expectErrorMentioning([] { shiftAndScale({}, 20.0); }, "at least one");
}

TEST(ExponentialFit, RejectsBadInput) {
  const Curve good = sample(ExponentialSum({{1.0, 0.05}}), 10.0, 11);
  auto fit = [](const std::vector<double>& x, const std::vector<double>& t, int terms) {
    return [=] { fitExponentialSum(x, t, terms); };
  };
  const auto& x = good.path_mm;
  const auto& t = good.transmission;

  std::vector<double> shorter(t.begin(), t.end() - 1);
  expectErrorMentioning(fit(x, shorter, 2), "11 values but transmission has 10");
  expectErrorMentioning(fit({0.0, 1.0, 2.0}, {1.0, 0.9, 0.8}, 3), "at least 5");
  expectErrorMentioning(fit(x, t, 0), "1 to 8 terms");
  expectErrorMentioning(fit(x, t, 9), "1 to 8 terms");

  auto with = [](std::vector<double> v, size_t i, double value) {
    v[i] = value;
    return v;
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  expectErrorMentioning(fit(x, with(t, 3, 0.0), 2), "transmission[3]");
  expectErrorMentioning(fit(x, with(t, 3, -0.1), 2), "transmission[3]");
  expectErrorMentioning(fit(x, with(t, 0, 1.01), 2), "not in (0, 1]");
  expectErrorMentioning(fit(x, with(t, 4, nan), 2), "transmission[4]");
  expectErrorMentioning(fit(with(x, 4, nan), t, 2), "path_mm[4]");
  expectErrorMentioning(fit(with(x, 0, -1.0), t, 2), "path_mm[0]");
  expectErrorMentioning(fit(with(x, 5, x[4]), t, 2), "strictly increasing");
  expectErrorMentioning(fit(with(x, 5, x[3]), t, 2), "strictly increasing");

  // Within rounding of 1 is fine.
  EXPECT_NO_THROW(fitExponentialSum(x, with(t, 0, 1.0 + 1e-12), 1));

  ExponentialFitOptions options;
  options.max_evaluations_per_start = 10;
  EXPECT_THROW(fitExponentialSum(x, t, 1, options), Error);
}

}  // namespace
}  // namespace xgauge
