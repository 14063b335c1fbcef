#include "xgauge/report/calibration.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/output.h"
#include "xgauge/report/measurement.h"
#include "xgauge/report/plot.h"
#include "xgauge/version.h"

#include <spdlog/spdlog.h>

#include <cmath>

namespace xgauge {

void writeCalibrationOutputs(const std::filesystem::path& folder, const ExponentialSum& material,
                             nlohmann::json figures, const CalibrationPlot& plot,
                             const TrueCurve& true_curve) {
  createOutputFolder(folder);
  auto fitted = [&](double x) { return material.transmission(x); };

  // Residuals of the final material against the data.
  std::vector<double> residual;
  double sum_squares = 0.0, worst = 0.0;
  for (size_t i = 0; i < plot.path_mm.size(); ++i) {
    residual.push_back(plot.transmission[i] - fitted(plot.path_mm[i]));
    sum_squares += residual.back() * residual.back();
    worst = std::max(worst, std::abs(residual.back()));
  }
  const double rms = plot.path_mm.empty()
                         ? 0.0
                         : std::sqrt(sum_squares / static_cast<double>(plot.path_mm.size()));
  figures["material_vs_data"] = {
      {"rms_residual", rms}, {"max_abs_residual", worst}, {"points", plot.path_mm.size()}};

  // The curve, densely, a little past the calibrated range.
  std::vector<double> curve_x, curve_y, truth_y, deviation;
  for (int i = 0; i <= 400; ++i) {
    const double x = 1.05 * plot.x_max_mm * i / 400.0;
    curve_x.push_back(x);
    curve_y.push_back(fitted(x));
    if (!true_curve.empty()) {
      truth_y.push_back(true_curve(x));
      deviation.push_back(curve_y.back() - truth_y.back());
    }
  }
  if (!true_curve.empty()) {
    const CurveDeviation dev = curveDeviation(fitted, true_curve, plot.x_max_mm);
    figures["against_true_curve"] = {{"max_abs_deviation", dev.max_abs},
                                     {"at_mm", dev.at_mm},
                                     {"over_mm", {0.0, plot.x_max_mm}}};
    spdlog::info("against the true curve: largest deviation {:.5f} at {:.2f} mm (0 .. {:.2f} mm)",
                 dev.max_abs, dev.at_mm, plot.x_max_mm);
  }

  PlotFigure figure;
  figure.x_label = "path length x (mm)";
  PlotPanel curve;
  curve.title = plot.title;
  curve.y_label = "I(x)";
  curve.height_weight = 2.0;
  curve.series.push_back({plot.path_mm,
                          plot.transmission,
                          PlotSeries::Style::kPoints,
                          {40, 90, 200},
                          plot.data_label});
  if (!true_curve.empty())
    curve.series.push_back(
        {curve_x, truth_y, PlotSeries::Style::kLine, {150, 150, 150}, "true curve (simulation)"});
  curve.series.push_back({curve_x,
                          curve_y,
                          PlotSeries::Style::kLine,
                          {200, 30, 30},
                          fmt::format("fitted: {} exponentials", material.terms().size())});
  figure.panels.push_back(curve);
  PlotPanel res;
  res.title = fmt::format("residual: data - fit (rms {:.2g})", rms);
  res.y_label = "data - I(x)";
  res.zero_line = true;
  res.series.push_back({plot.path_mm, residual, PlotSeries::Style::kPoints, {40, 90, 200}, ""});
  figure.panels.push_back(res);
  if (!true_curve.empty()) {
    PlotPanel dev;
    dev.title = "fit - true curve";
    dev.y_label = "I(x) - true";
    dev.zero_line = true;
    dev.series.push_back({curve_x, deviation, PlotSeries::Style::kLine, {200, 30, 30}, ""});
    figure.panels.push_back(dev);
  }
  writePlotPng(folder / "calibration.png", figure);

  figures["software"] = "xgauge " XGAUGE_VERSION_STRING;
  writeFileAtomically(folder / "calibration.json", figures.dump(2) + "\n");
  writeFileAtomically(folder / "material.json", material.toJson().dump(2) + "\n");
}

void writeWedgeCalibration(const WedgeCalibrationJob& job, const WedgeCalibration& result,
                           const TrueCurve& true_curve, const std::filesystem::path& folder) {
  const RampDetection& ramp = result.ramp;
  // The table on the final curve's path axis: eq. 3.7 maps x to x s + x0.
  const double s = (result.x_max_mm - result.x0_mm) / result.x_max_mm;
  std::vector<double> shifted;
  for (double x : result.path_mm) shifted.push_back((x - result.x0_mm) / s);

  nlohmann::json figures = {{"kind", "wedge"},
                            {"job", job.file.string()},
                            {"radiograph", job.radiograph.image.string()},
                            {"ramp",
                             {{"columns", {ramp.column_begin, ramp.column_end}},
                              {"automatic_columns", ramp.automatic_columns},
                              {"thin_end_row", ramp.thin_row},
                              {"thick_end_row", ramp.thick_row},
                              {"automatic_rows", ramp.automatic_rows},
                              {"row_noise", ramp.row_noise},
                              {"rows_used", {result.rows.front(), result.rows.back()}}}},
                            {"geometry",
                             {{"back_face_magnification", result.magnification},
                              {"back_face_above_detector_mm", result.back_face_z_mm},
                              {"x_max_mm", result.x_max_mm},
                              {"max_thickness_mm", job.max_thickness_mm},
                              {"ramp_length_mm", job.ramp_length_mm}}},
                            {"fit", toJson(result.fit)},
                            {"eq_3_7", {{"x0_mm", result.x0_mm}, {"x_max_mm", result.x_max_mm}}},
                            {"material", result.material.toJson()},
                            {"table",
                             {{"row", result.rows},
                              {"path_mm_as_fitted", result.path_mm},
                              {"path_mm", shifted},
                              {"transmission", result.transmission}}},
                            {"seconds", result.seconds}};
  CalibrationPlot plot;
  plot.title = fmt::format("Wedge calibration: {} rows of {}", result.rows.size(),
                           job.radiograph.image.filename().string());
  plot.data_label = "rows of the ramp (scatter removed)";
  plot.path_mm = shifted;
  plot.transmission = result.transmission;
  plot.x_max_mm = result.x_max_mm;
  writeCalibrationOutputs(folder, result.material, figures, plot, true_curve);
}

void writePartCalibration(const PartCalibrationJob& job, const PartCalibration& result,
                          const TrueCurve& true_curve, const std::filesystem::path& folder) {
  nlohmann::json rounds = nlohmann::json::array();
  for (const PartCalibrationRound& r : result.rounds)
    rounds.push_back({{"material", r.material.toJson()},
                      {"rms_residual", r.report.rms_residual},
                      {"max_abs_residual", r.report.max_abs_residual},
                      {"change", r.change},
                      {"pose_loss", r.pose_loss},
                      {"pixels", r.pixels}});
  nlohmann::json poses = nlohmann::json::array();
  for (const MeasuredRadiograph& r : result.measurement.radiographs)
    poses.push_back({{"name", r.name}, {"pose", poseToJson(r.pose)}, {"loss", r.loss}});
  const nlohmann::json figures = {
      {"kind", "part"},
      {"job", job.measurement().file.string()},
      {"initial",
       {{"radiograph",
         job.measurement().radiographs[static_cast<size_t>(job.initial_radiograph)].name},
        {"region",
         {job.initial_region.x, job.initial_region.y, job.initial_region.width,
          job.initial_region.height}},
        {"path_mm", job.initial_path_mm},
        {"intensity", result.initial_intensity},
        {"mu_per_mm", result.initial_mu_per_mm}}},
      {"rounds", rounds},
      {"fit", toJson(result.fit)},
      {"max_path_mm", result.max_path_mm},
      {"material", result.material.toJson()},
      {"poses", poses},
      {"table", {{"path_mm", result.path_mm}, {"transmission", result.transmission}}},
      {"seconds", result.seconds}};
  CalibrationPlot plot;
  plot.title = fmt::format("Calibration from a known part: {} path bins", result.path_mm.size());
  plot.data_label = "pixels binned by path (scatter removed)";
  plot.path_mm = result.path_mm;
  plot.transmission = result.transmission;
  plot.x_max_mm = result.max_path_mm;
  writeCalibrationOutputs(folder, result.material, figures, plot, true_curve);

  // The last pose fit, with the calibrated material: the residual images show
  // what the model does not explain (thesis Figure 5.5, docs/method.md).
  ForwardModel model(*job.inputs, result.material);
  MeasurementResult fitted = result.measurement;
  fitted.theta.resize(static_cast<size_t>(model.size()));  // without the free material's parameters
  writeMeasurementOutputs(model, fitted, folder / "poses");
}

}  // namespace xgauge
