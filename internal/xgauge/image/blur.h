// Gaussian blur with mirror boundaries, fast for any width, and the fused
// blur-and-mix that the scintillator scatter (image/scatter.h) is built on.
#pragma once

#include "xgauge/image/image.h"

namespace xgauge {

// What a blur sees beyond the image's edges: the image mirrored (below), or
// zeros. A zero border blurs (image - outside) to take the world beyond a
// detector as a constant level (the open beam, image/scatter.h).
enum class BlurBorder { kMirror, kZero };

// Gaussian blur with standard deviation `sigma_px` (pixels, >= 0; 0 returns a
// copy) and half-sample-symmetric mirror boundaries (the image reflected about
// its outer pixel edges, and again as often as a wide kernel needs).
//
// Kernel: the sampled Gaussian exp(-k^2 / (2 sigma^2)) for |k| <= ceil(4.5
// sigma), divided by its sum, applied along rows and then columns.
//
// Sigma below 16 px: that separable convolution exactly (float arithmetic).
// Larger sigma: the image is box-averaged in f x f blocks (f the largest power
// of two with sigma / f >= 8), the small image blurred by the sampled
// Gaussian with sigma_small = sqrt(sigma^2 - (f^2 - 1) / 12 - f^2 / 6) / f
// (the box and the bilinear interpolation back add (f^2 - 1) / 12 and, on
// average, f^2 / 6 to the variance, so the kernel's variance stays sigma^2),
// and interpolated bilinearly back to full size (pixel centres aligned). The
// kernel shape then differs from the Gaussian by up to 3e-4 of the image's
// range; cost is two passes over the image whatever sigma is (4096 x 4096
// with sigma 500 px: 10 ms on 2 cores in place, see below).
//
// The image sum is preserved (to float rounding, about 1e-7 relative) and a
// constant image stays constant. The mirror convolution with a normalised
// symmetric kernel keeps the sum exactly; so does the large-sigma path when f
// divides width and height (block means, bilinear weights that give every
// block f^2 pixels' worth). Where it does not, the blocks at the right and
// bottom edge reach past the image and are filled by mirroring, and the sum
// is restored by adding the difference to the blurred image in proportion to
// its magnitude: a scale factor for an image >= 0, off 1 by a few 1e-5 for a
// random 4000 x 3000 image (sigma 500 px, f = 32).
//
// The image is taken by value: pass an rvalue (std::move) and the large-sigma
// path blurs in place, sparing the allocation of a new image (for 4096 x 4096,
// 64 MiB of fresh pages cost more than the blur itself: 30 ms against 10).
//
// Throws Error if sigma_px is negative or not finite.
// With BlurBorder::kZero the samples beyond the image are zeros instead (the
// large-sigma path then pads its edge blocks with zeros and does not restore
// the sum: what spreads past the edge is lost).
Image gaussianBlur(Image image, double sigma_px, BlurBorder border = BlurBorder::kMirror);

// gaussianBlur of an image that equals `outside` wherever it is not some
// feature (the background of a render, or zero around a derivative image):
// outside + G(image - outside), the sum taken over the bounding box of the
// pixels that differ from `outside` alone, with the direct path's taps folded
// by the mirror. Its cost scales with that box's width times the image's
// rather than the image's area times the kernel's width: the model's scatter
// estimates blur a 128 px render of the whole detector with a kernel wider
// than the part's shadow (measured: a fifth of the direct convolution's
// time there). Equal to gaussianBlur within float rounding (a few 1e-7) where
// gaussianBlur takes its direct path (sigma below 16 px), which it is for
// larger sigma. With BlurBorder::kZero the world beyond the image is
// `outside` too (outside + G(image - outside) with zero padding), the open
// beam beyond a panel. Throws Error as gaussianBlur.
Image gaussianBlurAround(const Image& image, double sigma_px, float outside,
                         BlurBorder border = BlurBorder::kMirror);

// weight * G(image, sigma_px) + (1 - weight) * image, fused so that a large
// blur works in place; ScatterModel::apply is the scatter built on it (the
// blurred part lowers the bright side of every edge and raises the dark side,
// the edge itself stays sharp). Preserves the image sum.
// Throws Error if weight is outside [0, 1] or sigma_px as gaussianBlur.
Image scatterBlur(Image image, double weight, double sigma_px);

}  // namespace xgauge
