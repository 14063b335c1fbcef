// Intensity normalization of raw radiographs, so that 1.0 means "nothing
// attenuates" (PARTS.md). Arithmetic runs in double and is rounded to float
// once per pixel.
#pragma once

#include "xgauge/image/image.h"

namespace xgauge {

// raw / mean(raw over `white`), then clamped to at most 1 (thesis eq. 3.9).
// `white` is a region where the beam passes nothing but air. Values below 0
// (possible after a dark subtraction) are kept.
// Throws Error if `white` is empty or not inside the image (naming the
// rectangle and the image size), or if the mean there is not > 0.
Image normalizeByWhiteRegion(const Image& raw, const PixelRect& white);

// Flat-field correction: (raw - dark) / (flat - dark), per pixel. `dark` is an
// image taken without beam, `flat` one with beam and without part, both in the
// same units as `raw` (usually averages of several frames). The result is not
// clamped; 1.0 is the flat-field intensity, so normalizing by a white region
// afterwards removes a change of source output between the exposures.
// Throws Error if the three sizes differ (naming them) or if flat <= dark at
// some pixel (a dead or saturated pixel: naming the first one, "(x, y)" in
// row-major order, with both values).
Image flatFieldCorrect(const Image& raw, const Image& dark, const Image& flat);

}  // namespace xgauge
