#include "xgauge/image/preview.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/error.h"
#include "xgauge/image/stats.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

// The encoder's functions stay private to this file (STATIC), so another
// module may include its own copy of stb_image_write without clashing.
#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STB_IMAGE_WRITE_STATIC
// GCC inlines differently with -fPIC (XGAUGE_PYTHON) and then sees stb's
// unchecked realloc in its zlib writer as a potential null dereference.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wnull-dereference"
#include <stb_image_write.h>
#pragma GCC diagnostic pop

namespace xgauge {

std::string encodePng(int width, int height, int channels, const std::vector<uint8_t>& pixels) {
  if (width <= 0 || height <= 0 || (channels != 1 && channels != 3 && channels != 4) ||
      pixels.size() !=
          static_cast<size_t>(width) * static_cast<size_t>(height) * static_cast<size_t>(channels))
    throw Error(fmt::format("cannot encode a {} x {} PNG of {} channels from {} bytes", width,
                            height, channels, pixels.size()));
  std::string png;
  const auto append = [](void* context, void* data, int size) {
    static_cast<std::string*>(context)->append(static_cast<const char*>(data),
                                               static_cast<size_t>(size));
  };
  if (stbi_write_png_to_func(append, &png, width, height, channels, pixels.data(),
                             width * channels) == 0)
    throw Error("cannot encode the PNG image");
  return png;
}

namespace {

// Encodes to memory and writes with writeFileAtomically: stbi_write_png()
// ignores fwrite/fclose failures, so a full disk would go unnoticed.
void writePng(const std::filesystem::path& path, int width, int height, int channels,
              const std::vector<uint8_t>& pixels) {
  std::string png;
  try {
    png = encodePng(width, height, channels, pixels);
  } catch (const Error&) {
    throw Error("cannot encode the PNG image", SourceLocation::inFile(path.string()));
  }
  writeFileAtomically(path, png);
}

void requireNotEmpty(const std::filesystem::path& path, const Image& image) {
  if (image.empty())
    throw Error("cannot write an empty image", SourceLocation::inFile(path.string()));
}

// ColorBrewer RdBu, 11 classes, from the negative (blue) to the positive (red)
// end; the centre class #f7f7f7 is replaced by white so that 0 is white.
constexpr std::array<Rgb8, 11> kRdBu = {{{5, 48, 97},
                                         {33, 102, 172},
                                         {67, 147, 195},
                                         {146, 197, 222},
                                         {209, 229, 240},
                                         {255, 255, 255},
                                         {253, 219, 199},
                                         {244, 165, 130},
                                         {214, 96, 77},
                                         {178, 24, 43},
                                         {103, 0, 31}}};

}  // namespace

uint8_t greyLevel(double value, double window_lo, double window_hi) {
  XG_CHECK(window_lo < window_hi, "empty grey window [{}, {}]", window_lo, window_hi);
  if (std::isnan(value)) return 0;
  const double level = (value - window_lo) / (window_hi - window_lo) * 255.0;
  return static_cast<uint8_t>(std::lround(std::clamp(level, 0.0, 255.0)));
}

GreyWindow autoWindow(const Image& image) {
  if (!finiteRange(image)) return {0.0, 1.0};
  const double lo = percentileOf(image, 0.5);
  const double hi = percentileOf(image, 99.5);
  if (hi > lo) return {lo, hi};
  return {lo - 0.5, lo + 0.5};
}

void writePreviewPng(const std::filesystem::path& path, const Image& image, double window_lo,
                     double window_hi) {
  if (!(std::isfinite(window_lo) && std::isfinite(window_hi) && window_lo < window_hi))
    failAt(SourceLocation::inFile(path.string()),
           "invalid grey window [{}, {}]: needs finite values with lo < hi", window_lo, window_hi);
  requireNotEmpty(path, image);
  std::vector<uint8_t> grey(image.size());
  const auto pixels = image.pixels();
  for (size_t i = 0; i < pixels.size(); ++i)
    grey[i] = greyLevel(static_cast<double>(pixels[i]), window_lo, window_hi);
  writePng(path, image.width(), image.height(), 1, grey);
}

void writePreviewPng(const std::filesystem::path& path, const Image& image) {
  const GreyWindow window = autoWindow(image);
  writePreviewPng(path, image, window.lo, window.hi);
}

Rgb8 divergingColor(double t) {
  if (std::isnan(t)) return {0, 0, 0};
  // Position among the 11 stops: -1 -> 0, 0 -> 5, +1 -> 10.
  const double position = (std::clamp(t, -1.0, 1.0) + 1.0) * 5.0;
  const int i = std::min(static_cast<int>(position), 9);
  const double f = position - i;
  const Rgb8& a = kRdBu[static_cast<size_t>(i)];
  const Rgb8& b = kRdBu[static_cast<size_t>(i) + 1];
  const auto mix = [f](uint8_t from, uint8_t to) {
    return static_cast<uint8_t>(std::lround(from + f * (to - from)));
  };
  return {mix(a.r, b.r), mix(a.g, b.g), mix(a.b, b.b)};
}

double defaultDifferenceScale(const Image& signed_difference) {
  const auto range = finiteRange(signed_difference);
  if (!range) return 1.0;
  const double max_abs = std::max(std::abs(static_cast<double>(range->min)),
                                  std::abs(static_cast<double>(range->max)));
  return max_abs > 0.0 ? max_abs : 1.0;
}

void writeDifferencePng(const std::filesystem::path& path, const Image& signed_difference,
                        double scale) {
  if (!(std::isfinite(scale) && scale > 0.0))
    failAt(SourceLocation::inFile(path.string()),
           "invalid difference scale {}: needs a finite value > 0", scale);
  requireNotEmpty(path, signed_difference);
  std::vector<uint8_t> rgb(3 * signed_difference.size());
  const auto pixels = signed_difference.pixels();
  for (size_t i = 0; i < pixels.size(); ++i) {
    const Rgb8 colour = divergingColor(static_cast<double>(pixels[i]) / scale);
    rgb[3 * i] = colour.r;
    rgb[3 * i + 1] = colour.g;
    rgb[3 * i + 2] = colour.b;
  }
  writePng(path, signed_difference.width(), signed_difference.height(), 3, rgb);
}

void writeDifferencePng(const std::filesystem::path& path, const Image& signed_difference) {
  writeDifferencePng(path, signed_difference, defaultDifferenceScale(signed_difference));
}

}  // namespace xgauge
