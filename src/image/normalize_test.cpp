#include "xgauge/image/normalize.h"
#include "xgauge/core/error.h"
#include "xgauge/image/radiograph.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace xgauge {
namespace {

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(NormalizeRadiograph, DividesByWhiteMeanAndClampsAtOne) {
  Image raw(6, 4, 1000.0f);
  // White region: columns 4..5, all rows, mean (3000 + 5000) / 2 = 4000.
  for (int y = 0; y < 4; ++y) {
    raw(4, y) = 3000.0f;
    raw(5, y) = 5000.0f;
  }
  raw(0, 0) = -400.0f;  // below zero stays below zero
  const NormalizedRadiograph out =
      normalizeRadiograph(raw, {}, PixelRect{4, 0, 2, 4}, ClampPolicy::kAtOne, "raw.tif");
  const Image& normalized = out.image;
  EXPECT_EQ(out.white_mean, 4000.0);
  // Its uncertainty: 8 pixels of 3000 and 5000, standard deviation
  // 1000 sqrt(8 / 7), divided by sqrt(8) and by the mean.
  EXPECT_NEAR(out.white_mean_uncertainty, 1000.0 * std::sqrt(8.0 / 7.0) / std::sqrt(8.0) / 4000.0,
              1e-12);
  EXPECT_EQ(normalized(1, 1), 0.25f);
  EXPECT_FLOAT_EQ(normalized(4, 2), 0.75f);
  EXPECT_EQ(normalized(5, 2), 1.0f);  // 1.25 clamped
  EXPECT_FLOAT_EQ(normalized(0, 0), -0.1f);
  // Without the clamp the open beam's values above 1 stay.
  EXPECT_FLOAT_EQ(
      normalizeRadiograph(raw, {}, PixelRect{4, 0, 2, 4}, ClampPolicy::kNone, "raw.tif").image(5, 2),
      1.25f);
}

TEST(NormalizeRadiograph, Errors) {
  const Image raw(64, 48, 10.0f);
  try {
    normalizeRadiograph(raw, {}, PixelRect{60, 10, 8, 8}, ClampPolicy::kAtOne, "raw.tif");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_TRUE(contains(e.what(), "{x=60, y=10, width=8, height=8}")) << e.what();
    EXPECT_TRUE(contains(e.what(), "64x48")) << e.what();
    EXPECT_TRUE(contains(e.what(), "raw.tif")) << e.what();
  }
  EXPECT_THROW(normalizeRadiograph(raw, {}, PixelRect{0, 0, 0, 8}, ClampPolicy::kAtOne, "r"), Error);
  EXPECT_THROW(normalizeRadiograph(raw, {}, PixelRect{-1, 0, 4, 4}, ClampPolicy::kAtOne, "r"),
               Error);
  try {
    normalizeRadiograph(Image(8, 8, 0.0f), {}, PixelRect{0, 0, 4, 4}, ClampPolicy::kAtOne, "r");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_TRUE(contains(e.what(), "must be positive")) << e.what();
  }
}

TEST(FlatFieldCorrect, RecoversKnownTransmission) {
  // raw = dark + t * (flat - dark) with a per-pixel gain and offset.
  const int w = 9, h = 7;
  Image raw(w, h), dark(w, h), flat(w, h), transmission(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      dark(x, y) = static_cast<float>(100 + 3 * x + y);
      flat(x, y) = static_cast<float>(40000 - 500 * y + 17 * x);
      transmission(x, y) = static_cast<float>(0.05 + 0.1 * ((x + 2 * y) % 10));
      raw(x, y) = static_cast<float>(
          static_cast<double>(dark(x, y)) +
          static_cast<double>(transmission(x, y)) *
              (static_cast<double>(flat(x, y)) - static_cast<double>(dark(x, y))));
    }
  }
  const Image corrected = flatFieldCorrect(raw, dark, flat);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      EXPECT_NEAR(corrected(x, y), transmission(x, y), 1e-6) << x << ", " << y;
  // Not clamped: brighter than the flat field is above 1.
  Image bright = flat;
  bright(0, 0) = flat(0, 0) + (flat(0, 0) - dark(0, 0));
  EXPECT_EQ(flatFieldCorrect(bright, dark, flat)(0, 0), 2.0f);
}

TEST(FlatFieldCorrect, Errors) {
  const Image a(10, 8, 5.0f);
  try {
    flatFieldCorrect(a, Image(10, 7), a);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_TRUE(contains(e.what(), "raw 10x8, dark 10x7, flat 10x8")) << e.what();
  }
  Image dark(10, 8, 100.0f), flat(10, 8, 1000.0f);
  flat(7, 3) = 100.0f;  // equal: dead pixel
  flat(2, 5) = 50.0f;   // later in row-major order
  try {
    flatFieldCorrect(a, dark, flat);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_TRUE(contains(e.what(), "pixel (7, 3)")) << e.what();
  }
}

// A panel whose every pixel also reads c times its column's mean signal
// (the detector file's crosstalk): with c given, the flat-field corrected
// image is the true transmission again; without, a column through a dark
// shadow reads open pixels too dark and shadowed ones too bright.
TEST(NormalizeRadiograph, UndoesTheColumnCrosstalkOfACharacterisedPanel) {
  constexpr int kW = 40, kH = 30;
  constexpr double kC = 0.006;
  Image dark(kW, kH), flat(kW, kH), raw(kW, kH);
  Image truth(kW, kH);
  for (int v = 0; v < kH; ++v)
    for (int u = 0; u < kW; ++u) {
      dark(u, v) = static_cast<float>(900.0 + 3.0 * ((u * 7 + v * 3) % 5));
      const double gain = 30000.0 * (1.0 + 0.02 * std::sin(0.3 * u + 0.2 * v));
      const double t = (u > 10 && u < 30 && v > 5 && v < 25) ? 0.2 + 0.02 * u : 1.0;
      truth(u, v) = static_cast<float>(t);
      flat(u, v) = static_cast<float>(gain);  // signals R; crosstalk and dark added below
      raw(u, v) = static_cast<float>(gain * t);
    }
  auto read = [&](const Image& r) {  // X = R + c mean_v R, plus the dark level
    Image x(kW, kH);
    for (int u = 0; u < kW; ++u) {
      double mean = 0.0;
      for (int v = 0; v < kH; ++v) mean += static_cast<double>(r(u, v));
      mean /= kH;
      for (int v = 0; v < kH; ++v)
        x(u, v) = static_cast<float>(static_cast<double>(r(u, v)) + kC * mean +
                                     static_cast<double>(dark(u, v)));
    }
    return x;
  };
  const Image flat_read = read(flat), raw_read = read(raw);
  RadiographFrames frames;
  frames.dark = &dark;
  frames.flat = &flat_read;
  const Image plain =
      normalizeRadiograph(raw_read, frames, std::nullopt, ClampPolicy::kNone, "r").image;
  frames.column_crosstalk = kC;
  const Image undone =
      normalizeRadiograph(raw_read, frames, std::nullopt, ClampPolicy::kNone, "r").image;
  double worst_plain = 0.0, worst_undone = 0.0;
  for (int v = 0; v < kH; ++v)
    for (int u = 0; u < kW; ++u) {
      worst_plain = std::max(worst_plain, std::abs(static_cast<double>(plain(u, v) - truth(u, v))));
      worst_undone =
          std::max(worst_undone, std::abs(static_cast<double>(undone(u, v) - truth(u, v))));
    }
  EXPECT_GT(worst_plain, 1e-3);  // c (1 - t) of the column's mean shadow
  EXPECT_LT(worst_undone, 1e-5);

  // The pair made ready once (a measurement's radiographs share it) gives
  // the same image to the bit.
  const FlatField field = flatFieldOf(frames);
  EXPECT_FALSE(field.undone_flat.empty());
  RadiographFrames shared = frames;
  shared.flat_field = &field;
  const Image from_shared =
      normalizeRadiograph(raw_read, shared, std::nullopt, ClampPolicy::kNone, "r").image;
  for (int v = 0; v < kH; ++v)
    for (int u = 0; u < kW; ++u) ASSERT_EQ(from_shared(u, v), undone(u, v)) << u << ", " << v;

  // A previous frame is corrected as the image is, its crosstalk undone
  // against the same undone flat: the image as its own previous frame, a
  // fraction f of it subtracted, leaves (1 - f) of the corrected image,
  // the true transmission again once divided by its white region (where
  // the previous frame was corrected with the raw flat, its columns through
  // the shadow kept c times their mean shadow: 3e-5 here, 3 times the bound).
  for (RadiographFrames* f : {&frames, &shared}) {
    f->previous = &raw_read;
    f->lag_fraction = 0.2;
    const PixelRect white{0, 0, 10, kH};
    const Image lagged = normalizeRadiograph(raw_read, *f, white, ClampPolicy::kNone, "r").image;
    double worst = 0.0;
    for (int v = 0; v < kH; ++v)
      for (int u = 0; u < kW; ++u)
        worst = std::max(worst, std::abs(static_cast<double>(lagged(u, v) - truth(u, v))));
    EXPECT_LT(worst, 1e-5);
  }
}

// A hot pixel that saturates under the beam: its flat is above its dark, so
// the dark and flat frames do not show it, but a characterised detector's
// map does, and it is repaired from its neighbours.
TEST(NormalizeRadiograph, RepairsTheCharacterisedDetectorsBadPixels) {
  Image dark(6, 5, 100.0f), flat(6, 5, 1100.0f), raw(6, 5, 600.0f);
  dark(2, 3) = 900.0f, flat(2, 3) = 1200.0f, raw(2, 3) = 1200.0f;  // clipped at 1200
  RadiographFrames frames;
  frames.dark = &dark;
  frames.flat = &flat;
  const NormalizedRadiograph plain =
      normalizeRadiograph(raw, frames, std::nullopt, ClampPolicy::kNone, "r");
  EXPECT_EQ(plain.repaired_pixels, 0);
  EXPECT_FLOAT_EQ(plain.image(2, 3), 1.0f);  // reads open beam behind the part
  ImageT<uint8_t> map(6, 5, 0);
  map(2, 3) = 1;
  frames.bad_pixels = &map;
  const NormalizedRadiograph repaired =
      normalizeRadiograph(raw, frames, std::nullopt, ClampPolicy::kNone, "r");
  EXPECT_EQ(repaired.repaired_pixels, 1);
  EXPECT_FLOAT_EQ(repaired.image(2, 3), 0.5f);
  ImageT<uint8_t> wrong(5, 5, 0);
  frames.bad_pixels = &wrong;
  EXPECT_THROW(normalizeRadiograph(raw, frames, std::nullopt, ClampPolicy::kNone, "r"), Error);
}

}  // namespace
}  // namespace xgauge
