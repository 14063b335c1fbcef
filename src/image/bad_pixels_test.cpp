#include "xgauge/image/bad_pixels.h"

#include <gtest/gtest.h>

namespace xgauge {
namespace {

TEST(BadPixels, FoundFromDarkAndFlat) {
  Image dark(20, 10, 100.0f), flat(20, 10, 1100.0f);
  flat(3, 4) = 100.0f;   // dead: reads its dark level
  flat(7, 2) = 150.0f;   // 5 % of the normal gain: bad at the default 10 %
  flat(9, 9) = 400.0f;   // 30 %: weak but usable
  const auto bad = findBadPixels(dark, flat);
  int count = 0;
  for (uint8_t b : bad.pixels()) count += b;
  EXPECT_EQ(count, 2);
  EXPECT_EQ(bad(3, 4), 1);
  EXPECT_EQ(bad(7, 2), 1);
  EXPECT_EQ(bad(9, 9), 0);
}

TEST(BadPixels, RepairUsesGoodNeighboursAndFillsClusters) {
  Image image(8, 8);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) image(x, y) = static_cast<float>(x + 10 * y);  // a linear ramp
  ImageT<uint8_t> mask(8, 8, 0);
  mask(3, 3) = mask(4, 3) = mask(3, 4) = mask(4, 4) = 1;  // a 2x2 cluster
  image(3, 3) = image(4, 3) = image(3, 4) = image(4, 4) = -999.0f;
  EXPECT_EQ(repairBadPixels(image, mask), 4);
  // A linear ramp is reproduced exactly by symmetric neighbour means only in
  // the first ring; the cluster gets values within the ramp's local range.
  for (int y = 3; y <= 4; ++y)
    for (int x = 3; x <= 4; ++x) {
      EXPECT_GT(image(x, y), 21.0f);
      EXPECT_LT(image(x, y), 56.0f);
    }
  ImageT<uint8_t> all(8, 8, 1);
  EXPECT_THROW(repairBadPixels(image, all), Error);
}

TEST(BadPixels, FlatFieldCorrectionRepairsInsteadOfFailing) {
  Image dark(16, 16, 100.0f), flat(16, 16, 1100.0f), raw(16, 16, 600.0f);
  flat(5, 5) = 100.0f;  // dead
  int64_t repaired = 0;
  const Image corrected = flatFieldCorrectRepairing(raw, dark, flat, &repaired);
  EXPECT_EQ(repaired, 1);
  for (float v : corrected.pixels()) EXPECT_FLOAT_EQ(v, 0.5f);
  Image small(4, 4);
  EXPECT_THROW(flatFieldCorrectRepairing(small, dark, flat), Error);
}

}  // namespace
}  // namespace xgauge
