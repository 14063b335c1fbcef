// A single-channel image with row-major storage, and rectangles of pixels.
//
// Pixel (x, y) = (column u, row v), row 0 at the top as images are stored
// (docs/conventions.md). The pixel centre of (u, v) sits at continuous coordinate
// (u + 0.5, v + 0.5).
#pragma once

#include "xgauge/core/error.h"

#include <algorithm>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace xgauge {

// A rectangle of pixels: columns [x, x + width), rows [y, y + height).
struct PixelRect {
  int x = 0;
  int y = 0;
  int width = 0;
  int height = 0;

  bool empty() const { return width <= 0 || height <= 0; }
  int64_t area() const { return empty() ? 0 : int64_t{width} * height; }
  int right() const { return x + width; }    // one past the last column
  int bottom() const { return y + height; }  // one past the last row
  bool contains(const PixelRect& other) const {
    return other.x >= x && other.y >= y && other.right() <= right() &&
           other.bottom() <= bottom();
  }
  PixelRect intersect(const PixelRect& other) const {
    const int x0 = std::max(x, other.x), y0 = std::max(y, other.y);
    const int x1 = std::min(right(), other.right()), y1 = std::min(bottom(), other.bottom());
    return {x0, y0, std::max(0, x1 - x0), std::max(0, y1 - y0)};
  }
  bool operator==(const PixelRect&) const = default;
};

// "{x=10, y=20, width=30, height=40}", the key names a config file uses; for
// error messages.
inline std::string toString(const PixelRect& r) {
  return fmt::format("{{x={}, y={}, width={}, height={}}}", r.x, r.y, r.width, r.height);
}

template <typename T>
class ImageT {
 public:
  ImageT() = default;
  ImageT(int width, int height, T fill = T{}) { resize(width, height, fill); }

  void resize(int width, int height, T fill = T{}) {
    XG_CHECK(width >= 0 && height >= 0, "negative image size {}x{}", width, height);
    width_ = width;
    height_ = height;
    pixels_.assign(static_cast<size_t>(width) * static_cast<size_t>(height), fill);
  }

  int width() const { return width_; }
  int height() const { return height_; }
  PixelRect rect() const { return {0, 0, width_, height_}; }
  bool empty() const { return pixels_.empty(); }
  size_t size() const { return pixels_.size(); }

  T& operator()(int x, int y) { return pixels_[index(x, y)]; }
  const T& operator()(int x, int y) const { return pixels_[index(x, y)]; }
  T* row(int y) { return pixels_.data() + index(0, y); }
  const T* row(int y) const { return pixels_.data() + index(0, y); }
  std::span<T> pixels() { return pixels_; }
  std::span<const T> pixels() const { return pixels_; }
  void fill(T value) { std::fill(pixels_.begin(), pixels_.end(), value); }

  // A copy of a rectangle, which must lie inside the image.
  ImageT crop(const PixelRect& r) const {
    XG_CHECK(rect().contains(r), "crop rectangle outside the image");
    ImageT out(r.width, r.height);
    for (int y = 0; y < r.height; ++y)
      std::copy_n(row(r.y + y) + r.x, r.width, out.row(y));
    return out;
  }

 private:
  size_t index(int x, int y) const {
    return static_cast<size_t>(y) * static_cast<size_t>(width_) + static_cast<size_t>(x);
  }

  int width_ = 0;
  int height_ = 0;
  std::vector<T> pixels_;
};

using Image = ImageT<float>;

}  // namespace xgauge
