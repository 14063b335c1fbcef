#include "xgauge/image/pyramid.h"

#include "xgauge/core/error.h"

#include <algorithm>

namespace xgauge {

Image downsample2x(const Image& image) {
  Image half(image.width() / 2, image.height() / 2);
  for (int y = 0; y < half.height(); ++y) {
    const float* top = image.row(2 * y);
    const float* bottom = image.row(2 * y + 1);
    float* out = half.row(y);
    for (int x = 0; x < half.width(); ++x) {
      const double sum =
          (static_cast<double>(top[2 * x]) + static_cast<double>(top[2 * x + 1])) +
          (static_cast<double>(bottom[2 * x]) + static_cast<double>(bottom[2 * x + 1]));
      out[x] = static_cast<float>(0.25 * sum);
    }
  }
  return half;
}

std::vector<Image> buildPyramid(Image full, int levels) {
  if (levels < 1) fail("an image pyramid needs at least 1 level, not {}", levels);
  const int width = full.width(), height = full.height();
  std::vector<Image> pyramid;
  pyramid.reserve(static_cast<size_t>(levels));
  pyramid.push_back(std::move(full));
  for (int level = 1; level < levels; ++level) {
    Image next = downsample2x(pyramid.back());
    if (next.empty())
      fail("a {}x{} image is too small for {} pyramid levels: level {} would be empty", width,
           height, levels, level);
    pyramid.push_back(std::move(next));
  }
  return pyramid;
}

PixelRect rectAtLevel(const PixelRect& rect, int level) {
  XG_CHECK(level >= 0 && level < 31, "pyramid level {} out of range", level);
  // Floor and ceiling division by 2^level, also for negative coordinates
  // (>> is an arithmetic shift in C++20).
  const auto floor_div = [level](int64_t v) { return v >> level; };
  const auto ceil_div = [level](int64_t v) { return -((-v) >> level); };
  const int64_t x0 = ceil_div(rect.x), x1 = floor_div(int64_t{rect.x} + rect.width);
  const int64_t y0 = ceil_div(rect.y), y1 = floor_div(int64_t{rect.y} + rect.height);
  return {static_cast<int>(x0), static_cast<int>(y0),
          static_cast<int>(std::max<int64_t>(0, x1 - x0)),
          static_cast<int>(std::max<int64_t>(0, y1 - y0))};
}

}  // namespace xgauge
