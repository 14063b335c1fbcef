// Bad pixels, lag and column crosstalk from their shots (characterize.h).
#include "xgauge/characterize/characterize.h"

#include "xgauge/core/error.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

namespace xgauge {

namespace {

double median(std::vector<double> values) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  auto mid = values.begin() + static_cast<ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

// The median of each 32 x 32 block, at every pixel: the neighbourhood a
// pixel is compared with (gain and dark vary smoothly beyond it).
Image blockMedians(const Image& image) {
  constexpr int kBlock = 32;
  Image out(image.width(), image.height());
  for (int y0 = 0; y0 < image.height(); y0 += kBlock)
    for (int x0 = 0; x0 < image.width(); x0 += kBlock) {
      const int x1 = std::min(image.width(), x0 + kBlock),
                y1 = std::min(image.height(), y0 + kBlock);
      std::vector<double> values;
      for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) values.push_back(static_cast<double>(image(x, y)));
      const auto m = static_cast<float>(median(values));
      for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) out(x, y) = m;
    }
  return out;
}

// A robust standard deviation of the pixels' differences from `reference`:
// 1.4826 median absolute deviation.
double robustSigma(const Image& image, const Image& reference) {
  std::vector<double> d;
  for (size_t i = 0; i < image.size(); i += 3)
    d.push_back(std::abs(static_cast<double>(image.pixels()[i]) -
                         static_cast<double>(reference.pixels()[i])));
  return 1.4826 * median(d);
}

}  // namespace

ImageT<uint8_t> BadPixelMap::mask() const {
  ImageT<uint8_t> out(kinds.width(), kinds.height());
  for (size_t i = 0; i < kinds.size(); ++i) out.pixels()[i] = kinds.pixels()[i] != 0;
  return out;
}

BadPixelMap findDetectorBadPixels(const std::vector<Image>& darks, const Image& dark,
                                  const Image& flat) {
  if (dark.width() != flat.width() || dark.height() != flat.height())
    fail("the mean dark is {}x{} but the mean flat {}x{}", dark.width(), dark.height(),
         flat.width(), flat.height());
  BadPixelMap out;
  out.kinds = ImageT<uint8_t>(dark.width(), dark.height(), 0);
  Image response(dark.width(), dark.height());
  for (size_t i = 0; i < dark.size(); ++i)
    response.pixels()[i] = flat.pixels()[i] - dark.pixels()[i];
  // Dead: under half its neighbourhood's response (the gain spreads by
  // about a percent). Hot: a dark more than 20 robust sigmas (column and
  // pixel offsets, read noise) above its neighbourhood's.
  const Image response_ref = blockMedians(response), dark_ref = blockMedians(dark);
  const double dark_sigma = robustSigma(dark, dark_ref);
  // Noisy: a temporal variance a normal pixel reaches with probability 1e-6.
  Image variance(dark.width(), dark.height(), 0.0f);
  if (darks.size() >= 2) {
    for (size_t i = 0; i < dark.size(); ++i) {
      double sum = 0.0, sum2 = 0.0;
      for (const Image& d : darks) {
        const auto v = static_cast<double>(d.pixels()[i]);
        sum += v, sum2 += v * v;
      }
      const double n = static_cast<double>(darks.size()), mean = sum / n;
      variance.pixels()[i] =
          static_cast<float>(std::max(0.0, (sum2 - n * mean * mean) / (n - 1.0)));
    }
  }
  std::vector<double> sample;
  for (size_t i = 0; i < variance.size(); i += 7)
    sample.push_back(static_cast<double>(variance.pixels()[i]));
  // The variance over k = n - 1 degrees of freedom that a normal pixel
  // exceeds with probability 1e-6 (z = 4.75), by Wilson and Hilferty's
  // cube-root normal approximation of chi2_k, the pixels' true variance
  // taken from the median's (chi2_k's median is about k (1 - 2/(9k))^3).
  const double k = std::max(1.0, static_cast<double>(darks.size()) - 1.0), h = 2.0 / (9.0 * k);
  const double noisy_limit =
      median(sample) / std::pow(1.0 - h, 3) * std::pow(1.0 - h + 4.75 * std::sqrt(h), 3);
  for (size_t i = 0; i < dark.size(); ++i) {
    uint8_t kind = 0;
    const double r = static_cast<double>(response.pixels()[i]);
    if (!(r > 0.5 * static_cast<double>(response_ref.pixels()[i]))) kind |= kDeadPixel;
    if (static_cast<double>(dark.pixels()[i] - dark_ref.pixels()[i]) > 20.0 * dark_sigma)
      kind |= kHotPixel;
    if (darks.size() >= 2 && static_cast<double>(variance.pixels()[i]) > noisy_limit)
      kind |= kNoisyPixel;
    out.kinds.pixels()[i] = kind;
    out.dead += (kind & kDeadPixel) != 0, out.hot += (kind & kHotPixel) != 0;
    out.noisy += (kind & kNoisyPixel) != 0;
  }
  return out;
}

Estimate estimateLag(const Image& bright, const Image& after, const Image& dark,
                     const ImageT<uint8_t>& bad) {
  constexpr int kBlocks = 16;
  const int width = dark.width(), height = dark.height();
  std::vector<double> ratios;
  double total_after = 0.0, total_bright = 0.0;
  for (int j = 0; j < kBlocks; ++j)
    for (int i = 0; i < kBlocks; ++i) {
      double a = 0.0, b = 0.0;
      for (int y = j * height / kBlocks; y < (j + 1) * height / kBlocks; ++y)
        for (int x = i * width / kBlocks; x < (i + 1) * width / kBlocks; ++x) {
          if (bad(x, y)) continue;
          a += static_cast<double>(after(x, y) - dark(x, y));
          b += static_cast<double>(bright(x, y) - dark(x, y));
        }
      if (b > 0.0) ratios.push_back(a / b);
      total_after += a, total_bright += b;
    }
  if (!(total_bright > 0.0) || ratios.size() < 4)
    fail(
        "characterize, lag: the bright frame is not brighter than the dark (signal sum {:.4g} ADU)",
        total_bright);
  double mean = 0.0, var = 0.0;
  for (const double r : ratios) mean += r;
  mean /= static_cast<double>(ratios.size());
  for (const double r : ratios) var += (r - mean) * (r - mean);
  var /= static_cast<double>(ratios.size() - 1);
  // A panel without lag reads a ratio scattered about zero; a lag fraction
  // is not negative, so a negative reading is a lag of zero (with the
  // reading's uncertainty), which every reader of the detector file takes.
  return {std::max(0.0, total_after / total_bright),
          std::sqrt(var / static_cast<double>(ratios.size()))};
}

Estimate estimateCrosstalk(const Image& c) {
  const int width = c.width(), height = c.height();
  // The plate's right edge: the column where the upper band (rows 15 to 40
  // %) turns open; its bottom edge: the row where the left band turns open.
  auto bandMean = [&](int x0, int x1, int y0, int y1) {
    double sum = 0.0;
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) sum += static_cast<double>(c(x, y));
    return sum / (static_cast<double>(x1 - x0) * (y1 - y0));
  };
  int edge = -1, bottom = -1;
  for (int x = width / 10; x < width * 9 / 10 && edge < 0; ++x)
    if (bandMean(x, x + 1, height * 15 / 100, height * 40 / 100) > 0.5) edge = x;
  const int left0 = width * 15 / 100, left1 = std::max(left0 + 1, edge - width / 20);
  for (int y = height / 10; y < height * 9 / 10 && bottom < 0 && edge > 0; ++y)
    if (bandMean(left0, left1, y, y + 1) > 0.5) bottom = y;
  if (edge < width / 5 || bottom < height / 5)
    fail(
        "characterize, crosstalk: no covered top-left quadrant found (its right edge at column "
        "{}, bottom at row {}): the shot needs an opaque plate over the top-left quadrant",
        edge, bottom);
  // Column means over all rows (the crosstalk's source), and the open rows'
  // profile below the plate, away from its corner's halo step and the panel.
  const int y0 = bottom + height / 10, y1 = height - height / 50;
  const int half = std::max(8, width / 25);
  const int x0 = std::max(0, edge - half), x1 = std::min(width, edge + half);
  const int n = x1 - x0;
  Eigen::MatrixXd a(n, 4);
  Eigen::VectorXd b(n);
  for (int x = x0; x < x1; ++x) {
    const double t = (x - edge) / static_cast<double>(half);
    double column = 0.0;
    for (int y = 0; y < height; ++y) column += static_cast<double>(c(x, y));
    a.row(x - x0) << 1.0, t, t * t, column / height;
    b(x - x0) = bandMean(x, x + 1, y0, y1);
  }
  // profile = smooth halo (quadratic) + kappa column mean, kappa = c / (1 + c).
  const Eigen::VectorXd p = a.colPivHouseholderQr().solve(b);
  const Eigen::VectorXd r = b - a * p;
  const double s2 = r.squaredNorm() / std::max(1, n - 4);
  const Eigen::MatrixXd cov = s2 * (a.transpose() * a).inverse();
  const double kappa = p(3), u_kappa = std::sqrt(cov(3, 3));
  // A panel without crosstalk reads kappa scattered about zero; c is not
  // negative (the detector file's readers refuse it), so a negative reading
  // is a crosstalk of zero with the reading's uncertainty.
  const double value = std::max(0.0, kappa / (1.0 - kappa));
  return {value, u_kappa / ((1.0 - kappa) * (1.0 - kappa))};
}

}  // namespace xgauge
