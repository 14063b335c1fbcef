// What a calibration writes for people and scripts: the material file (the
// machine-readable result jobs read), its figures as JSON and the HTML
// report with the data, the fitted curve and its residual (the thesis's
// Figure 5.8, docs/method.md). docs/formats.md documents every key.
#pragma once

#include "xgauge/calibrate/curve.h"
#include "xgauge/calibrate/part.h"
#include "xgauge/calibrate/wedge.h"
#include "xgauge/material/exponential_sum.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace xgauge {

struct CalibrationData {
  std::vector<double> path_mm, transmission;  // the data, on the final curve's path axis
  double x_max_mm = 0.0;                      // the calibrated range
};

// Into `folder` (created if needed), each file atomically: calibration.json
// (`figures` plus the residual of the material against the data and, with a
// true curve, the largest deviation from it over 0 .. x_max), with
// `html_report` report.html (report/html.h: the data, the fitted and true
// curves, the residual and `pictures`, the radiograph as the calibration
// saw it) and, last, material.json, so that a failure leaves no material
// file. With `scatter` (not null), material.json carries it under "scatter"
// for the measurements that use the material without a scatter of their own.
void writeCalibrationOutputs(const std::filesystem::path& folder, const ExponentialSum& material,
                             const nlohmann::json& scatter, nlohmann::json figures,
                             const CalibrationData& data, const TrueCurve& true_curve,
                             const nlohmann::json& pictures, bool html_report);

// material.json, calibration.json (every figure and the table) and
// report.html (with the normalized radiograph and the ramp found in it)
// into `folder`, each written atomically. With `true_curve` (a simulated
// dataset's transmission table), the figures also give the largest
// deviation from it over 0 .. x_max.
void writeWedgeCalibration(const WedgeCalibrationJob& job, const WedgeCalibration& result,
                           const TrueCurve& true_curve, const std::filesystem::path& folder,
                           bool html_report = true);

// After a failed wedge calibration (`partial` as calibrateFromWedge left
// it): failed_calibration.json, the step that failed, the error and what
// the steps had found (the ramp, the table, the fits tried), and with
// `html_report` failed_calibration.html, the same as a page with the
// radiograph and the ramp marked, into `folder`. Never material.json or
// calibration.json: nothing there can be mistaken for a result.
void writeFailedWedgeCalibration(const WedgeCalibrationJob& job, const WedgeCalibration& partial,
                                 const std::string& error, const std::filesystem::path& folder,
                                 bool html_report = true);

// The same after a failed part calibration: the step, the error, eq. 3.8's
// initial material, the rounds and poses so far, the last table and the
// fits tried.
void writeFailedPartCalibration(const PartCalibrationJob& job, const PartCalibration& partial,
                                const std::string& error, const std::filesystem::path& folder,
                                bool html_report = true);

// material.json, calibration.json, report.html (as writeCalibrationOutputs,
// with the last pose fit's radiographs), and that pose fit's result.json
// with its simulated and difference images (report/measurement.h) in
// `folder`/poses.
void writePartCalibration(const PartCalibrationJob& job, const PartCalibration& result,
                          const TrueCurve& true_curve, const std::filesystem::path& folder,
                          bool html_report = true);

}  // namespace xgauge
