// Sums, means and order statistics of image pixels. Sums accumulate in double
// in row-major order, so results do not depend on anything but the pixels.
#pragma once

#include "xgauge/image/image.h"

#include <optional>

namespace xgauge {

// Sum of all pixels (0 for an empty image).
double sumOf(const Image& image);
// Sum over `rect` (0 for an empty rect). Throws Error if a non-empty `rect`
// does not lie inside the image (naming the rectangle and the image size).
double sumOf(const Image& image, const PixelRect& rect);

// Mean of all pixels; throws Error for an empty image.
double meanOf(const Image& image);
// Mean over `rect`; throws Error if `rect` is empty or not inside the image.
double meanOf(const Image& image, const PixelRect& rect);

// Smallest and largest finite pixel value; nullopt when no pixel is finite.
struct ValueRange {
  float min = 0.0f;
  float max = 0.0f;
};
std::optional<ValueRange> finiteRange(const Image& image);

// The `percent` percentile (0..100) of the finite pixels, interpolating
// linearly between neighbouring order statistics (position
// percent / 100 * (n - 1) in the sorted values: NumPy's default "linear"
// method). 0 gives the minimum, 100 the maximum. Throws Error if `percent` is
// outside [0, 100] or no pixel is finite.
double percentileOf(const Image& image, double percent);

// The noise of one pixel of a normalized image over `region`, from the
// differences of horizontal neighbours (a smooth trend such as the heel
// effect cancels): sigma = 1.4826 median |d| / sqrt(2); 0 for a region
// without two pixels side by side.
double neighbourNoise(const Image& image, const PixelRect& region);

}  // namespace xgauge
