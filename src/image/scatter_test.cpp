// The halo kernels and the border convention of image/scatter.h against
// closed forms.
#include "xgauge/image/scatter.h"

#include "xgauge/core/config.h"
#include "xgauge/image/blur.h"
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

// A transmission image under a strongly non-uniform open beam (cos^3 at a
// source 25 mm away, a heel), its halo added before the flat-field, by
// direct blurs of a canvas that holds the panel and the open beam around
// it; the flat frame has its halo too. The removal in the open beam's field
// gives the transmission back; the uniform removal does not.
TEST(HaloBorder, OpenBorderIsRemovedInTheOpenBeamsField) {
  const int width = 160, height = 120, margin = 60;  // the taps reach 54 px
  const OpenBeamField field({25.0, 70.0, 65.0, 0.1, 0.1}, 0.01, -0.02);
  Image transmission(width, height, 1.0f);
  for (int y = 30; y < 90; ++y)
    for (int x = 20; x < 70; ++x) transmission(x, y) = 0.2f + 0.004f * static_cast<float>(x - 20);
  ScatterModel halo;
  halo.weight = 0.15, halo.sigma_mm = 1.2, halo.border = HaloBorder::kOpen;
  // What the detector records of the signal T O, and of the flat O.
  auto recorded = [&](bool flat) {
    Image canvas(width + 2 * margin, height + 2 * margin);
    for (int j = 0; j < canvas.height(); ++j)
      for (int i = 0; i < canvas.width(); ++i) {
        const int x = i - margin, y = j - margin;
        const bool inside = x >= 0 && x < width && y >= 0 && y < height;
        canvas(i, j) =
            static_cast<float>(field.at(x + 0.5, y + 0.5) *
                               (inside && !flat ? static_cast<double>(transmission(x, y)) : 1.0));
      }
    return halo.apply(std::move(canvas), 0.1, 0.0f).crop({margin, margin, width, height});
  };
  const Image raw = recorded(false), flat = recorded(true);
  const PixelRect white{120, 5, 30, 20};
  Image normalized = raw;
  for (size_t i = 0; i < normalized.size(); ++i) normalized.pixels()[i] /= flat.pixels()[i];
  const auto level = static_cast<float>(meanOf(normalized, white));
  for (float& v : normalized.pixels()) v /= level;
  auto worst = [&](const Image& removed) {
    double out = 0.0;
    for (size_t i = 0; i < removed.size(); ++i)
      out = std::max(out, std::abs(static_cast<double>(removed.pixels()[i]) -
                                   static_cast<double>(transmission.pixels()[i])));
    return out;
  };
  EXPECT_LT(worst(halo.remove(normalized, 0.1, white, field)), 2e-6);
  EXPECT_GT(worst(halo.remove(normalized, 0.1, white)), 1e-3);
  // The forward formula the removal inverts: mix(T, H(T)) / mix(1, H(1)).
  const HaloField in_field = halo.haloField(field, width, height, 0.1);
  const Image h = halo.spreadIn(transmission, 0.1, 1.0f, in_field);
  double forward = 0.0;
  for (size_t i = 0; i < h.size(); ++i) {
    const double t = static_cast<double>(transmission.pixels()[i]);
    const double ratio =
        static_cast<double>(raw.pixels()[i]) / static_cast<double>(flat.pixels()[i]);
    forward = std::max(forward, std::abs(halo.mix(t, static_cast<double>(h.pixels()[i])) /
                                             static_cast<double>(in_field.flat.pixels()[i]) -
                                         ratio));
  }
  EXPECT_LT(forward, 1e-6);
}

// A flat frame shaped cos^3 (1 + a x + b y) with dead and hot pixels: the
// fit gives a and b back, the field half of them (the flat cannot tell the
// tube's heel from the panel's gain), the whole at the heel's share 1.
TEST(OpenBeamField, FitsTheFlatsHeel) {
  const OpenBeamGeometry geometry{400.0, 240.0, 200.0, 0.2, 0.2};
  const OpenBeamField truth(geometry, 2e-4, -1.5e-4);
  Image flat = truth.sampled(512, 384, 1.0);
  for (float& v : flat.pixels()) v *= 3000.0f;
  for (int k = 0; k < 300; ++k) flat((k * 37) % 512, (k * 91) % 384) = k % 2 ? 0.0f : 20000.0f;
  const OpenBeamField fitted = OpenBeamField::fit(geometry, flat);
  EXPECT_NEAR(fitted.heelUPerMm(), 1e-4, 1e-7);
  EXPECT_NEAR(fitted.heelVPerMm(), -0.75e-4, 1e-7);
  const OpenBeamField all_heel = fitted.withHeelShare(1.0);
  EXPECT_NEAR(all_heel.heelUPerMm(), 2e-4, 1e-7);
  EXPECT_NEAR(all_heel.at(10.0, 300.0), truth.at(10.0, 300.0), 1e-6);
  EXPECT_NEAR(fitted.withHeelShare(0.0).at(10.0, 300.0),
              OpenBeamField(geometry, 0.0, 0.0).at(10.0, 300.0), 1e-6);
  EXPECT_TRUE(OpenBeamField().uniform());
  EXPECT_EQ(OpenBeamField().at(3.0, 4.0), 1.0);
  // The field over the plane for a narrow kernel: the blur of the field
  // continued beyond the image (the centre's, where no border is near, is
  // the panel's own blur).
  const Image blurred = truth.blurredOverThePlane(512, 384, 1.0, 2.0);
  EXPECT_NEAR(static_cast<double>(blurred(256, 192)),
              static_cast<double>(gaussianBlur(truth.sampled(512, 384, 1.0), 10.0)(256, 192)),
              1e-6);
  EXPECT_LT(static_cast<double>(blurred(0, 0)),
            static_cast<double>(truth.sampled(1, 1, 1.0)(0, 0)));
}

TEST(OpenBeamField, TheFlatDecidesHowMuchFallOffThePanelShows) {
  // A flat with the heel but no fall-off (a simulator's): the field is the
  // plane alone, not the machine's cos^3 (8 % down at this panel's corner).
  const OpenBeamGeometry geometry{400.0, 240.0, 200.0, 0.2, 0.2};
  Image flat(512, 384);
  for (int v = 0; v < 384; ++v)
    for (int u = 0; u < 512; ++u)
      flat(u, v) = static_cast<float>(
          3000.0 * (1.0 + 2e-4 * (u + 0.5 - 240.0) * 0.2 - 1.5e-4 * (v + 0.5 - 200.0) * 0.2));
  const OpenBeamField fitted = OpenBeamField::fit(geometry, flat);
  const double plane = 1.0 + 2e-4 * (0.5 - 240.0) * 0.2 - 1.5e-4 * (0.5 - 200.0) * 0.2;
  const OpenBeamField all_heel = fitted.withHeelShare(1.0);
  EXPECT_NEAR(all_heel.at(0.5, 0.5) / all_heel.at(240.0, 200.0), plane, 1e-5);
  const OpenBeamField cosine(geometry, 2e-4, -1.5e-4);
  EXPECT_LT(cosine.at(0.5, 0.5) / cosine.at(240.0, 200.0), plane - 0.02);
  // Half the fall-off (the share 0.5, off the grid's best by its parabola).
  const OpenBeamGeometry half{400.0 / std::sqrt(0.5), 240.0, 200.0, 0.2, 0.2};
  const OpenBeamField fitted_half =
      OpenBeamField::fit(geometry, OpenBeamField(half, 0.0, 0.0).sampled(512, 384, 1.0));
  EXPECT_NEAR(fitted_half.at(0.5, 0.5), OpenBeamField(half, 0.0, 0.0).at(0.5, 0.5), 1e-5);
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

// A two-width kernel's end: read, written back and taken as a kernel of the
// same shape and border with the end's parameters; a Gaussian has none, and
// an end must name its u.
TEST(HaloConfig, AKernelsEquivalentEndRoundTrips) {
  auto read = [](const std::string& text) {
    const ConfigNode node = ConfigNode::parse(text, "detector.json");
    ScatterModel m = ScatterModel::fromConfig(node);
    node.finish();
    return m;
  };
  const std::string tail =
      R"({"weight": 0.12, "shape": "gauss_exp", "border": "open", "sigma_mm": 30,
          "tail_fraction": 0.25, "tail_length_mm": 80, "equivalent_end": {"weight": 0.119,
          "sigma_mm": 31, "tail_fraction": 0.22, "tail_length_mm": 95,
          "equivalent_sigma_uncertainty_mm": 9.5}})";
  const ScatterModel m = read(tail);
  ASSERT_TRUE(m.equivalent_end.has_value());
  const ScatterModel end = m.as(*m.equivalent_end);
  EXPECT_EQ(end.shape, HaloShape::kGaussExp);
  EXPECT_EQ(end.border, HaloBorder::kOpen);
  EXPECT_EQ(end.weight, 0.119);
  EXPECT_FALSE(end.equivalent_end.has_value());
  EXPECT_NEAR(end.equivalentSigmaMm(), std::sqrt(0.78 * 31 * 31 + 3 * 0.22 * 95 * 95), 1e-9);
  const ScatterModel back = ScatterModel::fromConfig(ConfigNode::fromJson(m.toJson(), "x"));
  EXPECT_TRUE(back.equivalent_end == m.equivalent_end);
  // The other kernel names its shape, and keeps the halo's border.
  const ScatterModel choice = read(
      R"({"weight": 0.12, "shape": "gauss_exp", "border": "open", "sigma_mm": 30,
          "tail_fraction": 0.25, "tail_length_mm": 80, "kernel_choice": {"shape": "two_gauss",
          "weight": 0.121, "sigma1_mm": 29, "sigma2_mm": 90, "fraction2": 0.3,
          "equivalent_sigma_uncertainty_mm": 12}})");
  ASSERT_TRUE(choice.kernel_choice.has_value());
  const ScatterModel other = choice.as(*choice.kernel_choice);
  EXPECT_EQ(other.shape, HaloShape::kTwoGauss);
  EXPECT_EQ(other.border, HaloBorder::kOpen);
  EXPECT_NEAR(other.equivalentSigmaMm(), std::sqrt(0.7 * 29 * 29 + 0.3 * 90 * 90), 1e-9);
  const ScatterModel again = ScatterModel::fromConfig(ConfigNode::fromJson(choice.toJson(), "x"));
  EXPECT_TRUE(again.kernel_choice == choice.kernel_choice);
  EXPECT_FALSE(again.equivalent_end.has_value());
  EXPECT_THROW(read(R"({"weight": 0.1, "sigma_mm": 30, "equivalent_end": {"weight": 0.1,
                        "sigma_mm": 31, "equivalent_sigma_uncertainty_mm": 1}})"),
               Error);
  EXPECT_THROW(read(R"({"weight": 0.1, "shape": "two_gauss", "sigma1_mm": 20, "sigma2_mm": 70,
                        "fraction2": 0.3, "equivalent_end": {"weight": 0.1, "sigma1_mm": 20,
                        "sigma2_mm": 80, "fraction2": 0.3}})"),
               Error);
}

}  // namespace
}  // namespace xgauge
