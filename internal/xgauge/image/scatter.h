// The scintillator scatter of a flat-panel detector (thesis eq. 5.4,
// docs/method.md): light spreads in the scintillator, so the detector records
//   I' = (1 - w) I + w K * I
// with K a normalised radial kernel (mm on the detector): a Gaussian of
// sigma (the thesis's), a Gaussian plus an exponential tail
//   (1 - f) G(sigma) + f e^(-r/lambda) / (2 pi lambda^2),
// or two Gaussians (1 - f2) G(sigma1) + f2 G(sigma2). Every kernel is a
// weighted sum of Gaussians (the tail a fixed mixture of six, below), so the
// fast Gaussian blur (image/blur.h) serves all. The one type that owns this
// formula and its inverse: the virtual lab adds it, the forward model of a
// measurement adds it to its simulation, and the calibrations take it out of
// measured radiographs.
//
// The border: what the kernel sees beyond the panel. "mirror" reflects the
// image at its edges (the thesis's blur, and what a job without "border"
// means); "open" takes the world beyond the panel as open beam, the level
// `outside` (1 in a transmission image), which is what a scintillator
// larger than the active area under a beam wider than it sees. An edge shot
// (xgauge characterize) tells them apart.
#pragma once

#include "xgauge/core/config.h"
#include "xgauge/image/image.h"
#include "xgauge/image/open_beam.h"

#include <optional>
#include <vector>

namespace xgauge {

// The thesis's fit for its 4096 x 4096 panel of 0.1 mm pixels: w = 0.139,
// sigma = 500 px = 50 mm.
inline constexpr double kThesisScatterWeight = 0.139;
inline constexpr double kThesisScatterSigmaMm = 50.0;

enum class HaloShape { kGaussian, kGaussExp, kTwoGauss };
enum class HaloBorder { kMirror, kOpen };

// "gaussian", "gauss_exp", "two_gauss"; "mirror", "open".
const char* toString(HaloShape shape);
const char* toString(HaloBorder border);

// e^(-r) / (2 pi) in 2-D (lambda = 1) as sum_j a_j G(s_j): fitted once
// (least squares of the area-weighted kernel, scipy) and normalised to sum 1.
// Its L1 distance from the closed form is 1.6e-3 of the kernel's mass, its
// edge response (the blur of a half-plane) is within 7e-5 of the closed
// form's, its E[r^2] within 3e-5 of 6 lambda^2 (scatter_test checks these).
struct GaussianTerm {
  double fraction;
  double sigma;  // in the caller's unit
};
inline constexpr GaussianTerm kExponentialTailMixture[] = {
    {0.003079883151, 0.1551531672}, {0.0251902533, 0.3618463035}, {0.1162606368, 0.6837757676},
    {0.3198362559, 1.166504387},    {0.4108837975, 1.872753185},  {0.1247491734, 2.923084313}};

// The open beam's field at the pixels of an image of one size and its halo
// there (ScatterModel::haloField), shared by the many spreads of a fit.
struct HaloField {
  Image open;       // O; empty: a uniform field
  Image open_halo;  // K * O: O over the plane (open border) or mirrored
  // mix(1, K * O / O): the flat frame's own halo relative to O, by which a
  // flat-field division divides.
  Image flat;
  bool uniform() const { return open.empty(); }
};

// Another kernel that fits a two-width halo's edge shot about as well
// (xgauge characterize), of the same border, and the u of the
// Gaussian-equivalent width it stands for; a measurement's budget moves
// the halo to it (docs/method.md, "Detector characterisation"):
// - the end (key "equivalent_end"): the same shape with its second width
//   held where the equivalent width reaches sigma_eq + u, the other
//   parameters refitted, u from the profile, the halves and the heel;
// - the other kernel (key "kernel_choice"): the other two-width shape as
//   it was fitted, u its equivalent width's difference.
struct HaloKernelEnd {
  HaloShape shape = HaloShape::kGaussian;
  double weight = 0.0, sigma_mm = 0.0;
  double tail_fraction = 0.0, tail_length_mm = 0.0;  // gauss_exp
  double sigma2_mm = 0.0, fraction2 = 0.0;           // two_gauss
  // The Gaussian-equivalent width's standard uncertainty u it stands for.
  double equivalent_sigma_uncertainty_mm = 0.0;
  bool operator==(const HaloKernelEnd&) const = default;
};

struct HaloAlternative;

struct ScatterModel {
  double weight = 0.0;    // w in [0, 0.9]; 0 = no scatter
  // On the detector: the Gaussian's sigma ("gaussian"), the core's
  // ("gauss_exp"), the first Gaussian's ("two_gauss", key "sigma1_mm").
  double sigma_mm = 0.0;
  HaloShape shape = HaloShape::kGaussian;
  HaloBorder border = HaloBorder::kMirror;
  // gauss_exp: the tail's share f and its decay length lambda (mm).
  double tail_fraction = 0.0, tail_length_mm = 0.0;
  // two_gauss: the second Gaussian's sigma (mm) and share f2.
  double sigma2_mm = 0.0, fraction2 = 0.0;
  // Their standard uncertainties.
  double tail_fraction_uncertainty = 0.0, tail_length_uncertainty_mm = 0.0;
  double sigma2_uncertainty_mm = 0.0, fraction2_uncertainty = 0.0;
  // Standard uncertainties of both (optional keys "weight_uncertainty",
  // "sigma_uncertainty_mm"); default 5 % of the weight and 10 % of the
  // width, what a fit of the halo around an edge typically leaves. They
  // enter a measurement's uncertainty budget.
  double weight_uncertainty = 0.0;
  double sigma_uncertainty_mm = 0.0;
  // A two-width kernel's end and the other kernel, where the
  // characterisation found them.
  std::optional<HaloKernelEnd> equivalent_end = std::nullopt;
  std::optional<HaloKernelEnd> kernel_choice = std::nullopt;

  bool enabled() const { return weight > 0.0; }
  double sigmaPx(double pitch_mm) const { return sigma_mm / pitch_mm; }
  // The plain Gaussian with a mirror border: the thesis's model, which the
  // fused, bit-for-bit unchanged scatterBlur path computes.
  bool isMirroredGaussian() const {
    return shape == HaloShape::kGaussian && border == HaloBorder::kMirror;
  }
  // The kernel as Gaussians (fractions summing to 1, sigma in mm).
  std::vector<GaussianTerm> components() const;
  // sqrt(E[r^2] / 2): the sigma of the Gaussian with the kernel's second
  // moment (lab2's "gaussian_equivalent_sigma_mm").
  double equivalentSigmaMm() const;
  // Whether `other` is this kernel (shape, border, weight, widths and
  // shares to 1e-9 relative; the uncertainties are not compared).
  bool sameKernel(const ScatterModel& other) const;
  // The kernel `k` (equivalent_end or kernel_choice) with this one's border
  // and uncertainties, without alternatives of its own.
  ScatterModel as(const HaloKernelEnd& k) const;
  // Each alternative with a u and a distance in sigma_eq (HaloAlternative).
  std::vector<HaloAlternative> alternatives() const;

  // Job key "scatter": {"weight": w in [0, 0.9], optional "shape"
  // ("gaussian" by default), the shape's keys: "sigma_mm" in [0.01, 1e4]
  // (gaussian, gauss_exp); "tail_fraction" in [0, 1], "tail_length_mm" in
  // [0.01, 1e4] (gauss_exp); "sigma1_mm", "sigma2_mm" in [0.01, 1e4],
  // "fraction2" in [0, 1] (two_gauss); optional "border" ("mirror" by
  // default, "open"); optional uncertainties "weight_uncertainty",
  // "sigma_uncertainty_mm" (of sigma_mm or sigma1_mm),
  // "tail_fraction_uncertainty", "tail_length_uncertainty_mm",
  // "sigma2_uncertainty_mm", "fraction2_uncertainty"; optional for a
  // two-width kernel "equivalent_end": {"weight", the shape's width and
  // share keys, "equivalent_sigma_uncertainty_mm"} and "kernel_choice": the
  // same with the other kernel's "shape"} (Error at the node otherwise;
  // another shape's key is an unknown key at Config::finish).
  static ScatterModel fromConfig(const ConfigNode& node);
  // The same keys, all written; a mirrored Gaussian writes exactly the four
  // keys it always did (a material.json's "scatter").
  nlohmann::json toJson() const;

  // K * I over a whole image with pixels of `pitch_mm`, the world beyond the
  // panel at `outside` (open border) or mirrored.
  Image spread(Image image, double pitch_mm, float outside) const;
  // The same for an image that equals `outside` away from a feature
  // (gaussianBlurAround: the forward model's coarse renders); `sigma_shrink_px2`
  // is taken off every component's variance (the coarse pixels' own
  // spread), at most down to a quarter of it.
  Image spreadAround(const Image& image, double pitch_mm, float outside,
                     double sigma_shrink_px2 = 0.0) const;

  // The halo in the open beam's field (image/open_beam.h; decision 0041):
  //   H(I) = K * (I O) / O,
  // the world beyond the panel `outside` times O (open border) or I O
  // mirrored at the panel's edges, for an image of pixels of `pitch_mm`,
  // each `scale` full-size pixels a side. A flat-field-corrected radiograph
  // of transmission T then reads mix(T, H(T)) / mix(1, H(1)) (the flat has
  // its halo too), up to the white region's normalization. Computed as
  // (K * ((I - outside) O) + outside K * O) / O. With a uniform field:
  // spread() (the field's K * O is 1).
  HaloField haloField(const OpenBeamField& field, int width, int height, double pitch_mm,
                      double scale = 1.0) const;
  Image spreadIn(const Image& image, double pitch_mm, float outside, const HaloField& field) const;
  // The same for an image that equals `outside` away from a feature, as
  // spreadAround (the forward model's coarse renders).
  Image spreadAroundIn(const Image& image, double pitch_mm, float outside, const HaloField& field,
                       double sigma_shrink_px2 = 0.0) const;

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

  // I' for a whole image with pixels of `pitch_mm`, `outside` the level
  // beyond the panel (open border only). Preserves the image sum with a
  // mirror border. Throws Error if weight is outside [0, 1] or sigma is not
  // positive.
  Image apply(Image image, double pitch_mm, float outside = 1.0f) const;

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
  // The same in the open beam's `field` (decision 0041): the fixed point
  //   I <- (n r F - w H(I)) / (1 - w),
  // H = spreadIn, F = mix(1, H(1)) the flat's own halo, r the white
  // region's mean of mix(1, H(I)) / F (its normalization). A uniform field:
  // remove() above, bit for bit.
  Image remove(const Image& normalized, double pitch_mm, const PixelRect& white,
               const OpenBeamField& field, int iterations = 12) const;
};

// A two-width halo's alternative (ScatterModel::alternatives): "scatter
// kernel" (equivalent_end) or "scatter kernel choice" (kernel_choice), the
// kernel, its u and u over its distance in sigma_eq, by which a linearised
// move to it is scaled to u (the budget's and the wedge calibration's).
struct HaloAlternative {
  const char* name;
  bool end;  // equivalent_end, else kernel_choice
  ScatterModel kernel;
  double u = 0.0, scale = 1.0;
};

}  // namespace xgauge
