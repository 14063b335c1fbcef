// The measurement pipeline: a job in, dimensions and poses out.
//
// Schedules (thesis 3.8 and ours), as stages over the forward model:
//   thesis   per radiograph: global search of x, y and the rotation about the
//            vertical axis (or the 2-DOF axis of a translated radiograph) by
//            uniform sampling, 5000 points, on a coarse pyramid level; then a
//            local 6-DOF (2-DOF) Nelder-Mead, 5000 evaluations; then every free
//            parameter of every radiograph together at full resolution,
//            Nelder-Mead, 5000 evaluations.
//   default  the same structure, faster: the initial position comes from the
//            shadow's centroid, the global search samples 150 points around it
//            and refines the best 4 (multi-start) with BOBYQA, local
//            stages use BOBYQA with restarts and small budgets on coarse levels,
//            and the joint fit runs coarse to fine on levels 512, 1024 and 2048 px
//            wide (or full size when smaller) with 2 x 2 area sampling, so
//            sub-pixel changes are seen.
#pragma once

#include "xgauge/core/transform.h"
#include "xgauge/measure/job.h"

#include <string>
#include <vector>

namespace xgauge {

struct StageReport {
  std::string name;
  std::string method;
  int level = 0;    // pyramid level (0 = full size)
  int samples = 1;  // area samples per axis
  int evaluations = 0;
  double seconds = 0.0;
  double loss_before = 0.0;  // the stage's objective (for the reweighted least-squares
  double loss_after = 0.0;   // stage: the weighted sum of squared residuals)
  std::string termination;
};

struct MeasuredDimension {
  std::string name;
  double value = 0.0;
  bool free = false;
  std::string unit;
};

struct MeasuredRadiograph {
  std::string name;
  std::string pattern;
  Pose pose;
  double loss = 0.0;  // final loss at full size
};

struct MeasurementResult {
  std::vector<MeasuredDimension> dimensions;
  std::vector<MeasuredRadiograph> radiographs;
  std::vector<StageReport> stages;
  std::vector<double> theta;  // the full parameter vector
  double total_loss = 0.0;
  double seconds = 0.0;
  int evaluations = 0;
};

// Runs the job's schedule. Shows a progress bar per stage.
MeasurementResult measure(const MeasurementJob& job);

class ForwardModel;
struct MeasureOptions {
  // false: skip each radiograph's own pose search and only refine every free
  // parameter together from `theta` (a calibration's later rounds).
  bool search_poses = true;
  // false: skip the derivative-free joint stages too; only the final
  // (reweighted) least-squares stage runs.
  bool joint_search = true;
};
// The same on a model built by the caller, from `theta` (model.start() for a
// fresh measurement).
MeasurementResult measure(ForwardModel& model, std::vector<double> theta,
                          const MeasureOptions& options = {});

// Writes result.json, the final simulated radiographs and the difference
// images (float TIFF and diverging-colour PNG) into `folder`, atomically.
void writeMeasurementOutputs(const MeasurementJob& job, const MeasurementResult& result,
                             const std::filesystem::path& folder);

}  // namespace xgauge
