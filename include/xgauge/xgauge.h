// xgauge's front door: a part's dimensions measured from radiographs, and a
// material calibrated, from code, in the style of Ceres's Solver::Options / Solve / Summary. This
// header, xgauge/runtime.h, radiographs.h, lab.h, production.h and
// xgauge/version.h are what the installed package exposes; they need
// nothing but the C++ standard library. docs/library.md shows a whole
// program; docs/formats.md documents the job and result.json.
//
//   xgauge::MeasurementOptions options;
//   options.job_file = "examples/prism_a_small_job.json";
//   std::string why;
//   if (!options.IsValid(&why)) ...
//   const xgauge::MeasurementSummary summary = xgauge::measure(options);
//   std::cout << summary.FullReport();
//   if (summary.termination == xgauge::TerminationType::kMeasured) ...
//
// Nothing here throws for bad input or a failed fit: the summary's
// termination and message say what happened. The library writes its own
// messages (stages, warnings) to spdlog's default logger on stderr; a
// program that wants them per call sets `on_stage`.
#pragma once

#include "xgauge/runtime.h"

#include <cstddef>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace xgauge {

// How a measurement ended.
enum class TerminationType {
  kMeasured,     // the fit explains the radiographs: the values are results
  kNotMeasured,  // the data contradict every fit tried (failures say why):
                 // the values are the rejected fit's, not results; no verdict
  kFailure,      // the inputs could not be used (message names the file and key)
};
const char* TerminationTypeToString(TerminationType type);  // "measured", ...

// A dimension's verdict against its tolerance (ISO 14253-1, the decision
// rule in docs/method.md); kNone where there is no tolerance, or the U is
// unverified and the job does not accept unverified verdicts.
enum class VerdictType { kNone, kConforms, kDoesNotConform, kInconclusive };
const char* VerdictTypeToString(VerdictType type);  // "", "conforms", ...

// One stage of the fit, as it ends (a pose search, a joint search, the
// least-squares fit): what an iteration callback sees.
struct StageSummary {
  std::string name;    // e.g. "pose t00", "joint", "least squares"
  std::string method;  // the optimiser
  int level = 0;       // image pyramid level (0: full size)
  int evaluations = 0;
  double loss_before = 0.0, loss_after = 0.0;
  double seconds = 0.0;
  std::string termination;  // the optimiser's reason to stop
};
using StageCallback = std::function<void(const StageSummary&)>;

struct MeasurementOptions {
  // The job (docs/formats.md, "Measurement job"): a file, whose relative
  // paths are taken from its folder; or its JSON text, whose relative paths
  // are taken from `base_folder`. Exactly one of the two.
  std::filesystem::path job_file;
  std::string job_json;
  std::filesystem::path base_folder = ".";
  // Optional: a virtual lab's truth.json; the reports show each dimension's
  // error against it.
  std::filesystem::path truth_file;
  // Optional: where result.json, the simulated and difference images,
  // measure.log and (with write_report) report.html go, each written
  // atomically; empty: nothing is written. The folder's parent must exist.
  std::filesystem::path output_folder;
  bool write_report = true;
  // Called on the calling thread as each stage of the fit ends.
  StageCallback on_stage;

  // True when the options are consistent (one form of the job, a base
  // folder for its text); otherwise false with the reason in *error (when
  // error is not null). Files are checked as measure() reads them.
  bool IsValid(std::string* error) const;
};

struct DimensionSummary {
  std::string name;
  std::string unit;  // "mm" or "deg"
  double value = 0.0;
  bool free = false;  // measured (false: held at the job's value)
  // U (k = 2); nullopt where the radiographs cannot determine the dimension
  // alone, and for held dimensions.
  std::optional<double> expanded_uncertainty;
  bool verified = false;  // U from a verification (substitution) on a master
  std::optional<double> lower_limit, upper_limit;  // the tolerance zone
  VerdictType verdict = VerdictType::kNone;
  std::optional<double> true_value;  // from truth_file
};

struct MeasurementSummary {
  TerminationType termination = TerminationType::kFailure;
  std::string message;  // kFailure: the error; otherwise empty
  std::vector<DimensionSummary> dimensions;
  std::vector<std::string> failures;  // kNotMeasured: the acceptance rule's reasons
  std::vector<std::string> warnings;  // what may be wrong with a result
  std::vector<StageSummary> stages;
  int attempts = 0;
  int evaluations = 0;
  double final_loss = 0.0;
  double seconds = 0.0;
  // The exit status `xgauge measure` gives (docs/formats.md): 0 every
  // verdict conforms, 1 not measured or failure, 2 some verdict
  // inconclusive or withheld, 3 some dimension does not conform.
  int exit_status = 1;

  // One line: the termination, the dimensions' count and the worst verdict.
  std::string BriefReport() const;
  // The table `xgauge measure` prints: every dimension with its U, tolerance
  // zone and verdict (and error against the truth), combinations,
  // warnings; for kNotMeasured the failures first.
  std::string FullReport() const;
  // result.json's text (docs/formats.md); empty for kFailure.
  std::string ToJson() const;

 private:
  friend class MeasurementSummaryBuilder;
  std::string full_report_;
  std::string json_;
};

// Measures the job. Never throws for bad input or a failed fit (see
// TerminationType); std::bad_alloc and the like propagate.
MeasurementSummary measure(const MeasurementOptions& options);

// Calibration of a material's curve I(x) (docs/method.md): from one
// radiograph of a wedge, or from radiographs of a part of known dimensions;
// or of the detector's pose (tilt and turn) from radiographs of a part of
// known dimensions (kGeometry: machine.json and geometry.json).
enum class CalibrationKind { kWedge, kPart, kGeometry };

enum class CalibrationTermination {
  kCalibrated,  // material.json, calibration.json (and report.html) written
  kStepFailed,  // a step could not go on (step and message say which and
                // why); what the steps found is in failed_calibration.json
                // (and .html), and no material was written
  kFailure,     // the inputs could not be used (message names the file and key)
};
const char* CalibrationTerminationToString(CalibrationTermination type);

struct CalibrationOptions {
  CalibrationKind kind = CalibrationKind::kWedge;
  // The calibration job (docs/formats.md), relative paths from its folder.
  std::filesystem::path job_file;
  // Required: the outputs, each written atomically; an earlier run's
  // outputs that this run's contradict (a failure's diagnostic beside a new
  // material, or the reverse) are removed as this run's arrive.
  std::filesystem::path output_folder;
  // Optional: a virtual lab's truth.json: the outputs give the curve's
  // deviation from the true one.
  std::filesystem::path truth_file;
  bool write_report = true;
  // kGeometry: how far from the machine's stated pose each angle may go (deg).
  double reach_deg = 2.0;

  bool IsValid(std::string* error) const;
};

struct CalibrationSummary {
  CalibrationTermination termination = CalibrationTermination::kFailure;
  std::string message;  // kStepFailed and kFailure: why
  std::string step;     // the step that ran last (kStepFailed: the one that failed)
  // The material: I(x) = sum_k weight_k exp(-mu_k x) (x in mm), the
  // standard uncertainty of I(x), the paths it was calibrated over.
  struct Term {
    double weight = 0.0, mu_per_mm = 0.0;
  };
  std::vector<Term> terms;
  double transmission_uncertainty = 0.0;
  std::optional<std::pair<double, double>> calibrated_range_mm;
  // kGeometry: the detector's tilt about u and v and its rotation (deg),
  // their standard uncertainties, and the worst misfit ratio.
  std::vector<double> detector_angles_deg, detector_angle_uncertainties_deg;
  double misfit_ratio = 0.0;
  double seconds = 0.0;

  std::string BriefReport() const;
  // What `xgauge calibrate` prints: the wedge's ramp or pose, the fits by
  // number of terms, the curve's uncertainty and its influences, the material.
  std::string FullReport() const;
  // material.json's text; empty unless kCalibrated, and for kGeometry.
  std::string ToJson() const;

 private:
  friend class CalibrationSummaryBuilder;
  std::string full_report_;
  std::string json_;
};

// Calibrates. Never throws for bad input or a failed step (see
// CalibrationTermination).
CalibrationSummary calibrate(const CalibrationOptions& options);

// The detector characterised from dark and flat series and shots of an
// opaque edge, a lag pair and a covered quadrant: halo, lag, crosstalk, bad
// pixels (detector.json and bad_pixels.json).
struct CharacterizationOptions {
  std::filesystem::path job_file;       // the characterisation job (docs/formats.md)
  std::filesystem::path output_folder;  // required
};

struct CharacterizationSummary {
  RunTermination termination = RunTermination::kFailure;
  // kFailure: why; otherwise what was written, in words.
  std::string message;
  std::string report;  // what `xgauge characterize` prints
};

// Never throws for bad input; shows a progress bar where enabled (xgauge/runtime.h).
CharacterizationSummary characterize(const CharacterizationOptions& options);

// The measuring method verified on a calibrated master (ISO 15530-3): its
// bias and repeatability per dimension (verification.json), for
// measurement jobs to name.
struct VerificationOptions {
  std::filesystem::path job_file;       // the master's certificate and its measurement jobs
  std::filesystem::path output_folder;  // required
};

struct VerificationSummary {
  RunTermination termination = RunTermination::kFailure;
  // kFailure: why; otherwise what was written, in words.
  std::string message;
  std::size_t measurements = 0;  // of the master
  std::string report;            // the table `xgauge verify` prints
};

VerificationSummary verify(const VerificationOptions& options);

// Where to put the part (xgauge plan): every set of the job's candidate
// views predicted before a shot is taken, each free dimension's U from the
// measurement's own budget at the nominal part, the sets ranked by the
// job's criterion (plan.json, job.json: the best set's measurement job,
// report.html; docs/method.md, "Planning the views").
struct PlanOptions {
  std::filesystem::path job_file;       // the plan job (docs/formats.md, "Plan job")
  std::filesystem::path output_folder;  // required
};

struct PlanSummary {
  RunTermination termination = RunTermination::kFailure;
  // kFailure: why; otherwise what was written, in words.
  std::string message;
  std::size_t screened = 0;  // sets of views screened
  std::string report;        // the table `xgauge plan` prints: the best and the compared sets
};

// Never throws for bad input; shows a progress bar where enabled.
PlanSummary plan(const PlanOptions& options);

}  // namespace xgauge
