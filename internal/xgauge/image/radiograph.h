// Radiograph preparation: the one path from what a detector recorded to
// normalized intensity (1.0 where nothing attenuates, docs/conventions.md),
// used by `xgauge normalize`, the measurement and both calibrations.
//
//   raw --(the panel's column crosstalk undone, when it is known)-->
//       --(dark, flat: flat-field correction, bad pixels repaired)-->
//       --(the previous frame's lag subtracted, when it is given: image/lag.h)-->
//       --(divided by the mean of an open-beam white region, thesis eq. 3.9,
//         docs/method.md)-->
//       --(clamped to 1, or not)--> normalized
#pragma once

#include "xgauge/image/image.h"
#include "xgauge/image/lag.h"

#include <cstdint>
#include <limits>
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

// A dark and flat pair made ready once for every frame corrected with it:
// the flat with the column crosstalk undone (empty without crosstalk: the
// flat itself) and the bad pixels the pair shows, with the detector's known
// ones. Made for each frame otherwise (a flat of 3072^2 took a tenth of a
// second a frame).
struct FlatField {
  Image undone_flat;
  ImageT<uint8_t> bad;
};

struct RadiographFrames {
  const Image* dark = nullptr;  // both or neither
  const Image* flat = nullptr;
  // The raw frame exposed just before this one (same dark and flat), whose
  // lag is subtracted; null: none. With it, `lag_fraction` is the detector's
  // when known (NaN: estimated from the pair, image/lag.h).
  const Image* previous = nullptr;
  std::string previous_name;  // its file, for messages
  double lag_fraction = std::numeric_limits<double>::quiet_NaN();
  double lag_fraction_uncertainty = 0.0;  // of a known lag_fraction (standard)
  // The panel's column crosstalk c (xgauge characterize): every pixel reads
  // its own signal plus c times its column's mean signal, X = R + c mean_v R.
  // Undone on the dark-subtracted frames (image, flat, previous) before the
  // flat-field correction; needs dark and flat (0: none).
  double column_crosstalk = 0.0;
  // Pixels known to be bad (a characterised detector's map, 1 = bad),
  // repaired like those the dark and flat frames show; null: none.
  const ImageT<uint8_t>* bad_pixels = nullptr;
  // The pair made ready (flatFieldOf), shared by the frames that name it;
  // null: made for this frame.
  const FlatField* flat_field = nullptr;
};

struct NormalizedRadiograph {
  Image image;
  int64_t repaired_pixels = 0;  // bad pixels repaired by the flat-field correction
  double white_mean = 1.0;      // the white region's mean before dividing (1 without one)
  // That mean's relative standard uncertainty: the pixels' standard
  // deviation over the region / sqrt(their count) / the mean (0 without a
  // region). Every pixel of the image is divided by the mean, so its noise is
  // an error common to the whole radiograph (1e-4 over 51 x 51 pixels of 0.5 %
  // noise), which the per-pixel statistics cannot see.
  double white_mean_uncertainty = 0.0;
  // The lag subtracted (frames.previous given): the fraction used, with its
  // standard uncertainty when estimated from the pair (0 when stated).
  std::optional<LagEstimate> lag;
  // When the fraction was estimated: the previous frame as subtracted, per
  // unit fraction (flat-field corrected and divided by the white mean, as
  // `image`), for the budget's component of the estimate's uncertainty.
  Image lag_signal;
};

// Flat-field corrects `raw` with `frames` when given (bad pixels, where
// flat <= dark, are repaired from their neighbours), subtracts the previous
// frame's lag when frames.previous is given (corrected the same way), then
// divides by the mean
// over `white` when given, then applies `clamp`. `name` (the raw image's
// file) names the image in errors. Throws Error naming the image when the
// frames' sizes differ from it, when the white region lies outside it, or
// when the white region's mean is not positive, and when the lag is to be
// estimated but the pair cannot tell it (uncertainty above
// kMaxLagUncertainty: the machine must state it).
NormalizedRadiograph normalizeRadiograph(Image raw, const RadiographFrames& frames,
                                         const std::optional<PixelRect>& white,
                                         ClampPolicy clamp, const std::string& name);

// Undoes column crosstalk c on `frame` against `dark`: with X = R + c m(R),
// m the mean over a column's rows, m(X) = (1 + c) m(R), so
// R = X - c / (1 + c) m(X - dark) (the dark frame carries no signal and
// stays as it is). Exact for that model; the caller checks the sizes.
Image undoColumnCrosstalk(const Image& frame, const Image& dark, double c);

// The same on `frame` itself (no second image of its size).
void undoColumnCrosstalkInPlace(Image& frame, const Image& dark, double c);

// `frames`' dark and flat made ready (FlatField): needs both. Throws Error
// naming the frames when their sizes differ or the flat is not above the
// dark.
FlatField flatFieldOf(const RadiographFrames& frames);

// Thesis eq. 3.9's clamp: every value above 1 becomes 1.
void clampToOne(Image& image);

}  // namespace xgauge
