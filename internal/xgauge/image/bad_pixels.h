// Bad detector pixels: dead, stuck or saturated pixels whose flat field is
// not clearly above their dark field. Real flat panels have some; their
// flat-field correction is undefined, so they are found once from the dark
// and flat frames and repaired from their neighbours.
#pragma once

#include "xgauge/image/image.h"

#include <cstdint>

namespace xgauge {

// 1 where flat - dark <= min_fraction * median(flat - dark) (or is not
// finite), else 0. Sizes must match (Error naming them).
ImageT<uint8_t> findBadPixels(const Image& dark, const Image& flat, double min_fraction = 0.1);

// Replaces every masked pixel by the mean of its unmasked 8-neighbours,
// growing inwards for clusters; returns how many pixels were replaced.
// Throws Error if every pixel is masked.
int64_t repairBadPixels(Image& image, const ImageT<uint8_t>& mask);

// Flat-field correction (normalize.h) that repairs bad pixels instead of
// failing on them: (raw - dark) / (flat - dark) where the pixel is good, the
// neighbours' mean where it is bad. `repaired`, if given, receives the count.
// `known`, if given, marks more bad pixels (a characterised detector's hot
// and noisy ones, which the dark and flat frames do not show); its size must
// be the image's (Error).
Image flatFieldCorrectRepairing(const Image& raw, const Image& dark, const Image& flat,
                                int64_t* repaired = nullptr,
                                const ImageT<uint8_t>* known = nullptr);

// The bad pixels flatFieldCorrectRepairing repairs: findBadPixels' and
// `known`'s (Error on a size that is not the frames').
ImageT<uint8_t> badPixelsOf(const Image& dark, const Image& flat, const ImageT<uint8_t>* known);

// The same correction of `frame` itself, with the mask `bad` made once
// (badPixelsOf) for every frame of a dark and flat pair; returns how many
// pixels were repaired.
int64_t flatFieldCorrectInPlace(Image& frame, const Image& dark, const Image& flat,
                                const ImageT<uint8_t>& bad);

}  // namespace xgauge
