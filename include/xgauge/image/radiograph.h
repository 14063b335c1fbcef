// Radiograph preparation: the one path from what a detector recorded to
// normalized intensity (1.0 where nothing attenuates, docs/conventions.md),
// used by `xgauge normalize`, the measurement and both calibrations.
//
//   raw --(dark, flat: flat-field correction, bad pixels repaired)-->
//       --(divided by the mean of an open-beam white region, thesis eq. 3.9,
//         docs/method.md)-->
//       --(clamped to 1, or not)--> normalized
#pragma once

#include "xgauge/image/image.h"

#include <cstdint>
#include <optional>
#include <string>

namespace xgauge {

// What the clamp to 1 of thesis eq. 3.9 does with the open beam's noise.
enum class ClampPolicy {
  kAtOne,  // eq. 3.9: values above 1 become 1 (for viewing, and as the thesis did)
  // Keep values above 1: a fit compares the noise on both sides of 1, and a
  // clamp would bias the open beam's mean below 1.
  kNone,
};

struct RadiographFrames {
  const Image* dark = nullptr;  // both or neither
  const Image* flat = nullptr;
};

struct NormalizedRadiograph {
  Image image;
  int64_t repaired_pixels = 0;  // bad pixels repaired by the flat-field correction
  double white_mean = 1.0;      // the white region's mean before dividing (1 without one)
};

// Flat-field corrects `raw` with `frames` when given (bad pixels, where
// flat <= dark, are repaired from their neighbours), then divides by the mean
// over `white` when given, then applies `clamp`. `name` (the raw image's
// file) names the image in errors. Throws Error naming the image when the
// frames' sizes differ from it, when the white region lies outside it, or
// when the white region's mean is not positive.
NormalizedRadiograph normalizeRadiograph(Image raw, const RadiographFrames& frames,
                                         const std::optional<PixelRect>& white,
                                         ClampPolicy clamp, const std::string& name);

// Thesis eq. 3.9's clamp: every value above 1 becomes 1.
void clampToOne(Image& image);

}  // namespace xgauge
