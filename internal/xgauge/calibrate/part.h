// Material calibration from radiographs of a part whose dimensions are known
// (thesis 3.4b, docs/method.md): the measurement problem with the material free.
//
//   1. Initial material (thesis eq. 3.8): one exponential through I(0) = 1
//      and the mean intensity I1 of a uniform region of known path x1,
//      mu1 = -ln(I1) / x1 (or, for a wedge, I1 the darkest 2 % of the
//      shadow and x1 the wedge's thickness).
//   2. Poses: the measurement schedule (measure/measure.h) with the known
//      dimensions fixed, finds every radiograph's pose with that material.
//   3. Material: with the poses fixed, every pixel of every roi (on the
//      coarsest level at least table_width_px wide) whose path is
//      smooth around it (not on an edge, where the pixel's mean intensity is
//      not the intensity of its centre's path) gives a pair (path, intensity);
//      the intensity has the modelled scatter taken out, w G(I) computed from
//      the current model, as the forward model adds it. The pairs are binned
//      by path (bins of 1/300 of the longest path, at least 20 pixels each;
//      fewer and smaller bins when there are few pixels, as on a line
//      detector: about 100 pixels per bin, at least 20 bins of 5 pixels)
//      into a table, to which M = 1 .. terms exponentials are fitted
//      (curve.h; weights summing to 1, so I(0) = 1).
//   4. Everything together: poses, the material's weights and rates (and any
//      free dimension) by the measurement's final least-squares stage on the
//      per-pixel residuals on the schedule's level (thesis: "in the last
//      hierarchical step, we only optimize the pose and the coefficients").
//      Steps 3 and 4 fix what an alternation would leave coupled: a pose
//      found with the wrong material has absorbed part of the error (a
//      rotation changes the paths), and only a joint step removes it.
//      Step 4 repeats, up to `rounds` times, until the material changes by
//      less than 2e-4 in intensity.
//   5. The material returned: step 3's fit (M = 1 .. terms, the smallest
//      that fits within the noise, curve.h) on the pixels at the final poses.
//      The joint fit's own material follows the image loss, which barely sees
//      short paths (they occur only next to edges); the binned table weights
//      every path length alike, as a wedge would.
//
// Job JSON: a measurement job (measure/job.h) without "material", with the
// known dimensions under "dimensions": {"fixed": {...}} (any left free are
// measured as well), and
//   calibration  {"terms": M (1 to 4, default 3),
//                 "rounds": 1 to 10 (default 4),
//                 "initial": {"radiograph": name, "region": [x, y, w, h],
//                             "path_mm": x1},
//                 "rate_floor": optional {"compound", "density_g_cm3", "tube_kv"}
//                 (curve.h: every rate at least the material's attenuation
//                 at its weakest in the tube's spectrum)}
// The material written carries the calibrated path range and, as its
// transmission uncertainty, what its table shows (CurveFit::tableUncertainty).
#pragma once

#include "xgauge/calibrate/curve.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/measure/inputs.h"
#include "xgauge/measure/job.h"
#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"
#include "xgauge/measure/schedule.h"

#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace xgauge {

struct PartCalibrationJob {
  // The measurement job (material_file empty) and everything it names,
  // loaded once.
  std::shared_ptr<const MeasurementInputs> inputs;
  const MeasurementJob& measurement() const { return inputs->job; }
  int terms = 3;
  int rounds = 4;
  int initial_radiograph = 0;  // index into measurement().radiographs
  // Eq. 3.8's uniform region; without it (a wedge calibration), the darkest
  // kDarkestPercent of the radiograph's roi, which initial_path_mm then
  // gives for the part's longest path (a calibration wedge seen through its
  // thickness).
  std::optional<PixelRect> initial_region;
  double initial_path_mm = 0.0;
  std::optional<RateFloor> rate_floor;
  // The schedule to follow instead of the job's, in the pose search and the
  // rounds' least squares (a wedge calibration's search over the turn in
  // plane and the depth). Without an initial region its parts run apart:
  // the pose stages alone with eq. 3.8's guess, the joint stages with the
  // curve free, the least squares in the rounds.
  std::optional<Schedule> pose_schedule;
  // Greater than 0: after the poses with a free curve, the initial
  // radiograph's tilts (rotation about x and y) that the fit leaves in doubt
  // are searched again by this step and by their mirror images (part.cpp,
  // retryTilts), for a part such as a calibration wedge seen in part, whose
  // tilt the local fit can leave a few degrees off or mirrored.
  double tilt_retry_deg = 0.0;
  // The table's level: the coarsest pyramid level at least this wide
  // (registeredTable).
  int table_width_px = 2048;

  static PartCalibrationJob load(const std::filesystem::path& path);
};

// The wall time of one step of a calibration (its bench's figures).
struct StepSeconds {
  std::string step;
  double seconds = 0.0;
};
// Appends the seconds since `since` under `step` and restarts `since`.
void addStepSeconds(std::vector<StepSeconds>& into, std::string step,
                    std::chrono::steady_clock::time_point& since);

struct PartCalibrationRound {
  ExponentialSum material{{{1.0, 0.0}}};
  ExponentialFitReport report;
  double change = 0.0;     // largest intensity change from the previous material
  double pose_loss = 0.0;  // the measurement's total loss before this material
  int64_t pixels = 0;      // pixel pairs used
};

struct PartCalibration {
  double initial_intensity = 0.0;  // I1
  double initial_mu_per_mm = 0.0;  // eq. 3.8
  std::vector<PartCalibrationRound> rounds;
  CurveFit fit;                               // of the last round
  std::vector<double> path_mm, transmission;  // the last round's table
  double max_path_mm = 0.0;                   // longest path in the table
  ExponentialSum material{{{1.0, 0.0}}};
  MeasurementResult measurement;  // the last pose fit
  double seconds = 0.0;
  std::vector<StepSeconds> step_seconds;  // each step's, in order
  // The step under way or, after a success, "done": what a failure names.
  std::string step;
};

// The percentile of the radiograph's roi that stands for the longest path
// when the job gives no initial region.
inline constexpr double kDarkestPercent = 2.0;

// Step 3's table at `theta`: the smooth pixels' (path, scatter-free
// intensity) pairs of the coarsest pyramid level at least `width_px` wide,
// binned by path. `noise` is the median standard error of a bin's mean.
// Throws Error when too few paths remain.
struct RegisteredTable {
  std::vector<double> path_mm, transmission;
  double noise = 0.0;
  int64_t pixels = 0;
};
RegisteredTable registeredTable(ForwardModel& model, const std::vector<double>& theta,
                                int width_px = 2048);

PartCalibration calibrateFromPart(const PartCalibrationJob& job);
// Its steps 1 and 2 into `out` (eq. 3.8's material, the pose fit): returns
// the parameters found. Without an initial region, searchKnownPart and
// then freeCurvePoses.
std::vector<double> poseKnownPart(const PartCalibrationJob& job, PartCalibration& out);
// Step 1 and the pose search of step 2 (without an initial region: its
// schedule's pose stages alone, with eq. 3.8's curve bent).
std::vector<double> searchKnownPart(const PartCalibrationJob& job, PartCalibration& out);
// The rest of step 2 without an initial region, from `theta`
// (searchKnownPart's, for inputs of the same parameters: a wedge
// calibration removes the scatter in between): the poses again with the
// bent curve free, by the schedule's joint stages, and the tilts the fit
// doubts searched again (PartCalibrationJob::tilt_retry_deg).
std::vector<double> freeCurvePoses(const PartCalibrationJob& job, std::vector<double> theta,
                                   PartCalibration& out);
// Its steps 3 to 5 into `out`, from `theta` (poseKnownPart's, for inputs of
// the same parameters: a wedge calibration removes the scatter in between).
void refineKnownPart(const PartCalibrationJob& job, std::vector<double> theta,
                     PartCalibration& out);
// The same into `out`, which holds what the steps found so far when it
// throws (eq. 3.8, the rounds, the last table and fits tried): a failed
// calibration's diagnostic (report/calibration.h).
void calibrateFromPart(const PartCalibrationJob& job, PartCalibration& out);

}  // namespace xgauge
