// What the radiograph readers (TIFF, raw, NXtomo, DICONDE) share: converting
// stored samples to float with the first bad pixel named, averaging repeated
// frames, and the memory limit (tiff.h: tiffMemoryLimit(), --max-image-mb)
// checked before any pixel buffer is allocated. Private to src/image.
#pragma once

#include "xgauge/core/error.h"
#include "xgauge/image/image.h"

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

namespace xgauge::frames {

// "12.5 MiB" or "1088 MiB".
std::string mebibytes(uint64_t bytes);

// The memory a read of `frames` frames of width x height pixels holds at its
// peak: the frame being decoded as floats, with more than one frame also the
// previous one and the running sum in double (FrameMean), plus
// `buffer_bytes` of the reader's own (a strip, a frame of stored samples).
// Saturates instead of overflowing.
uint64_t peakBytes(uint64_t width, uint64_t height, uint64_t frames, uint64_t buffer_bytes);

// Throws (at `where`) when peakBytes() exceeds the memory limit, saying what
// the file declares.
void checkMemory(const SourceLocation& where, uint64_t width, uint64_t height, uint64_t frames,
                 uint64_t buffer_bytes);

// Reverses the bytes of a sample (big-endian files on this little-endian
// machine, and the other way round).
template <typename T>
T byteSwapped(T value) {
  unsigned char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  for (size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(bytes[i], bytes[sizeof(T) - 1 - i]);
  std::memcpy(&value, bytes, sizeof(T));
  return value;
}

// Converts samples to floats, remembering the first pixel (in frame, then
// row-major order) that a radiograph cannot hold: NaN, infinite, or a double
// beyond the float range. `frame_label` (e.g. " of page 3") is appended to
// the pixel's name when the file holds several frames.
template <typename Sample>
struct SampleConverter {
  bool swap_bytes = false;
  std::string frame_label;
  int64_t bad_index = std::numeric_limits<int64_t>::max();
  std::string bad_message;

  void convert(const unsigned char* in, float* out, int count, int x0, int y, int width) {
    for (int i = 0; i < count; ++i) {
      Sample value;
      std::memcpy(&value, in + size_t(i) * sizeof(Sample), sizeof(Sample));
      if (swap_bytes) value = byteSwapped(value);
      if constexpr (std::is_floating_point_v<Sample>) {
        const bool finite = std::isfinite(value);
        bool too_large = false;
        if constexpr (sizeof(Sample) > sizeof(float))
          too_large =
              finite && std::abs(value) > static_cast<Sample>(std::numeric_limits<float>::max());
        if (!finite || too_large) {
          const int64_t index = int64_t{y} * width + x0 + i;
          if (index < bad_index) {
            bad_index = index;
            bad_message =
                finite ? fmt::format("pixel ({}, {}){} = {} is beyond the float range", x0 + i, y,
                                     frame_label, value)
                       : fmt::format("pixel ({}, {}){} is {}: a radiograph must hold finite values",
                                     x0 + i, y, frame_label, value);
          }
        }
      }
      out[i] = static_cast<float>(value);
    }
  }
  // Throws the first bad pixel's message, if any.
  void check(const SourceLocation& where) const {
    if (!bad_message.empty()) failAt(where, "{}", bad_message);
  }
};

// The mean of repeated frames of one size, added one at a time. One frame
// is returned as it was read (bit for bit); several are summed in double
// in the order given and divided once, so the mean does not depend on
// anything but the frames and their order. Memory: from the second frame on
// the running sum (8 bytes a pixel), and while the second is added both
// frames; peakBytes() accounts for it.
class FrameMean {
 public:
  // Takes `frame` (moved from); its size must be the first frame's.
  void add(Image&& frame);
  int count() const { return count_; }
  // The mean; at least one frame must have been added.
  Image take();

 private:
  int count_ = 0;
  Image first_;
  std::vector<double> sum_;
  int width_ = 0, height_ = 0;
};

}  // namespace xgauge::frames
