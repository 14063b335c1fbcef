// The detector's scintillator scatter (image/scatter.h) estimated from a
// calibration shot, so that nobody has to type its weight and width into a
// job: the halo it leaves in the open beam around a dark part.
//
// In the open beam the primary intensity is 1 everywhere, so whatever varies
// there comes from the scatter (the dark part's blur lowers the open beam
// near it) and from the panel's signal-dependent column darkening (a column
// reads lower in proportion to the attenuation along it). With P the primary
// image, g = G(P, sigma) its Gaussian blur and A the mean attenuation
// 1 - n of the pixel's column, a normalized radiograph reads
//   n = a P + b g + c A,   a = (1 - w) / open, b = w / open, c = -s / open
// (`open` the white region's level). For a given sigma this is linear in
// (a, b, c) over the open-beam pixels (P = 1); P inside the part's shadow comes
// from the fixed point P = (n - b g - c A) / a. Sigma is searched on a
// logarithmic grid and refined; the weight is w = b / (a + b) and the column
// darkening s = -c / (a + b). The width's uncertainty is the larger of the
// curvature's and the profile's (the widths whose residual sum of squares
// stays within one correlated variance of the least, and the weights
// there); the panel's border is searched too (HaloOptions::borders). The
// shape is taken as Gaussian: a detector characterised behind an opaque
// edge (xgauge characterize) measures it instead.
//
// The open beam is everything outside the part's shadow: the bounding box of
// the image's sharp edges (a part's outline steps by far more per pixel than a
// halo of a few hundred pixels can), widened by a margin. The estimate works
// on a copy binned to at most `max_side` pixels (the halo is smooth; binning
// changes the blur's width by a fraction of a binned pixel).
#pragma once

#include "xgauge/image/image.h"
#include "xgauge/image/scatter.h"

#include <string>
#include <vector>

namespace xgauge {

struct HaloOptions {
  int max_side = 512;  // bin by 2 until both sides are at most this
  // The search range of the width: from the larger of min_sigma_px
  // (full-size pixels) and min_sigma_mm (narrower light spread is the
  // detector's unsharpness, not a halo) ...
  double min_sigma_px = 4.0;
  double min_sigma_mm = 2.0;
  double max_sigma_fraction = 1.5;  // ... up to this fraction of the longer side
  double min_open_fraction = 0.05;  // of the image outside the shadow's box
  double min_open_level = 0.9;      // median of the normalized image there
  // What a scintillator and a panel can do; a fit beyond either explains
  // something else (a part that fills the image) and is refused.
  double max_weight = 0.5;
  double max_column_darkening = 0.1;
  // What the halo sees beyond the panel (image/scatter.h): each is tried,
  // the one whose best width leaves the smaller open-beam residual is taken,
  // and one the shot cannot rule out (its residual within 3 standard
  // deviations of the profile) widens the weight's and width's uncertainty
  // by half their difference.
  std::vector<HaloBorder> borders = {HaloBorder::kMirror, HaloBorder::kOpen};
  // The open beam's field the halo acts in (image/open_beam.h, decision
  // 0041): G(P) is then K * (P O) / O and the flat's own halo divides n.
  OpenBeamField field;
};

struct HaloFit {
  ScatterModel scatter;           // weight and sigma_mm with their uncertainties
  double column_darkening = 0.0;  // s: a column's drop per unit mean attenuation
  PixelRect shadow;               // the part's shadow box (full-size pixels, margin included)
  int binning = 1;                // full-size pixels per binned pixel along each side
  int open_pixels = 0;            // binned open-beam pixels the fit used
  double rms = 0.0;               // residual of the open beam at the optimum
  // The residual's correlation at the optimum (1 for white noise, up to the
  // 256 pixels of a block for a residual smooth over it), by whose square
  // root the uncertainties of scatter.* are widened (halo.cpp).
  double correlation = 1.0;
  // The search: sigma_mm and the open beam's residual rms at each.
  std::vector<double> sigma_mm, residual_rms;
  double open_level = 1.0;  // 1 / (a + b): the open beam's level in `normalized`
  // No measurable halo (scatter.weight 0): the most a halo that fits the
  // open beam as well could change the part's shadow by (in transmission),
  // as a standard uncertainty (a third of the 3-sigma bound), which a curve
  // read without a scatter counts in its uncertainty.
  double unseen_change = 0.0;
  // The radiograph without the scatter and the darkening: (n - b g - c A) / a.
  Image primary;
  OpenBeamField field;  // the options' field, for primaryWith

  // That primary for another weight and width (the same darkening and open
  // level): how a curve's uncertainty propagates the halo's.
  Image primaryWith(const Image& normalized, double pitch_mm, double weight, double sigma_mm) const;
};

// Fits the halo of `normalized` (a radiograph divided by its flat field, its
// open beam near 1), pixels of `pitch_mm`; `name` is the file the messages
// name. Throws Error, naming the file and the figures, when there is too
// little open beam (or what lies outside the part's shadow is not open), the
// part has no sharp outline, the fit is not a scatter a detector has (weight
// above max_weight, darkening above max_column_darkening), or the halo does
// not decide the width (optimum at the widest width searched, or a width or
// weight uncertain by more than half its value): the job must then give its
// "scatter".
HaloFit fitScatterHalo(const Image& normalized, double pitch_mm, const std::string& name,
                       const HaloOptions& options = {});

// The same with the part's path known at every pixel (a posed known part,
// calibrate/wedge_part.h): `path_mm` the path through the part at the
// centre of each pixel of the radiograph binned by a power of 2 (at most
// options.max_side a side). The open beam is then every pixel the part does
// not cover, its neighbours neither, rather than what lies outside the box
// of the sharp edges: a part seen in part, or one with edges of its own
// inside its shadow (a wedge's ramp), leaves no doubt where it is. The same
// refusals as fitScatterHalo.
HaloFit fitScatterWithPaths(const Image& normalized, const Image& path_mm, double pitch_mm,
                            const std::string& name, const HaloOptions& options = {});

}  // namespace xgauge
