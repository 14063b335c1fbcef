// The measurement pipeline: loaded inputs in, dimensions and poses out, by
// the job's schedule (measure/schedule.h) over the forward model
// (measure/model.h).
#pragma once

#include "xgauge/core/transform.h"
#include "xgauge/measure/inputs.h"
#include "xgauge/measure/job.h"
#include "xgauge/measure/schedule.h"
#include "xgauge/measure/self_check.h"
#include "xgauge/measure/tolerance.h"
#include "xgauge/measure/uncertainty.h"

#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace xgauge {

struct StageReport {
  std::string name;
  std::string method;
  int level = 0;             // pyramid level (0 = full size)
  int samples = 1;           // area samples per axis
  int evaluations = 0;       // renders of every radiograph in the stage...
  int with_derivatives = 0;  // ...of which renders with derivatives (xray/derivatives.h)
  double seconds = 0.0;
  double loss_before = 0.0;  // the stage's objective (for the reweighted least-squares
  double loss_after = 0.0;   // stage: the weighted sum of squared residuals)
  std::string termination;
  // The objective as the stage went: at each evaluation in order (derivative
  // -free stages; +inf where infeasible), or after each iteration (least
  // squares). For the report's chart of the loss by stage and evaluation.
  std::vector<double> trace;
};

struct MeasuredDimension {
  std::string name;
  double value = 0.0;
  bool free = false;
  std::string unit;
  // Free dimensions: the expanded uncertainty U (k = 2; the budget is in
  // MeasurementResult::uncertainty), nullopt when the radiographs cannot
  // determine the dimension on its own; the tolerance, when the job or the
  // part model gives one, and the verdict on it.
  std::optional<double> expanded_uncertainty;
  std::optional<Tolerance> tolerance;
  std::optional<Decision> decision;
  // With the job's verification (measure/verification.h) and this dimension
  // in it: `value` is corrected by the method's bias and
  // expanded_uncertainty is the substitution's U; the fit's own value and
  // the model budget's U are kept here. Without: an unverified U.
  bool verified = false;
  std::optional<Substitution> substitution;
  double fitted_value = 0.0;
  std::optional<double> own_expanded_uncertainty;
};

struct MeasuredRadiograph {
  std::string name;
  std::string pattern;
  Pose pose;
  double loss = 0.0;           // final loss at full size
  double magnification = 0.0;  // of the part's centre (its bounding box's), D / (D - z)
};

// Whether a fit is a measurement (measure/self_check.h, AcceptanceRule).
enum class MeasurementStatus {
  kMeasured,
  // Every attempt failed the job's acceptance rule (SelfCheck::failures
  // says why): the values are the best attempt's fit, not a result; no
  // dimension has a verdict.
  kNotMeasured,
};
std::string_view measurementStatusName(MeasurementStatus status);

struct MeasurementResult {
  MeasurementStatus status = MeasurementStatus::kMeasured;
  int attempts = 1;  // the pipeline's runs: 1 + the retries the acceptance rule took
  // Of the kept attempt: the pose candidates its joint fit started from
  // until one passed the acceptance rule (docs/method.md, "Pose
  // candidates"), and which of them it kept (1: the search's best).
  int candidates_tried = 1;
  int candidate_taken = 1;
  std::string candidate_origin = "the search's best";  // "r00: search start 2", ...
  std::vector<MeasuredDimension> dimensions;
  std::vector<MeasuredRadiograph> radiographs;
  std::vector<StageReport> stages;
  std::vector<double> theta;  // the full parameter vector
  double total_loss = 0.0;
  double seconds = 0.0;
  int evaluations = 0;
  // The budget of every free dimension (measure/uncertainty.h) and the
  // fit's checks of itself (measure/self_check.h): what a result may be
  // trusted for, and what may be wrong with it.
  UncertaintyBudget uncertainty;
  SelfCheck check;
};

// Runs the job's schedule on the loaded inputs. Shows a progress bar per
// stage.
MeasurementResult measure(const MeasurementInputs& inputs);

class ForwardModel;
struct MeasureOptions {
  // false: skip each radiograph's own pose search and only refine every free
  // parameter together from `theta` (a calibration's later rounds).
  bool search_poses = true;
  // false: skip the derivative-free joint stages too; only the final
  // (reweighted) least-squares stage runs.
  bool joint_search = true;
  // false: skip the uncertainty budget and the self-checks (a calibration's
  // intermediate fits, with a provisional material: their budget would cost
  // re-solves and warn about a misfit the next round removes).
  bool assess = true;
  // false: what the job's acceptance rule calls a failure is a warning, and
  // nothing is retried (a calibration's fit of its known part, which has
  // checks of its own).
  bool judge = true;
  // The schedule to follow instead of the job's (a wedge calibration's
  // search over the in-plane turn and the depth); not owned.
  const Schedule* schedule = nullptr;
  // false: leave each radiograph's loss at full size and the total to the
  // caller's takeFullSizeLosses, from the full-size simulation it renders
  // for its outputs anyway (`xgauge measure`: about 0.9 s of a 4096^2
  // pair's measurement was these two renders).
  bool full_size_losses = true;
  // Called on the calling thread as each stage ends, retries' stages too
  // (the front door's iteration callback, xgauge/xgauge.h); empty: none.
  std::function<void(const StageReport&)> on_stage;
};
// The same on a model built by the caller, from `theta` (model.start() for a
// fresh measurement).
MeasurementResult measure(ForwardModel& model, std::vector<double> theta,
                          const MeasureOptions& options = {});

// Each radiograph's loss at full size, and their total, from its simulation
// over the whole detector at the solution (report/measurement.h,
// simulateRadiographs): the same numbers measure() takes from renders of the
// rois alone.
void takeFullSizeLosses(const ForwardModel& model, const std::vector<Image>& simulated_full,
                        MeasurementResult& result);

}  // namespace xgauge
