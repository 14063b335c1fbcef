#include "frames.h"

#include "xgauge/image/tiff.h"

#include <algorithm>

namespace xgauge::frames {

std::string mebibytes(uint64_t bytes) {
  const double mib = static_cast<double>(bytes) / (1024.0 * 1024.0);
  return mib < 10.0 ? fmt::format("{:.1f} MiB", mib) : fmt::format("{:.0f} MiB", mib);
}

namespace {

uint64_t saturatingMultiply(uint64_t a, uint64_t b) {
  if (a != 0 && b > std::numeric_limits<uint64_t>::max() / a)
    return std::numeric_limits<uint64_t>::max();
  return a * b;
}

uint64_t saturatingAdd(uint64_t a, uint64_t b) {
  return b > std::numeric_limits<uint64_t>::max() - a ? std::numeric_limits<uint64_t>::max()
                                                      : a + b;
}

}  // namespace

uint64_t peakBytes(uint64_t width, uint64_t height, uint64_t frames, uint64_t buffer_bytes) {
  const uint64_t pixels = saturatingMultiply(width, height);
  // One frame as floats; several: two frames and the sum in double.
  const uint64_t per_pixel = frames > 1 ? 2 * sizeof(float) + sizeof(double) : sizeof(float);
  return saturatingAdd(saturatingMultiply(pixels, per_pixel), buffer_bytes);
}

void checkMemory(const SourceLocation& where, uint64_t width, uint64_t height, uint64_t frames,
                 uint64_t buffer_bytes) {
  const uint64_t limit = tiffMemoryLimit();
  const uint64_t need = peakBytes(width, height, frames, buffer_bytes);
  if (need <= limit) return;
  if (frames > 1)
    failAt(where,
           "the file declares {} frames of {}x{} pixels: averaging them needs {}, more than the "
           "limit of {} (--max-image-mb)",
           frames, width, height, mebibytes(need), mebibytes(limit));
  failAt(where,
         "the file declares {}x{} pixels: reading them needs {}, more than the limit of {} "
         "(--max-image-mb)",
         width, height, mebibytes(need), mebibytes(limit));
}

void FrameMean::add(Image&& frame) {
  XG_CHECK(!frame.empty(), "an empty frame");
  if (count_ == 0) {
    first_ = std::move(frame);
    width_ = first_.width(), height_ = first_.height();
    count_ = 1;
    return;
  }
  XG_CHECK(frame.width() == width_ && frame.height() == height_, "frames of different sizes");
  if (count_ == 1) {
    sum_.assign(first_.pixels().begin(), first_.pixels().end());
    first_ = Image();
  }
  const auto pixels = frame.pixels();
  for (size_t i = 0; i < sum_.size(); ++i) sum_[i] += static_cast<double>(pixels[i]);
  ++count_;
  frame = Image();
}

Image FrameMean::take() {
  XG_CHECK(count_ > 0, "no frame added");
  if (count_ == 1) return std::move(first_);
  Image mean(width_, height_);
  const double n = static_cast<double>(count_);
  const auto pixels = mean.pixels();
  for (size_t i = 0; i < sum_.size(); ++i) pixels[i] = static_cast<float>(sum_[i] / n);
  sum_ = std::vector<double>();
  return mean;
}

}  // namespace xgauge::frames
