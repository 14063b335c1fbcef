// A measurement job: what to measure, from which radiographs, how. Plain
// data (paths and settings); measure/inputs.h turns it into the loaded
// inputs. Every key is documented in docs/formats.md.
//
// Job JSON keys (paths relative to the job file; unknown keys are errors):
//   description        free text
//   part               part model file (geometry/part_model.h)
//   dimensions         optional:
//     free             names to measure (default: all); the others stay fixed
//     fixed            {name: value} for dimensions held at a known value (default nominal)
//     start            {name: value} starting values of free dimensions (default nominal)
//     bounds           {name: [min, max]} search bounds of free dimensions (default: the
//                      model's bounds narrowed to nominal +- 10 %)
//   machine            machine file (xray/machine.h)
//   material           exponential-sum material file (material/exponential_sum.h)
//   scatter            optional {"weight": w, "sigma_mm": s}: the detector's scintillator
//                      scatter, modelled in the fit (image/scatter.h)
//   radiographs        list of:
//     name             unique name
//     image            raw or normalized radiograph (TIFF)
//     dark, flat       optional dark and flat frames (TIFF); bad pixels are repaired
//     white_region     [x, y, w, h]: open beam; the image is divided by its mean
//                      (thesis eq. 3.9, docs/method.md)
//     roi              optional [x, y, w, h]: pixels compared; default: the part's shadow
//                      (below 0.9 of the open beam on a copy about 256 px wide) grown by
//                      10 % of its size + 8 px on each side
//     pattern          optional, "free" (default) | "translated" | "rotated" | "known"
//                      (docs/conventions.md)
//     reference        translated and rotated: the radiograph it refers to
//     distance_mm      translated: the exact distance moved (mm)
//     distance_uncertainty_mm
//                      translated, optional: its standard uncertainty (mm),
//                      0 .. 100, default kDefaultTranslationUncertaintyMm
//     axis_elevation_bounds_deg
//                      translated, optional: [lo, hi] within [-90, 90], default
//                      [-90, 90]: bounds of the move's angle out of the world's
//                      x-z plane (towards the detector's columns). A line
//                      detector (one row) cannot see a move along its columns'
//                      direction, so it needs them (a conveyor in the row's plane)
//     pose             known: the pose (xray/machine.h keys)
//   pose_bounds        search bounds of every free pose (world frame, of the part's
//                      bounding-box centre; angles in degrees, R = Rz Ry Rx):
//                      {"rotation_deg": [[rx0, rx1], [ry0, ry1], [rz0, rz1]],
//                       "centre_mm": [[x0, x1], [y0, y1], [z0, z1]]}
//   nominals           optional {name: value}: this part number's nominal values of free
//                      dimensions: the report's deviations are taken from them (or from a
//                      tolerance's nominal), never from the part model's defaults
//   tolerances         optional {name: {"nominal" (optional, default the job's "nominals",
//                      else the part model's), "lower", "upper"}}: tolerances of free
//                      dimensions, replacing the part model's defaults (measure/tolerance.h)
//   schedule           optional, "default", "bobyqa", "gauss-newton" or "thesis"
//                      (measure/schedule.h)
//   loss               optional, "l1" (thesis eq. 3.13, default) or "l2"
//   acceptance         optional: when a fit is not a measurement (measure/self_check.h,
//                      AcceptanceRule): {"max_misfit_ratio": 1 .. 1000, default 4;
//                      "max_region_share": 0 .. 1, default 0.10; "fail_at_bound": bool,
//                      default true; "retries": 0 .. 10, default 2}
//   verification       optional: a verification file (`xgauge verify`,
//                      measure/verification.h): free dimensions it verified are
//                      corrected by its bias and get U by substitution
//   unverified_verdicts
//                      optional, default false: give verdicts on tolerances with a
//                      U no verification backs (the model budget's alone)
//   seed               optional, default 1
#pragma once

#include "xgauge/core/config.h"
#include "xgauge/core/transform.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/image/image.h"
#include "xgauge/image/scatter.h"
#include "xgauge/loss/loss.h"
#include "xgauge/measure/schedule.h"
#include "xgauge/measure/self_check.h"
#include "xgauge/measure/tolerance.h"

#include <array>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace xgauge {

enum class Acquisition { kFree, kTranslated, kRotated, kKnown, kTurned };

// What of the material's curve the final fit may correct (job
// "refine_material"): nothing, or a common scale of its rates with the
// calibration's uncertainty as a prior (docs/method.md, "The curve refined
// in situ"). Needs a view from another direction: a rotated radiograph or a
// second free one.
enum class MaterialRefinement { kNone, kRateScale };

// The standard uncertainty of a translated radiograph's distance when the
// job states none: a linear stage's positioning, 5 um.
inline constexpr double kDefaultTranslationUncertaintyMm = 0.005;

// The standard uncertainty of a turned radiograph's angle when the job states
// none: a rotary stage's encoder, 0.005 deg.
inline constexpr double kDefaultTurnUncertaintyDeg = 0.005;

struct RadiographSpec {
  std::string name;
  std::filesystem::path image, dark, flat;  // dark/flat empty when not given
  // The raw frame the detector exposed just before this one, whose lag is
  // subtracted (image/lag.h); empty when not given.
  std::filesystem::path previous;
  PixelRect white_region;
  std::optional<PixelRect> roi;
  Acquisition pattern = Acquisition::kFree;
  int reference = -1;        // index of the reference radiograph
  double distance_mm = 0.0;  // translated
  double distance_uncertainty_mm = kDefaultTranslationUncertaintyMm;  // translated
  std::array<double, 2> axis_elevation_bounds_deg{-90.0, 90.0};       // translated
  Pose known_pose;                                                    // known
  double angle_deg = 0.0;                                             // turned
  double angle_uncertainty_deg = kDefaultTurnUncertaintyDeg;          // turned
};

struct MeasurementJob {
  std::filesystem::path file;
  std::string description;
  std::filesystem::path part_file, machine_file, material_file;
  std::vector<std::string> free_dimensions;             // in model order
  std::map<std::string, double> fixed_dimensions;       // overrides of nominal
  std::map<std::string, double> start;                  // starting values
  std::map<std::string, std::array<double, 2>> bounds;  // explicit bounds
  ScatterModel scatter;
  std::vector<RadiographSpec> radiographs;
  std::array<std::array<double, 2>, 3> rotation_bounds_deg{};
  std::array<std::array<double, 2>, 3> centre_bounds_mm{};
  // The job's own tolerances of free dimensions, source "job"; tolerancesFor()
  // adds the part model's defaults.
  std::map<std::string, Tolerance> tolerances;
  // The job's stated nominal values ("nominals"), per free dimension.
  std::map<std::string, double> nominals;
  ScheduleKind schedule = ScheduleKind::kDefault;
  LossKind loss = LossKind::kMeanAbsolute;
  MaterialRefinement refine_material = MaterialRefinement::kNone;
  AcceptanceRule acceptance;
  std::filesystem::path verification_file;  // empty: unverified
  bool unverified_verdicts = false;
  uint64_t seed = 1;

  // Reads a parsed job file whose part model `part` the caller has loaded
  // from the "part" key (job.part_file names it; partFileOf gives it);
  // validates every key against the model (Error naming the file and key).
  // Does not call finish(): a calibration job adds keys of its own. Without
  // `needs_material` the material key is optional (material_file empty).
  static MeasurementJob fromConfig(const ConfigNode& root, const std::filesystem::path& path,
                                   const PartModel& part, bool needs_material);
  // The part model file a parsed job names (relative to the job file).
  static std::filesystem::path partFileOf(const ConfigNode& root,
                                          const std::filesystem::path& path);
};

// [x, y, width, height] in whole pixels, not empty (Error at the node otherwise).
PixelRect pixelRectFromConfig(const ConfigNode& node);

std::string_view acquisitionName(Acquisition pattern);

}  // namespace xgauge
