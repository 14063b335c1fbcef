#include "xgauge/image/radiograph.h"

#include "xgauge/core/error.h"
#include "xgauge/image/bad_pixels.h"
#include "xgauge/image/stats.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace xgauge {

namespace {

// Subtracts the lag of frames.previous (flat-field corrected as `out` was)
// from out.image, with the stated fraction or one estimated from the pair.
void subtractPreviousLag(NormalizedRadiograph& out, const RadiographFrames& frames,
                         const std::optional<PixelRect>& white, const std::string& name) {
  const std::string previous_name =
      frames.previous_name.empty() ? "the previous frame" : frames.previous_name;
  if (frames.previous->width() != out.image.width() ||
      frames.previous->height() != out.image.height())
    fail("{}: its previous frame {} is {}x{}, it is {}x{}", name, previous_name,
         frames.previous->width(), frames.previous->height(), out.image.width(),
         out.image.height());
  Image previous = *frames.previous;
  if (frames.dark) {
    try {
      FlatField own;
      const FlatField& field = frames.flat_field ? *frames.flat_field : (own = flatFieldOf(frames));
      if (!field.undone_flat.empty()) {
        if (previous.width() != frames.dark->width() || previous.height() != frames.dark->height())
          fail("raw image is {}x{} but dark frame is {}x{}", previous.width(), previous.height(),
               frames.dark->width(), frames.dark->height());
        undoColumnCrosstalkInPlace(previous, *frames.dark, frames.column_crosstalk);
      }
      flatFieldCorrectInPlace(previous, *frames.dark,
                              field.undone_flat.empty() ? *frames.flat : field.undone_flat,
                              field.bad);
    } catch (const Error& e) {
      fail("{} with its dark and flat frames: {}", previous_name, e.message());
    }
  }
  LagEstimate lag;
  if (std::isnan(frames.lag_fraction)) {
    const double open = white ? meanOf(out.image, *white) : percentileOf(out.image, 99.5);
    lag = estimateLag(out.image, previous, open, name);
    if (!(lag.uncertainty <= kMaxLagUncertainty))
      fail("{}: the lag of its previous frame {} cannot be told from the pair (fraction {:.4f}, "
           "standard uncertainty {:.2g} over {} pixels of open beam near the previous frame's "
           "edges, whose band-pass is {:.2f} times its noise there): measure the panel's lag on "
           "its own, with a characterisation's lag pair (xgauge characterize: \"lag\": a bright "
           "frame after a rest and a dark one right after it; the machine's "
           "detector.characterization names the detector file it writes), or state the "
           "machine's detector lag_fraction",
           name, previous_name, lag.fraction, lag.uncertainty, lag.pixels, lag.structure);
  } else {
    lag.fraction = frames.lag_fraction;
    lag.uncertainty = frames.lag_fraction_uncertainty;
    lag.stated = true;
  }
  subtractLag(out.image, previous, lag.fraction);
  out.lag = lag;
  if (lag.uncertainty > 0.0) out.lag_signal = std::move(previous);
}

}  // namespace

NormalizedRadiograph normalizeRadiograph(Image raw, const RadiographFrames& frames,
                                         const std::optional<PixelRect>& white,
                                         ClampPolicy clamp, const std::string& name) {
  XG_CHECK((frames.dark == nullptr) == (frames.flat == nullptr), "give both dark and flat");
  NormalizedRadiograph out;
  out.image = std::move(raw);
  if (frames.dark) {
    try {
      FlatField own;
      const FlatField& field = frames.flat_field ? *frames.flat_field : (own = flatFieldOf(frames));
      if (!field.undone_flat.empty()) {
        if (out.image.width() != frames.dark->width() ||
            out.image.height() != frames.dark->height())
          fail("raw image is {}x{} but dark frame is {}x{}", out.image.width(), out.image.height(),
               frames.dark->width(), frames.dark->height());
        undoColumnCrosstalkInPlace(out.image, *frames.dark, frames.column_crosstalk);
      }
      out.repaired_pixels = flatFieldCorrectInPlace(
          out.image, *frames.dark, field.undone_flat.empty() ? *frames.flat : field.undone_flat,
          field.bad);
    } catch (const Error& e) {
      fail("{} with its dark and flat frames: {}", name, e.message());
    }
  }
  if (white && (white->empty() || !out.image.rect().contains(*white)))
    fail("{}: white region {} is not a non-empty region inside the {}x{} image", name,
         toString(*white), out.image.width(), out.image.height());
  if (frames.previous) subtractPreviousLag(out, frames, white, name);
  if (white) {
    out.white_mean = meanOf(out.image, *white);
    if (!(out.white_mean > 0.0))
      fail("{}: the white region {} has mean {} (must be positive: is it in the open beam?)", name,
           toString(*white), out.white_mean);
    double squares = 0.0;
    for (int v = white->y; v < white->bottom(); ++v)
      for (int u = white->x; u < white->right(); ++u) {
        const double d = static_cast<double>(out.image(u, v)) - out.white_mean;
        squares += d * d;
      }
    const auto n = static_cast<double>(white->area());
    out.white_mean_uncertainty =
        n > 1.0 ? std::sqrt(squares / (n - 1.0) / n) / out.white_mean : 0.0;
    const float scale = static_cast<float>(1.0 / out.white_mean);
    for (float& p : out.image.pixels()) p *= scale;
    for (float& p : out.lag_signal.pixels()) p *= scale;
  }
  if (clamp == ClampPolicy::kAtOne) clampToOne(out.image);
  return out;
}

void undoColumnCrosstalkInPlace(Image& frame, const Image& dark, double c) {
  XG_CHECK(frame.width() == dark.width() && frame.height() == dark.height(),
           "a frame and its dark frame differ in size");
  XG_CHECK(c >= 0.0 && c < 1.0, "column crosstalk out of range");
  const int width = frame.width(), height = frame.height();
  std::vector<double> mean(static_cast<size_t>(width), 0.0);
  for (int v = 0; v < height; ++v)
    for (int u = 0; u < width; ++u)
      mean[static_cast<size_t>(u)] +=
          static_cast<double>(frame(u, v)) - static_cast<double>(dark(u, v));
  const double k = c / (1.0 + c) / height;
  for (int v = 0; v < height; ++v)
    for (int u = 0; u < width; ++u)
      frame(u, v) =
          static_cast<float>(static_cast<double>(frame(u, v)) - k * mean[static_cast<size_t>(u)]);
}

Image undoColumnCrosstalk(const Image& frame, const Image& dark, double c) {
  Image out = frame;
  undoColumnCrosstalkInPlace(out, dark, c);
  return out;
}

FlatField flatFieldOf(const RadiographFrames& frames) {
  XG_CHECK(frames.dark && frames.flat, "a flat field needs dark and flat frames");
  const Image& dark = *frames.dark;
  const Image& flat = *frames.flat;
  FlatField out;
  // The crosstalk is undone where the sizes allow; else the bad-pixel
  // search below names the sizes.
  if (frames.column_crosstalk > 0.0 && flat.width() == dark.width() &&
      flat.height() == dark.height())
    out.undone_flat = undoColumnCrosstalk(flat, dark, frames.column_crosstalk);
  out.bad = badPixelsOf(dark, out.undone_flat.empty() ? flat : out.undone_flat, frames.bad_pixels);
  return out;
}

void clampToOne(Image& image) {
  for (float& p : image.pixels()) p = std::min(p, 1.0f);
}

}  // namespace xgauge
