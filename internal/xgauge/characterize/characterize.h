// Detector characterisation (`xgauge characterize`, docs/method.md
// "Detector characterisation"): the flat panel's halo, lag, column crosstalk
// and bad pixels measured on dedicated shots, once per detector, instead of
// inside every calibration.
//
// The shots (ASTM E2597-style; tools/lab2 writes them):
//   darks, flats   series of raw frames: the mean dark and flat, and the bad
//                  pixels (dead: flat - dark far below its neighbours'; hot:
//                  dark far above; noisy: temporal variance far above).
//   edge           an opaque plate over part of the panel, open beam around
//                  it: behind the plate the flat-corrected signal IS the halo
//                  w K * T, so its shape, weight and width are fitted
//                  directly (fitEdgeHalo).
//   lag            a bright open frame, then a beam-off frame right after it:
//                  the second's signal over the first's is the lag fraction.
//   crosstalk      a plate over a quadrant: in the open rows below it the
//                  covered columns read lower by c times their column mean's
//                  deficit, a step at the plate's edge column.
#pragma once

#include "xgauge/core/config.h"
#include "xgauge/image/image.h"
#include "xgauge/image/scatter.h"

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace xgauge {

// The job (docs/formats.md, "Characterisation job"). Paths relative to the
// job file; a file name may hold '*' (sorted matches, at least one).
struct CharacterizeJob {
  std::filesystem::path machine_file;
  std::vector<std::filesystem::path> darks, flats;
  std::optional<std::filesystem::path> edge, lag_bright, lag_dark, crosstalk;
  // The widest halo an edge shot may report, as a fraction of the panel's
  // shorter side: wider, the halo is indistinguishable from a level and the
  // step fails.
  double max_sigma_fraction = 0.5;
  static CharacterizeJob load(const std::filesystem::path& path);
};

struct Estimate {
  double value = 0.0;
  double uncertainty = 0.0;  // standard
};

// Bad pixels: bit 1 dead, 2 hot, 4 noisy.
enum BadPixelKind : uint8_t { kDeadPixel = 1, kHotPixel = 2, kNoisyPixel = 4 };
struct BadPixelMap {
  ImageT<uint8_t> kinds;
  int64_t dead = 0, hot = 0, noisy = 0;
  ImageT<uint8_t> mask() const;  // 1 where any kind
};
// From the raw dark frames (>= 2 for the noisy ones) and the mean flat.
// Throws Error if sizes differ.
BadPixelMap findDetectorBadPixels(const std::vector<Image>& darks, const Image& dark,
                                  const Image& flat);

// The lag fraction g from raw frames: (after - dark) / (bright - dark) over
// the good pixels, its u from the spread of 16 x 16 block estimates.
// Throws Error if the bright frame is not brighter than the dark.
Estimate estimateLag(const Image& bright, const Image& after, const Image& dark,
                     const ImageT<uint8_t>& bad);

// The column crosstalk c from a flat-corrected crosstalk shot (an opaque
// plate over the top-left quadrant). Throws Error, with the figures, when the
// shot shows no covered quadrant.
Estimate estimateCrosstalk(const Image& corrected);

// One candidate of the edge fit.
struct EdgeHaloCandidate {
  ScatterModel scatter;  // parameters only (no uncertainties)
  double chi2 = 0.0;
  double misfit_ratio = 0.0;  // sqrt(chi2 / (bins - parameters))
  // Of the normalised residuals: the mean squared sum over 8 x 8 blocks of
  // bins per bin over the mean square (1: white; else the bins a misfit
  // spreads over).
  double residual_correlation = 1.0;
  double bic = 0.0;  // chi2 / s^2 + k ln(bins / correlation), s^2 the noise scale
  int parameters = 0;
};

struct EdgeHaloFit {
  ScatterModel scatter;  // the chosen candidate with profile uncertainties
  double equivalent_sigma_mm = 0.0, equivalent_sigma_uncertainty_mm = 0.0;
  std::vector<EdgeHaloCandidate> candidates;
  std::string choice;  // which was chosen and why
  int binning = 1;
  int bins = 0;
  // The upper, lower, left and right halves fitted on their own (the
  // chosen shape), and the term they add in quadrature to the
  // uncertainties: splitHalvesTerm of the full fit's value and theirs.
  std::array<double, 4> split_halves_weight{}, split_halves_equivalent_sigma_mm{};
  double split_halves_weight_term = 0.0, split_halves_equivalent_sigma_term_mm = 0.0;
  // The chosen shape fitted again in a field whose heel's share of the
  // flat's slope is moved by its standard uncertainty (image/open_beam.h):
  // the weight's and the Gaussian-equivalent width's changes, in the
  // uncertainties too (0 in a field without a slope).
  double heel_share_weight_change = 0.0, heel_share_equivalent_sigma_change_mm = 0.0;
  // The other kernels of the chosen border that fit the shot about as well
  // (misfit ratio within kKernelChoiceMisfit of the chosen's): the largest
  // difference of their Gaussian-equivalent width from the chosen's, a
  // standard uncertainty of the width (0 when none), and that kernel's
  // weight less the chosen's, one of the weight. "shape" names it.
  double kernel_choice_equivalent_sigma_change_mm = 0.0, kernel_choice_weight_change = 0.0;
  std::string kernel_choice_shape;
  // s: the misfit ratio times the square root of the residual correlation
  // (>= 1), by which the profile's chi2 is scaled.
  double noise_scale = 1.0;
};

struct EdgeHaloOptions {
  double crosstalk = 0.0;  // c, modelled in the shot
  // The open beam's field (image/open_beam.h, fitted to the flat frame;
  // uniform by default): the halo acts on the field times the
  // transmission, K * (O T) / O (decision 0041).
  OpenBeamField field;
  double max_sigma_fraction = 0.5;
  // The profile uncertainties (slow for the 4-parameter shapes); without,
  // the candidates' parameters alone.
  bool profiles = true;
};

// Fits the three kernel shapes with both borders to a flat-corrected (not
// white-normalised) edge shot: data = a [(1 - w) T + w K * T], T the open
// mask (1 open, 0 behind the plate; pixels within a bin of its edge left
// out), binned to about 256 px. Chooses by BIC on the noise-scaled chi2;
// uncertainties from the profile of the loss (delta chi2 / s^2 = 1), with
// the halves' term (splitHalvesTerm), the heel's share and the kernel's
// choice added in quadrature.
// Throws Error naming the step and the figures if there is no plate, no open
// beam, or the halo is wider than max_sigma_fraction of the shorter side.
EdgeHaloFit fitEdgeHalo(const Image& corrected, double pitch_mm, const EdgeHaloOptions& options);

// The split halves' term of a parameter: the root mean square of the
// halves' estimates' deviations from the full shot's,
//   sqrt(mean over the halves of (half - full)^2).
// For one pair (upper and lower) it is
//   sqrt(((upper - lower) / 2)^2 + ((upper + lower) / 2 - full)^2),
// the delete-half jackknife's mean squared error: its variance plus its
// bias estimate squared (the halves' mean less the full fit). Where the
// data is the model, the full fit is about each pair's mean and the term
// is about half their difference, the noise of a half; where the kernel
// does not describe the shot, the estimate moves with the part of the
// panel it is fitted to, and the full fit is one more such part. 0 for
// no halves.
double splitHalvesTerm(double full, std::span<const double> halves);

struct InputFile {
  std::string file, sha256;
};

struct Characterization {
  std::optional<EdgeHaloFit> halo;
  std::optional<Estimate> lag, crosstalk;
  BadPixelMap bad_pixels;
  std::vector<InputFile> inputs;
  std::vector<std::string> steps;  // what was done, for the report
};

// Runs every step the job's shots allow; `advance` is called after each.
Characterization characterize(const CharacterizeJob& job, const std::function<void()>& advance);
int characterizeSteps(const CharacterizeJob& job);

// detector.json (docs/schemas/detector.schema.json); `bad_pixels_file` the
// name written beside it.
nlohmann::json detectorJson(const Characterization& c, const std::string& bad_pixels_file);
// bad_pixels.json: {"dead": [[u, v], ...], "hot": [...], "noisy": [...]}.
nlohmann::json badPixelsJson(const BadPixelMap& map);
std::string characterizationReport(const Characterization& c);

}  // namespace xgauge
