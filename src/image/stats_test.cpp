#include "xgauge/image/stats.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace xgauge {
namespace {

// f(x, y) = x + 10 y on a 7 x 5 image.
Image ramp() {
  Image image(7, 5);
  for (int y = 0; y < 5; ++y)
    for (int x = 0; x < 7; ++x) image(x, y) = static_cast<float>(x + 10 * y);
  return image;
}

TEST(Stats, SumsAndMeansInClosedForm) {
  const Image image = ramp();
  // sum = 5 * (0 + ... + 6) + 10 * 7 * (0 + ... + 4) = 105 + 700.
  EXPECT_EQ(sumOf(image), 805.0);
  EXPECT_EQ(meanOf(image), 805.0 / 35.0);
  // Columns 2..4, rows 1..2: 2 * (2 + 3 + 4) + 10 * 3 * (1 + 2) = 18 + 90.
  const PixelRect rect{2, 1, 3, 2};
  EXPECT_EQ(sumOf(image, rect), 108.0);
  EXPECT_EQ(meanOf(image, rect), 18.0);
  EXPECT_EQ(sumOf(image, PixelRect{3, 3, 0, 2}), 0.0);
}

TEST(Stats, SumAccumulatesInDouble) {
  // 2^24 + 1 + 1 + ... is not representable step by step in float.
  Image image(1001, 1, 1.0f);
  image(0, 0) = 16777216.0f;
  EXPECT_EQ(sumOf(image), 16777216.0 + 1000.0);
}

TEST(Stats, RectangleErrors) {
  const Image image = ramp();
  EXPECT_THROW(meanOf(image, PixelRect{0, 0, 0, 3}), Error);
  try {
    sumOf(image, PixelRect{5, 0, 3, 2});
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("{x=5, y=0, width=3, height=2}"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("7x5"), std::string::npos) << e.what();
  }
  EXPECT_THROW(meanOf(Image()), Error);
}

TEST(Stats, FiniteRangeSkipsNanAndInfinity) {
  Image image = ramp();
  image(0, 0) = std::numeric_limits<float>::quiet_NaN();
  image(6, 4) = std::numeric_limits<float>::infinity();
  const auto range = finiteRange(image);
  ASSERT_TRUE(range.has_value());
  EXPECT_EQ(range->min, 1.0f);
  EXPECT_EQ(range->max, 45.0f);
  EXPECT_FALSE(finiteRange(Image(2, 2, std::numeric_limits<float>::quiet_NaN())).has_value());
}

TEST(Stats, PercentilesInterpolateLinearly) {
  // Values 1..100 in a scrambled order, plus a NaN that must be ignored.
  Image image(101, 1);
  for (int i = 0; i < 100; ++i) image(i, 0) = static_cast<float>((i * 37) % 100 + 1);
  image(100, 0) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(percentileOf(image, 0.0), 1.0);
  EXPECT_EQ(percentileOf(image, 100.0), 100.0);
  EXPECT_DOUBLE_EQ(percentileOf(image, 50.0), 50.5);
  EXPECT_NEAR(percentileOf(image, 99.5), 99.505, 1e-12);  // position 98.505
  EXPECT_NEAR(percentileOf(image, 0.5), 1.495, 1e-12);    // position 0.495
  EXPECT_THROW(percentileOf(image, 101.0), Error);
  EXPECT_THROW(percentileOf(image, std::nan("")), Error);
  EXPECT_THROW(percentileOf(Image(1, 1, std::numeric_limits<float>::quiet_NaN()), 50.0), Error);
}

}  // namespace
}  // namespace xgauge
