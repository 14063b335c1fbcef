// The characterisation's steps on small shots simulated here from closed
// forms and the scatter model (image/scatter.h, itself checked against the
// analytic halo in scatter_test).
#include "xgauge/characterize/characterize.h"

#include "xgauge/core/error.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace xgauge {
namespace {

// 1 open, 0 behind a plate over columns [x0, x1), rows [y0, y1).
Image plate(int width, int height, int x0, int x1, int y0, int y1) {
  Image t(width, height, 1.0f);
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) t(x, y) = 0.0f;
  return t;
}

void addNoise(Image& image, double sigma, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma);
  for (float& v : image.pixels()) v += static_cast<float>(noise(rng));
}

// An edge shot: the plate over the left part, open beam around it, a flat
// field's scale of 0.98 (the flats' lag), noise 0.004 per pixel.
Image edgeShot(const ScatterModel& halo, double pitch_mm) {
  Image shot = halo.apply(plate(200, 180, 20, 95, 15, 165), pitch_mm, 1.0f);
  for (float& v : shot.pixels()) v *= 0.98f;
  addNoise(shot, 0.004, 7);
  return shot;
}

TEST(EdgeHalo, AGaussianHaloIsFoundWithItsBorderAndCoveringUncertainties) {
  ScatterModel truth;
  truth.weight = 0.12, truth.sigma_mm = 9.0, truth.border = HaloBorder::kOpen;
  const EdgeHaloFit fit = fitEdgeHalo(edgeShot(truth, 0.5), 0.5, {});
  EXPECT_EQ(fit.scatter.shape, HaloShape::kGaussian) << fit.choice;
  EXPECT_EQ(fit.scatter.border, HaloBorder::kOpen) << fit.choice;
  EXPECT_NEAR(fit.scatter.weight, truth.weight, 0.02 * truth.weight);
  EXPECT_NEAR(fit.scatter.sigma_mm, truth.sigma_mm, 0.03 * truth.sigma_mm);
  // The profile's half-widths: positive, and the errors within 3 of them.
  EXPECT_GT(fit.scatter.weight_uncertainty, 0.0);
  EXPECT_GT(fit.scatter.sigma_uncertainty_mm, 0.0);
  EXPECT_LT(std::abs(fit.scatter.weight - truth.weight), 3.0 * fit.scatter.weight_uncertainty);
  EXPECT_LT(std::abs(fit.scatter.sigma_mm - truth.sigma_mm),
            3.0 * fit.scatter.sigma_uncertainty_mm);
  EXPECT_EQ(fit.candidates.size(), 6u);
  EXPECT_LT(fit.noise_scale, 1.2);  // the noise alone: the model is right
  // The data is the model: the halves scatter about the full fit by their
  // noise, about the profile's half-width (a half has half the bins), not
  // by more.
  const double term = fit.split_halves_equivalent_sigma_term_mm;
  const double profile = std::sqrt(std::max(
      0.0, fit.scatter.sigma_uncertainty_mm * fit.scatter.sigma_uncertainty_mm - term * term));
  EXPECT_GT(term, 0.0);
  EXPECT_LT(term, 3.0 * profile) << "halves' term " << term << " mm, profile " << profile << " mm";
}

TEST(EdgeHalo, TwoGaussiansAreToldFromOne) {
  ScatterModel truth;
  truth.weight = 0.15, truth.shape = HaloShape::kTwoGauss, truth.border = HaloBorder::kOpen;
  truth.sigma_mm = 3.0, truth.sigma2_mm = 15.0, truth.fraction2 = 0.4;
  EdgeHaloOptions options;
  options.profiles = false;
  const EdgeHaloFit fit = fitEdgeHalo(edgeShot(truth, 0.5), 0.5, options);
  EXPECT_EQ(fit.scatter.shape, HaloShape::kTwoGauss) << fit.choice;
  EXPECT_NEAR(fit.scatter.weight, truth.weight, 0.05 * truth.weight);
  EXPECT_NEAR(fit.equivalent_sigma_mm, truth.equivalentSigmaMm(), 0.05 * truth.equivalentSigmaMm());
}

// A Gaussian with an exponential tail: the tail's kernel finds it (its
// search also starts from the two Gaussians' widths), and where the other
// two-width kernel fits about as well the difference of their widths is in
// the width's uncertainty, which covers the error.
TEST(EdgeHalo, ATailedHalosWidthIsCoveredWhicheverKernelFitsIt) {
  ScatterModel truth;
  truth.weight = 0.09, truth.shape = HaloShape::kGaussExp, truth.border = HaloBorder::kOpen;
  truth.sigma_mm = 4.0, truth.tail_fraction = 0.2, truth.tail_length_mm = 10.0;
  const EdgeHaloFit fit = fitEdgeHalo(edgeShot(truth, 0.5), 0.5, {});
  const EdgeHaloCandidate* tail = nullptr;
  for (const EdgeHaloCandidate& c : fit.candidates)
    if (c.scatter.shape == HaloShape::kGaussExp && c.scatter.border == HaloBorder::kOpen) tail = &c;
  ASSERT_NE(tail, nullptr);
  EXPECT_NEAR(tail->scatter.equivalentSigmaMm(), truth.equivalentSigmaMm(),
              0.05 * truth.equivalentSigmaMm());
  EXPECT_LT(tail->misfit_ratio, 1.2);
  EXPECT_NEAR(fit.scatter.weight, truth.weight, 0.03 * truth.weight) << fit.choice;
  EXPECT_LT(std::abs(fit.equivalent_sigma_mm - truth.equivalentSigmaMm()),
            2.0 * fit.equivalent_sigma_uncertainty_mm)
      << fit.choice;
  if (!fit.kernel_choice_shape.empty()) {
    EXPECT_GE(fit.equivalent_sigma_uncertainty_mm,
              std::abs(fit.kernel_choice_equivalent_sigma_change_mm));
    EXPECT_NE(fit.kernel_choice_shape, toString(fit.scatter.shape));
  }
  // The kernel at the equivalent width's end: the chosen shape refitted
  // with its width one u wider (bisected to a few percent of u), u without
  // the kernel choice's term, which the other kernel carries itself; both
  // are what the measurement's budget moves the halo to.
  ASSERT_TRUE(fit.scatter.equivalent_end.has_value()) << fit.choice;
  const ScatterModel end = fit.scatter.as(*fit.scatter.equivalent_end);
  EXPECT_EQ(end.shape, fit.scatter.shape);
  const double choice = fit.kernel_choice_equivalent_sigma_change_mm;
  const double u = std::sqrt(std::pow(fit.equivalent_sigma_uncertainty_mm, 2) - choice * choice);
  EXPECT_NEAR(fit.scatter.equivalent_end->equivalent_sigma_uncertainty_mm, u, 1e-9 * u);
  const double reach = end.equivalentSigmaMm() - fit.equivalent_sigma_mm;
  EXPECT_GE(reach, 0.99 * u);
  EXPECT_LE(reach, 1.1 * u);
  EXPECT_NEAR(end.weight, fit.scatter.weight, 0.2 * fit.scatter.weight);
  ASSERT_EQ(fit.scatter.kernel_choice.has_value(), !fit.kernel_choice_shape.empty());
  if (fit.scatter.kernel_choice) {
    const ScatterModel other = fit.scatter.as(*fit.scatter.kernel_choice);
    EXPECT_EQ(toString(other.shape), fit.kernel_choice_shape);
    EXPECT_NEAR(other.equivalentSigmaMm() - fit.equivalent_sigma_mm, choice, 1e-9);
    EXPECT_EQ(fit.scatter.kernel_choice->equivalent_sigma_uncertainty_mm, std::abs(choice));
  }
}

// The halves' term in closed form: half the halves' difference where the
// full fit is their mean; their root mean square deviation from the full
// fit where it is not (lab2's m02: upper and lower halves 59.5 and 55.8 mm,
// full 51.7 mm, half their difference 1.85 mm).
TEST(EdgeHalo, TheHalvesTermIsTheirRootMeanSquareDeviationFromTheFullFit) {
  using Halves = std::vector<double>;
  EXPECT_DOUBLE_EQ(splitHalvesTerm(10.0, Halves{11.0, 9.0}), 1.0);
  EXPECT_DOUBLE_EQ(splitHalvesTerm(10.0, Halves{9.0, 11.0, 9.0, 11.0}), 1.0);
  EXPECT_DOUBLE_EQ(splitHalvesTerm(3.0, Halves{3.0, 3.0, 3.0, 3.0}), 0.0);
  EXPECT_DOUBLE_EQ(splitHalvesTerm(3.0, Halves{}), 0.0);
  EXPECT_NEAR(splitHalvesTerm(51.7, Halves{59.5, 55.8}), std::sqrt((7.8 * 7.8 + 4.1 * 4.1) / 2.0),
              1e-12);
  // = sqrt(half difference^2 + (halves' mean - full)^2)
  EXPECT_NEAR(splitHalvesTerm(51.7, Halves{59.5, 55.8}), std::hypot(1.85, 57.65 - 51.7), 1e-12);
  // Two pairs: the mean of their squares.
  EXPECT_NEAR(splitHalvesTerm(0.0, Halves{1.0, 1.0, 3.0, -3.0}), std::sqrt(5.0), 1e-12);
}

// A panel whose halo differs between its upper and lower halves (weight
// 0.10 above, 0.14 below): one kernel cannot be both. The upper and lower
// halves' fits find about 0.10 and 0.14, the left and right ones (each
// half above, half below) about the full fit's 0.12, so the halves' term
// is about sqrt((0.02^2 + 0.02^2) / 4) = 0.014, and both halves' weights
// lie within 2u of the estimate.
TEST(EdgeHalo, HalvesThatDisagreeWidenTheUncertainty) {
  ScatterModel upper, lower;
  upper.weight = 0.10, upper.sigma_mm = 9.0, upper.border = HaloBorder::kOpen;
  lower = upper, lower.weight = 0.14;
  const Image t = plate(200, 180, 20, 95, 15, 165);
  Image shot = upper.apply(t, 0.5, 1.0f);
  const Image below = lower.apply(t, 0.5, 1.0f);
  for (int y = 90; y < 180; ++y)
    for (int x = 0; x < 200; ++x) shot(x, y) = below(x, y);
  for (float& v : shot.pixels()) v *= 0.98f;
  addNoise(shot, 0.004, 7);
  const EdgeHaloFit fit = fitEdgeHalo(shot, 0.5, {});
  EXPECT_NEAR(fit.split_halves_weight_term,
              splitHalvesTerm(fit.scatter.weight, fit.split_halves_weight), 1e-12);
  EXPECT_NEAR(fit.split_halves_weight_term, 0.02 / std::sqrt(2.0), 0.004) << fit.choice;
  EXPECT_GE(fit.scatter.weight_uncertainty, fit.split_halves_weight_term);
  EXPECT_LT(std::abs(fit.scatter.weight - upper.weight), 2.0 * fit.scatter.weight_uncertainty);
  EXPECT_LT(std::abs(fit.scatter.weight - lower.weight), 2.0 * fit.scatter.weight_uncertainty);
}

TEST(EdgeHalo, AHaloWiderThanHalfThePanelIsRefusedWithItsFigures) {
  ScatterModel truth;
  truth.weight = 0.2, truth.sigma_mm = 80.0, truth.border = HaloBorder::kOpen;  // panel 100 x 90 mm
  EdgeHaloOptions options;
  options.profiles = false;
  try {
    fitEdgeHalo(edgeShot(truth, 0.5), 0.5, options);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("characterize, edge"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("shorter side"), std::string::npos) << e.what();
  }
  // No plate at all: refused too.
  EXPECT_THROW(fitEdgeHalo(Image(100, 100, 1.0f), 0.5, options), Error);
}

TEST(Lag, TheFractionOfTheBrightFrameInTheNext) {
  Image dark(128, 128, 1000.0f), bright(128, 128), after(128, 128);
  addNoise(dark, 1.0, 1);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 8.0);
  for (size_t i = 0; i < dark.size(); ++i) {
    const double signal = 30000.0 * (1.0 + 0.1 * std::sin(0.01 * static_cast<double>(i)));
    bright.pixels()[i] =
        static_cast<float>(static_cast<double>(dark.pixels()[i]) + signal + noise(rng));
    after.pixels()[i] =
        static_cast<float>(static_cast<double>(dark.pixels()[i]) + 0.004 * signal + noise(rng));
  }
  ImageT<uint8_t> bad(128, 128, 0);
  const Estimate g = estimateLag(bright, after, dark, bad);
  EXPECT_NEAR(g.value, 0.004, 3.0 * g.uncertainty);
  EXPECT_GT(g.uncertainty, 0.0);
  EXPECT_LT(g.uncertainty, 2e-5);
  EXPECT_THROW(estimateLag(dark, after, dark, bad), Error);
  // A panel without lag: the frame after is the dark frame plus noise, read
  // below zero about half the time; the estimate is zero then, never
  // negative (a detector file with a negative lag is refused by its reader).
  int zero = 0;
  for (int seed = 10; seed < 20; ++seed) {
    Image none = dark;
    addNoise(none, 8.0, static_cast<uint64_t>(seed));
    const Estimate z = estimateLag(bright, none, dark, bad);
    EXPECT_GE(z.value, 0.0);
    EXPECT_LT(z.value, 3.0 * z.uncertainty + 1e-12);
    zero += z.value == 0.0 ? 1 : 0;
  }
  EXPECT_GT(zero, 0);
}

TEST(Crosstalk, TheColumnStepBelowACoveredQuadrant) {
  // A halo smooth across the quadrant's edge, then X = R + c colmean(R),
  // divided by the flat's (1 + c).
  const double c = 0.005;
  ScatterModel halo;
  halo.weight = 0.1, halo.sigma_mm = 20.0, halo.border = HaloBorder::kOpen;
  Image r = halo.apply(plate(400, 400, 20, 200, 20, 200), 0.2, 1.0f);
  Image x = r;
  for (int u = 0; u < 400; ++u) {
    double mean = 0.0;
    for (int v = 0; v < 400; ++v) mean += static_cast<double>(r(u, v));
    mean /= 400.0;
    for (int v = 0; v < 400; ++v)
      x(u, v) = static_cast<float>((static_cast<double>(r(u, v)) + c * mean) / (1.0 + c));
  }
  addNoise(x, 0.003, 5);
  const Estimate e = estimateCrosstalk(x);
  EXPECT_NEAR(e.value, c, 3.0 * e.uncertainty);
  EXPECT_LT(e.uncertainty, 0.1 * c);
  EXPECT_THROW(estimateCrosstalk(Image(100, 100, 1.0f)), Error);
  // A panel without crosstalk: zero or a small positive reading, never
  // negative, over noise draws that read below zero about half the time.
  int zero = 0;
  for (uint64_t seed = 20; seed < 30; ++seed) {
    Image none = r;
    addNoise(none, 0.003, seed);
    const Estimate z = estimateCrosstalk(none);
    EXPECT_GE(z.value, 0.0);
    EXPECT_LT(z.value, 3.0 * z.uncertainty + 1e-12);
    zero += z.value == 0.0 ? 1 : 0;
  }
  EXPECT_GT(zero, 0);
}

TEST(BadPixels, DeadHotAndNoisyFromTheSeries) {
  std::vector<Image> darks;
  for (int k = 0; k < 8; ++k) {
    Image d(96, 80, 4000.0f);
    addNoise(d, 8.0, 100 + static_cast<uint64_t>(k));
    d(10, 12) += 9000.0f;                                    // hot
    d(50, 40) += static_cast<float>((k % 2 ? 1 : -1) * 80);  // noisy
    darks.push_back(d);
  }
  Image dark(96, 80, 0.0f);
  for (const Image& d : darks)
    for (size_t i = 0; i < dark.size(); ++i) dark.pixels()[i] += d.pixels()[i] / 8.0f;
  Image flat = dark;
  for (float& v : flat.pixels()) v += 30000.0f;
  flat(70, 20) = dark(70, 20) + 100.0f;  // dead
  const BadPixelMap map = findDetectorBadPixels(darks, dark, flat);
  EXPECT_EQ(map.dead, 1);
  EXPECT_EQ(map.hot, 1);
  EXPECT_EQ(map.noisy, 1);
  EXPECT_EQ(map.kinds(70, 20), kDeadPixel);
  EXPECT_EQ(map.kinds(10, 12), kHotPixel);
  EXPECT_EQ(map.kinds(50, 40), kNoisyPixel);
  const nlohmann::json j = badPixelsJson(map);
  EXPECT_EQ(j["dead"][0], nlohmann::json({70, 20}));
}

}  // namespace
}  // namespace xgauge
