#include "xgauge/image/blur.h"

#include "xgauge/image/stats.h"

#include "xgauge/core/error.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <span>
#include <vector>

namespace xgauge {

namespace {

using Rows = tbb::blocked_range<int>;

// ---------------------------------------------------------------------------
// Gaussian blur
// ---------------------------------------------------------------------------

// Half-sample-symmetric reflection of index i into [0, n): the signal
// mirrored about its outer pixel edges, periodic with period 2n, so a kernel
// wider than the image folds back as often as it needs.
int reflect(int64_t i, int n) {
  const int64_t period = 2 * int64_t{n};
  int64_t r = i % period;
  if (r < 0) r += period;
  return static_cast<int>(r < n ? r : period - 1 - r);
}

// The sampled Gaussian of the header: exp(-k^2 / (2 sigma^2)), |k| <=
// ceil(4.5 sigma), divided by its sum (truncation loses 7e-6 of the mass
// before the division).
std::vector<double> gaussianTaps(double sigma) {
  const int radius = static_cast<int>(std::ceil(4.5 * sigma));
  std::vector<double> taps(2 * static_cast<size_t>(radius) + 1);
  double sum = 0.0;
  for (int k = -radius; k <= radius; ++k) {
    const double z = k / sigma;
    taps[static_cast<size_t>(k + radius)] = std::exp(-0.5 * z * z);
    sum += taps[static_cast<size_t>(k + radius)];
  }
  for (double& tap : taps) tap /= sum;
  return taps;
}

// Float taps whose sum is 1 to float precision: rounding each tap on its own
// leaves the sum off by up to ~1e-7, a systematic gain in every output pixel,
// so the centre tap takes up the difference.
std::vector<float> floatTaps(const std::vector<double>& taps) {
  std::vector<float> out(taps.begin(), taps.end());
  double sum = 0.0;
  for (const float tap : out) sum += static_cast<double>(tap);
  float& centre = out[out.size() / 2];
  centre = static_cast<float>(static_cast<double>(centre) + (1.0 - sum));
  return out;
}

// reflect(i, n) for i in [-radius, n + radius), at i + radius: computed once
// per pass (a 64-bit division per tap and row cost as much as the taps'
// arithmetic on the 128 px scatter renders, whose kernels are wider than
// they are).
// With a zero border, -1 marks an index outside [0, n) (a zero sample).
std::vector<int> reflectedIndices(int n, int radius, BlurBorder border = BlurBorder::kMirror) {
  std::vector<int> out(static_cast<size_t>(n) + 2 * static_cast<size_t>(radius));
  for (int i = -radius; i < n + radius; ++i)
    out[static_cast<size_t>(i + radius)] =
        border == BlurBorder::kMirror ? reflect(i, n) : (i >= 0 && i < n ? i : -1);
  return out;
}

// out(x, y) = sum_k taps[k] in(x, reflect(y + k)), symmetric taps of odd size.
// Column strips keep the 2 * radius + 1 input rows of a strip in cache.
template <typename T>
void convolveColumns(const ImageT<T>& in, ImageT<T>& out, std::span<const T> taps,
                     BlurBorder border = BlurBorder::kMirror) {
  const int width = in.width(), height = in.height();
  const int radius = static_cast<int>(taps.size() / 2);
  const std::vector<int> reflected = reflectedIndices(height, radius, border);
  const std::vector<T> zeros(static_cast<size_t>(width), T{0});
  const auto row = [&](int y) {
    const int j = reflected[static_cast<size_t>(y + radius)];
    return j < 0 ? zeros.data() : in.row(j);
  };
  constexpr int kStrip = 512;
  tbb::parallel_for(Rows(0, height, 16), [&](const Rows& rows) {
    for (int x0 = 0; x0 < width; x0 += kStrip) {
      const int x1 = std::min(width, x0 + kStrip);
      for (int y = rows.begin(); y < rows.end(); ++y) {
        T* o = out.row(y);
        const T* centre = in.row(y);
        const T tap0 = taps[static_cast<size_t>(radius)];
        for (int x = x0; x < x1; ++x) o[x] = tap0 * centre[x];
        for (int k = 1; k <= radius; ++k) {
          const T* above = row(y - k);
          const T* below = row(y + k);
          const T tap = taps[static_cast<size_t>(radius + k)];
          for (int x = x0; x < x1; ++x) o[x] += tap * (above[x] + below[x]);
        }
      }
    }
  });
}

// out(x, y) = mix_blur * sum_k taps[k] in(reflect(x + k), y) + mix_original *
// original(x, y). `original` is read only when mix_original != 0.
template <typename T>
void convolveRows(const ImageT<T>& in, ImageT<T>& out, std::span<const T> taps, T mix_blur,
                  T mix_original, const ImageT<T>& original,
                  BlurBorder border = BlurBorder::kMirror) {
  const int width = in.width(), height = in.height();
  const int radius = static_cast<int>(taps.size() / 2);
  const std::vector<int> reflected = reflectedIndices(width, radius, border);
  tbb::parallel_for(Rows(0, height, 8), [&](const Rows& rows) {
    std::vector<T> padded(static_cast<size_t>(width) + 2 * static_cast<size_t>(radius));
    for (int y = rows.begin(); y < rows.end(); ++y) {
      const T* src = in.row(y);
      for (size_t i = 0; i < padded.size(); ++i)
        padded[i] = reflected[i] < 0 ? T{0} : src[reflected[i]];
      T* centre = padded.data() + radius;
      T* o = out.row(y);
      const T tap0 = taps[static_cast<size_t>(radius)];
      for (int x = 0; x < width; ++x) o[x] = tap0 * centre[x];
      for (int k = 1; k <= radius; ++k) {
        const T tap = taps[static_cast<size_t>(radius + k)];
        for (int x = 0; x < width; ++x) o[x] += tap * (centre[x - k] + centre[x + k]);
      }
      if (mix_original != T{0}) {
        const T* orig = original.row(y);
        for (int x = 0; x < width; ++x) o[x] = mix_blur * o[x] + mix_original * orig[x];
      } else if (mix_blur != T{1}) {
        for (int x = 0; x < width; ++x) o[x] *= mix_blur;
      }
    }
  });
}

// weight * G(image) + (1 - weight) * image by the direct separable
// convolution.
Image blurDirect(const Image& image, double sigma_px, double weight, BlurBorder border) {
  const std::vector<float> taps = floatTaps(gaussianTaps(sigma_px));
  Image columns(image.width(), image.height());
  convolveColumns<float>(image, columns, taps, border);
  Image out(image.width(), image.height());
  convolveRows<float>(columns, out, taps, static_cast<float>(weight),
                      static_cast<float>(1.0 - weight), image, border);
  return out;
}

// Linear interpolation from a grid of n samples, sample i at full-resolution
// continuous coordinate (i + 0.5) * f, to full-resolution pixel centres
// x + 0.5, constant beyond the first and last sample. Pixel x lies between
// samples i = floor(u) and i + 1 with u = (x + 0.5) / f - 0.5 (exact for a
// power of two f). Calls visit(i, weight) for both samples.
// With `extrapolate` (a zero border, whose blur falls steeply towards the
// edge) the line through the first or last two samples continues instead.
template <typename Visit>
void interpolationWeights(int x, int n, int f, Visit&& visit, bool extrapolate = false) {
  const double u = (x + 0.5) / f - 0.5;
  if (extrapolate && n >= 2 && (u < 0.0 || u > n - 1)) {
    const int i = u < 0.0 ? 0 : n - 2;
    const double t = u - i;
    visit(i, 1.0 - t);
    visit(i + 1, t);
  } else if (u <= 0.0) {
    visit(0, 1.0);
  } else if (u >= n - 1) {
    visit(n - 1, 1.0);
  } else {
    const int i = static_cast<int>(u);
    const double t = u - i;
    visit(i, 1.0 - t);
    visit(i + 1, t);
  }
}

// Sum over the `length` full-resolution pixels of each sample's weight.
std::vector<double> interpolationMass(int length, int n, int f) {
  std::vector<double> mass(static_cast<size_t>(n), 0.0);
  for (int x = 0; x < length; ++x)
    interpolationWeights(x, n, f, [&](int i, double w) { mass[static_cast<size_t>(i)] += w; });
  return mass;
}

// weight * G(image) + (1 - weight) * image through an f-times smaller image:
// block means -> Gaussian of about sigma_px / f -> bilinear interpolation back
// (header of gaussianBlur). Works in place: `image` becomes the result.
// With a zero border the blocks past the image hold zeros, the small image is
// blurred with zero padding and the sum is not restored (what leaves the
// image is lost, as it should be).
Image blurReduced(Image image, double sigma_px, int f, double weight, BlurBorder border) {
  const bool mirror = border == BlurBorder::kMirror;
  const int width = image.width(), height = image.height();
  const int nx = (width + f - 1) / f, ny = (height + f - 1) / f;
  const double f2 = static_cast<double>(f) * f;

  // Block means in double, of the mirror-extended image where a block at the
  // right or bottom edge reaches past it. Also the image sum, per block row.
  ImageT<double> means(nx, ny);
  std::vector<double> block_row_sums(static_cast<size_t>(ny));
  tbb::parallel_for(Rows(0, ny), [&](const Rows& block_rows) {
    std::vector<double> columns(static_cast<size_t>(width));
    for (int j = block_rows.begin(); j < block_rows.end(); ++j) {
      std::fill(columns.begin(), columns.end(), 0.0);
      for (int y = j * f; y < (j + 1) * f; ++y) {
        if (y == height) {
          double sum = 0.0;
          for (const double c : columns) sum += c;
          block_row_sums[static_cast<size_t>(j)] = sum;
        }
        if (!mirror && y >= height) continue;
        const float* row = image.row(reflect(y, height));
        for (int x = 0; x < width; ++x)
          columns[static_cast<size_t>(x)] += static_cast<double>(row[x]);
      }
      if ((j + 1) * f <= height) {
        double sum = 0.0;
        for (const double c : columns) sum += c;
        block_row_sums[static_cast<size_t>(j)] = sum;
      }
      for (int i = 0; i < nx; ++i) {
        double sum = 0.0;
        if ((i + 1) * f <= width) {
          for (int x = i * f; x < (i + 1) * f; ++x) sum += columns[static_cast<size_t>(x)];
        } else {
          for (int x = i * f; x < (i + 1) * f; ++x)
            if (mirror || x < width) sum += columns[static_cast<size_t>(reflect(x, width))];
        }
        means(i, j) = sum / f2;
      }
    }
  });
  double image_sum = 0.0;
  for (const double s : block_row_sums) image_sum += s;

  // Blur the means; the box and the interpolation widen the kernel by
  // (f^2 - 1) / 12 + f^2 / 6 of variance (full pixels^2), taken off here.
  const double sigma_small = std::sqrt(sigma_px * sigma_px - (f2 - 1.0) / 12.0 - f2 / 6.0) / f;
  const std::vector<double> taps = gaussianTaps(sigma_small);
  ImageT<double> columns(nx, ny), blurred(nx, ny);
  convolveColumns<double>(means, columns, taps, border);
  convolveRows<double>(columns, blurred, taps, 1.0, 0.0, columns, border);

  // Keep the sum. The interpolation gives sample (i, j) the total weight
  // mass_x[i] * mass_y[j] over the image, which is f^2 for every sample when
  // f divides both sides: then the blurred sum equals the image sum already.
  // Otherwise (partial blocks at the edges) add the difference in proportion
  // to |blurred|: for an image >= 0 a scale factor, typically 1 +- 1e-5.
  const std::vector<double> mass_x = interpolationMass(width, nx, f);
  const std::vector<double> mass_y = interpolationMass(height, ny, f);
  double blurred_sum = 0.0, blurred_abs_sum = 0.0;
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const double mass = mass_x[static_cast<size_t>(i)] * mass_y[static_cast<size_t>(j)];
      blurred_sum += blurred(i, j) * mass;
      blurred_abs_sum += std::abs(blurred(i, j)) * mass;
    }
  }
  const double correction =
      mirror && blurred_abs_sum > 0.0 ? (image_sum - blurred_sum) / blurred_abs_sum : 0.0;
  Image density(nx, ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i)
      density(i, j) =
          static_cast<float>(weight * (blurred(i, j) + correction * std::abs(blurred(i, j))));

  // Interpolate back to full size. Between samples i and i + 1 lie the f
  // pixels i * f + f / 2 + m, m = 0..f-1, with weight t_m = (m + 0.5) / f on
  // sample i + 1 (the same t as interpolationWeights, exactly).
  std::vector<float> t(static_cast<size_t>(f));
  for (int m = 0; m < f; ++m) t[static_cast<size_t>(m)] = static_cast<float>((m + 0.5) / f);
  const float keep = static_cast<float>(1.0 - weight);
  tbb::parallel_for(Rows(0, height, 8), [&](const Rows& rows) {
    std::vector<float> line(static_cast<size_t>(nx)), blurred_row(static_cast<size_t>(width));
    for (int y = rows.begin(); y < rows.end(); ++y) {
      // Vertical interpolation of the sample rows into `line`.
      std::fill(line.begin(), line.end(), 0.0f);
      interpolationWeights(
          y, ny, f,
          [&](int j, double w) {
            const float wf = static_cast<float>(w);
            const float* sample_row = density.row(j);
            for (int i = 0; i < nx; ++i) line[static_cast<size_t>(i)] += wf * sample_row[i];
          },
          !mirror);
      // Horizontal interpolation: constant before the first and after the
      // last sample, linear between.
      float* b = blurred_row.data();
      const int lead = std::min(width, f / 2);
      for (int i = 0; i + 1 < nx; ++i) {
        const int x0 = i * f + f / 2;
        const int count = std::min(f, width - x0);
        const float left = line[static_cast<size_t>(i)], right = line[static_cast<size_t>(i) + 1];
        for (int m = 0; m < count; ++m)
          b[x0 + m] = (1.0f - t[static_cast<size_t>(m)]) * left + t[static_cast<size_t>(m)] * right;
      }
      if (mirror || nx < 2) {
        for (int x = 0; x < lead; ++x) b[x] = line[0];
        for (int x = std::max(lead, (nx - 1) * f + f / 2); x < width; ++x)
          b[x] = line[static_cast<size_t>(nx) - 1];
      } else {
        for (int x = 0; x < width; ++x) {
          const double u = (x + 0.5) / f - 0.5;
          if (u >= 0.0 && u <= nx - 1) continue;
          b[x] = 0.0f;
          interpolationWeights(
              x, nx, f,
              [&](int i, double w) {
                b[x] += static_cast<float>(w) * line[static_cast<size_t>(i)];
              },
              true);
        }
      }
      // Mix with the original row, which this overwrites.
      float* o = image.row(y);
      for (int x = 0; x < width; ++x) o[x] = b[x] + keep * o[x];
    }
  });
  return image;
}

Image blurMix(Image image, double sigma_px, double weight,
              BlurBorder border = BlurBorder::kMirror) {
  if (!std::isfinite(sigma_px) || sigma_px < 0.0)
    fail("Gaussian blur sigma must be finite and >= 0 px, got {}", sigma_px);
  if (!(weight >= 0.0 && weight <= 1.0)) fail("scatter weight must be in [0, 1], got {}", weight);
  if (sigma_px == 0.0 || weight == 0.0 || image.empty()) return image;
  // Reduce by the largest power of two that leaves >= 8 px of sigma.
  int f = 1;
  while (sigma_px / (2.0 * f) >= 8.0 && f < (1 << 20)) f *= 2;
  return f == 1 ? blurDirect(image, sigma_px, weight, border)
                : blurReduced(std::move(image), sigma_px, f, weight, border);
}

}  // namespace

Image gaussianBlur(Image image, double sigma_px, BlurBorder border) {
  return blurMix(std::move(image), sigma_px, 1.0, border);
}

Image gaussianBlurAround(const Image& image, double sigma_px, float outside, BlurBorder border) {
  if (!std::isfinite(sigma_px) || sigma_px < 0.0)
    fail("Gaussian blur sigma must be finite and >= 0 px, got {}", sigma_px);
  const int width = image.width(), height = image.height();
  // The support: the bounding box of the pixels that are not `outside`.
  int x0 = width, x1 = -1, y0 = height, y1 = -1;
  for (int y = 0; y < height; ++y) {
    const float* row = image.row(y);
    for (int x = 0; x < width; ++x)
      if (row[x] != outside)
        x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
  }
  if (x1 < 0 || sigma_px == 0.0) return image;  // constant: its blur is itself
  int f = 1;
  while (sigma_px / (2.0 * f) >= 8.0 && f < (1 << 20)) f *= 2;
  if (f > 1 && border == BlurBorder::kMirror) return gaussianBlur(image, sigma_px);
  if (f > 1) {
    Image shifted = image;
    for (float& value : shifted.pixels()) value -= outside;
    shifted = gaussianBlur(std::move(shifted), sigma_px, BlurBorder::kZero);
    for (float& value : shifted.pixels()) value += outside;
    return shifted;
  }
  // The direct path's taps folded by the mirror onto the support's rows and
  // columns: w(y, j) = sum of taps[k] over the k with reflect(y + k) = j.
  const std::vector<float> taps = floatTaps(gaussianTaps(sigma_px));
  const int radius = static_cast<int>(taps.size() / 2);
  const auto folded = [&](int n, int first, int last) {
    Eigen::MatrixXd w = Eigen::MatrixXd::Zero(n, last - first + 1);
    const std::vector<int> reflected = reflectedIndices(n, radius, border);
    for (int y = 0; y < n; ++y)
      for (int k = -radius; k <= radius; ++k) {
        const int j = reflected[static_cast<size_t>(y + k + radius)];
        if (j < 0) continue;
        if (j >= first && j <= last)
          w(y, j - first) += static_cast<double>(taps[static_cast<size_t>(k + radius)]);
      }
    return w;
  };
  const Eigen::MatrixXd wy = folded(height, y0, y1), wx = folded(width, x0, x1);
  Eigen::MatrixXd d(y1 - y0 + 1, x1 - x0 + 1);
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x)
      d(y - y0, x - x0) = static_cast<double>(image(x, y)) - static_cast<double>(outside);
  const Eigen::MatrixXd blurred = (wy * d) * wx.transpose();
  Image out(width, height);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      out(x, y) = static_cast<float>(static_cast<double>(outside) + blurred(y, x));
  return out;
}

Image scatterBlur(Image image, double weight, double sigma_px) {
  return blurMix(std::move(image), sigma_px, weight);
}

}  // namespace xgauge
