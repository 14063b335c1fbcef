#include "xgauge/image/bad_pixels.h"

#include "xgauge/core/error.h"
#include "xgauge/image/stats.h"

#include <cmath>
#include <vector>

namespace xgauge {

namespace {
void requireSameSize(const Image& a, const char* a_name, const Image& b, const char* b_name) {
  if (a.width() != b.width() || a.height() != b.height())
    fail("{} is {}x{} but {} is {}x{}", a_name, a.width(), a.height(), b_name, b.width(), b.height());
}

// (raw - dark) / (flat - dark) into `out` (which may be `raw` itself), 0
// where the pixel is bad.
void correctInto(const Image& raw, const Image& dark, const Image& flat, const ImageT<uint8_t>& bad,
                 Image& out) {
  for (size_t i = 0; i < raw.size(); ++i) {
    const double d = static_cast<double>(dark.pixels()[i]);
    out.pixels()[i] =
        bad.pixels()[i] ? 0.0f
                        : static_cast<float>((static_cast<double>(raw.pixels()[i]) - d) /
                                             (static_cast<double>(flat.pixels()[i]) - d));
  }
}
}  // namespace

ImageT<uint8_t> findBadPixels(const Image& dark, const Image& flat, double min_fraction) {
  requireSameSize(flat, "flat frame", dark, "dark frame");
  Image gain(flat.width(), flat.height());
  for (size_t i = 0; i < gain.size(); ++i) gain.pixels()[i] = flat.pixels()[i] - dark.pixels()[i];
  const double median = percentileOf(gain, 50.0);
  if (!(median > 0.0)) fail("flat frame is not above dark frame (median difference {})", median);
  const double threshold = min_fraction * median;
  ImageT<uint8_t> bad(flat.width(), flat.height(), 0);
  for (size_t i = 0; i < gain.size(); ++i) {
    const double g = static_cast<double>(gain.pixels()[i]);
    bad.pixels()[i] = !std::isfinite(g) || g <= threshold ? 1 : 0;
  }
  return bad;
}

int64_t repairBadPixels(Image& image, const ImageT<uint8_t>& mask) {
  if (image.width() != mask.width() || image.height() != mask.height())
    fail("bad-pixel mask is {}x{} but the image is {}x{}", mask.width(), mask.height(),
         image.width(), image.height());
  ImageT<uint8_t> pending = mask;
  int64_t total = 0;
  for (size_t i = 0; i < pending.size(); ++i) total += pending.pixels()[i] != 0;
  if (total == static_cast<int64_t>(pending.size()) && total > 0)
    fail("every pixel is bad: nothing to repair from");
  // Each pass fills the pending pixels that touch a good one, so a cluster
  // shrinks from its rim inwards.
  int64_t left = total;
  std::vector<std::pair<int, int>> filled;
  while (left > 0) {
    filled.clear();
    for (int y = 0; y < image.height(); ++y)
      for (int x = 0; x < image.width(); ++x) {
        if (!pending(x, y)) continue;
        double sum = 0.0;
        int count = 0;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int u = x + dx, v = y + dy;
            if ((dx || dy) && u >= 0 && v >= 0 && u < image.width() && v < image.height() &&
                !pending(u, v)) {
              sum += static_cast<double>(image(u, v));
              ++count;
            }
          }
        if (count > 0) {
          image(x, y) = static_cast<float>(sum / count);
          filled.emplace_back(x, y);
        }
      }
    for (const auto& [x, y] : filled) pending(x, y) = 0;
    left -= static_cast<int64_t>(filled.size());
  }
  return total;
}

ImageT<uint8_t> badPixelsOf(const Image& dark, const Image& flat, const ImageT<uint8_t>* known) {
  ImageT<uint8_t> bad = findBadPixels(dark, flat);
  if (known) {
    if (known->width() != bad.width() || known->height() != bad.height())
      fail("the detector's bad-pixel map is {}x{}, the image {}x{}", known->width(),
           known->height(), bad.width(), bad.height());
    for (size_t i = 0; i < bad.size(); ++i) bad.pixels()[i] |= known->pixels()[i];
  }
  return bad;
}

int64_t flatFieldCorrectInPlace(Image& frame, const Image& dark, const Image& flat,
                                const ImageT<uint8_t>& bad) {
  requireSameSize(frame, "raw image", dark, "dark frame");
  XG_CHECK(bad.width() == frame.width() && bad.height() == frame.height() &&
               flat.width() == frame.width() && flat.height() == frame.height(),
           "a bad-pixel mask or flat frame of another size than the image");
  correctInto(frame, dark, flat, bad, frame);
  return repairBadPixels(frame, bad);
}

Image flatFieldCorrectRepairing(const Image& raw, const Image& dark, const Image& flat,
                                int64_t* repaired, const ImageT<uint8_t>* known) {
  requireSameSize(raw, "raw image", dark, "dark frame");
  const ImageT<uint8_t> bad = badPixelsOf(dark, flat, known);
  Image corrected(raw.width(), raw.height());
  correctInto(raw, dark, flat, bad, corrected);
  const int64_t count = repairBadPixels(corrected, bad);
  if (repaired) *repaired = count;
  return corrected;
}

}  // namespace xgauge
