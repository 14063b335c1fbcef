// What a measurement writes for people and scripts: result.json (the
// machine-readable truth), the final simulated radiographs and the
// difference images. docs/formats.md documents every key.
#pragma once

#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <functional>
#include <span>
#include <vector>

namespace xgauge {

// Writes result.json (with the SHA-256 of every input as it was read), the
// final simulated radiographs and the difference images (float TIFF and
// diverging-colour PNG) and, with `html_report`, report.html (report/html.h)
// into `folder`, each file atomically, from the model that measured. `truth`
// (a virtual lab's true dimensions, name -> value; null when unknown) is
// shown beside the measured values in the page. `simulated_full`: the
// final simulated radiographs when the caller has them
// (simulateRadiographs), else they are rendered here.
// `result_json`: measurementJson(model, result) when the caller has it
// already (the front door's summary), else it is made here.
void writeMeasurementOutputs(ForwardModel& model, const MeasurementResult& result,
                             const std::filesystem::path& folder, bool html_report = true,
                             const nlohmann::json& truth = nullptr,
                             std::vector<Image> simulated_full = {},
                             const nlohmann::json* result_json = nullptr);

// The final simulated radiograph of each radiograph, whole detector, full
// size, 2 x 2 samples per pixel: what the outputs and the page show.
std::vector<Image> simulateRadiographs(ForwardModel& model, std::span<const double> theta);

// A measurement as `xgauge measure`, `xgauge inspect` and the Python module
// run it: measure() from the model's start, then the final simulated
// radiographs, from which each radiograph's full-size loss is taken
// (MeasureOptions::full_size_losses) instead of rendering them twice.
struct MeasurementWithPictures {
  MeasurementResult result;
  std::vector<Image> simulated;  // simulateRadiographs at the solution
};
// `on_stage`: MeasureOptions::on_stage.
MeasurementWithPictures measureWithPictures(ForwardModel& model,
                                            std::function<void(const StageReport&)> on_stage = {});

// The pictures of a measurement's page, {"residual_scale", "colour_map",
// "radiographs"}; per radiograph the normalized radiograph, the simulated
// one and the residual (simulated - measured) around its roi, the residual
// under one symmetric colour scale shared by all radiographs (residualScale
// over every roi), and the fitted part's outline (xray/contour.h) in
// detector pixels. `simulated_full`: simulateRadiographs(model, theta).
nlohmann::json radiographPictures(ForwardModel& model, std::span<const double> theta,
                                  const std::vector<Image>& simulated_full);

// The part model's dimensions (nominal and range), the machine and the
// material the measurement used, for the page's header.
nlohmann::json measurementContext(const ForwardModel& model);

// The contents of result.json (docs/formats.md): dimensions with their U,
// tolerances and verdicts, the uncertainty budget, the self-checks' warnings
// and residual regions, poses, stages and the inputs' SHA-256.
nlohmann::json measurementJson(const ForwardModel& model, const MeasurementResult& result);

}  // namespace xgauge
