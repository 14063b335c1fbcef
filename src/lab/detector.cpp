#include "xgauge/lab/detector.h"

#include "xgauge/image/blur.h"

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

Image beamProfile(int columns, int rows, double pitch_u_mm, double pitch_v_mm, double cx_px,
                  double cy_px, double source_detector_distance_mm, double heel_gradient,
                  bool cos3) {
  if (!(std::abs(heel_gradient) <= 0.5))
    fail("heel_gradient must be in [-0.5, 0.5], got {}", heel_gradient);
  if (columns < 1 || rows < 1) fail("detector size must be positive, got {}x{}", columns, rows);
  Image profile(columns, rows, 1.0f);
  const double d = source_detector_distance_mm;
  for (int v = 0; v < rows; ++v)
    for (int u = 0; u < columns; ++u) {
      double value = 1.0 + heel_gradient * (v + 0.5 - cy_px) / rows;
      if (cos3) {
        const double x = (u + 0.5 - cx_px) * pitch_u_mm, y = (v + 0.5 - cy_px) * pitch_v_mm;
        value *= std::pow(d / std::sqrt(d * d + x * x + y * y), 3.0);
      }
      if (!(value > 0.0)) fail("the open beam's profile reaches 0 at pixel ({}, {})", u, v);
      profile(u, v) = static_cast<float>(value);
    }
  return profile;
}

void darkenColumns(Image& intensity, double strength) {
  if (!(strength >= 0.0 && strength <= 0.1))
    fail("column_darkening must be in [0, 0.1], got {}", strength);
  if (strength == 0.0) return;
  for (int u = 0; u < intensity.width(); ++u) {
    double attenuation = 0.0;
    for (int v = 0; v < intensity.height(); ++v)
      attenuation += 1.0 - static_cast<double>(intensity(u, v));
    const double drop = strength * attenuation / intensity.height();
    for (int v = 0; v < intensity.height(); ++v)
      intensity(u, v) =
          static_cast<float>(std::max(0.0, static_cast<double>(intensity(u, v)) - drop));
  }
}

}  // namespace xgauge
