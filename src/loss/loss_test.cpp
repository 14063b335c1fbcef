#include "xgauge/loss/loss.h"

#include "core/expect_error.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <random>
#include <string>

namespace xgauge {
namespace {

// A 9 x 7 radiograph with values k / 64 (exact in float), and a roi inside.
Image measuredImage() {
  Image image(9, 7);
  for (int y = 0; y < 7; ++y)
    for (int x = 0; x < 9; ++x) image(x, y) = static_cast<float>((x + 9 * y) % 50) / 64.0f;
  return image;
}
const PixelRect kRoi{2, 1, 5, 4};

// measured over the roi plus offset(x, y) (roi coordinates).
Image simulatedImage(const Image& measured, const std::function<float(int, int)>& offset) {
  Image simulated = measured.crop(kRoi);
  for (int y = 0; y < kRoi.height; ++y)
    for (int x = 0; x < kRoi.width; ++x) simulated(x, y) += offset(x, y);
  return simulated;
}

TEST(Loss, KindNames) {
  for (LossKind kind : {LossKind::kMeanAbsolute, LossKind::kMeanSquared})
    EXPECT_EQ(lossKindFromName(lossKindName(kind)), kind);
  EXPECT_EQ(lossKindName(LossKind::kMeanAbsolute), "l1");
  EXPECT_EQ(lossKindName(LossKind::kMeanSquared), "l2");
  expectErrorMentioning([] { lossKindFromName("L1"); }, "unknown loss 'L1' (known: l1, l2)");
}

TEST(Loss, ConstantOffsetInClosedForm) {
  Image measured = measuredImage();
  // Pixels outside the roi do not count.
  measured(0, 0) = 100.0f;
  measured(8, 6) = std::numeric_limits<float>::quiet_NaN();
  // A dyadic offset is exact in float: exact results.
  const Image exact = simulatedImage(measured, [](int, int) { return 0.125f; });
  EXPECT_EQ(imageLoss(exact, measured, kRoi, LossKind::kMeanAbsolute), 0.125);
  EXPECT_EQ(imageLoss(exact, measured, kRoi, LossKind::kMeanSquared), 0.015625);
  // 0.1 rounds in float.
  const Image tenth = simulatedImage(measured, [](int, int) { return 0.1f; });
  EXPECT_NEAR(imageLoss(tenth, measured, kRoi, LossKind::kMeanAbsolute), 0.1, 1e-7);
  EXPECT_NEAR(imageLoss(tenth, measured, kRoi, LossKind::kMeanSquared), 0.01, 2e-8);
  // Identical images: zero.
  EXPECT_EQ(imageLoss(measured.crop(kRoi), measured, kRoi, LossKind::kMeanAbsolute), 0.0);
}

TEST(Loss, SignsAndMeanInClosedForm) {
  const Image measured = measuredImage();
  // +-0.25 on a checkerboard and one pixel off by 1: of 20 pixels, 19 at
  // 0.25 and 1 at 1.
  const Image simulated = simulatedImage(measured, [](int x, int y) {
    if (x == 4 && y == 3) return 1.0f;
    return (x + y) % 2 == 0 ? 0.25f : -0.25f;
  });
  EXPECT_EQ(imageLoss(simulated, measured, kRoi, LossKind::kMeanAbsolute), (19 * 0.25 + 1.0) / 20);
  EXPECT_EQ(imageLoss(simulated, measured, kRoi, LossKind::kMeanSquared), (19 * 0.0625 + 1.0) / 20);
}

TEST(Loss, MaskSkipsPixels) {
  Image measured = measuredImage();
  Image simulated = simulatedImage(measured, [](int, int) { return 0.125f; });
  ImageT<uint8_t> use(measured.width(), measured.height(), 1);
  // Two bad pixels inside the roi: one way off, one NaN in the radiograph.
  simulated(1, 1) += 10.0f;  // measured (3, 2)
  use(3, 2) = 0;
  measured(5, 4) = std::numeric_limits<float>::quiet_NaN();
  simulated(3, 3) = 0.0f;
  use(5, 4) = 0;
  for (LossKind kind : {LossKind::kMeanAbsolute, LossKind::kMeanSquared})
    EXPECT_TRUE(std::isnan(imageLoss(simulated, measured, kRoi, kind)));
  EXPECT_EQ(imageLoss(simulated, measured, kRoi, LossKind::kMeanAbsolute, &use), 0.125);
  EXPECT_EQ(imageLoss(simulated, measured, kRoi, LossKind::kMeanSquared, &use), 0.015625);

  // The mean is over the 18 used pixels: 17 at 0.125, pixel (4, 1) at 2.125.
  simulated(2, 0) += 2.0f;  // measured (4, 1)
  EXPECT_DOUBLE_EQ(imageLoss(simulated, measured, kRoi, LossKind::kMeanAbsolute, &use),
                   (17 * 0.125 + 2.125) / 18);

  // A null mask uses every pixel.
  const Image clean = simulatedImage(measuredImage(), [](int, int) { return 0.125f; });
  EXPECT_EQ(imageLoss(clean, measuredImage(), kRoi, LossKind::kMeanAbsolute, nullptr), 0.125);

  // A mask that leaves nothing in the roi, and one of the wrong size.
  ImageT<uint8_t> none(measured.width(), measured.height(), 0);
  none(0, 0) = 1;  // outside the roi
  expectErrorMentioning(
      [&] { imageLoss(simulated, measured, kRoi, LossKind::kMeanAbsolute, &none); },
      "leaves no pixel");
  ImageT<uint8_t> small(4, 4, 1);
  expectErrorMentioning(
      [&] { imageLoss(simulated, measured, kRoi, LossKind::kMeanAbsolute, &small); },
      "pixel mask is 4x4 but the measured radiograph is 9x7");
}

TEST(Loss, DifferenceImage) {
  const Image measured = measuredImage();
  const Image simulated = simulatedImage(measured, [](int x, int y) {
    return 0.25f * static_cast<float>(x) - 0.5f * static_cast<float>(y);
  });
  const Image difference = differenceImage(simulated, measured, kRoi);
  ASSERT_EQ(difference.width(), kRoi.width);
  ASSERT_EQ(difference.height(), kRoi.height);
  for (int y = 0; y < kRoi.height; ++y)
    for (int x = 0; x < kRoi.width; ++x)
      EXPECT_EQ(difference(x, y), 0.25f * static_cast<float>(x) - 0.5f * static_cast<float>(y));
}

TEST(Loss, BadRegionsThrow) {
  const Image measured = measuredImage();
  const Image simulated = measured.crop(kRoi);
  const auto l1 = LossKind::kMeanAbsolute;
  expectErrorMentioning(
      [&] {
        imageLoss(simulated, measured, {6, 1, 5, 4}, l1);
      },
      "{x=6, y=1, width=5, height=4} is not inside the 9x7 measured");
  expectErrorMentioning([&] { imageLoss(simulated, measured, {-1, 1, 5, 4}, l1); }, "not inside");
  expectErrorMentioning([&] { imageLoss(simulated, measured, {2, 1, 0, 4}, l1); }, "is empty");
  expectErrorMentioning(
      [&] {
        imageLoss(simulated, measured, {2, 1, 4, 4}, l1);
      },
      "simulated image is 5x4 but the region of interest "
      "{x=2, y=1, width=4, height=4} is 4x4");
  expectErrorMentioning(
      [&] {
        differenceImage(simulated, measured, {2, 1, 5, 3});
      },
      "simulated image is 5x4");
  expectErrorMentioning([&] { differenceImage(simulated, measured, {5, 4, 5, 4}); }, "not inside");
}

TEST(Loss, SameBitsAtAnyThreadCount) {
  // A 2000 x 1500 radiograph and an off-centre roi of odd width (the lanes'
  // tail runs), with a mask that drops about 1% of the pixels.
  std::mt19937 rng(42);
  std::uniform_real_distribution<float> value(0.05f, 1.0f), noise(-0.02f, 0.02f);
  Image measured(2000, 1500);
  for (float& v : measured.pixels()) v = value(rng);
  const PixelRect roi{13, 7, 1979, 1490};
  Image simulated = measured.crop(roi);
  for (float& v : simulated.pixels()) v += noise(rng);
  ImageT<uint8_t> use(measured.width(), measured.height(), 1);
  std::uniform_int_distribution<int> percent(0, 99);
  for (uint8_t& u : use.pixels()) u = percent(rng) != 0;

  struct Result {
    double l1, l2, l1_masked;
  };
  auto evaluate = [&](int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                              static_cast<size_t>(threads));
    return Result{imageLoss(simulated, measured, roi, LossKind::kMeanAbsolute),
                  imageLoss(simulated, measured, roi, LossKind::kMeanSquared),
                  imageLoss(simulated, measured, roi, LossKind::kMeanAbsolute, &use)};
  };
  const Result one = evaluate(1);
  for (int threads : {2, 4}) {
    const Result many = evaluate(threads);
    // Bit for bit: equal doubles compare equal only when every bit matches
    // (no NaN can occur here).
    EXPECT_EQ(one.l1, many.l1) << threads << " threads";
    EXPECT_EQ(one.l2, many.l2) << threads << " threads";
    EXPECT_EQ(one.l1_masked, many.l1_masked) << threads << " threads";
  }

  // And agrees with a plain serial sum (to rounding).
  double l1 = 0.0, l2 = 0.0, masked = 0.0;
  int64_t used = 0;
  for (int y = 0; y < roi.height; ++y)
    for (int x = 0; x < roi.width; ++x) {
      const double d = static_cast<double>(simulated(x, y)) -
                       static_cast<double>(measured(roi.x + x, roi.y + y));
      l1 += std::abs(d);
      l2 += d * d;
      if (use(roi.x + x, roi.y + y)) {
        masked += std::abs(d);
        ++used;
      }
    }
  const double n = static_cast<double>(roi.area());
  EXPECT_NEAR(one.l1, l1 / n, 1e-12 * one.l1);
  EXPECT_NEAR(one.l2, l2 / n, 1e-12 * one.l2);
  EXPECT_NEAR(one.l1_masked, masked / static_cast<double>(used), 1e-12 * one.l1_masked);
  EXPECT_NEAR(one.l1, 0.01, 1e-4);  // mean |U(-0.02, 0.02)|, less float rounding
}

}  // namespace
}  // namespace xgauge
