// Image losses between a simulated and a measured radiograph over a region of
// interest (thesis 3.7, eq. 3.13, docs/method.md: the mean absolute per-pixel
// difference; the caller sums it over radiographs).
//
// Contract shared by every function here:
//   - `measured` is the whole normalized radiograph; `roi` is a rectangle of
//     its pixels and must be non-empty and lie inside it.
//   - `simulated` covers exactly `roi`: its size is roi.width x roi.height and
//     simulated(0, 0) is measured(roi.x, roi.y).
// A violation throws Error naming the rectangle and the sizes.
//
// Sums are accumulated in double over a fixed partition of the roi's rows
// into blocks, one partial sum per block, added in block order: the result
// depends on the pixels only, never on the thread count (oneTBB runs the
// blocks in parallel). A NaN pixel that is used makes the loss NaN.
#pragma once

#include "xgauge/image/image.h"

#include <cstdint>
#include <string_view>

namespace xgauge {

enum class LossKind {
  kMeanAbsolute,  // "l1": mean |s - m| (eq. 3.13)
  kMeanSquared,   // "l2": mean (s - m)^2
};

// "l1" <-> kMeanAbsolute, "l2" <-> kMeanSquared. An unknown name throws Error
// listing the known ones.
LossKind lossKindFromName(std::string_view name);
std::string_view lossKindName(LossKind kind);

// The loss over every pixel of `roi`.
double imageLoss(const Image& simulated, const Image& measured, const PixelRect& roi,
                 LossKind kind);

// The loss over the pixels of `roi` where `use_mask` is non-zero (1 = use the
// pixel). The mask has the size of `measured` and is indexed like it; note
// that findBadPixels (image/bad_pixels.h) marks the pixels to skip with 1,
// the opposite sense. A null mask uses every pixel. Masked-out pixels may
// hold anything, NaN included. Throws Error if the mask's size differs from
// the measured image's or it leaves no pixel of the roi.
double imageLoss(const Image& simulated, const Image& measured, const PixelRect& roi, LossKind kind,
                 const ImageT<uint8_t>* use_mask);

// The signed residual simulated - measured over `roi` (roi.width x
// roi.height, pixel (0, 0) at the roi's top-left corner).
Image differenceImage(const Image& simulated, const Image& measured, const PixelRect& roi);

}  // namespace xgauge
