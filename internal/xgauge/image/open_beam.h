// The open beam's field over the panel, the shape the scintillator's halo
// acts in (docs/decisions/0041-halo-in-the-open-beams-field.md): the X-ray
// field O falls off as cos^3 of the ray's angle (the inverse square and the
// obliquity of a pixel seen from the focal spot) and has the tube's heel, a
// linear slope across the panel:
//   O(u, v) = cos^3(angle) (1 + a x + b y),
//   x = (u - cx) pitch_u,  y = (v - cy) pitch_v  (mm from the principal point,
//   u, v continuous pixel coordinates, pixel centres at x + 0.5),
//   cos(angle) = D / sqrt(D^2 + x^2 + y^2)  (D the source-detector distance).
// The halo spreads the signal O T before the flat field divides by O, so
// what a flat-corrected radiograph holds of it is K * (O T) / O, not K * T
// (image/scatter.h, ScatterModel::spreadIn). O is continued beyond the
// panel by the same formula: the open beam the panel's edge is padded with.
// Without a flat frame the field is uniform (O = 1), the model of before.
#pragma once

#include "xgauge/image/image.h"

#include <optional>

namespace xgauge {

// What the field needs of the machine (xray/machine.h).
struct OpenBeamGeometry {
  double source_detector_distance_mm = 1000.0;
  double cx_px = 0.0, cy_px = 0.0;  // the principal point
  double pitch_u_mm = 0.1, pitch_v_mm = 0.1;
};

class OpenBeamField {
 public:
  OpenBeamField() = default;  // uniform: O = 1
  OpenBeamField(const OpenBeamGeometry& geometry, double heel_u_per_mm, double heel_v_per_mm)
      : geometry_(geometry), heel_u_(heel_u_per_mm), heel_v_(heel_v_per_mm) {}

  // The field fitted to `flat` (a flat frame minus its dark, full size):
  // how much of `geometry`'s cos^3 curvature the flat shows (a share s in
  // 0 .. 2, the fall-off of a source at D / sqrt(s): a real panel shows
  // s = 1, a simulator without fall-off 0), then the heel plane's a, b by
  // least squares to the flat divided by that fall-off; pixels that are not
  // positive and finite, or more than 5 % off the first fit (bad pixels),
  // are left out. The field carries kHeelShare of that plane (below).
  // Throws Error when the flat has fewer than 100 such pixels.
  static OpenBeamField fit(const OpenBeamGeometry& geometry, const Image& flat);

  // A flat cannot tell the tube's heel (a slope of the X-rays, in the field
  // the halo spreads) from a slope of the panel's gain (after the halo; the
  // flat field divides it out and the halo never sees it). The share h of
  // the flat's plane that is heel is taken as rectangular over 0 .. 1
  // (GUM 4.3.7): the field carries its expectation, half the plane, and
  // the budget moves h by its standard uncertainty 1 / sqrt(12).
  static constexpr double kHeelShare = 0.5;
  static constexpr double kHeelShareUncertainty = 0.28867513459481287;  // 1 / sqrt(12)
  // This field with the share of the flat's plane it carries moved from
  // kHeelShare to `share`.
  OpenBeamField withHeelShare(double share) const;
  // fit() to flat - dark (dark null: flat as it is); uniform without a flat.
  static OpenBeamField fromFrames(const OpenBeamGeometry& geometry, const Image* dark,
                                  const Image* flat);

  bool uniform() const { return !geometry_; }
  bool sloped() const { return heel_u_ != 0.0 || heel_v_ != 0.0; }
  double heelUPerMm() const { return heel_u_; }
  double heelVPerMm() const { return heel_v_; }
  // O at a continuous full-size pixel coordinate (1 when uniform).
  double at(double u, double v) const;
  // O at the pixel centres of an image of width x height pixels, each
  // `scale` full-size pixels a side (a binned image or a pyramid level).
  Image sampled(int width, int height, double scale) const;
  // G(sigma) * O over the plane (O continued beyond the panel), at those
  // pixel centres; sigma in mm. Numerically on a grid of cells of an eighth
  // of sigma (whole pixels of the image), padded by 5 sigma beyond it.
  Image blurredOverThePlane(int width, int height, double scale, double sigma_mm) const;

 private:
  std::optional<OpenBeamGeometry> geometry_;
  double heel_u_ = 0.0, heel_v_ = 0.0;
};

}  // namespace xgauge
