// The halo kernels and the border convention of image/scatter.h against
// closed forms.
#include "xgauge/image/scatter.h"

#include "xgauge/core/config.h"
#include "xgauge/image/stats.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace xgauge {
namespace {

ScatterModel model(HaloShape shape, HaloBorder border) {
  ScatterModel m;
  m.weight = 0.15, m.shape = shape, m.border = border, m.sigma_mm = 1.2;
  m.tail_fraction = 0.3, m.tail_length_mm = 1.5;  // gauss_exp
  m.sigma2_mm = 4.0, m.fraction2 = 0.35;          // two_gauss
  return m;
}

double sum(const Image& image) {
  double total = 0.0;
  for (const float v : image.pixels()) total += static_cast<double>(v);
  return total;
}

// Phi(z), the standard normal distribution.
double phi(double z) { return 0.5 * std::erfc(-z / std::numbers::sqrt2); }

TEST(HaloKernel, EveryShapeConservesTheSignal) {
  // A blob far from the borders: the open border (outside 0) loses nothing,
  // the mirror keeps the sum wherever the blob is.
  Image blob(400, 360, 0.0f);
  for (int y = 170; y < 190; ++y)
    for (int x = 190; x < 215; ++x) blob(x, y) = 1.0f + 0.01f * static_cast<float>(x - y);
  Image corner(160, 140, 0.0f);
  for (int y = 0; y < 10; ++y)
    for (int x = 0; x < 12; ++x) corner(x, y) = 2.0f;
  for (const HaloShape shape : {HaloShape::kGaussian, HaloShape::kGaussExp, HaloShape::kTwoGauss}) {
    SCOPED_TRACE(toString(shape));
    // pitch 0.1 mm: sigmas of 12 to 40 px, the tail's components to 44 px,
    // so both blur paths (direct and reduced) are used.
    const ScatterModel open = model(shape, HaloBorder::kOpen);
    const ScatterModel mirror = model(shape, HaloBorder::kMirror);
    double fractions = 0.0;
    for (const GaussianTerm& t : open.components()) fractions += t.fraction;
    EXPECT_NEAR(fractions, 1.0, 1e-12);
    EXPECT_NEAR(sum(open.apply(blob, 0.1, 0.0f)) / sum(blob), 1.0, 2e-4);
    EXPECT_NEAR(sum(mirror.apply(corner, 0.1)) / sum(corner), 1.0, 1e-5);
    // A constant image (the open beam) stays constant under both.
    const Image flat(50, 40, 1.0f);
    for (const Image& out : {open.apply(flat, 0.1, 1.0f), mirror.apply(flat, 0.1)}) {
      const auto range = finiteRange(out);
      ASSERT_TRUE(range);
      EXPECT_NEAR(range->min, 1.0, 1e-5);
      EXPECT_NEAR(range->max, 1.0, 1e-5);
    }
  }
}

TEST(HaloKernel, ExponentialTailMixtureMatchesTheClosedForm) {
  // lambda = 1: the 2-D kernel e^(-r) / (2 pi) against sum_j a_j G(s_j),
  // by the radial integral (area element 2 pi r dr).
  double total = 0.0, moment = 0.0;
  for (const GaussianTerm& t : kExponentialTailMixture) {
    total += t.fraction;
    moment += t.fraction * 2.0 * t.sigma * t.sigma;
  }
  EXPECT_NEAR(total, 1.0, 1e-9);
  EXPECT_NEAR(moment / 6.0, 1.0, 1e-4);  // E[r^2] = 6 lambda^2
  const double dr = 1e-3;
  double l1 = 0.0;
  for (double r = 0.5 * dr; r < 40.0; r += dr) {
    double mixture = 0.0;
    for (const GaussianTerm& t : kExponentialTailMixture)
      mixture += t.fraction / total * std::exp(-0.5 * r * r / (t.sigma * t.sigma)) /
                 (2.0 * std::numbers::pi * t.sigma * t.sigma);
    l1 += std::abs(mixture - std::exp(-r) / (2.0 * std::numbers::pi)) * 2.0 * std::numbers::pi * r *
          dr;
  }
  EXPECT_LT(l1, 2e-3);
  // The edge response (a half-plane blurred): the kernel's marginal along x
  // is |x| K1(|x|) / pi for the exponential, integrated from -inf.
  const double dx = 1e-3;
  double closed = 0.0, mixed = 0.0, worst = 0.0;
  for (double x = -30.0 + 0.5 * dx; x < 30.0; x += dx) {
    const double ax = std::abs(x);
    closed += ax * std::cyl_bessel_k(1.0, ax) / std::numbers::pi * dx;
    for (const GaussianTerm& t : kExponentialTailMixture)
      mixed += t.fraction / total * std::exp(-0.5 * x * x / (t.sigma * t.sigma)) /
               (std::sqrt(2.0 * std::numbers::pi) * t.sigma) * dx;
    worst = std::max(worst, std::abs(closed - mixed));
  }
  EXPECT_LT(worst, 1e-4);
}

// A dark band (columns [0, x1), rows [y0, y1)) on an open-beam image: with
// the open border it is a dark rectangle in an open world, whose Gaussian
// halo is 1 - the product of two erf differences.
TEST(HaloBorder, OpenBorderIsTheAnalyticHaloOfADarkRectangle) {
  const int width = 200, height = 160, x1 = 60, y0 = 40, y1 = 120;
  Image image(width, height, 1.0f);
  for (int y = y0; y < y1; ++y)
    for (int x = 0; x < x1; ++x) image(x, y) = 0.0f;
  for (const double sigma_px : {9.0, 40.0}) {
    SCOPED_TRACE(sigma_px);
    ScatterModel open;
    open.weight = 0.2, open.sigma_mm = sigma_px * 0.1, open.border = HaloBorder::kOpen;
    const Image spread = open.spread(image, 0.1, 1.0f);
    const double s = sigma_px;
    double worst = 0.0;
    for (int y = 0; y < height; y += 3) {
      for (int x = 0; x < width; x += 3) {
        const double cx = x + 0.5, cy = y + 0.5;
        const double dark =
            (phi((x1 - cx) / s) - phi((0.0 - cx) / s)) * (phi((y1 - cy) / s) - phi((y0 - cy) / s));
        worst = std::max(worst, std::abs(static_cast<double>(spread(x, y)) - (1.0 - dark)));
      }
    }
    EXPECT_LT(worst, sigma_px < 16.0 ? 3e-4 : 2e-3);
    // The mirror sees the band continued beyond the left edge: darker there.
    ScatterModel mirror = open;
    mirror.border = HaloBorder::kMirror;
    const Image mirrored = mirror.spread(image, 0.1, 1.0f);
    EXPECT_GT(static_cast<double>(spread(0, height / 2) - mirrored(0, height / 2)), 0.1);
  }
}

TEST(HaloBorder, GaussExpMatchesTheClosedFormKernelSummed) {
  // The same dark rectangle, a Gaussian core plus an exponential tail: the
  // closed-form kernel summed over the rectangle at probes outside it.
  const int width = 220, height = 180, x1 = 70, y0 = 50, y1 = 130;
  Image image(width, height, 1.0f);
  for (int y = y0; y < y1; ++y)
    for (int x = 0; x < x1; ++x) image(x, y) = 0.0f;
  ScatterModel m = model(HaloShape::kGaussExp, HaloBorder::kOpen);
  m.sigma_mm = 0.8, m.tail_length_mm = 1.5, m.tail_fraction = 0.4;  // 8 px, 15 px
  const Image spread = m.spread(image, 0.1, 1.0f);
  const double s = 8.0, lambda = 15.0;
  for (const auto& [px, py] : {std::pair{80, 90}, {100, 60}, {140, 100}, {30, 20}, {75, 140}}) {
    double dark = 0.0;
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < x1; ++x) {
        const double r2 = (x - px) * (x - px) + (y - py) * (y - py);
        dark += (1.0 - m.tail_fraction) * std::exp(-0.5 * r2 / (s * s)) /
                    (2.0 * std::numbers::pi * s * s) +
                m.tail_fraction * std::exp(-std::sqrt(r2) / lambda) /
                    (2.0 * std::numbers::pi * lambda * lambda);
      }
    EXPECT_NEAR(static_cast<double>(spread(px, py)), 1.0 - dark, 2e-3) << px << "," << py;
  }
}

TEST(HaloConfig, ShapesBordersAndTheirErrors) {
  auto read = [](const char* text) {
    const ConfigNode node = ConfigNode::parse(text, "job.json");
    ScatterModel m = ScatterModel::fromConfig(node);
    node.finish();
    return m;
  };
  const ScatterModel old = read(R"({"weight": 0.1, "sigma_mm": 30})");
  EXPECT_TRUE(old.isMirroredGaussian());
  EXPECT_EQ(old.toJson().size(), 4u);  // a material.json as it always was
  const ScatterModel two = read(
      R"({"weight": 0.1, "shape": "two_gauss", "sigma1_mm": 20, "sigma2_mm": 70,
          "fraction2": 0.35, "border": "open", "fraction2_uncertainty": 0.02})");
  EXPECT_EQ(two.shape, HaloShape::kTwoGauss);
  EXPECT_EQ(two.border, HaloBorder::kOpen);
  EXPECT_NEAR(two.equivalentSigmaMm(), 44.44097208657794, 1e-9);  // lab2's m03
  const ScatterModel back = ScatterModel::fromConfig(ConfigNode::fromJson(two.toJson(), "x"));
  EXPECT_EQ(back.sigma2_mm, 70.0);
  EXPECT_EQ(back.fraction2_uncertainty, 0.02);
  const ScatterModel exp = read(
      R"({"weight": 0.12, "shape": "gauss_exp", "sigma_mm": 30, "tail_fraction": 0.25,
          "tail_length_mm": 80})");
  EXPECT_NEAR(exp.equivalentSigmaMm(), 73.9932429347437, 1e-9);  // lab2's m02
  EXPECT_THROW(read(R"({"weight": 0.1, "sigma_mm": 30, "border": "closed"})"), Error);
  EXPECT_THROW(read(R"({"weight": 0.1, "shape": "lorentz", "sigma_mm": 30})"), Error);
  EXPECT_THROW(read(R"({"weight": 0.1, "sigma_mm": 30, "tail_fraction": 0.2})"), Error);
  EXPECT_THROW(read(R"({"weight": 0.1, "shape": "two_gauss", "sigma1_mm": 30,
                        "sigma2_mm": 50, "fraction2": 1.5})"),
               Error);
}

}  // namespace
}  // namespace xgauge
