#include "xgauge/lab/detector.h"

#include "xgauge/core/parallel.h"
#include "xgauge/image/normalize.h"
#include "xgauge/image/stats.h"
#include "xgauge/lab/random.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <set>
#include <string>
#include <vector>

namespace xgauge {
namespace {

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

bool identical(const Image& a, const Image& b) {
  return a.width() == b.width() && a.height() == b.height() &&
         std::memcmp(a.pixels().data(), b.pixels().data(), a.size() * sizeof(float)) == 0;
}

// Rows of a step: `low` left of column `edge`, 1 from it on.
Image stepImage(int width, int height, int edge, float low) {
  Image image(width, height, 1.0f);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < edge; ++x) image(x, y) = low;
  return image;
}

struct Moments {
  double mean = 0.0;
  double variance = 0.0;
};

Moments momentsOf(const Image& image, double offset = 0.0) {
  double sum = 0.0, squares = 0.0;
  for (const float value : image.pixels()) {
    const double v = static_cast<double>(value) - offset;
    sum += v;
    squares += v * v;
  }
  const auto n = static_cast<double>(image.size());
  return {sum / n, squares / n - (sum / n) * (sum / n)};
}

// ---------------------------------------------------------------------------
// Random streams

TEST(SplitMix64, MatchesTheReferenceSequence) {
  // First outputs of SplitMix64 seeded with 0 (Vigna's splitmix64.c).
  SplitMix64 rng(0);
  EXPECT_EQ(rng(), 0xe220a8397b1dcdafULL);
  EXPECT_EQ(rng(), 0x6e789e6aa1b965f4ULL);
  EXPECT_EQ(rng(), 0x06c45d188009454fULL);
}

TEST(SplitMix64, DistinctKeysGiveDistinctStreams) {
  std::set<uint64_t> first;
  for (uint64_t seed = 0; seed < 8; ++seed)
    for (uint64_t a = 0; a < 128; ++a)
      for (uint64_t b = 0; b < 128; ++b) first.insert(SplitMix64::stream(seed, a, b)());
  EXPECT_EQ(first.size(), 8u * 128u * 128u);
  EXPECT_NE(SplitMix64::stream(1, 2)(), SplitMix64::stream(1, 2, 0)());
  EXPECT_NE(SplitMix64::stream(1, 2, 3)(), SplitMix64::stream(1, 3, 2)());
  EXPECT_EQ(SplitMix64::stream(1, 2, 3)(), SplitMix64::stream(1, 2, 3)());
}

TEST(SplitMix64, FeedsStandardDistributions) {
  SplitMix64 rng = SplitMix64::stream(42, 7);
  std::normal_distribution<double> normal(3.0, 2.0);
  const int n = 400000;
  double sum = 0.0, squares = 0.0, uniform_sum = 0.0;
  for (int i = 0; i < n; ++i) {
    const double v = normal(rng);
    sum += v;
    squares += v * v;
    const double u = rng.uniform();
    ASSERT_TRUE(u >= 0.0 && u < 1.0);
    uniform_sum += u;
  }
  const double mean = sum / n, variance = squares / n - mean * mean;
  EXPECT_NEAR(mean, 3.0, 5 * 2.0 / std::sqrt(n));
  EXPECT_NEAR(variance, 4.0, 5 * 4.0 * std::sqrt(2.0 / n));
  EXPECT_NEAR(uniform_sum / n, 0.5, 5 * std::sqrt(1.0 / 12.0 / n));
}

// ---------------------------------------------------------------------------
// Detector noise and patterns

// Photon and read noise only: gain 1, a flat dark level, no dead pixels.
DetectorNoiseModel idealDetector() {
  DetectorNoiseModel model;
  model.photons_per_open_pixel = 10000.0;
  model.adu_per_photon = 1.5;
  model.read_noise_adu = 20.0;
  model.dark_level_adu = 4000.0;
  model.dark_pixel_sigma_adu = 0.0;
  model.column_offset_sigma_adu = 0.0;
  model.gain_pixel_sigma = 0.0;
  model.gain_smooth_sigma = 0.0;
  model.dead_pixel_fraction = 0.0;
  model.ghost_fraction = 0.0;
  return model;
}

TEST(BeamProfile, HeelAndCosineCubedFallOffInClosedForm) {
  // 200 x 100 pixels of 0.5 mm, principal point (60.5, 40.5), D = 400 mm.
  const Image heel = beamProfile(200, 100, 0.5, 0.5, 60.5, 40.5, 400.0, 0.1, false);
  // Linear in the row, 1 at the principal point's row, 0.1 over the height.
  EXPECT_NEAR(heel(7, 40), 1.0, 1e-6);
  EXPECT_NEAR(heel(150, 90), 1.0 + 0.1 * 50.0 / 100.0, 1e-6);
  EXPECT_NEAR(heel(0, 99) - heel(0, 0), 0.1 * 99.0 / 100.0, 1e-6);
  EXPECT_EQ(heel(0, 30), heel(199, 30));  // no change along a row
  const Image fall = beamProfile(200, 100, 0.5, 0.5, 60.5, 40.5, 400.0, 0.0, true);
  EXPECT_NEAR(fall(60, 40), 1.0, 1e-9);
  // Pixel (199, 99): centre 139 px = 69.5 mm and 59 px = 29.5 mm away.
  const double r2 = 69.5 * 69.5 + 29.5 * 29.5;
  EXPECT_NEAR(fall(199, 99), std::pow(400.0 / std::sqrt(400.0 * 400.0 + r2), 3.0), 1e-6);
  EXPECT_LT(fall(199, 99), 0.96);
  EXPECT_THROW(beamProfile(10, 10, 0.5, 0.5, 5, 5, 400.0, 0.6, false), Error);
}

TEST(ColumnDarkening, EachColumnDropsByItsMeanAttenuation) {
  Image image(4, 10, 1.0f);
  for (int v = 0; v < 5; ++v) image(1, v) = 0.5f;  // column 1: mean attenuation 0.25
  Image flat = image;
  darkenColumns(image, 0.04);
  EXPECT_EQ(image(0, 7), 1.0f);  // open columns unchanged
  EXPECT_NEAR(image(1, 7), 1.0 - 0.04 * 0.25, 1e-7);
  EXPECT_NEAR(image(1, 2), 0.5 - 0.04 * 0.25, 1e-7);
  Image open(4, 10, 1.0f);
  darkenColumns(open, 0.1);  // a flat frame is unchanged
  for (float p : open.pixels()) EXPECT_EQ(p, 1.0f);
  EXPECT_THROW(darkenColumns(flat, 0.2), Error);
}

TEST(Detector, FlatFrameHasPhotonAndReadNoise) {
  const DetectorNoiseModel model = idealDetector();
  const DetectorPattern pattern = DetectorPattern::generate(model, 1024, 1024, 1);
  const Image flat = flatFrame(pattern, model, 2, 0, 1);
  const Moments m = momentsOf(flat, model.dark_level_adu);
  const double photons = model.photons_per_open_pixel, adu = model.adu_per_photon;
  // Rounding to whole ADU adds 1/12 ADU^2.
  const double variance =
      adu * adu * photons + model.read_noise_adu * model.read_noise_adu + 1.0 / 12.0;
  EXPECT_NEAR(m.mean / (adu * photons), 1.0, 0.02);
  EXPECT_NEAR(m.variance / variance, 1.0, 0.02);
  // Much tighter in fact: 1e6 pixels measure the mean to 1e-5 and the
  // variance to 0.3 % (5 standard errors).
  EXPECT_NEAR(m.mean / (adu * photons), 1.0, 5e-5);
  EXPECT_NEAR(m.variance / variance, 1.0, 5 * std::sqrt(2.0 / 1048576.0));
  for (const float value : flat.pixels()) ASSERT_EQ(value, std::round(value));

  // Averaging N frames divides the variance by N; darks have read noise only.
  const Moments m16 = momentsOf(flatFrame(pattern, model, 2, 1, 16), model.dark_level_adu);
  EXPECT_NEAR(m16.mean / (adu * photons), 1.0, 5e-5);
  EXPECT_NEAR(m16.variance / ((variance - 1.0 / 12.0) / 16.0), 1.0, 0.01);
  const Moments dark = momentsOf(darkFrame(pattern, model, 2, 0, 4), model.dark_level_adu);
  EXPECT_NEAR(dark.mean, 0.0, 0.1);
  EXPECT_NEAR(dark.variance / (model.read_noise_adu * model.read_noise_adu / 4.0), 1.0, 0.01);
}

TEST(Detector, SwitchedOffNoiseGivesTheExpectedValue) {
  DetectorNoiseModel model = idealDetector();
  model.photon_noise = false;
  model.read_noise_adu = 0.0;
  model.quantize_16bit = false;
  const DetectorPattern pattern = DetectorPattern::generate(model, 16, 8, 1);
  Image intensity(16, 8);
  for (int x = 0; x < 16; ++x)
    for (int y = 0; y < 8; ++y) intensity(x, y) = static_cast<float>(x) / 16.0f;
  const Exposure e = exposeRaw(intensity, pattern, model, 3, 0);
  for (int x = 0; x < 16; ++x)
    EXPECT_FLOAT_EQ(e.raw_adu(x, 5), static_cast<float>(4000.0 + 1.5 * 10000.0 * x / 16.0));
}

TEST(Detector, SameSeedSameImagesAtAnyThreadCount) {
  DetectorNoiseModel model;  // every effect on
  model.dead_pixel_fraction = 1e-3;
  const int width = 300, height = 257;
  Image intensity = scatterBlur(stepImage(width, height, 120, 0.25f), 0.139, 37.0);
  struct Run {
    DetectorPattern pattern;
    Exposure first, second;
    Image dark, flat, blur_direct, blur_reduced;
  };
  const auto run = [&](int threads) {
    ThreadLimit limit(threads);
    Run r;
    r.pattern = DetectorPattern::generate(model, width, height, 99);
    r.first = exposeRaw(intensity, r.pattern, model, 7, 0);
    r.second = exposeRaw(intensity, r.pattern, model, 7, 1, &r.first.signal);
    r.dark = darkFrame(r.pattern, model, 7, 0, 8);
    r.flat = flatFrame(r.pattern, model, 7, 0, 8);
    r.blur_direct = scatterBlur(r.first.raw_adu, 0.139, 6.0);
    r.blur_reduced = scatterBlur(r.first.raw_adu, 0.139, 90.0);
    return r;
  };
  const Run one = run(1), two = run(2), four = run(4);
  for (const Run* other : {&two, &four}) {
    EXPECT_TRUE(identical(one.pattern.gain, other->pattern.gain));
    EXPECT_TRUE(identical(one.pattern.dark_adu, other->pattern.dark_adu));
    EXPECT_TRUE(one.pattern.dead.pixels().size() == other->pattern.dead.pixels().size() &&
                std::equal(one.pattern.dead.pixels().begin(), one.pattern.dead.pixels().end(),
                           other->pattern.dead.pixels().begin()));
    EXPECT_TRUE(identical(one.first.raw_adu, other->first.raw_adu));
    EXPECT_TRUE(identical(one.second.raw_adu, other->second.raw_adu));
    EXPECT_TRUE(identical(one.second.signal, other->second.signal));
    EXPECT_TRUE(identical(one.dark, other->dark));
    EXPECT_TRUE(identical(one.flat, other->flat));
    EXPECT_TRUE(identical(one.blur_direct, other->blur_direct));
    EXPECT_TRUE(identical(one.blur_reduced, other->blur_reduced));
  }
  // A different seed, shot or detector gives a different image.
  EXPECT_FALSE(
      identical(one.first.raw_adu, exposeRaw(intensity, one.pattern, model, 8, 0).raw_adu));
  EXPECT_FALSE(
      identical(one.first.raw_adu, exposeRaw(intensity, one.pattern, model, 7, 2).raw_adu));
  EXPECT_FALSE(
      identical(one.pattern.gain, DetectorPattern::generate(model, width, height, 98).gain));
  EXPECT_FALSE(identical(one.dark, darkFrame(one.pattern, model, 7, 1, 8)));
}

TEST(Detector, FlatFieldCorrectionRemovesTheGainPattern) {
  DetectorNoiseModel model = idealDetector();
  model.gain_pixel_sigma = 0.02;
  model.gain_smooth_sigma = 0.03;
  model.gain_smooth_length_px = 100.0;
  model.dark_pixel_sigma_adu = 30.0;
  model.column_offset_sigma_adu = 50.0;
  const int size = 512, frames = 32;
  const DetectorPattern pattern = DetectorPattern::generate(model, size, size, 4);
  const Image open = exposeRaw(Image(size, size, 1.0f), pattern, model, 5, 0).raw_adu;
  const Image dark = darkFrame(pattern, model, 5, 0, frames);
  const Image flat = flatFrame(pattern, model, 5, 0, frames);
  const Moments corrected = momentsOf(flatFieldCorrect(open, dark, flat));

  // Relative noise left: the exposure's photons, the flat's photons (1/N of
  // them) and read noise plus rounding against the signal.
  const double photons = model.photons_per_open_pixel, signal_adu = model.adu_per_photon * photons;
  const double read = model.read_noise_adu * model.read_noise_adu + 1.0 / 12.0;
  const double expected =
      (1.0 + 1.0 / frames) / photons + read * (1.0 + 2.0 / frames) / (signal_adu * signal_adu);
  EXPECT_NEAR(corrected.mean, 1.0, 1e-4);
  EXPECT_NEAR(corrected.variance / expected, 1.0, 0.03);

  // Uncorrected, the gain pattern dominates the spread (0.02^2 + 0.03^2
  // against 1e-4 of photon noise).
  const Moments raw = momentsOf(open, model.dark_level_adu);
  EXPECT_GT(raw.variance / (raw.mean * raw.mean), 5 * expected);
}

TEST(Detector, GainPatternHasTheRequestedSpread) {
  DetectorNoiseModel model = idealDetector();
  model.gain_smooth_sigma = 0.03;
  model.gain_smooth_length_px = 64.0;
  const DetectorPattern smooth = DetectorPattern::generate(model, 512, 384, 8);
  const Moments m = momentsOf(smooth.gain);
  EXPECT_NEAR(m.mean, 1.0, 1e-6);
  EXPECT_NEAR(std::sqrt(m.variance), 0.03, 1e-5);
  // Smooth: neighbours differ by far less than the spread.
  double step = 0.0;
  for (int y = 0; y < 384; ++y)
    for (int x = 0; x + 1 < 512; ++x)
      step =
          std::max(step, std::abs(static_cast<double>(smooth.gain(x + 1, y) - smooth.gain(x, y))));
  EXPECT_LT(step, 0.03 * 0.1);

  model.gain_smooth_sigma = 0.0;
  model.gain_pixel_sigma = 0.01;
  const Moments pixel = momentsOf(DetectorPattern::generate(model, 512, 384, 8).gain);
  EXPECT_NEAR(pixel.mean, 1.0, 5 * 0.01 / std::sqrt(512.0 * 384.0));
  EXPECT_NEAR(std::sqrt(pixel.variance) / 0.01, 1.0, 0.01);
}

TEST(Detector, ColumnOffsetsAreFixedPerColumn) {
  DetectorNoiseModel model = idealDetector();
  model.column_offset_sigma_adu = 40.0;
  const DetectorPattern pattern = DetectorPattern::generate(model, 2000, 6, 3);
  double sum = 0.0, squares = 0.0;
  for (int x = 0; x < 2000; ++x) {
    const double offset = static_cast<double>(pattern.dark_adu(x, 0)) - model.dark_level_adu;
    for (int y = 1; y < 6; ++y) ASSERT_EQ(pattern.dark_adu(x, y), pattern.dark_adu(x, 0));
    sum += offset;
    squares += offset * offset;
  }
  EXPECT_NEAR(std::sqrt(squares / 2000 - (sum / 2000) * (sum / 2000)) / 40.0, 1.0, 0.1);
}

TEST(Detector, DeadPixelsAtTheRequestedFractionReadDark) {
  DetectorNoiseModel model = idealDetector();
  model.dead_pixel_fraction = 0.01;
  model.dark_pixel_sigma_adu = 25.0;
  const DetectorPattern pattern = DetectorPattern::generate(model, 1024, 1024, 12);
  int64_t dead = 0;
  for (const uint8_t d : pattern.dead.pixels()) dead += d;
  const double n = 1024.0 * 1024.0, p = 0.01;
  EXPECT_NEAR(static_cast<double>(dead), n * p, 5 * std::sqrt(n * p * (1 - p)));

  const Image raw = exposeRaw(Image(1024, 1024, 0.8f), pattern, model, 1, 0).raw_adu;
  const Image flat = flatFrame(pattern, model, 1, 0, 4);
  for (int y = 0; y < 1024; ++y) {
    for (int x = 0; x < 1024; ++x) {
      if (!pattern.dead(x, y)) continue;
      ASSERT_EQ(raw(x, y), std::round(pattern.dark_adu(x, y)));
      ASSERT_EQ(flat(x, y), pattern.dark_adu(x, y));
    }
  }
  // Switching dead pixels on leaves every other pixel as it was.
  model.dead_pixel_fraction = 0.0;
  DetectorPattern alive = pattern;
  alive.dead.fill(0);
  const Image raw_alive = exposeRaw(Image(1024, 1024, 0.8f), alive, model, 1, 0).raw_adu;
  for (size_t i = 0; i < raw.size(); ++i)
    if (!pattern.dead.pixels()[i]) {
      ASSERT_EQ(raw.pixels()[i], raw_alive.pixels()[i]);
    }
}

TEST(Detector, GhostAddsAFractionOfThePreviousExposure) {
  DetectorNoiseModel model = idealDetector();
  model.ghost_fraction = 0.05;
  const int width = 1024, height = 512;
  const DetectorPattern pattern = DetectorPattern::generate(model, width, height, 2);
  // The previous shot: open beam on the left half, dark on the right.
  const Image previous_intensity = stepImage(width, height, width / 2, 0.0f);
  Image left_dark = previous_intensity;
  for (float& v : left_dark.pixels()) v = 1.0f - v;
  const Exposure first = exposeRaw(left_dark, pattern, model, 1, 0);
  const Exposure second =
      exposeRaw(Image(width, height, 0.4f), pattern, model, 1, 1, &first.signal);

  const double scale = model.adu_per_photon * model.photons_per_open_pixel;
  const PixelRect left{0, 0, width / 2, height}, right{width / 2, 0, width / 2, height};
  const double noise = std::sqrt(0.5 / model.photons_per_open_pixel / (width / 2.0 * height));
  EXPECT_NEAR((meanOf(second.raw_adu, left) - model.dark_level_adu) / scale, 0.4 + 0.05, 5 * noise);
  EXPECT_NEAR((meanOf(second.raw_adu, right) - model.dark_level_adu) / scale, 0.4, 5 * noise);
  EXPECT_FLOAT_EQ(second.signal(10, 10), 0.45f);
  EXPECT_FLOAT_EQ(second.signal(width - 10, 10), 0.4f);

  // The lag of older shots fades geometrically: 0.05 * (0.4 + 0.05 * 1).
  const Exposure third =
      exposeRaw(Image(width, height, 0.0f), pattern, model, 1, 2, &second.signal);
  EXPECT_FLOAT_EQ(third.signal(10, 10), 0.05f * 0.45f);
  EXPECT_FLOAT_EQ(third.signal(width - 10, 10), 0.05f * 0.4f);
}

TEST(Detector, QuantizesTo16Bits) {
  DetectorNoiseModel model = idealDetector();
  model.dark_level_adu = 0.0;
  const DetectorPattern pattern = DetectorPattern::generate(model, 64, 64, 1);
  // Over-exposed: saturates at 65535. Dark with read noise around 0: some
  // negative values clamp to 0.
  Image intensity(64, 64, 0.0f);
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 64; ++x) intensity(x, y) = 10.0f;
  const Image raw = exposeRaw(intensity, pattern, model, 1, 0).raw_adu;
  int zeros = 0;
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      const float v = raw(x, y);
      ASSERT_EQ(v, std::round(v));
      ASSERT_GE(v, 0.0f);
      ASSERT_LE(v, 65535.0f);
      if (y < 32) {
        ASSERT_EQ(v, 65535.0f);
      }
      zeros += v == 0.0f;
    }
  }
  EXPECT_GT(zeros, 64 * 32 / 4);

  model.quantize_16bit = false;
  const Image unclamped = exposeRaw(intensity, pattern, model, 1, 0).raw_adu;
  EXPECT_GT(unclamped(3, 3), 100000.0f);
  float lowest = 0.0f;
  for (const float v : unclamped.pixels()) lowest = std::min(lowest, v);
  EXPECT_LT(lowest, -20.0f);
}

TEST(Detector, Errors) {
  const DetectorNoiseModel model;
  const DetectorPattern pattern = DetectorPattern::generate(model, 8, 6, 1);
  try {
    exposeRaw(Image(8, 5, 1.0f), pattern, model, 1, 0);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_TRUE(contains(e.what(), "8x5")) << e.what();
    EXPECT_TRUE(contains(e.what(), "8x6")) << e.what();
  }
  Image bad(8, 6, 1.0f);
  bad(3, 4) = -0.5f;
  bad(5, 5) = std::nanf("");
  try {
    exposeRaw(bad, pattern, model, 1, 0);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_TRUE(contains(e.what(), "(3, 4)")) << e.what();
  }
  EXPECT_THROW(exposeRaw(Image(8, 6, 2e6f), pattern, model, 1, 0), Error);
  Image bad_lag(8, 6, 0.0f);
  bad_lag(7, 0) = -1.0f;
  try {
    exposeRaw(Image(8, 6, 1.0f), pattern, model, 1, 0, &bad_lag);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_TRUE(contains(e.what(), "previous exposure")) << e.what();
    EXPECT_TRUE(contains(e.what(), "(7, 0)")) << e.what();
  }
  EXPECT_THROW(darkFrame(pattern, model, 1, 0, 0), Error);
  EXPECT_THROW(DetectorPattern::generate(model, 0, 4, 1), Error);
  DetectorNoiseModel negative = model;
  negative.read_noise_adu = -1.0;
  try {
    negative.validate();
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_TRUE(contains(e.what(), "read_noise_adu")) << e.what();
  }
}

TEST(DetectorNoiseModel, ReadsAndWritesJson) {
  const ConfigNode node = ConfigNode::parse(
      R"({"photons_per_open_pixel": 12345, "ghost_fraction": 0.01, "quantize_16bit": false})",
      "detector.json");
  const DetectorNoiseModel model = DetectorNoiseModel::fromConfig(node);
  node.finish();
  EXPECT_EQ(model.photons_per_open_pixel, 12345.0);
  EXPECT_EQ(model.ghost_fraction, 0.01);
  EXPECT_FALSE(model.quantize_16bit);
  EXPECT_EQ(model.dark_level_adu, DetectorNoiseModel{}.dark_level_adu);  // default kept

  // Round trip: every key written is read back, none is left over.
  const ConfigNode written = ConfigNode::fromJson(model.toJson(), "written");
  const DetectorNoiseModel again = DetectorNoiseModel::fromConfig(written);
  written.finish();
  EXPECT_EQ(again.toJson(), model.toJson());
  EXPECT_EQ(model.toJson().size(), 13u);

  for (const char* text :
       {R"({"ghost_fraction": 2})", R"({"read_noise_adu": -3})", R"({"photon_noise": 1})"}) {
    try {
      DetectorNoiseModel::fromConfig(ConfigNode::parse(text, "bad.json"));
      FAIL() << "expected an error for " << text;
    } catch (const Error& e) {
      const std::string key = std::string(text).substr(2, std::string(text).find('"', 2) - 2);
      EXPECT_TRUE(contains(e.what(), "/" + key)) << e.what();
      EXPECT_TRUE(contains(e.what(), "bad.json")) << e.what();
    }
  }
  // A misspelled key is reported by finish().
  const ConfigNode typo = ConfigNode::parse(R"({"read_noise": 3})", "typo.json");
  DetectorNoiseModel::fromConfig(typo);
  EXPECT_THROW(typo.finish(), Error);
}

}  // namespace
}  // namespace xgauge
