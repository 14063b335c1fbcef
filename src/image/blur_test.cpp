#include "xgauge/image/blur.h"
#include "xgauge/image/scatter.h"

#include "xgauge/core/error.h"
#include "xgauge/image/stats.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

namespace xgauge {
namespace {

bool identical(const Image& a, const Image& b) {
  return a.width() == b.width() && a.height() == b.height() &&
         std::memcmp(a.pixels().data(), b.pixels().data(), a.size() * sizeof(float)) == 0;
}

Image randomImage(int width, int height, uint64_t seed) {
  Image image(width, height);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  for (float& value : image.pixels()) value = static_cast<float>(uniform(rng));
  return image;
}

// ---------------------------------------------------------------------------
// Gaussian blur and scatter

int reflectIndex(int i, int n) {
  const int period = 2 * n;
  int r = ((i % period) + period) % period;
  return r < n ? r : period - 1 - r;
}

// The header's kernel, written out again, applied as a plain 2-D sum in
// double with half-sample mirror boundaries.
Image naiveBlur(const Image& in, double sigma) {
  const int radius = static_cast<int>(std::ceil(4.5 * sigma));
  std::vector<double> taps;
  double sum = 0.0;
  for (int k = -radius; k <= radius; ++k) {
    taps.push_back(std::exp(-0.5 * k * k / (sigma * sigma)));
    sum += taps.back();
  }
  for (double& t : taps) t /= sum;
  Image out(in.width(), in.height());
  for (int y = 0; y < in.height(); ++y) {
    for (int x = 0; x < in.width(); ++x) {
      double value = 0.0;
      for (int j = -radius; j <= radius; ++j)
        for (int i = -radius; i <= radius; ++i)
          value += taps[static_cast<size_t>(i + radius)] * taps[static_cast<size_t>(j + radius)] *
                   static_cast<double>(
                       in(reflectIndex(x + i, in.width()), reflectIndex(y + j, in.height())));
      out(x, y) = static_cast<float>(value);
    }
  }
  return out;
}

double maxAbsDifference(const Image& a, const Image& b) {
  double worst = 0.0;
  for (size_t i = 0; i < a.size(); ++i)
    worst = std::max(
        worst, std::abs(static_cast<double>(a.pixels()[i]) - static_cast<double>(b.pixels()[i])));
  return worst;
}

TEST(GaussianBlur, SmallSigmaIsTheDirectMirrorConvolution) {
  // The last case has a kernel (radius 45) wider than the image: it folds.
  const struct {
    int width, height;
    double sigma;
  } cases[] = {{37, 29, 3.0}, {64, 48, 1.3}, {23, 17, 10.0}, {5, 40, 0.4}};
  for (const auto& c : cases) {
    const Image in = randomImage(c.width, c.height, 11);
    const Image expected = naiveBlur(in, c.sigma);
    EXPECT_LT(maxAbsDifference(gaussianBlur(in, c.sigma), expected), 1e-6)
        << c.width << "x" << c.height << " sigma " << c.sigma;
    // Scatter mixes the same blur with the original.
    const Image scattered = scatterBlur(in, 0.3, c.sigma);
    double worst = 0.0;
    for (size_t i = 0; i < in.size(); ++i)
      worst = std::max(worst, std::abs(static_cast<double>(scattered.pixels()[i]) -
                                       (0.3 * static_cast<double>(expected.pixels()[i]) +
                                        0.7 * static_cast<double>(in.pixels()[i]))));
    EXPECT_LT(worst, 1e-6);
  }
}

TEST(GaussianBlur, AroundAFeatureIsTheWholeImagesBlur) {
  // A feature on a constant background, inside and touching the border (its
  // mirror images count), the kernel narrower and wider than the image; the
  // large sigma takes the reduced path either way.
  const struct {
    int width, height, x, y, w, h;
    double sigma;
    float outside;
  } cases[] = {{64, 48, 20, 10, 15, 9, 3.0, 1.0f},
               {128, 128, 40, 50, 30, 20, 15.2, 1.0f},
               {128, 96, 0, 70, 25, 26, 15.2, 0.0f},
               {37, 29, 30, 0, 7, 29, 10.0, 0.5f},
               {300, 200, 100, 80, 40, 30, 40.0, 1.0f}};
  for (const auto& c : cases) {
    Image in(c.width, c.height, c.outside);
    const Image feature = randomImage(c.w, c.h, 5);
    for (int y = 0; y < c.h; ++y)
      for (int x = 0; x < c.w; ++x) in(c.x + x, c.y + y) = feature(x, y);
    EXPECT_LT(
        maxAbsDifference(gaussianBlurAround(in, c.sigma, c.outside), gaussianBlur(in, c.sigma)),
        1e-6)
        << c.width << "x" << c.height << " sigma " << c.sigma;
  }
  // A constant image is its own blur; the errors are gaussianBlur's.
  const Image flat(20, 10, 1.0f);
  EXPECT_TRUE(identical(gaussianBlurAround(flat, 3.0, 1.0f), flat));
  EXPECT_THROW(gaussianBlurAround(flat, -1.0, 1.0f), Error);
}

TEST(GaussianBlur, PreservesTheImageSum) {
  const struct {
    int width, height;
    double sigma;
  } cases[] = {{1024, 768, 500.0}, {64, 48, 3.0},   {1000, 777, 100.0},
               {333, 100, 40.0},   {50, 30, 200.0}, {4096, 3, 500.0}};
  for (const auto& c : cases) {
    const Image in = randomImage(c.width, c.height, 5);
    const double sum = sumOf(in);
    EXPECT_NEAR(sumOf(gaussianBlur(in, c.sigma)) / sum, 1.0, 1e-6)
        << c.width << "x" << c.height << " sigma " << c.sigma;
    EXPECT_NEAR(sumOf(scatterBlur(in, kThesisScatterWeight, c.sigma)) / sum, 1.0, 1e-6)
        << c.width << "x" << c.height << " sigma " << c.sigma;
  }
  // An image of both signs keeps its sum too (here nearly 0 against 1e4 of
  // absolute mass).
  Image signed_image = randomImage(300, 200, 6);
  for (float& value : signed_image.pixels()) value -= 0.5f;
  const double sum = sumOf(signed_image);
  EXPECT_NEAR(sumOf(gaussianBlur(signed_image, 60.0)), sum, 1e-6 * 3e4);
}

TEST(GaussianBlur, KeepsAConstantImage) {
  for (const double sigma : {0.7, 2.5, 12.0, 40.0, 500.0}) {
    for (const auto& [width, height] : {std::pair{300, 200}, std::pair{256, 64}, std::pair{7, 3}}) {
      const Image blurred = gaussianBlur(Image(width, height, 0.7f), sigma);
      for (const float value : blurred.pixels())
        ASSERT_NEAR(value, 0.7f, 1e-6f) << width << "x" << height << " sigma " << sigma;
    }
  }
}

TEST(GaussianBlur, ZeroSigmaAndEmptyImageAndErrors) {
  const Image in = randomImage(20, 10, 3);
  EXPECT_TRUE(identical(gaussianBlur(in, 0.0), in));
  EXPECT_TRUE(identical(scatterBlur(in, 0.0, 50.0), in));
  EXPECT_TRUE(gaussianBlur(Image(), 5.0).empty());
  EXPECT_THROW(gaussianBlur(in, -1.0), Error);
  EXPECT_THROW(gaussianBlur(in, std::nan("")), Error);
  EXPECT_THROW(scatterBlur(in, 1.5, 3.0), Error);
}

// Rows of a step: `low` left of column `edge`, 1 from it on.
Image stepImage(int width, int height, int edge, float low) {
  Image image(width, height, 1.0f);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < edge; ++x) image(x, y) = low;
  return image;
}

TEST(GaussianBlur, LargeSigmaFollowsTheGaussianProfile) {
  // A step blurs to low + (1 - low) Phi(d / sigma), d the distance of the
  // pixel centre from the edge. The reduced path (sigma >= 16) differs from
  // it by the shape of its kernel, up to 2.5e-4 of the step of 0.8.
  for (const double sigma : {10.0, 16.0, 20.0, 100.0, 500.0}) {
    const int width = static_cast<int>(16 * sigma), edge = width / 2;
    const Image blurred = gaussianBlur(stepImage(width, 4, edge, 0.2f), sigma);
    double worst = 0.0;
    for (int x = 0; x < width; ++x) {
      const double d = x + 0.5 - edge;
      const double expected = 0.2 + 0.8 * 0.5 * std::erfc(-d / (sigma * std::sqrt(2.0)));
      for (int y = 0; y < 4; ++y)
        worst = std::max(worst, std::abs(static_cast<double>(blurred(x, y)) - expected));
    }
    EXPECT_LT(worst, 4e-4) << "sigma " << sigma;
  }
}

TEST(ScatterModel, RemoveUndoesScatterAndWhiteRegionNormalization) {
  // A dark block on an open beam, scattered and normalized by a white region
  // as a measured radiograph is; removeScatter must return the block.
  Image truth(300, 200, 1.0f);
  for (int y = 60; y < 150; ++y)
    for (int x = 120; x < 260; ++x) truth(x, y) = static_cast<float>(0.2 + 0.002 * (x - 120));
  const PixelRect white{5, 5, 30, 30};
  Image measured = scatterBlur(truth, 0.139, 80.0);
  const double c = meanOf(measured, white);
  ASSERT_LT(c, 0.995);  // the scatter darkens the open beam too
  for (float& p : measured.pixels()) p = static_cast<float>(static_cast<double>(p) / c);
  // Pixels of 1 mm: sigma 80 px.
  const Image recovered = ScatterModel{0.139, 80.0}.remove(measured, 1.0, white);
  double worst = 0.0, before = 0.0;
  for (int y = 0; y < truth.height(); ++y)
    for (int x = 0; x < truth.width(); ++x) {
      worst = std::max(worst, std::abs(static_cast<double>(recovered(x, y) - truth(x, y))));
      before = std::max(before, std::abs(static_cast<double>(measured(x, y) - truth(x, y))));
    }
  EXPECT_GT(before, 0.02);
  EXPECT_LT(worst, 2e-5);
  // No scatter: a copy. Bad arguments: errors.
  EXPECT_TRUE(identical(ScatterModel{0.0, 80.0}.remove(truth, 1.0, white), truth));
  EXPECT_THROW(ScatterModel({0.95, 80.0}).remove(truth, 1.0, white), Error);
  EXPECT_THROW(ScatterModel({0.1, 80.0}).remove(truth, 1.0, PixelRect{290, 5, 30, 30}), Error);
  // apply() is the forward formula mix() for every pixel.
  const ScatterModel model{0.139, 80.0};
  const Image forward = model.apply(truth, 1.0);
  const Image blurred = gaussianBlur(truth, 80.0);
  for (int y = 0; y < truth.height(); y += 7)
    for (int x = 0; x < truth.width(); x += 7)
      EXPECT_NEAR(forward(x, y), model.mix(truth(x, y), blurred(x, y)), 2e-6);
}

TEST(ScatterBlur, ShadowsBothSidesOfAnEdge) {
  // The thesis's scatter on its 4096-pixel detector: a part (transmission
  // 0.2) left of column 2048, open beam right of it.
  const int width = 4096, edge = 2048;
  const double w = kThesisScatterWeight, sigma = 500.0;
  const Image scattered = scatterBlur(stepImage(width, 8, edge, 0.2f), w, sigma);
  const auto profile = [&](double d) {
    const double blurred = 0.2 + 0.8 * 0.5 * std::erfc(-d / (sigma * std::sqrt(2.0)));
    return w * blurred + (1.0 - w) * (d > 0 ? 1.0 : 0.2);
  };
  // Next to the edge the open beam loses about w * 0.8 / 2 = 5.6 %, and the
  // part gains as much; the shadow fades over a few sigma.
  EXPECT_NEAR(scattered(edge, 3), 1.0 - w * 0.4, 1e-3);
  EXPECT_NEAR(scattered(edge - 1, 3), 0.2 + w * 0.4, 1e-3);
  for (const int d : {0, 1, 10, 100, 250, 500, 1000, 1500}) {
    EXPECT_NEAR(scattered(edge + d, 5), profile(d + 0.5), 1e-3) << d;
    EXPECT_NEAR(scattered(edge - 1 - d, 5), profile(-d - 0.5), 1e-3) << d;
  }
  for (int x = edge; x < edge + 1500; ++x) {
    ASSERT_LT(scattered(x, 0), 1.0f) << x;
    ASSERT_LE(scattered(x, 0), scattered(x + 1, 0)) << x;
  }
  // The edge itself stays sharp: a jump of (1 - w) * 0.8.
  EXPECT_NEAR(scattered(edge, 0) - scattered(edge - 1, 0), (1.0 - w) * 0.8, 1e-3);
}

}  // namespace
}  // namespace xgauge
