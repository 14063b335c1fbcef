// The wedge calibration with the wedge fitted as a known part (private to
// calibrate/): the wedge's model, at the lab's caliper values, is posed in
// the radiograph by the measurement's own pose search, and the path of every
// pixel comes from the renderer rather than from rows and a straight ramp.
// This is the part calibration (part.h) on the one shot, so that a turned,
// tilted or partly seen wedge, or one a few tenths off its nominal
// dimensions, is read as it lies:
//
//   1. The initial material: thesis eq. 3.8 with I1 the darkest 2 % of the
//      shadow and x1 the wedge's smallest extent at its caliper values (its
//      thickness: a calibration wedge is shot through it), bent as beam
//      hardening bends a curve (part.h) for the pose search.
//   2. The pose: nothing about it is given. The global search samples the
//      turn in the detector's plane over a whole turn with the position
//      around the shadow's centroid, at depths spread evenly in magnification
//      from 1.05 to the detector's width over 30 mm (kMinVisibleMm of the
//      wedge across the detector); the best distinct samples are refined in
//      6 DOF and the best of those coarse to fine, on coarse levels (the
//      pose stages alone: the curve is a guess). Tilts are bounded by
//      kMaxTiltDeg.
//   3. The scatter, when the job gives none: the halo fit (halo.h) on the
//      open beam the posed wedge leaves; where that does not decide, the
//      halo around the box of the radiograph's sharp edges if it did. The
//      rest runs on the radiograph without it.
//   4. The pose again with the curve free (the joint fit on the render's
//      derivatives), and the tilts the fit doubts searched again from
//      kTiltRetryDeg either way and their mirror images (part.cpp).
//   5. The rounds of the part calibration: the table of the pixels whose
//      path is smooth (on the level about kTableWidthPx wide), its curve,
//      then the pose and the curve together, until the curve settles; the
//      final curve from the final table.
//   6. The curve's uncertainty: the table's own, combined with the curve's
//      change when the scatter's weight and width and each caliper value move
//      by their standard uncertainties (the table read again at the fitted
//      pose: the pose is fitted to the outline, which these barely move).
#pragma once

#include "xgauge/calibrate/wedge.h"

#include <optional>
#include <string>

namespace xgauge {

// A wedge lies on a holder: tilted by a few degrees at most.
inline constexpr double kMaxTiltDeg = 6.0;
// The step of the tilts' second search (PartCalibrationJob::tilt_retry_deg).
inline constexpr double kTiltRetryDeg = 3.0;
inline constexpr double kMinVisibleMm = 30.0;
// The tables' level (PartCalibrationJob::table_width_px): the coarsest at
// least this wide. A binned pixel is the mean of the pixels it bins, whose
// paths a smooth region holds linear across it, so its (path, intensity)
// is theirs with the noise averaged, and the bins' means come out nearly
// as precise from fewer, less noisy pixels; binned further, the band near
// the edges that the smoothness test leaves out widens, and the shortest
// paths (next to a wedge's thin end) leave the table (docs/method.md).
inline constexpr int kTableWidthPx = 1024;

// Steps 2 to 7 of calibrateFromWedge for a job with a model: `normalized`
// the radiograph as normalized, `image` with the job's scatter removed (the
// same as `normalized` when the scatter is estimated), `box_halo` the halo
// around the box of the radiograph's sharp edges when it decided (the
// fallback of the one around the posed wedge). Fills `out` as far as it
// gets.
void calibrateKnownWedge(const WedgeCalibrationJob& job, const Image& normalized,
                         const Image& image, std::optional<HaloFit> box_halo,
                         WedgeCalibration& out);

// Step 7's end, shared by both methods: the curve's standard uncertainty,
// the table's combined with every influence's change (and with the
// unmeasured halo's, out.halo->unseen_change, added to out.influences),
// set on out.material;
// a warning naming the largest part when it exceeds kLargeCurveUncertainty.
inline constexpr double kLargeCurveUncertainty = 0.005;
void combineCurveUncertainty(const std::string& name, WedgeCalibration& out);

}  // namespace xgauge
