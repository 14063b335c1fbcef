// Image pyramids for coarse-to-fine fitting. Level 0 is the full image; each
// level halves the previous one. A pixel (x, y) of level l covers the level-0
// pixels [x * 2^l, (x + 1) * 2^l) x [y * 2^l, (y + 1) * 2^l), so continuous
// pixel coordinates scale by exactly 2^-l between levels (pixel edges line up;
// the principal point (cx, cy) of level l is (cx, cy) / 2^l).
#pragma once

#include "xgauge/image/image.h"

#include <vector>

namespace xgauge {

// 2x2 box average: out(x, y) is the mean of in(2x..2x+1, 2y..2y+1). The
// output is floor(width / 2) x floor(height / 2): an odd last column or row is
// dropped rather than averaged over fewer pixels, which keeps the pixel
// footprints of all levels aligned to the top-left corner. An image narrower
// or lower than 2 pixels gives an empty image.
Image downsample2x(const Image& image);

// `levels` images, level 0 = `full` (moved in where the caller no longer
// needs it), level k = downsample2x of level k - 1. Throws Error if `levels`
// < 1 or a level would be empty (the message says which level and the full
// size).
std::vector<Image> buildPyramid(Image full, int levels);

// The pixels of pyramid level `level` (>= 0) fully covered by `rect`, a
// rectangle of level-0 pixels: columns ceil(x / 2^l) to floor(right / 2^l),
// likewise for rows. The result may be empty; it is not clipped to the
// level's image (intersect it with the level's rect()).
PixelRect rectAtLevel(const PixelRect& rect, int level);

}  // namespace xgauge
