#include "xgauge/image/pyramid.h"

#include "xgauge/image/stats.h"

#include <gtest/gtest.h>

namespace xgauge {
namespace {

TEST(Downsample2x, KnownFourByFour) {
  Image image(4, 4);
  for (int i = 0; i < 16; ++i) image.pixels()[static_cast<size_t>(i)] = static_cast<float>(i);
  const Image half = downsample2x(image);
  ASSERT_EQ(half.width(), 2);
  ASSERT_EQ(half.height(), 2);
  EXPECT_EQ(half(0, 0), 2.5f);   // (0 + 1 + 4 + 5) / 4
  EXPECT_EQ(half(1, 0), 4.5f);   // (2 + 3 + 6 + 7) / 4
  EXPECT_EQ(half(0, 1), 10.5f);  // (8 + 9 + 12 + 13) / 4
  EXPECT_EQ(half(1, 1), 12.5f);
}

TEST(Downsample2x, PreservesSumForEvenSizes) {
  // f(x, y) = x + 2 y on 8 x 6: sum = 6 * 28 + 2 * 8 * 15 = 408; each coarse
  // pixel is the mean of four, so 4 * sum(half) = sum(full).
  Image image(8, 6);
  for (int y = 0; y < 6; ++y)
    for (int x = 0; x < 8; ++x) image(x, y) = static_cast<float>(x + 2 * y);
  ASSERT_EQ(sumOf(image), 408.0);
  const Image half = downsample2x(image);
  EXPECT_EQ(4.0 * sumOf(half), 408.0);
  const Image quarter = downsample2x(half);
  ASSERT_EQ(quarter.width(), 2);
  ASSERT_EQ(quarter.height(), 1);
  // Rows 0..3, columns 0..3: mean 1.5 + 2 * 1.5.
  EXPECT_EQ(quarter(0, 0), 4.5f);
}

TEST(Downsample2x, DropsOddLastRowAndColumn) {
  Image image(5, 3, 1.0f);
  for (int y = 0; y < 3; ++y) image(4, y) = 100.0f;  // dropped column
  for (int x = 0; x < 5; ++x) image(x, 2) = 100.0f;  // dropped row
  const Image half = downsample2x(image);
  ASSERT_EQ(half.width(), 2);
  ASSERT_EQ(half.height(), 1);
  EXPECT_EQ(half(0, 0), 1.0f);
  EXPECT_EQ(half(1, 0), 1.0f);
  EXPECT_TRUE(downsample2x(Image(1, 9)).empty());
}

TEST(BuildPyramid, ConstantImageStaysConstant) {
  const float value = 0.3f;  // not a power of two: rounding would show
  const auto pyramid = buildPyramid(Image(37, 20, value), 4);
  ASSERT_EQ(pyramid.size(), 4u);
  const int widths[] = {37, 18, 9, 4}, heights[] = {20, 10, 5, 2};
  for (size_t level = 0; level < pyramid.size(); ++level) {
    EXPECT_EQ(pyramid[level].width(), widths[level]);
    EXPECT_EQ(pyramid[level].height(), heights[level]);
    for (const float v : pyramid[level].pixels()) ASSERT_EQ(v, value) << level;
  }
}

TEST(BuildPyramid, Errors) {
  EXPECT_THROW(buildPyramid(Image(8, 8), 0), Error);
  EXPECT_EQ(buildPyramid(Image(8, 8), 4).back().width(), 1);
  try {
    buildPyramid(Image(8, 8), 5);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("level 4"), std::string::npos) << e.what();
  }
}

TEST(RectAtLevel, KnownValues) {
  EXPECT_EQ(rectAtLevel(PixelRect{3, 4, 10, 9}, 0), (PixelRect{3, 4, 10, 9}));
  EXPECT_EQ(rectAtLevel(PixelRect{3, 4, 10, 9}, 1), (PixelRect{2, 2, 4, 4}));
  EXPECT_EQ(rectAtLevel(PixelRect{3, 4, 10, 9}, 2), (PixelRect{1, 1, 2, 2}));
  EXPECT_EQ(rectAtLevel(PixelRect{3, 4, 10, 9}, 3).area(), 0);
}

// Brute force: coarse column X is in the result exactly when its footprint
// [X 2^l, (X + 1) 2^l) lies inside [x, x + width), also for negative x.
// (The rows of these 1-row rectangles vanish at level >= 1; only columns count.)
TEST(RectAtLevel, MatchesBruteForceCoverage) {
  for (int level = 0; level <= 3; ++level) {
    const int scale = 1 << level;
    for (int x = -9; x <= 9; ++x) {
      for (int width = 0; width <= 20; ++width) {
        const PixelRect coarse = rectAtLevel(PixelRect{x, 0, width, 1}, level);
        for (int cx = -10; cx <= 10; ++cx) {
          const bool covered = cx * scale >= x && (cx + 1) * scale <= x + width;
          const bool inside = coarse.width > 0 && cx >= coarse.x && cx < coarse.right();
          ASSERT_EQ(inside, covered)
              << "level " << level << " x " << x << " width " << width << " coarse " << cx;
        }
        // Rows follow the same rule.
        const PixelRect transposed = rectAtLevel(PixelRect{0, x, 1, width}, level);
        ASSERT_EQ(transposed.height, coarse.width);
        if (coarse.width > 0) {
          ASSERT_EQ(transposed.y, coarse.x);
        }
      }
    }
  }
}

}  // namespace
}  // namespace xgauge
