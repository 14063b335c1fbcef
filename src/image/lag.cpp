#include "xgauge/image/lag.h"

#include "xgauge/core/error.h"
#include "xgauge/image/blur.h"
#include "xgauge/image/pyramid.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

namespace xgauge {

namespace {

// The band-pass: a difference of Gaussians. The inner 1 px takes the
// pixel noise down; the outer 4 px keeps a shot's edges (1 to 3 px wide
// after the focal spot and the pixel) and removes everything smoother: the
// open level, the scatter's halo, the heel and the gain's slow drift.
constexpr double kInnerSigmaPx = 1.0;
constexpr double kOuterSigmaPx = 4.0;
// The band-pass spreads this shot's own edges by about four outer sigmas:
// that far around its shadow, the current image is not open beam.
constexpr int kMarginPx = 16;
constexpr double kShadowLevel = 0.95;  // of the open level, smoothed over 2 px
constexpr int kTilePx = 16;
constexpr int kEstimateWidthPx = 1024;
constexpr int kMinBinnedHeightPx = 64;

// The previous frame's level for the noise model, smoothed enough that its
// own noise does not matter.
constexpr double kLevelSigmaPx = 3.0;

// What noise alone puts into dc * dp and dp * dp at a pixel, as quadratics
// in the previous frame's level l: photon noise has a variance
// proportional to l, the flat frame's noise (common to both frames, which
// the flat-field correction divides by the same flat) and the gain's to
// l^2, read and dark noise a constant. Fitted over the open beam away from
// the previous frame's edges, where no lag signal is.
struct NoiseModel {
  bool valid = false;
  // The open beam near the previous frame's edges, where its lag shows:
  // the regression's pixels. The rest of the open beam carries no lag
  // signal, only noise (on a 4096^2 panel, 15 million pixels of it, whose
  // products of noise outweighed the edges' signal: 0.0044 +- 0.0017 for
  // a lag of 0.003).
  ImageT<uint8_t> near_edges;
  std::array<double, 3> cross_coef{}, square_coef{};
  double square_sum = 0.0;  // the modelled noise in sum dp^2 over the open beam (0: none)
  double cross(double l) const { return cross_coef[0] + l * (cross_coef[1] + l * cross_coef[2]); }
  double square(double l) const {
    return square_coef[0] + l * (square_coef[1] + l * square_coef[2]);
  }
};

// Solves the 3x3 normal equations of a quadratic fit (Cramer's rule on a
// small, well-scaled system); false when singular.
bool solveQuadratic(const std::array<double, 5>& moments, const std::array<double, 3>& rhs,
                    std::array<double, 3>& coef) {
  const double a[3][3] = {{moments[0], moments[1], moments[2]},
                          {moments[1], moments[2], moments[3]},
                          {moments[2], moments[3], moments[4]}};
  auto det3 = [](const double m[3][3]) {
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
           m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
  };
  const double d = det3(a);
  if (!(std::abs(d) > 1e-12 * moments[0] * moments[2] * moments[4])) return false;
  for (int c = 0; c < 3; ++c) {
    double m[3][3];
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) m[r][k] = k == c ? rhs[static_cast<size_t>(r)] : a[r][k];
    coef[static_cast<size_t>(c)] = det3(m) / d;
  }
  return true;
}

NoiseModel fitNoiseModel(const Image& dc, const Image& dp, const Image& level,
                         const ImageT<uint8_t>& open) {
  const int w = dc.width(), h = dc.height();
  // Where the previous frame has no edge within a few outer sigmas: its
  // smoothed gradient, blurred again, below three times its median over
  // the open beam (the median is noise: edges cover little of it).
  Image edges(w, h, 0.0f);
  for (int y = 1; y < h - 1; ++y)
    for (int x = 1; x < w - 1; ++x) {
      const float gx = level(x + 1, y) - level(x - 1, y);
      const float gy = level(x, y + 1) - level(x, y - 1);
      edges(x, y) = std::sqrt(gx * gx + gy * gy);
    }
  edges = gaussianBlur(std::move(edges), kOuterSigmaPx);
  std::vector<float> values;
  for (int y = 0; y < h; y += 2)
    for (int x = 0; x < w; x += 2)
      if (open(x, y)) values.push_back(edges(x, y));
  NoiseModel model;
  if (values.size() < 64) return model;
  auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  const float quiet = 3.0f * *middle;

  std::array<double, 5> moments{};
  std::array<double, 3> cross_rhs{}, square_rhs{};
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if (!open(x, y) || edges(x, y) > quiet) continue;
      const double l = static_cast<double>(level(x, y));
      const double c = static_cast<double>(dc(x, y)) * static_cast<double>(dp(x, y));
      const double s = static_cast<double>(dp(x, y)) * static_cast<double>(dp(x, y));
      double power = 1.0;
      for (size_t k = 0; k < 5; ++k, power *= l) {
        moments[k] += power;
        if (k < 3) cross_rhs[k] += power * c, square_rhs[k] += power * s;
      }
    }
  if (moments[0] < 64.0) return model;
  // A level that hardly varies over the quiet pixels leaves the quadratic
  // undetermined: fall back to a constant there.
  if (!solveQuadratic(moments, cross_rhs, model.cross_coef) ||
      !solveQuadratic(moments, square_rhs, model.square_coef)) {
    model.cross_coef = {cross_rhs[0] / moments[0], 0.0, 0.0};
    model.square_coef = {square_rhs[0] / moments[0], 0.0, 0.0};
  }
  model.near_edges = ImageT<uint8_t>(w, h, 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      if (open(x, y) && edges(x, y) > quiet) {
        model.near_edges(x, y) = 1;
        model.square_sum += model.square(static_cast<double>(level(x, y)));
      }
  spdlog::debug(
      "lag: noise model over {} pixels without the previous frame's edges (mean level {:.3f}): "
      "dc*dp = {:.3g} + {:.3g} l + {:.3g} l^2, dp^2 = {:.3g} + {:.3g} l + {:.3g} l^2",
      moments[0], moments[1] / moments[0], model.cross_coef[0], model.cross_coef[1],
      model.cross_coef[2], model.square_coef[0], model.square_coef[1], model.square_coef[2]);
  model.valid = true;
  return model;
}

Image bandPass(const Image& image) {
  Image inner = gaussianBlur(image, kInnerSigmaPx);
  const Image outer = gaussianBlur(image, kOuterSigmaPx);
  auto a = inner.pixels();
  auto b = outer.pixels();
  for (size_t k = 0; k < a.size(); ++k) a[k] -= b[k];
  return inner;
}

// 1 where the pixel is this shot's open beam: not within kMarginPx of a
// pixel of its shadow, nor of the image's border.
ImageT<uint8_t> openBeamMask(const Image& current, double open_level) {
  const int w = current.width(), h = current.height();
  const Image smooth = gaussianBlur(current, 2.0);
  const float level = static_cast<float>(kShadowLevel * open_level);
  // Shadow counts summed over (2m+1)^2 boxes through an integral image.
  std::vector<int32_t> integral(static_cast<size_t>(w + 1) * static_cast<size_t>(h + 1), 0);
  auto at = [&](int x, int y) -> int32_t& {
    return integral[static_cast<size_t>(y) * static_cast<size_t>(w + 1) + static_cast<size_t>(x)];
  };
  for (int y = 0; y < h; ++y) {
    int32_t row = 0;
    for (int x = 0; x < w; ++x) {
      row += smooth(x, y) < level ? 1 : 0;
      at(x + 1, y + 1) = at(x + 1, y) + row;
    }
  }
  ImageT<uint8_t> open(w, h, 0);
  for (int y = kMarginPx; y < h - kMarginPx; ++y)
    for (int x = kMarginPx; x < w - kMarginPx; ++x) {
      const int x0 = x - kMarginPx, x1 = x + kMarginPx + 1;
      const int y0 = y - kMarginPx, y1 = y + kMarginPx + 1;
      const int32_t shadow = at(x1, y1) - at(x0, y1) - at(x1, y0) + at(x0, y0);
      open(x, y) = shadow == 0 ? 1 : 0;
    }
  return open;
}

}  // namespace

LagEstimate estimateLag(const Image& current_full, const Image& previous_full, double open_level,
                        const std::string& name) {
  if (current_full.width() != previous_full.width() ||
      current_full.height() != previous_full.height())
    fail("{}: the previous frame is {}x{} but this one is {}x{}", name, previous_full.width(),
         previous_full.height(), current_full.width(), current_full.height());
  if (!(open_level > 0.0) || !std::isfinite(open_level))
    fail("{}: the open beam's level {} is not positive", name, open_level);
  for (const Image* image : {&current_full, &previous_full})
    for (int y = 0; y < image->height(); ++y)
      for (int x = 0; x < image->width(); ++x)
        if (!std::isfinite((*image)(x, y)))
          fail("{}: {} frame has a non-finite value at pixel ({}, {})", name,
               image == &current_full ? "this" : "the previous", x, y);
  // On a panel wider than kEstimateWidthPx, both frames binned 2 x 2 until
  // they are not: the band-pass's scales are in pixels, and on a fine
  // panel's pixels an edge spreads over several while each pixel's noise
  // is larger (on the replica's 4096^2 panel, 0.0044 +- 0.0009 for a lag
  // of 0.003; binned to 1024^2, see method.md).
  Image current = current_full, previous = previous_full;
  while (current.width() > kEstimateWidthPx && current.height() >= 2 * kMinBinnedHeightPx) {
    current = downsample2x(current);
    previous = downsample2x(previous);
  }

  const ImageT<uint8_t> open = openBeamMask(current, open_level);
  const Image dc = bandPass(current);
  const Image dp = bandPass(previous);
  const Image level = gaussianBlur(previous, kLevelSigmaPx);
  const NoiseModel noise = fitNoiseModel(dc, dp, level, open);
  LagEstimate out;
  if (!noise.valid) {
    out.uncertainty = std::numeric_limits<double>::infinity();
    return out;
  }

  // Sums per tile, in a fixed order.
  struct Tile {
    double cross = 0.0, square = 0.0;
    int64_t count = 0;
  };
  const int tiles_x = (dc.width() + kTilePx - 1) / kTilePx;
  const int tiles_y = (dc.height() + kTilePx - 1) / kTilePx;
  std::vector<Tile> tiles(static_cast<size_t>(tiles_x) * static_cast<size_t>(tiles_y));
  for (int y = 0; y < dc.height(); ++y)
    for (int x = 0; x < dc.width(); ++x) {
      if (!noise.near_edges(x, y)) continue;
      Tile& t = tiles[static_cast<size_t>(y / kTilePx) * static_cast<size_t>(tiles_x) +
                      static_cast<size_t>(x / kTilePx)];
      const double p = static_cast<double>(dp(x, y));
      const double l = static_cast<double>(level(x, y));
      t.cross += static_cast<double>(dc(x, y)) * p - noise.cross(l);
      t.square += p * p - noise.square(l);
      ++t.count;
    }
  double cross = 0.0, square = 0.0;
  int64_t count = 0;
  std::vector<const Tile*> used;
  for (const Tile& t : tiles)
    if (t.count > 0) {
      cross += t.cross, square += t.square, count += t.count;
      used.push_back(&t);
    }
  out.pixels = count;
  out.tiles = static_cast<int>(used.size());
  out.structure = noise.square_sum > 0.0 ? 1.0 + square / noise.square_sum
                                         : std::numeric_limits<double>::infinity();
  auto slope = [&](double c, double s) {
    return s > 0.0 ? c / s : std::numeric_limits<double>::quiet_NaN();
  };
  out.fraction = slope(cross, square);
  spdlog::debug(
      "lag: {} pixels near the previous frame's edges in {} tiles, sum dc*dp {:.4g}, sum dp^2 "
      "{:.4g} (noise taken off)",
      count, used.size(), cross, square);
  if (!std::isfinite(out.fraction) || used.size() < 2) {
    out.fraction = 0.0;
    out.uncertainty = std::numeric_limits<double>::infinity();
    return out;
  }
  // Jackknife over tiles: the band-passed noise is correlated over a few
  // pixels and its variance differs between open beam and the previous
  // shot's shadow, which a formula for white noise would both miss.
  std::vector<double> leave_one_out;
  leave_one_out.reserve(used.size());
  for (const Tile* t : used) {
    const double g = slope(cross - t->cross, square - t->square);
    if (!std::isfinite(g)) {
      out.uncertainty = std::numeric_limits<double>::infinity();
      return out;
    }
    leave_one_out.push_back(g);
  }
  double mean = 0.0;
  for (double g : leave_one_out) mean += g;
  mean /= static_cast<double>(leave_one_out.size());
  double spread = 0.0;
  for (double g : leave_one_out) spread += (g - mean) * (g - mean);
  const double t = static_cast<double>(leave_one_out.size());
  out.uncertainty = std::sqrt((t - 1.0) / t * spread);
  return out;
}

std::string describeLag(const LagEstimate& lag) {
  if (!lag.stated)
    return fmt::format(
        "fraction {:.5f} +- {:.5f} (estimated over {} pixels of open beam near "
        "the previous frame's edges)",
        lag.fraction, lag.uncertainty, lag.pixels);
  return fmt::format("fraction {:.5f} +- {:.2g} (the machine's)", lag.fraction, lag.uncertainty);
}

void subtractLag(Image& current, const Image& previous, double fraction) {
  XG_CHECK(current.width() == previous.width() && current.height() == previous.height(),
           "lag: the frames differ in size");
  auto c = current.pixels();
  auto p = previous.pixels();
  const float g = static_cast<float>(fraction);
  for (size_t k = 0; k < c.size(); ++k) c[k] -= g * p[k];
}

}  // namespace xgauge
