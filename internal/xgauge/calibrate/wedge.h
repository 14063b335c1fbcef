// Material calibration from one radiograph of a wedge (thesis 3.4a, docs/method.md), done
// automatically:
//   1. normalize (dark, flat, white region) and remove the detector's
//      scintillator scatter (image/scatter.h), so that the curve is
//      the scatter-free I(x) that the forward model pairs with its own scatter:
//      the job's "scatter" or, when it has none, the scatter and the panel's
//      column darkening fitted to the halo around the wedge (halo.h), which
//      material.json then carries for the measurements that use it;
//   2. find the ramp's columns and its thin and thick end rows (ramp.h); when
//      that or the steps below fail along the columns (no ramp, or a band no
//      curve fits) and the job gives no ramp, all of it again along the rows
//      (the wedge turned by 90 or 270 degrees): the transposed radiograph
//      seen by the transposed machine; when both fail, the first failure;
//   3. map every pixel of the band to its path length through the wedge by
//      the machine geometry, not by a straight line in rows. Both ends of the
//      ramp lie on the wedge's back face (the face towards the detector), so
//      their distance on the detector, |Y_thin - Y_thick|, is the ramp length
//      H times that face's magnification M = D / (D - z_back): that gives the
//      face's height z_back above the detector and where the ends are. The
//      floor of the ramp is the plane through the thin end on the back face
//      and the thick end x_max above the back face; each pixel's ray crosses
//      the back face and that plane, and the distance between is its path.
//      The thin end is taken for 0 mm, as in the thesis; eq. 3.7 corrects it;
//   4. average every row of the band into a table (mean path, mean
//      intensity), leaving out `margin_rows` rows at each end;
//   5. fit M = 1 .. max_terms exponentials with a free amplitude and pick the
//      smallest M that fits within the noise (curve.h);
//   6. shift and scale by eq. 3.7 so that I(0) = 1 and I(x_max) is kept, with
//      x_max the path at the thick end (the wedge's full thickness, seen along
//      the slightly oblique ray there);
//   7. the curve's standard uncertainty, written into material.json: what
//      its table shows (CurveFit::tableUncertainty) combined with the curve's
//      largest change over the calibrated range when the scatter's weight and
//      width and the wedge's thickness and ramp length each move by their
//      standard uncertainty (GUM, sensitivities by re-solving). The range,
//      from the first row to x_max, is written with it.
// With "rate_floor" (curve.h) every rate is at least the material's
// attenuation at its weakest in the tube's spectrum, so the curve keeps
// falling beyond the wedge's thickness.
//
// Job JSON (paths relative to the job file; unknown keys are errors):
//   description        free text
//   machine            machine file (xray/machine.h)
//   radiograph         {"image", "dark", "flat" (optional, both or neither),
//                       "white_region": [x, y, w, h]}
//   wedge              either the wedge's model, fitted as a known part
//                      (wedge_part.h: steps 2 to 6 replaced, the ramp not used):
//                      {"model": part model file, "dimensions": {name: caliper
//                      value} for every dimension of the model, optional
//                      "dimension_uncertainty_mm" (standard, default 0.01)},
//                      or the ramp method's
//                      {"max_thickness_mm": x_max, "ramp_length_mm": H}: the full
//                      thickness at the thick end and the ramp's length along
//                      the detector's rows (thick end to thin end); optional
//                      "max_thickness_uncertainty_mm", "ramp_length_uncertainty_mm"
//                      (standard uncertainties, default 0.01 and 0.02 mm: a
//                      caliper's)
//   rate_floor         optional {"compound", "density_g_cm3", "tube_kv"} (curve.h)
//   scatter            optional {"weight": w, "sigma_mm": s} (measure/job.h);
//                      without it the scatter is estimated from the halo, and
//                      {"weight": 0, "sigma_mm": 1} says the detector has none
//   ramp               optional overrides: {"columns": [begin, end],
//                      "rows": [thin end, thick end]} (continuous row coordinates)
//   max_terms          optional, 1 to 4 (default 4)
//   margin_rows        optional, rows left out at each end (default 4)
#pragma once

#include "xgauge/calibrate/curve.h"
#include "xgauge/calibrate/halo.h"
#include "xgauge/calibrate/part.h"
#include "xgauge/calibrate/ramp.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/image/image.h"
#include "xgauge/image/lag.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/measure/job.h"
#include "xgauge/xray/machine.h"

#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace xgauge {

struct WedgeCalibrationJob {
  std::filesystem::path file;
  std::string description;
  std::filesystem::path machine_file;
  Machine machine;  // loaded from machine_file
  RadiographSpec radiograph;
  // The wedge as a known part (wedge_part.h): its model, with the lab's
  // caliper values of its dimensions; none: the ramp method below.
  std::filesystem::path model_file;
  std::shared_ptr<const PartModel> model;
  std::map<std::string, double> caliper;  // every dimension of the model
  double caliper_uncertainty_mm = 0.01;   // of each caliper value
  // The ramp method: the wedge's thickness and ramp length.
  double max_thickness_mm = 0.0;
  double ramp_length_mm = 0.0;
  double max_thickness_uncertainty_mm = 0.01;
  double ramp_length_uncertainty_mm = 0.02;
  std::optional<RateFloor> rate_floor;
  ScatterModel scatter;
  bool estimate_scatter = true;  // no "scatter" key: fit it to the halo
  RampOptions ramp;
  int max_terms = 4;
  int margin_rows = 4;

  static WedgeCalibrationJob load(const std::filesystem::path& path);
};

// One influence on the curve (step 7): its value and standard uncertainty,
// and the curve's largest change over the calibrated range when it moves by
// that uncertainty.
// The names of the scatter's influences on the curve: its weight, its
// width and a two-width kernel's end (image/scatter.h).
inline constexpr const char* kScatterWeightInfluence = "scatter weight";
inline constexpr const char* kScatterWidthInfluence = "scatter sigma_mm";
// (ScatterModel::alternatives' names).
inline constexpr const char* kScatterKernelInfluence = "scatter kernel";
inline constexpr const char* kScatterKernelChoiceInfluence = "scatter kernel choice";
// The share of the flat's slope that is the tube's heel (image/open_beam.h).
inline constexpr const char* kOpenBeamHeelInfluence = "open beam's heel";

struct CurveInfluence {
  std::string name;
  double value = 0.0, uncertainty = 0.0;
  double change = 0.0;
  // The curve calibrated with the influence moved by +uncertainty (absent
  // for an influence without one, such as the unmeasured halo).
  std::optional<ExponentialSum> moved;
  std::string unit = "mm";  // of value and uncertainty (every input but the scatter weight's)
};

struct WedgeCalibration {
  RampDetection ramp;
  // Geometry from the ramp's ends.
  double magnification = 0.0;   // of the back face (a known part: of its box's centre)
  double back_face_z_mm = 0.0;  // height of the back face above the detector
  double x_max_mm = 0.0;        // path at the thick end
  // The intensity table, thin end first.
  std::vector<double> rows, path_mm, transmission;
  CurveFit fit;
  double x0_mm = 0.0;  // eq. 3.7
  ExponentialSum material{{{1.0, 0.0}}};
  double table_uncertainty = 0.0;
  std::vector<CurveInfluence> influences;
  // The scatter taken out of the radiograph: the job's or the halo's.
  ScatterModel scatter;
  std::optional<HaloFit> halo;  // when estimated (its primary image moved to `normalized`)
  // The open beam's field the halo is removed in (image/open_beam.h): fitted
  // to the job's flat frame, uniform without one.
  OpenBeamField open_beam;
  double seconds = 0.0;
  // Each step's seconds, in order (a wedge fitted as a known part: its
  // part calibration's among them).
  std::vector<StepSeconds> step_seconds;
  Image normalized;                // the radiograph as the ramp was found in (scatter removed)
  std::optional<LagEstimate> lag;  // the previous frame's lag subtracted, if named
  // The step under way or, after a success, "done": what a failure names.
  std::string step;
  bool ramp_found = false;  // `ramp` holds a detection
  // The ramp runs along the rows (the wedge turned by 90 or 270 degrees):
  // `ramp`, `rows` and `normalized` are those of the transposed radiograph.
  bool turned = false;
  // The wedge fitted as a known part (wedge_part.h): its calibration job
  // (built from this one) and what it found (initial material, rounds,
  // pose); `path_mm`, `transmission`, `fit` and `material` are its final
  // table and curve.
  std::shared_ptr<const PartCalibrationJob> part_job;
  std::optional<PartCalibration> part;

  // `radiograph` (normalized, before the scatter's removal, as the
  // calibration read it) without a scatter of this weight and width in the
  // open beam's field carrying `heel_share` of the flat's slope: the
  // halo's removal (with its darkening) when it was estimated, else the
  // scatter's. How the curve's uncertainty propagates the scatter's.
  Image primaryWith(const Image& radiograph, double pitch_mm, const PixelRect& white_region,
                    double weight, double sigma_mm,
                    double heel_share = OpenBeamField::kHeelShare) const;
};

// The alternatives of the characterised halo the calibration removed
// (ScatterModel::alternatives, named as the wedge's influences), with which
// the curve is calibrated again, its change scaled by each one's scale as
// the budget scales its move; none for a halo estimated from the wedge's
// own shot.
std::vector<HaloAlternative> kernelAlternatives(const WedgeCalibration& calibration);

WedgeCalibration calibrateFromWedge(const WedgeCalibrationJob& job);
// The same into `out`, which holds what the steps found so far when it
// throws (normalized image, ramp, table, fits tried): a failed
// calibration's diagnostic (report/calibration.h).
void calibrateFromWedge(const WedgeCalibrationJob& job, WedgeCalibration& out);

}  // namespace xgauge
