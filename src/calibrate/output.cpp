#include "xgauge/calibrate/output.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/image/plot.h"
#include "xgauge/version.h"

#include <spdlog/spdlog.h>

#include <cmath>

namespace xgauge {

void writeCalibrationOutputs(const std::filesystem::path& folder, const ExponentialSum& material,
                             nlohmann::json figures, const CalibrationPlot& plot,
                             const TrueCurve& true_curve) {
  std::filesystem::create_directories(folder);
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

}  // namespace xgauge
