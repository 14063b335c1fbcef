#include "xgauge/lab/detector.h"

#include "xgauge/lab/random.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <random>
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

// out(x, y) = sum_k taps[k] in(x, reflect(y + k)), symmetric taps of odd size.
// Column strips keep the 2 * radius + 1 input rows of a strip in cache.
template <typename T>
void convolveColumns(const ImageT<T>& in, ImageT<T>& out, std::span<const T> taps) {
  const int width = in.width(), height = in.height();
  const int radius = static_cast<int>(taps.size() / 2);
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
          const T* above = in.row(reflect(y - k, height));
          const T* below = in.row(reflect(y + k, height));
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
                  T mix_original, const ImageT<T>& original) {
  const int width = in.width(), height = in.height();
  const int radius = static_cast<int>(taps.size() / 2);
  tbb::parallel_for(Rows(0, height, 8), [&](const Rows& rows) {
    std::vector<T> padded(static_cast<size_t>(width) + 2 * static_cast<size_t>(radius));
    for (int y = rows.begin(); y < rows.end(); ++y) {
      const T* src = in.row(y);
      T* centre = padded.data() + radius;
      std::copy_n(src, width, centre);
      for (int k = 1; k <= radius; ++k) {
        centre[-k] = src[reflect(-k, width)];
        centre[width - 1 + k] = src[reflect(width - 1 + k, width)];
      }
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
Image blurDirect(const Image& image, double sigma_px, double weight) {
  const std::vector<float> taps = floatTaps(gaussianTaps(sigma_px));
  Image columns(image.width(), image.height());
  convolveColumns<float>(image, columns, taps);
  Image out(image.width(), image.height());
  convolveRows<float>(columns, out, taps, static_cast<float>(weight),
                      static_cast<float>(1.0 - weight), image);
  return out;
}

// Linear interpolation from a grid of n samples, sample i at full-resolution
// continuous coordinate (i + 0.5) * f, to full-resolution pixel centres
// x + 0.5, constant beyond the first and last sample. Pixel x lies between
// samples i = floor(u) and i + 1 with u = (x + 0.5) / f - 0.5 (exact for a
// power of two f). Calls visit(i, weight) for both samples.
template <typename Visit>
void interpolationWeights(int x, int n, int f, Visit&& visit) {
  const double u = (x + 0.5) / f - 0.5;
  if (u <= 0.0) {
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
Image blurReduced(Image image, double sigma_px, int f, double weight) {
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
            sum += columns[static_cast<size_t>(reflect(x, width))];
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
  convolveColumns<double>(means, columns, taps);
  convolveRows<double>(columns, blurred, taps, 1.0, 0.0, columns);

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
      blurred_abs_sum > 0.0 ? (image_sum - blurred_sum) / blurred_abs_sum : 0.0;
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
      interpolationWeights(y, ny, f, [&](int j, double w) {
        const float wf = static_cast<float>(w);
        const float* sample_row = density.row(j);
        for (int i = 0; i < nx; ++i) line[static_cast<size_t>(i)] += wf * sample_row[i];
      });
      // Horizontal interpolation: constant before the first and after the
      // last sample, linear between.
      float* b = blurred_row.data();
      const int lead = std::min(width, f / 2);
      for (int x = 0; x < lead; ++x) b[x] = line[0];
      for (int i = 0; i + 1 < nx; ++i) {
        const int x0 = i * f + f / 2;
        const int count = std::min(f, width - x0);
        const float left = line[static_cast<size_t>(i)], right = line[static_cast<size_t>(i) + 1];
        for (int m = 0; m < count; ++m)
          b[x0 + m] = (1.0f - t[static_cast<size_t>(m)]) * left + t[static_cast<size_t>(m)] * right;
      }
      for (int x = std::max(lead, (nx - 1) * f + f / 2); x < width; ++x)
        b[x] = line[static_cast<size_t>(nx) - 1];
      // Mix with the original row, which this overwrites.
      float* o = image.row(y);
      for (int x = 0; x < width; ++x) o[x] = b[x] + keep * o[x];
    }
  });
  return image;
}

Image blurMix(Image image, double sigma_px, double weight) {
  if (!std::isfinite(sigma_px) || sigma_px < 0.0)
    fail("Gaussian blur sigma must be finite and >= 0 px, got {}", sigma_px);
  if (!(weight >= 0.0 && weight <= 1.0)) fail("scatter weight must be in [0, 1], got {}", weight);
  if (sigma_px == 0.0 || weight == 0.0 || image.empty()) return image;
  // Reduce by the largest power of two that leaves >= 8 px of sigma.
  int f = 1;
  while (sigma_px / (2.0 * f) >= 8.0 && f < (1 << 20)) f *= 2;
  return f == 1 ? blurDirect(image, sigma_px, weight)
                : blurReduced(std::move(image), sigma_px, f, weight);
}

// ---------------------------------------------------------------------------
// Detector
// ---------------------------------------------------------------------------

// Stream purposes (lab/random.h): the first id of every stream.
enum Purpose : uint64_t {
  kGainPixel = 1,
  kGainSmooth,
  kColumnOffset,
  kDarkPixel,
  kDeadPixel,
  kExposurePhotons,
  kExposureRead,
  kDarkPhotons,  // never drawn from (no beam), kept apart all the same
  kDarkRead,
  kFlatPhotons,
  kFlatRead,
};

// Smooth random field, mean 0 and standard deviation 1 over the image: white
// noise on a grid of spacing `length_px` (node i at i * length_px - length_px,
// so the grid covers the image with one node to spare on each side), blurred
// by one grid step and interpolated bilinearly.
Image smoothField(int width, int height, double length_px, uint64_t seed) {
  const int nx = static_cast<int>(std::ceil(width / length_px)) + 2;
  const int ny = static_cast<int>(std::ceil(height / length_px)) + 2;
  Image grid(nx, ny);
  tbb::parallel_for(0, ny, [&](int j) {
    SplitMix64 rng = SplitMix64::stream(seed, kGainSmooth, j);
    std::normal_distribution<double> normal;
    for (int i = 0; i < nx; ++i) grid(i, j) = static_cast<float>(normal(rng));
  });
  grid = gaussianBlur(std::move(grid), 1.0);

  const auto coordinate = [length_px](int x, int n) {
    const double u = std::clamp((x + 0.5) / length_px + 1.0, 0.0, n - 1.0);
    const int i = std::min(static_cast<int>(u), n - 2);
    return std::pair{i, u - i};
  };
  Image field(width, height);
  std::vector<double> row_sums(static_cast<size_t>(height));
  tbb::parallel_for(0, height, [&](int y) {
    const auto [j, ty] = coordinate(y, ny);
    double sum = 0.0;
    float* o = field.row(y);
    for (int x = 0; x < width; ++x) {
      const auto [i, tx] = coordinate(x, nx);
      const auto at = [&](int a, int b) { return static_cast<double>(grid(a, b)); };
      const double top = (1.0 - tx) * at(i, j) + tx * at(i + 1, j);
      const double bottom = (1.0 - tx) * at(i, j + 1) + tx * at(i + 1, j + 1);
      const double value = (1.0 - ty) * top + ty * bottom;
      o[x] = static_cast<float>(value);
      sum += value;
    }
    row_sums[static_cast<size_t>(y)] = sum;
  });

  // Standardise (sums in row order, so independent of the thread count).
  double sum = 0.0;
  for (const double s : row_sums) sum += s;
  const double mean = sum / static_cast<double>(field.size());
  tbb::parallel_for(0, height, [&](int y) {
    double squares = 0.0;
    for (const float value : std::span(field.row(y), static_cast<size_t>(width))) {
      const double d = static_cast<double>(value) - mean;
      squares += d * d;
    }
    row_sums[static_cast<size_t>(y)] = squares;
  });
  double squares = 0.0;
  for (const double s : row_sums) squares += s;
  const double sigma = std::sqrt(squares / static_cast<double>(field.size()));
  const double scale = sigma > 0.0 ? 1.0 / sigma : 0.0;
  tbb::parallel_for(0, height, [&](int y) {
    for (float& value : std::span(field.row(y), static_cast<size_t>(width)))
      value = static_cast<float>((static_cast<double>(value) - mean) * scale);
  });
  return field;
}

void checkSize(const char* what, const Image& image, const DetectorPattern& pattern) {
  if (image.width() != pattern.width() || image.height() != pattern.height())
    fail("{} is {}x{} but the detector pattern is {}x{}", what, image.width(), image.height(),
         pattern.width(), pattern.height());
}

// What a frame sees: an image of intensities, or one value everywhere.
struct Illumination {
  const Image* intensity = nullptr;  // null: `uniform` at every pixel
  double uniform = 0.0;
  const Image* previous = nullptr;  // lag signal, may be null
};

// Intensities above this (1 = open beam) are surely a mistake, and would let
// the photon counts overflow.
constexpr double kMaxIntensity = 1e6;
constexpr int kMaxFrames = 1000000;

struct FrameStreams {
  uint64_t photons;
  uint64_t read;
  uint64_t index;
};

// The mean of `frames` frames, drawn from its exact distribution (header of
// darkFrame). Writes the noise-free signal when `signal` is not null. Throws
// naming the first negative or non-finite intensity or lag value.
Image simulateFrames(const Illumination& light, const DetectorPattern& pattern,
                     const DetectorNoiseModel& model, uint64_t seed, FrameStreams streams,
                     int frames, Image* signal) {
  model.validate();
  if (frames < 1 || frames > kMaxFrames)
    fail("frames to average must be 1 to {}, got {}", kMaxFrames, frames);
  const int width = pattern.width(), height = pattern.height();
  if (width < 1 || height < 1 || pattern.dark_adu.width() != width ||
      pattern.dark_adu.height() != height || pattern.dead.width() != width ||
      pattern.dead.height() != height)
    fail("the detector pattern is empty or its maps differ in size");
  if (light.intensity) checkSize("the intensity image", *light.intensity, pattern);
  if (light.previous) checkSize("the previous exposure's signal", *light.previous, pattern);
  if (signal) signal->resize(width, height);

  const double photons = frames * model.photons_per_open_pixel;
  const double adu_per_frame_photon = model.adu_per_photon / frames;
  const double read_sigma = model.read_noise_adu / std::sqrt(static_cast<double>(frames));
  const bool round = model.quantize_16bit && frames == 1;
  using Poisson = std::poisson_distribution<int64_t>;

  Image raw(width, height);
  std::vector<int> first_bad(static_cast<size_t>(height), -1);
  tbb::parallel_for(Rows(0, height, 4), [&](const Rows& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      SplitMix64 photon_rng = SplitMix64::stream(seed, streams.photons, streams.index, y);
      SplitMix64 read_rng = SplitMix64::stream(seed, streams.read, streams.index, y);
      Poisson poisson;
      // Flat areas repeat the mean, and setting up its parameters (lgamma,
      // logs, exps) costs about as much as a draw.
      Poisson::param_type param(1.0);
      double param_mean = 1.0;
      std::normal_distribution<double> normal;

      const float* intensity = light.intensity ? light.intensity->row(y) : nullptr;
      const float* previous = light.previous ? light.previous->row(y) : nullptr;
      const float* gain = pattern.gain.row(y);
      const float* dark = pattern.dark_adu.row(y);
      const uint8_t* dead = pattern.dead.row(y);
      float* out = raw.row(y);
      float* expected = signal ? signal->row(y) : nullptr;
      for (int x = 0; x < width; ++x) {
        const double in = intensity ? static_cast<double>(intensity[x]) : light.uniform;
        const double lag = previous ? static_cast<double>(previous[x]) : 0.0;
        if (!(in >= 0.0 && in <= kMaxIntensity && lag >= 0.0 && lag <= kMaxIntensity)) {
          first_bad[static_cast<size_t>(y)] = x;
          break;
        }
        const double s = in + model.ghost_fraction * lag;
        if (expected) expected[x] = static_cast<float>(s);

        // Detected quanta, summed over the frames.
        const double mean = photons * s;
        double quanta = mean;
        if (model.photon_noise && mean > 0.0) {
          if (mean != param_mean) {
            param = Poisson::param_type(mean);
            param_mean = mean;
          }
          quanta = static_cast<double>(poisson(photon_rng, param));
        }
        double value = static_cast<double>(dark[x]) +
                       static_cast<double>(gain[x]) * adu_per_frame_photon * quanta;
        if (read_sigma > 0.0) value += read_sigma * normal(read_rng);
        if (dead[x]) value = static_cast<double>(dark[x]);
        if (model.quantize_16bit) {
          value = std::clamp(value, 0.0, 65535.0);
          if (round) value = std::round(value);
        }
        out[x] = static_cast<float>(value);
      }
    }
  });
  for (int y = 0; y < height; ++y) {
    const int x = first_bad[static_cast<size_t>(y)];
    if (x < 0) continue;
    const double in =
        light.intensity ? static_cast<double>((*light.intensity)(x, y)) : light.uniform;
    if (!(in >= 0.0 && in <= kMaxIntensity))
      fail("intensity {} at pixel ({}, {}) is outside [0, {}]", in, x, y, kMaxIntensity);
    fail("previous exposure's signal {} at pixel ({}, {}) is outside [0, {}]",
         (*light.previous)(x, y), x, y, kMaxIntensity);
  }
  return raw;
}

// The keys of DetectorNoiseModel and their ranges, for fromConfig, toJson and
// validate.
struct NumberField {
  const char* key;
  double DetectorNoiseModel::*field;
  double min, max;
};
constexpr NumberField kNumberFields[] = {
    {"photons_per_open_pixel", &DetectorNoiseModel::photons_per_open_pixel, 1e-6, 1e9},
    {"adu_per_photon", &DetectorNoiseModel::adu_per_photon, 1e-9, 1e6},
    {"read_noise_adu", &DetectorNoiseModel::read_noise_adu, 0.0, 1e5},
    {"dark_level_adu", &DetectorNoiseModel::dark_level_adu, 0.0, 65535.0},
    {"dark_pixel_sigma_adu", &DetectorNoiseModel::dark_pixel_sigma_adu, 0.0, 1e5},
    {"column_offset_sigma_adu", &DetectorNoiseModel::column_offset_sigma_adu, 0.0, 1e5},
    {"gain_pixel_sigma", &DetectorNoiseModel::gain_pixel_sigma, 0.0, 0.5},
    {"gain_smooth_sigma", &DetectorNoiseModel::gain_smooth_sigma, 0.0, 0.5},
    {"gain_smooth_length_px", &DetectorNoiseModel::gain_smooth_length_px, 1.0, 1e6},
    {"dead_pixel_fraction", &DetectorNoiseModel::dead_pixel_fraction, 0.0, 1.0},
    {"ghost_fraction", &DetectorNoiseModel::ghost_fraction, 0.0, 0.99},
};
struct FlagField {
  const char* key;
  bool DetectorNoiseModel::*field;
};
constexpr FlagField kFlagFields[] = {
    {"photon_noise", &DetectorNoiseModel::photon_noise},
    {"quantize_16bit", &DetectorNoiseModel::quantize_16bit},
};
void checkRange(const char* key, double value, double min, double max) {
  if (!(value >= min && value <= max))
    fail("detector noise model: {} = {} is outside [{}, {}]", key, value, min, max);
}

}  // namespace

Image gaussianBlur(Image image, double sigma_px) {
  return blurMix(std::move(image), sigma_px, 1.0);
}

Image scatterBlur(Image image, double weight, double sigma_px) {
  return blurMix(std::move(image), sigma_px, weight);
}

DetectorNoiseModel DetectorNoiseModel::fromConfig(const ConfigNode& node) {
  if (!node.isObject()) node.fail("expected an object of detector noise settings");
  DetectorNoiseModel model;
  for (const NumberField& f : kNumberFields)
    if (auto value = node.find(f.key)) model.*f.field = value->number(f.min, f.max);
  for (const FlagField& f : kFlagFields)
    if (auto value = node.find(f.key)) {
      if (!value->json().is_boolean()) value->fail("expected true or false");
      model.*f.field = value->json().get<bool>();
    }
  return model;
}

nlohmann::json DetectorNoiseModel::toJson() const {
  nlohmann::json out = nlohmann::json::object();
  for (const NumberField& f : kNumberFields) out[f.key] = this->*f.field;
  for (const FlagField& f : kFlagFields) out[f.key] = this->*f.field;
  return out;
}

void DetectorNoiseModel::validate() const {
  for (const NumberField& f : kNumberFields) checkRange(f.key, this->*f.field, f.min, f.max);
}

DetectorPattern DetectorPattern::generate(const DetectorNoiseModel& model, int width, int height,
                                          uint64_t seed) {
  model.validate();
  if (width < 1 || height < 1) fail("detector size must be positive, got {}x{}", width, height);
  DetectorPattern pattern;
  pattern.gain.resize(width, height);
  pattern.dark_adu.resize(width, height);
  pattern.dead.resize(width, height);

  // Column offsets: one stream along the row of columns.
  std::vector<double> column_offset(static_cast<size_t>(width), 0.0);
  if (model.column_offset_sigma_adu > 0.0) {
    SplitMix64 rng = SplitMix64::stream(seed, kColumnOffset);
    std::normal_distribution<double> normal;
    for (double& offset : column_offset) offset = model.column_offset_sigma_adu * normal(rng);
  }
  const Image smooth = model.gain_smooth_sigma > 0.0
                           ? smoothField(width, height, model.gain_smooth_length_px, seed)
                           : Image();

  tbb::parallel_for(0, height, [&](int y) {
    SplitMix64 gain_rng = SplitMix64::stream(seed, kGainPixel, y);
    SplitMix64 dark_rng = SplitMix64::stream(seed, kDarkPixel, y);
    SplitMix64 dead_rng = SplitMix64::stream(seed, kDeadPixel, y);
    std::normal_distribution<double> gain_normal, dark_normal;
    for (int x = 0; x < width; ++x) {
      double relative_gain = 1.0;
      if (!smooth.empty())
        relative_gain *= 1.0 + model.gain_smooth_sigma * static_cast<double>(smooth(x, y));
      if (model.gain_pixel_sigma > 0.0)
        relative_gain *= 1.0 + model.gain_pixel_sigma * gain_normal(gain_rng);
      pattern.gain(x, y) = static_cast<float>(std::max(0.0, relative_gain));

      double offset_adu = model.dark_level_adu + column_offset[static_cast<size_t>(x)];
      if (model.dark_pixel_sigma_adu > 0.0)
        offset_adu += model.dark_pixel_sigma_adu * dark_normal(dark_rng);
      pattern.dark_adu(x, y) = static_cast<float>(offset_adu);

      pattern.dead(x, y) =
          model.dead_pixel_fraction > 0.0 && dead_rng.uniform() < model.dead_pixel_fraction;
    }
  });
  return pattern;
}

Exposure exposeRaw(const Image& intensity, const DetectorPattern& pattern,
                   const DetectorNoiseModel& model, uint64_t seed, uint64_t shot_index,
                   const Image* previous_signal) {
  Exposure exposure;
  exposure.raw_adu =
      simulateFrames({&intensity, 0.0, previous_signal}, pattern, model, seed,
                     {kExposurePhotons, kExposureRead, shot_index}, 1, &exposure.signal);
  return exposure;
}

Image darkFrame(const DetectorPattern& pattern, const DetectorNoiseModel& model, uint64_t seed,
                uint64_t index, int frames_averaged) {
  return simulateFrames({nullptr, 0.0, nullptr}, pattern, model, seed,
                        {kDarkPhotons, kDarkRead, index}, frames_averaged, nullptr);
}

Image flatFrame(const DetectorPattern& pattern, const DetectorNoiseModel& model, uint64_t seed,
                uint64_t index, int frames_averaged) {
  return simulateFrames({nullptr, 1.0, nullptr}, pattern, model, seed,
                        {kFlatPhotons, kFlatRead, index}, frames_averaged, nullptr);
}

}  // namespace xgauge
