#include "xgauge/image/stats.h"

#include "xgauge/core/error.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace xgauge {

double sumOf(const Image& image) {
  double sum = 0.0;
  for (const float value : image.pixels()) sum += static_cast<double>(value);
  return sum;
}

double sumOf(const Image& image, const PixelRect& rect) {
  if (rect.empty()) return 0.0;
  if (!image.rect().contains(rect))
    fail("rectangle {} is not inside the {}x{} image", toString(rect), image.width(),
         image.height());
  double sum = 0.0;
  for (int y = rect.y; y < rect.bottom(); ++y) {
    const float* row = image.row(y);
    for (int x = rect.x; x < rect.right(); ++x) sum += static_cast<double>(row[x]);
  }
  return sum;
}

double meanOf(const Image& image) {
  if (image.empty()) fail("the mean of an empty image is undefined");
  return sumOf(image) / static_cast<double>(image.size());
}

double meanOf(const Image& image, const PixelRect& rect) {
  if (rect.empty())
    fail("rectangle {} is empty (in a {}x{} image)", toString(rect), image.width(), image.height());
  return sumOf(image, rect) / static_cast<double>(rect.area());
}

std::optional<ValueRange> finiteRange(const Image& image) {
  std::optional<ValueRange> range;
  for (const float value : image.pixels()) {
    if (!std::isfinite(value)) continue;
    if (!range) {
      range = ValueRange{value, value};
    } else {
      range->min = std::min(range->min, value);
      range->max = std::max(range->max, value);
    }
  }
  return range;
}

double percentileOf(const Image& image, double percent) {
  if (!(percent >= 0.0 && percent <= 100.0)) fail("percentile {} is outside [0, 100]", percent);
  std::vector<float> values;
  values.reserve(image.size());
  for (const float value : image.pixels())
    if (std::isfinite(value)) values.push_back(value);
  if (values.empty())
    fail("no finite pixel values in a {}x{} image", image.width(), image.height());

  // Order statistics k and k + 1 around position percent / 100 * (n - 1).
  const double position = percent / 100.0 * static_cast<double>(values.size() - 1);
  const auto k = std::min(static_cast<size_t>(position), values.size() - 1);
  const double fraction = position - static_cast<double>(k);
  const auto kth = values.begin() + static_cast<std::ptrdiff_t>(k);
  std::nth_element(values.begin(), kth, values.end());
  const auto lower = static_cast<double>(*kth);
  if (fraction == 0.0 || k + 1 == values.size()) return lower;
  // After nth_element everything behind kth is >= it: the next order
  // statistic is the smallest of those.
  const auto upper = static_cast<double>(*std::min_element(kth + 1, values.end()));
  return lower + fraction * (upper - lower);
}

double neighbourNoise(const Image& image, const PixelRect& region) {
  std::vector<double> d;
  for (int y = region.y; y < region.bottom(); ++y)
    for (int x = region.x; x + 1 < region.right(); ++x)
      d.push_back(
          std::abs(static_cast<double>(image(x + 1, y)) - static_cast<double>(image(x, y))));
  if (d.empty()) return 0.0;
  const auto middle = d.begin() + static_cast<ptrdiff_t>(d.size() / 2);
  std::nth_element(d.begin(), middle, d.end());
  return 1.4826 * *middle / std::sqrt(2.0);
}

}  // namespace xgauge
