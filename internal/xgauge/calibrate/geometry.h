// Geometry calibration: the detector's pose (its tilt about its two axes
// and its turn in its plane, xray/machine.h) fitted to radiographs of a part
// whose dimensions are known, with the poses of the part (docs/method.md,
// "Geometry calibration"). Input: a measurement job whose dimensions are all
// fixed at the part's known values; output: the machine file with the pose
// and its standard uncertainties.
#pragma once

#include "xgauge/measure/measure.h"
#include "xgauge/xray/machine.h"

#include <nlohmann/json.hpp>

#include <array>
#include <filesystem>
#include <string>
#include <vector>

namespace xgauge {

struct GeometryCalibration {
  Machine machine;              // the job's machine with the fitted pose and its uncertainties
  nlohmann::json machine_file;  // the job's machine file with the pose's keys added
  std::array<double, 3> angles_deg{};       // tilt_u, tilt_v, rotation
  // Their standard uncertainties: for each angle the larger of the least
  // squares' (statistical) and the leave-one-out jackknife's.
  std::array<double, 3> uncertainty_deg{};
  std::array<double, 3> statistical_uncertainty_deg{};
  std::array<double, 3> leave_one_out_uncertainty_deg{};  // zeros: fewer than 3 left out
  // The angles fitted without each radiograph that no other pose refers to.
  struct LeftOut {
    std::string radiograph;
    std::array<double, 3> angles_deg{};
  };
  std::vector<LeftOut> leave_one_out;
  // Whether the turn in the panel's plane was fitted: only where a pose is
  // known or turned; free poses take it up exactly, and it is held.
  bool rotation_fitted = false;
  // The residuals' rms over their noise's (1: the fit explains the
  // radiographs down to their noise).
  double misfit_ratio = 0.0;
  MeasurementResult fit;  // the final fit (poses, stages)
  nlohmann::json toJson() const;
};

// Fits the pose within +-reach_deg of the machine's. Throws Error naming the
// job for a job with a free dimension, and where an angle ends at its bound.
GeometryCalibration calibrateGeometry(const std::filesystem::path& job_file, double reach_deg);

// Writes `folder`/machine.json (the machine file to measure with: the
// job's, its relative paths as they were) and
// geometry.json (the fit), each atomically.
void writeGeometryCalibration(const GeometryCalibration& calibration,
                              const std::filesystem::path& folder);

}  // namespace xgauge
