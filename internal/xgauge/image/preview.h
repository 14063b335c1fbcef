// PNG figures of images for people (reports, debugging): never read back by
// xgauge, so values are quantized to 8 bits. Files are written atomically
// (encoded in memory by stb_image_write, then written with
// writeFileAtomically, which also notices a full disk). Every function throws
// Error naming the file when it cannot be written or the image is empty.
#pragma once

#include "xgauge/image/image.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace xgauge {

// PNG bytes of 8-bit pixels, row-major from the top (`channels`: 1 grey,
// 3 RGB, 4 RGBA), encoded in memory by stb_image_write. Throws Error when
// the sizes do not match or encoding fails.
std::string encodePng(int width, int height, int channels, const std::vector<uint8_t>& pixels);

// Grey level of `value` under a linear window: window_lo -> 0,
// window_hi -> 255, rounded to nearest and clamped; NaN -> 0.
// Requires window_lo < window_hi.
uint8_t greyLevel(double value, double window_lo, double window_hi);

// The default window for writePreviewPng: the 0.5th and 99.5th percentiles of
// the finite pixels (see percentileOf), so that a few hot or dead pixels do
// not wash out the picture. A constant image gets [v - 0.5, v + 0.5] (mid
// grey); an image without finite pixels [0, 1].
struct GreyWindow {
  double lo = 0.0;
  double hi = 1.0;
};
GreyWindow autoWindow(const Image& image);

// 8-bit grey PNG, one PNG pixel per image pixel, mapped by greyLevel.
// Throws Error if the window is not finite with window_lo < window_hi.
void writePreviewPng(const std::filesystem::path& path, const Image& image, double window_lo,
                     double window_hi);
// The same with autoWindow(image).
void writePreviewPng(const std::filesystem::path& path, const Image& image);

// A colour of the diverging map used for signed differences: ColorBrewer's
// 11-class RdBu (Cynthia Brewer, colorbrewer2.org) with its centre class set to
// pure white, interpolated linearly in sRGB. t = -1 is the dark blue end
// (5, 48, 97), 0 white, +1 the dark red end (103, 0, 31); t is clamped to
// [-1, 1]; NaN gives black, which the map never uses.
struct Rgb8 {
  uint8_t r = 0;
  uint8_t g = 0;
  uint8_t b = 0;
  bool operator==(const Rgb8&) const = default;
};
Rgb8 divergingColor(double t);

// The default scale of writeDifferencePng: the largest |value| among the
// finite pixels, or 1 when that is 0 or no pixel is finite.
double defaultDifferenceScale(const Image& signed_difference);

// 8-bit RGB PNG of a signed difference (e.g. measured - simulated): a pixel v
// gets divergingColor(v / scale), so -scale and below is dark blue, 0 white,
// +scale and above dark red. Throws Error unless scale is finite and > 0.
void writeDifferencePng(const std::filesystem::path& path, const Image& signed_difference,
                        double scale);
// The same with defaultDifferenceScale(signed_difference).
void writeDifferencePng(const std::filesystem::path& path, const Image& signed_difference);

}  // namespace xgauge
