// The detector of the virtual X-ray lab: light spreading in the scintillator,
// and the noise and fixed-pattern artefacts of an indirect flat panel
// (docs/method.md, "The thesis's set-up and data").
//
// Pipeline of one simulated radiograph:
//
//   intensity (renderer, 1 = open beam)
//     -> scatterBlur                  light spread in the scintillator
//     -> exposeRaw                    photons, gain, dark, read noise, dead
//                                     pixels, lag of the previous shot, 16 bit
//   raw ADU image, as the detector delivers it
//
// with darkFrame / flatFrame for the calibration images of the same detector.
// Fixed patterns (gain, dark offsets, dead pixels) belong to the detector and
// are generated once per detector seed (DetectorPattern); the noise of an
// exposure is drawn from (seed, shot index).
//
// Units: ADU (analog-to-digital units, the raw pixel value), photons (detected
// X-ray quanta per pixel), px (detector pixels).
//
// Reproducibility: every function here gives bit-identical results for the
// same inputs and seeds at any thread count (lab/random.h).
#pragma once

#include "xgauge/core/config.h"
#include "xgauge/image/blur.h"
#include "xgauge/image/image.h"

#include <cstdint>

namespace xgauge {

// ---------------------------------------------------------------------------
// The open beam's shape and the panel's signal-dependent artefacts
// ---------------------------------------------------------------------------

// The open beam's relative intensity over the detector (mean 1 at the
// principal point), what a flat frame shows and a flat-field correction
// removes:
//   - the heel effect: the anode absorbs more of the beam leaving towards its
//     heel, so the intensity falls along the anode-cathode axis, here the
//     detector's rows: factor 1 + heel_gradient (v - cy) / rows, with v the
//     row and cy the principal point's (heel_gradient in [-0.5, 0.5]: the
//     relative change from the top row to the bottom row);
//   - with `cos3`, the fall-off of a point source on a flat detector,
//     cos^3 of the angle between the ray and the detector's normal: the
//     inverse square of the distance times the obliquity,
//     (D / sqrt(D^2 + r^2))^3 for a pixel centre r mm from the principal point.
// Throws Error for a heel_gradient out of range or a profile that would
// reach 0.
Image beamProfile(int columns, int rows, double pitch_u_mm, double pitch_v_mm, double cx_px,
                  double cy_px, double source_detector_distance_mm, double heel_gradient,
                  bool cos3);

// Signal-dependent column darkening of a flat panel: each column reads lower
// in proportion to the attenuation along it,
//   I'(x, y) = I(x, y) - strength * mean_y (1 - I(x, y)),
// clamped at 0 (strength in [0, 0.1]). A flat frame (I = 1) is unchanged, so
// a flat-field correction does not remove it. Throws Error for a strength
// out of range.
void darkenColumns(Image& intensity, double strength);

// ---------------------------------------------------------------------------
// Noise and fixed-pattern artefacts
// ---------------------------------------------------------------------------

// Raw pixel value (ADU) of a live pixel with normalised intensity I and lag
// signal L of the previous exposure (both 1 = open beam):
//
//   raw = dark(x, y) + gain(x, y) * adu_per_photon * N + read noise
//   N   ~ Poisson(photons_per_open_pixel * (I + ghost_fraction * L))
//
// dark(x, y) = dark_level_adu + column offset(x) + pixel offset(x, y), and
// gain(x, y) = (1 + smooth(x, y)) * (1 + pixel(x, y)), clamped at 0. Every
// effect switches off with a zero (or false); switching one off does not
// change the random numbers of the others.
//
// The defaults mimic the thesis's panel (docs/method.md): 16 bit, a dark
// level of 4000 ADU, an open beam about 52000 ADU, and per-pixel noise of
// about 0.65 % in a flat
// area after normalising by a white region (photon noise 0.5 % and pixel gain
// 0.4 %), so normalised values there reach down to about 0.977 as in the
// thesis's figure 5.11.
//
// JSON keys (every key optional; the default below when absent):
//   photons_per_open_pixel   detected quanta per pixel in the open beam, > 0
//   photon_noise             false: N is its expected value (no Poisson noise)
//   adu_per_photon           conversion gain, ADU per detected quantum, > 0
//   read_noise_adu           std. dev. of the Gaussian read noise, >= 0
//   dark_level_adu           mean dark offset, 0..65535
//   dark_pixel_sigma_adu     std. dev. of fixed per-pixel dark offsets, >= 0
//   column_offset_sigma_adu  std. dev. of fixed per-column dark offsets, >= 0
//   gain_pixel_sigma         relative std. dev. of the per-pixel gain, 0..0.5
//   gain_smooth_sigma        relative std. dev. of the smooth gain, 0..0.5
//   gain_smooth_length_px    feature size of the smooth gain, px, >= 1
//   dead_pixel_fraction      probability that a pixel is dead, 0..1
//   ghost_fraction           lag: fraction of the previous exposure, 0..0.99
//   quantize_16bit           round and clamp to 0..65535 ADU
struct DetectorNoiseModel {
  double photons_per_open_pixel = 40000.0;
  bool photon_noise = true;
  double adu_per_photon = 1.2;
  double read_noise_adu = 10.0;
  double dark_level_adu = 4000.0;
  double dark_pixel_sigma_adu = 15.0;
  double column_offset_sigma_adu = 25.0;
  double gain_pixel_sigma = 0.004;
  double gain_smooth_sigma = 0.02;
  double gain_smooth_length_px = 400.0;
  // A dead pixel does not respond to light and reads its dark offset
  // dark(x, y) exactly, without read noise, in exposures, darks and flats
  // alike. So flat - dark is 0 there: mask dead pixels (DetectorPattern::dead)
  // before a flat-field correction.
  double dead_pixel_fraction = 1e-5;
  // Image lag (ghosting): the previous exposure's signal L adds
  // ghost_fraction * L to this one. L itself includes its own lag, so older
  // exposures fade as ghost_fraction^k.
  double ghost_fraction = 0.003;
  bool quantize_16bit = true;

  // Reads the keys above; absent keys keep their defaults. Errors name the
  // key. Does not call finish().
  static DetectorNoiseModel fromConfig(const ConfigNode& node);
  // Every key, so that a dataset records the model it was made with.
  nlohmann::json toJson() const;
  // Throws Error naming the first field out of range (the ranges above).
  void validate() const;
};

// The fixed patterns of one detector, width x height pixels. Generate once per
// detector and use for all of its exposures, darks and flats.
struct DetectorPattern {
  Image gain;            // relative gain, dimensionless, mean about 1
  Image dark_adu;        // dark offset dark(x, y), ADU
  ImageT<uint8_t> dead;  // 1 = dead pixel

  int width() const { return gain.width(); }
  int height() const { return gain.height(); }

  // Draws the patterns of `model` from `seed` (independent of exposure seeds:
  // the streams differ by purpose). The smooth gain is white noise on a grid
  // of gain_smooth_length_px spacing, blurred by one grid step and
  // interpolated bilinearly, then shifted and scaled to mean 0 and standard
  // deviation exactly gain_smooth_sigma over the image. Dead pixels are
  // independent with probability dead_pixel_fraction.
  // Throws Error if the model is invalid or the size is not positive.
  static DetectorPattern generate(const DetectorNoiseModel& model, int width, int height,
                                  uint64_t seed);
};

// One exposure as read out, and its noise-free signal for the lag of the next.
struct Exposure {
  Image raw_adu;  // the raw image, ADU (whole numbers in 0..65535 if quantized)
  // Expected normalised signal I + ghost_fraction * L (no noise, no gain):
  // pass it as `previous_signal` of the next exposure of the same detector.
  Image signal;
};

// Simulates one exposure of `intensity` (normalised, 1 = open beam, in
// [0, 1e6]; scatter already applied) on the detector `pattern`. The noise is drawn from
// (seed, shot_index): the same pair gives the same image, different shots of
// one seed are independent. `previous_signal` is the Exposure::signal of the
// detector's previous exposure (for ghosting), or null for a rested detector.
// Throws Error if the model is invalid, the sizes of intensity, pattern and
// previous_signal differ, or a value of intensity or previous_signal is
// outside [0, 1e6] or NaN (naming the first such pixel in row-major order).
//
// Cost: one Poisson and one Gaussian draw per pixel from libstdc++, about
// 140 ns per pixel and thread (4096 x 4096: 1.2 s on 2 cores).
Exposure exposeRaw(const Image& intensity, const DetectorPattern& pattern,
                   const DetectorNoiseModel& model, uint64_t seed, uint64_t shot_index,
                   const Image* previous_signal = nullptr);

// The mean of `frames_averaged` dark frames (no beam): dark(x, y) +
// read noise / sqrt(frames_averaged). Frame `index` of a series; darks, flats
// and exposures of one seed draw from separate streams.
//
// Averages are drawn directly from their exact distribution (the sum of
// Poisson counts is Poisson, the sum of Gaussians Gaussian) in one pass,
// rather than frame by frame. Per-frame rounding to whole ADU is not
// simulated (it adds 1/12 ADU^2 of variance per frame): with quantize_16bit a
// single frame is rounded and clamped to 0..65535 like exposeRaw, an average
// is clamped but not rounded. No lag.
// Throws Error if the model is invalid or frames_averaged is not 1..1000000.
Image darkFrame(const DetectorPattern& pattern, const DetectorNoiseModel& model, uint64_t seed,
                uint64_t index, int frames_averaged);

// The mean of `frames_averaged` open-beam frames (intensity 1, no
// part, no scatter needed: a uniform image stays uniform), drawn like
// darkFrame: the photon noise shrinks by sqrt(frames_averaged) as well.
Image flatFrame(const DetectorPattern& pattern, const DetectorNoiseModel& model, uint64_t seed,
                uint64_t index, int frames_averaged);

}  // namespace xgauge
