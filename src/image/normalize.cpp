#include "xgauge/image/normalize.h"

#include "xgauge/core/error.h"
#include "xgauge/image/stats.h"

#include <algorithm>

namespace xgauge {

Image flatFieldCorrect(const Image& raw, const Image& dark, const Image& flat) {
  if (raw.width() != dark.width() || raw.height() != dark.height() || raw.width() != flat.width() ||
      raw.height() != flat.height())
    fail("flat-field correction needs images of one size: raw {}x{}, dark {}x{}, flat {}x{}",
         raw.width(), raw.height(), dark.width(), dark.height(), flat.width(), flat.height());

  Image corrected(raw.width(), raw.height());
  for (int y = 0; y < raw.height(); ++y) {
    const float* r = raw.row(y);
    const float* d = dark.row(y);
    const float* f = flat.row(y);
    float* out = corrected.row(y);
    for (int x = 0; x < raw.width(); ++x) {
      const double gain = static_cast<double>(f[x]) - static_cast<double>(d[x]);
      if (!(gain > 0.0))
        fail(
            "flat field {} is not above dark field {} at pixel ({}, {}) (dead or saturated "
            "pixel?)",
            f[x], d[x], x, y);
      out[x] = static_cast<float>((static_cast<double>(r[x]) - static_cast<double>(d[x])) / gain);
    }
  }
  return corrected;
}

}  // namespace xgauge
