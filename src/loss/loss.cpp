#include "xgauge/loss/loss.h"

#include "xgauge/core/error.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace xgauge {

namespace {

// About this many pixels per block: enough work per task, and enough blocks
// to share among threads. Depends on the roi's width only, so the partition
// (and hence the rounding) is the same at any thread count.
constexpr int64_t kPixelsPerBlock = 32768;
// Below this many pixels the blocks run on the calling thread (same sums).
constexpr int64_t kParallelMinPixels = 4 * kPixelsPerBlock;

void checkRoi(const Image& simulated, const Image& measured, const PixelRect& roi) {
  if (roi.empty()) fail("the region of interest {} is empty", toString(roi));
  if (!measured.rect().contains(roi))
    fail("the region of interest {} is not inside the {}x{} measured radiograph", toString(roi),
         measured.width(), measured.height());
  if (simulated.width() != roi.width || simulated.height() != roi.height)
    fail("the simulated image is {}x{} but the region of interest {} is {}x{}", simulated.width(),
         simulated.height(), toString(roi), roi.width, roi.height);
}

template <LossKind kind>
inline double pixelLoss(float simulated, float measured) {
  const double d = static_cast<double>(simulated) - static_cast<double>(measured);
  if constexpr (kind == LossKind::kMeanAbsolute)
    return std::abs(d);
  else
    return d * d;
}

struct Partial {
  double sum = 0.0;
  int64_t count = 0;
};

// The loss summed over one row: eight interleaved lanes (so the compiler can
// vectorize), combined in a fixed order at the end. `use` is null or the
// mask's row, aligned with `measured`.
template <LossKind kind>
Partial rowLoss(const float* simulated, const float* measured, const uint8_t* use, int width) {
  constexpr int kLanes = 8;
  double lanes[kLanes] = {};
  Partial row;
  int x = 0;
  if (use == nullptr) {
    for (; x + kLanes <= width; x += kLanes)
      for (int j = 0; j < kLanes; ++j)
        lanes[j] += pixelLoss<kind>(simulated[x + j], measured[x + j]);
    for (; x < width; ++x) row.sum += pixelLoss<kind>(simulated[x], measured[x]);
    row.count = width;
  } else {
    // A select, not a multiplication: masked-out pixels may be NaN.
    for (; x + kLanes <= width; x += kLanes)
      for (int j = 0; j < kLanes; ++j) {
        const double value = pixelLoss<kind>(simulated[x + j], measured[x + j]);
        lanes[j] += use[x + j] != 0 ? value : 0.0;
        row.count += use[x + j] != 0;
      }
    for (; x < width; ++x)
      if (use[x] != 0) {
        row.sum += pixelLoss<kind>(simulated[x], measured[x]);
        ++row.count;
      }
  }
  for (int j = 0; j < kLanes; ++j) row.sum += lanes[j];
  return row;
}

template <LossKind kind>
Partial lossSum(const Image& simulated, const Image& measured, const PixelRect& roi,
                const ImageT<uint8_t>* use_mask) {
  const int rows_per_block = static_cast<int>(std::max<int64_t>(1, kPixelsPerBlock / roi.width));
  const int blocks = (roi.height + rows_per_block - 1) / rows_per_block;
  std::vector<Partial> partials(static_cast<size_t>(blocks));

  auto runBlocks = [&](int first, int last) {
    for (int b = first; b < last; ++b) {
      Partial block;
      const int y_end = std::min(roi.height, (b + 1) * rows_per_block);
      for (int y = b * rows_per_block; y < y_end; ++y) {
        const uint8_t* use = use_mask ? use_mask->row(roi.y + y) + roi.x : nullptr;
        const Partial row =
            rowLoss<kind>(simulated.row(y), measured.row(roi.y + y) + roi.x, use, roi.width);
        block.sum += row.sum;
        block.count += row.count;
      }
      partials[static_cast<size_t>(b)] = block;
    }
  };
  if (roi.area() < kParallelMinPixels) {
    runBlocks(0, blocks);
  } else {
    tbb::parallel_for(tbb::blocked_range<int>(0, blocks),
                      [&](const tbb::blocked_range<int>& r) { runBlocks(r.begin(), r.end()); });
  }

  // Block order, whatever order the blocks ran in.
  Partial total;
  for (const Partial& block : partials) {
    total.sum += block.sum;
    total.count += block.count;
  }
  return total;
}

}  // namespace

LossKind lossKindFromName(std::string_view name) {
  if (name == "l1") return LossKind::kMeanAbsolute;
  if (name == "l2") return LossKind::kMeanSquared;
  fail("unknown loss '{}' (known: l1, l2)", name);
}

std::string_view lossKindName(LossKind kind) {
  switch (kind) {
    case LossKind::kMeanAbsolute:
      return "l1";
    case LossKind::kMeanSquared:
      return "l2";
  }
  XG_CHECK(false, "unknown LossKind {}", static_cast<int>(kind));
  return {};
}

double imageLoss(const Image& simulated, const Image& measured, const PixelRect& roi,
                 LossKind kind) {
  return imageLoss(simulated, measured, roi, kind, nullptr);
}

double imageLoss(const Image& simulated, const Image& measured, const PixelRect& roi, LossKind kind,
                 const ImageT<uint8_t>* use_mask) {
  checkRoi(simulated, measured, roi);
  if (use_mask &&
      (use_mask->width() != measured.width() || use_mask->height() != measured.height()))
    fail("the pixel mask is {}x{} but the measured radiograph is {}x{}", use_mask->width(),
         use_mask->height(), measured.width(), measured.height());

  Partial total;
  switch (kind) {
    case LossKind::kMeanAbsolute:
      total = lossSum<LossKind::kMeanAbsolute>(simulated, measured, roi, use_mask);
      break;
    case LossKind::kMeanSquared:
      total = lossSum<LossKind::kMeanSquared>(simulated, measured, roi, use_mask);
      break;
    default:
      XG_CHECK(false, "unknown LossKind {}", static_cast<int>(kind));
  }
  if (total.count == 0)
    fail("the pixel mask leaves no pixel of the region of interest {}", toString(roi));
  return total.sum / static_cast<double>(total.count);
}

Image differenceImage(const Image& simulated, const Image& measured, const PixelRect& roi) {
  checkRoi(simulated, measured, roi);
  Image difference(roi.width, roi.height);
  tbb::parallel_for(0, roi.height, [&](int y) {
    const float* s = simulated.row(y);
    const float* m = measured.row(roi.y + y) + roi.x;
    float* d = difference.row(y);
    for (int x = 0; x < roi.width; ++x) d[x] = s[x] - m[x];
  });
  return difference;
}

}  // namespace xgauge
