// Flat-field correction of raw radiographs; the whole preparation, with the
// white-region normalization, is image/radiograph.h. Arithmetic runs in
// double and is rounded to float once per pixel.
#pragma once

#include "xgauge/image/image.h"

namespace xgauge {

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
