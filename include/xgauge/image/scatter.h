// The scintillator scatter of a flat-panel detector (thesis eq. 5.4,
// docs/method.md): light spreads in the scintillator, so the detector records
//   I' = (1 - w) I + w G(I, sigma)
// with G a Gaussian blur of sigma (mm on the detector). The one type that
// owns this formula and its inverse: the virtual lab adds it, the forward
// model of a measurement adds it to its simulation, and the calibrations
// take it out of measured radiographs.
#pragma once

#include "xgauge/core/config.h"
#include "xgauge/image/image.h"

namespace xgauge {

// The thesis's fit for its 4096 x 4096 panel of 0.1 mm pixels: w = 0.139,
// sigma = 500 px = 50 mm.
inline constexpr double kThesisScatterWeight = 0.139;
inline constexpr double kThesisScatterSigmaMm = 50.0;

struct ScatterModel {
  double weight = 0.0;    // w in [0, 0.9]; 0 = no scatter
  double sigma_mm = 0.0;  // on the detector
  // Standard uncertainties of both (optional keys "weight_uncertainty",
  // "sigma_uncertainty_mm"); default 5 % of the weight and 10 % of the
  // width, what a fit of the halo around an edge typically leaves. They
  // enter a measurement's uncertainty budget.
  double weight_uncertainty = 0.0;
  double sigma_uncertainty_mm = 0.0;

  bool enabled() const { return weight > 0.0; }
  double sigmaPx(double pitch_mm) const { return sigma_mm / pitch_mm; }

  // Job key "scatter": {"weight": w in [0, 0.9], "sigma_mm": s in [0.01, 1e4],
  // optional "weight_uncertainty", "sigma_uncertainty_mm"} (Error at the node
  // otherwise).
  static ScatterModel fromConfig(const ConfigNode& node);
  // The same keys, all four written (a material.json's "scatter").
  nlohmann::json toJson() const;

  // The forward formula at one pixel: intensity I and its blur G(I) there.
  double mix(double intensity, double blurred) const {
    return (1.0 - weight) * intensity + weight * blurred;
  }
  // Its inverse for a radiograph normalized by an open-beam region: the
  // normalized value n was divided by `open` = (1 - w) + w mean(G(I)) over
  // that region, in which the scatter shows too.
  double unmix(double normalized, double blurred, double open) const {
    return (normalized * open - weight * blurred) / (1.0 - weight);
  }

  // I' for a whole image with pixels of `pitch_mm`. Preserves the image sum.
  // Throws Error if weight is outside [0, 1] or sigma is not positive.
  Image apply(Image image, double pitch_mm) const;

  // The scatter-free I of a radiograph normalized by the mean of its
  // open-beam `white` region, by the fixed-point iteration
  //   I <- unmix(n, G(I), open(I)),
  // which contracts by about w / (1 - w) per step (0.16 for w = 0.139), from
  // I = n; 12 steps leave about 1e-9 of the scatter. For intensities read
  // directly from a radiograph (calibration) rather than compared with a
  // simulation that adds the scatter.
  // Throws Error if weight is outside [0, 0.9] or the white region lies
  // outside the image.
  Image remove(const Image& normalized, double pitch_mm, const PixelRect& white,
               int iterations = 12) const;
};

}  // namespace xgauge
