#include "xgauge/report/calibration.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/output.h"
#include "xgauge/report/html.h"
#include "xgauge/report/measurement.h"
#include "xgauge/version.h"

#include <spdlog/spdlog.h>

#include "xgauge/material/scatter_curves.h"

#include <cmath>

namespace xgauge {

void writeCalibrationOutputs(const std::filesystem::path& folder, const ExponentialSum& material,
                             const nlohmann::json& scatter, nlohmann::json figures,
                             const CalibrationData& data, const TrueCurve& true_curve,
                             const nlohmann::json& pictures, bool html_report) {
  createOutputFolder(folder);
  auto fitted = [&](double x) { return material.transmission(x); };

  // Residuals of the final material against the data.
  double sum_squares = 0.0, worst = 0.0;
  for (size_t i = 0; i < data.path_mm.size(); ++i) {
    const double residual = data.transmission[i] - fitted(data.path_mm[i]);
    sum_squares += residual * residual;
    worst = std::max(worst, std::abs(residual));
  }
  const double rms = data.path_mm.empty()
                         ? 0.0
                         : std::sqrt(sum_squares / static_cast<double>(data.path_mm.size()));
  figures["material_vs_data"] = {
      {"rms_residual", rms}, {"max_abs_residual", worst}, {"points", data.path_mm.size()}};
  const auto range = material.calibratedRange().value_or(std::array<double, 2>{0.0, data.x_max_mm});
  figures["calibrated_range_mm"] = {range[0], range[1]};
  nlohmann::json true_json = nullptr;
  if (!true_curve.empty()) {
    const CurveDeviation dev = curveDeviation(fitted, true_curve, data.x_max_mm);
    figures["against_true_curve"] = {{"max_abs_deviation", dev.max_abs},
                                     {"at_mm", dev.at_mm},
                                     {"over_mm", {0.0, data.x_max_mm}}};
    spdlog::info("against the true curve: largest deviation {:.5f} at {:.2f} mm (0 .. {:.2f} mm)",
                 dev.max_abs, dev.at_mm, data.x_max_mm);
    // The true curve for the page, densely, a little past the calibrated range.
    std::vector<double> x, y;
    for (int i = 0; i <= 400; ++i) {
      x.push_back(1.05 * data.x_max_mm * i / 400.0);
      y.push_back(true_curve(x.back()));
    }
    true_json = {{"path_mm", x}, {"transmission", y}};
  }
  figures["software"] = "xgauge " XGAUGE_VERSION_STRING;

  if (html_report) {
    const nlohmann::json page = {{"calibration", figures},
                                 {"material", material.toJson()},
                                 {"data",
                                  {{"path_mm", data.path_mm},
                                   {"transmission", data.transmission},
                                   {"x_max_mm", data.x_max_mm}}},
                                 {"true_curve", true_json},
                                 {"pictures", pictures},
                                 {"generated", utcTimestamp()}};
    writeReport(folder / "report.html", ReportKind::kCalibration,
                "xgauge calibration: " + figures.value("job", std::string()), page);
  }
  writeFileAtomically(folder / "calibration.json", figures.dump(2) + "\n");
  nlohmann::json material_file = material.toJson();
  if (!scatter.is_null()) material_file["scatter"] = scatter;
  writeFileAtomically(folder / "material.json", material_file.dump(2) + "\n");
}

namespace {

// The wedge radiograph with the ramp's rows (when found) and the white
// region marked, for the calibration's page.
nlohmann::json wedgePictures(const WedgeCalibrationJob& job, const WedgeCalibration& result) {
  if (result.normalized.empty()) return nullptr;
  const Image& image = result.normalized;
  nlohmann::json marks = nlohmann::json::array();
  if (result.ramp_found) {
    const RampDetection& ramp = result.ramp;
    const double lo = result.rows.empty() ? std::min(ramp.thin_row, ramp.thick_row)
                                          : std::min(result.rows.front(), result.rows.back());
    const double hi = result.rows.empty() ? std::max(ramp.thin_row, ramp.thick_row)
                                          : std::max(result.rows.front(), result.rows.back()) + 1;
    marks.push_back(
        {{"label", result.rows.empty() ? "ramp found" : "ramp rows used"},
         {"box", {ramp.column_begin, lo, ramp.column_end - ramp.column_begin, hi - lo}}});
  }
  // Boxes of the radiograph, on the picture (transposed when the ramp runs
  // along the rows).
  auto box = [&](const PixelRect& r) {
    return result.turned ? nlohmann::json{r.y, r.x, r.height, r.width}
                         : nlohmann::json{r.x, r.y, r.width, r.height};
  };
  if (result.halo)
    marks.push_back({{"label", "the wedge's shadow (outside: the halo fitted)"},
                     {"box", box(result.halo->shadow)}});
  marks.push_back({{"label", "white region"}, {"box", box(job.radiograph.white_region)}});
  return {{"kind", "wedge"},
          {"scatter_removed", result.scatter.enabled()},
          {"radiographs",
           nlohmann::json::array({{{"name", job.radiograph.image.filename().string()},
                                   {"measured", greyPicture(image, image.rect(), {0.0, 1.05}, 800)},
                                   {"marks", marks}}})}};
}

// The scatter taken out: the job's, or the halo's fit with its search; null
// when the halo's fit failed.
nlohmann::json wedgeScatterJson(const WedgeCalibrationJob& job, const WedgeCalibration& result) {
  if (job.estimate_scatter && !result.halo) return nullptr;
  nlohmann::json out = result.scatter.toJson();
  out["estimated"] = result.halo.has_value();
  if (const auto& halo = result.halo) {
    const PixelRect& box = halo->shadow;
    out["column_darkening"] = halo->column_darkening;
    out["open_beam_residual_rms"] = halo->rms;
    out["residual_correlation"] = halo->correlation;
    out["open_pixels"] = halo->open_pixels;
    out["binning"] = halo->binning;
    out["shadow_box"] = {box.x, box.y, box.width, box.height};
    out["search"] = {{"sigma_mm", halo->sigma_mm}, {"residual_rms", halo->residual_rms}};
  }
  return out;
}

nlohmann::json rampJson(const WedgeCalibration& result) {
  if (!result.ramp_found) return nullptr;
  const RampDetection& ramp = result.ramp;
  nlohmann::json out = {{"columns", {ramp.column_begin, ramp.column_end}},
                        {"automatic_columns", ramp.automatic_columns},
                        {"thin_end_row", ramp.thin_row},
                        {"thick_end_row", ramp.thick_row},
                        {"automatic_rows", ramp.automatic_rows},
                        {"row_noise", ramp.row_noise},
                        {"along_rows", result.turned}};
  if (!result.rows.empty()) out["rows_used"] = {result.rows.front(), result.rows.back()};
  return out;
}

}  // namespace

namespace {

// The rounds and poses of a part calibration, as calibration.json has them.
nlohmann::json roundsJson(const PartCalibration& result) {
  nlohmann::json rounds = nlohmann::json::array();
  for (const PartCalibrationRound& r : result.rounds)
    rounds.push_back({{"material", r.material.toJson()},
                      {"rms_residual", r.report.rms_residual},
                      {"max_abs_residual", r.report.max_abs_residual},
                      {"change", r.change},
                      {"pose_loss", r.pose_loss},
                      {"pixels", r.pixels}});
  return rounds;
}
nlohmann::json posesJson(const PartCalibration& result) {
  nlohmann::json poses = nlohmann::json::array();
  for (const MeasuredRadiograph& r : result.measurement.radiographs)
    poses.push_back({{"name", r.name}, {"pose", poseToJson(r.pose)}, {"loss", r.loss}});
  return poses;
}

// failed_calibration.json and, with html_report, failed_calibration.html.
void writeFailure(const std::filesystem::path& folder, nlohmann::json diagnostic,
                  const CurveFit& fit, const nlohmann::json& pictures, bool html_report) {
  createOutputFolder(folder);
  diagnostic["failed"] = true;
  diagnostic["fit"] = fit.fits.empty() ? nlohmann::json(nullptr) : toJson(fit);
  diagnostic["software"] = "xgauge " XGAUGE_VERSION_STRING;
  if (html_report)
    writeReport(
        folder / "failed_calibration.html", ReportKind::kCalibration,
        "xgauge calibration failed: " +
            std::filesystem::path(diagnostic.at("job").get<std::string>()).filename().string(),
        {{"failure", diagnostic}, {"pictures", pictures}, {"generated", utcTimestamp()}});
  writeFileAtomically(folder / "failed_calibration.json", diagnostic.dump(2) + "\n");
}

}  // namespace

namespace {

// A part calibration's outputs (writeCalibrationOutputs with `figures`) with
// the last pose fit's radiographs on the page and its result.json, simulated
// and difference images in `folder`/poses.
void writeKnownPartOutputs(const PartCalibrationJob& job, const PartCalibration& result,
                           const nlohmann::json& scatter, const nlohmann::json& figures,
                           const TrueCurve& true_curve, const std::filesystem::path& folder,
                           bool html_report) {
  // The last pose fit, with the calibrated material: the residual images show
  // what the model does not explain (thesis Figure 5.5, docs/method.md).
  ForwardModel model(*job.inputs, result.material);
  MeasurementResult fitted = result.measurement;
  fitted.theta.resize(static_cast<size_t>(model.size()));  // without the free material's parameters
  nlohmann::json pictures = nullptr;
  std::vector<Image> simulated = simulateRadiographs(model, fitted.theta);
  if (html_report)
    pictures = radiographPictures(model, fitted.theta, simulated), pictures["kind"] = "part";
  CalibrationData data;
  data.path_mm = result.path_mm;
  data.transmission = result.transmission;
  data.x_max_mm = result.max_path_mm;
  writeCalibrationOutputs(folder, result.material, scatter, figures, data, true_curve, pictures,
                          html_report);
  writeMeasurementOutputs(model, fitted, folder / "poses", false, nullptr, std::move(simulated));
}

nlohmann::json initialJson(const PartCalibrationJob& job, const PartCalibration& result) {
  const PixelRect* r = job.initial_region ? &*job.initial_region : nullptr;
  return {{"radiograph",
           job.measurement().radiographs[static_cast<size_t>(job.initial_radiograph)].name},
          {"region", r ? nlohmann::json{r->x, r->y, r->width, r->height} : nlohmann::json(nullptr)},
          {"darkest_percent", r ? nlohmann::json(nullptr) : nlohmann::json(kDarkestPercent)},
          {"path_mm", job.initial_path_mm},
          {"intensity", result.initial_intensity},
          {"mu_per_mm", result.initial_mu_per_mm}};
}

}  // namespace

void writeFailedWedgeCalibration(const WedgeCalibrationJob& job, const WedgeCalibration& partial,
                                 const std::string& error, const std::filesystem::path& folder,
                                 bool html_report) {
  nlohmann::json found = nlohmann::json(nullptr);
  if (partial.part && partial.part_job)
    found = {{"initial", initialJson(*partial.part_job, *partial.part)},
             {"rounds", roundsJson(*partial.part)},
             {"poses", posesJson(*partial.part)}};
  writeFailure(folder,
               {{"kind", "wedge"},
                {"step", partial.step},
                {"known_part", found},
                {"error", error},
                {"job", job.file.string()},
                {"radiograph", job.radiograph.image.string()},
                {"ramp", rampJson(partial)},
                {"scatter", wedgeScatterJson(job, partial)},
                {"table",
                 {{"row", partial.rows},
                  {"path_mm", partial.path_mm},
                  {"transmission", partial.transmission}}}},
               partial.fit, html_report ? wedgePictures(job, partial) : nlohmann::json(nullptr),
               html_report);
}

void writeFailedPartCalibration(const PartCalibrationJob& job, const PartCalibration& partial,
                                const std::string& error, const std::filesystem::path& folder,
                                bool html_report) {
  const nlohmann::json initial = partial.initial_mu_per_mm > 0.0
                                     ? nlohmann::json{{"intensity", partial.initial_intensity},
                                                      {"mu_per_mm", partial.initial_mu_per_mm}}
                                     : nlohmann::json(nullptr);
  writeFailure(folder,
               {{"kind", "part"},
                {"step", partial.step},
                {"error", error},
                {"job", job.measurement().file.string()},
                {"initial", initial},
                {"rounds", roundsJson(partial)},
                {"poses", posesJson(partial)},
                {"table", {{"path_mm", partial.path_mm}, {"transmission", partial.transmission}}}},
               partial.fit, nullptr, html_report);
}

namespace {

// The curve's uncertainty budget (wedge.h, step 7).
nlohmann::json wedgeUncertaintyJson(const WedgeCalibrationJob& job,
                                    const WedgeCalibration& result) {
  nlohmann::json influences = nlohmann::json::array();
  for (const CurveInfluence& i : result.influences)
    influences.push_back({{"name", i.name},
                          {"value", i.value},
                          {"standard_uncertainty", i.uncertainty},
                          {"curve_change", i.change}});
  return {{"transmission", result.material.transmissionUncertainty()},
          {"table", result.table_uncertainty},
          {"influences", influences},
          {"rate_floor", job.rate_floor ? job.rate_floor->toJson() : nlohmann::json(nullptr)}};
}

}  // namespace

// The previous frame's lag the calibration subtracted, or null.
nlohmann::json wedgeLagJson(const WedgeCalibrationJob& job, const WedgeCalibration& result) {
  if (!result.lag) return nullptr;
  nlohmann::json lag = {{"previous", job.radiograph.previous.string()},
                        {"fraction", result.lag->fraction},
                        {"source", result.lag->stated ? "machine" : "estimated"},
                        {"uncertainty", result.lag->uncertainty}};
  return lag;
}

// The scatter a wedge calibration removed, for material.json: the model,
// and how the curve moves with its weight and width (material/scatter_curves.h).
nlohmann::json materialScatterJson(const WedgeCalibration& result) {
  if (!result.scatter.enabled()) return nullptr;
  nlohmann::json out = result.scatter.toJson();
  ScatterCurves curves;
  double besides = result.table_uncertainty * result.table_uncertainty;
  for (const CurveInfluence& influence : result.influences) {
    if (influence.name == kScatterWeightInfluence && influence.moved)
      curves.weight_plus_u = influence.moved;
    else if (influence.name == kScatterWidthInfluence && influence.moved)
      curves.sigma_plus_u = influence.moved;
    else if (influence.name == kScatterKernelInfluence && influence.moved)
      curves.equivalent_end = influence.moved;
    else if (influence.name == kScatterKernelChoiceInfluence && influence.moved)
      curves.kernel_choice = influence.moved;
    else
      besides += influence.change * influence.change;
  }
  curves.transmission_uncertainty_besides = std::sqrt(besides);
  out["curve_moves"] = curves.toJson();
  return out;
}

void writeWedgeCalibration(const WedgeCalibrationJob& job, const WedgeCalibration& result,
                           const TrueCurve& true_curve, const std::filesystem::path& folder,
                           bool html_report) {
  if (result.part) {
    // The wedge fitted as a known part: its pose fit's pictures and poses/.
    const PartCalibration& part = *result.part;
    const nlohmann::json figures = {
        {"kind", "wedge"},
        {"method", "known part"},
        {"job", job.file.string()},
        {"radiograph", job.radiograph.image.string()},
        {"ramp", nullptr},
        {"model", {{"file", job.model_file.string()}, {"caliper", job.caliper},
                   {"caliper_uncertainty_mm", job.caliper_uncertainty_mm}}},
        {"initial", initialJson(*result.part_job, part)},
        {"rounds", roundsJson(part)},
        {"poses", posesJson(part)},
        {"geometry", {{"magnification", result.magnification}, {"x_max_mm", result.x_max_mm}}},
        {"fit", toJson(result.fit)},
        {"scatter", wedgeScatterJson(job, result)},
        {"lag", wedgeLagJson(job, result)},
        {"uncertainty", wedgeUncertaintyJson(job, result)},
        {"material", result.material.toJson()},
        {"table", {{"path_mm", result.path_mm}, {"transmission", result.transmission}}},
        {"seconds", result.seconds}};
    writeKnownPartOutputs(*result.part_job, part, materialScatterJson(result), figures,
                          true_curve, folder, html_report);
    return;
  }
  // The table on the final curve's path axis: eq. 3.7 maps x to x s + x0.
  const double s = (result.x_max_mm - result.x0_mm) / result.x_max_mm;
  std::vector<double> shifted;
  for (double x : result.path_mm) shifted.push_back((x - result.x0_mm) / s);

  nlohmann::json figures = {{"kind", "wedge"},
                            {"job", job.file.string()},
                            {"radiograph", job.radiograph.image.string()},
                            {"ramp", rampJson(result)},
                            {"geometry",
                             {{"back_face_magnification", result.magnification},
                              {"back_face_above_detector_mm", result.back_face_z_mm},
                              {"x_max_mm", result.x_max_mm},
                              {"max_thickness_mm", job.max_thickness_mm},
                              {"ramp_length_mm", job.ramp_length_mm}}},
                            {"fit", toJson(result.fit)},
                            {"eq_3_7", {{"x0_mm", result.x0_mm}, {"x_max_mm", result.x_max_mm}}},
                            {"scatter", wedgeScatterJson(job, result)},
                            {"lag", wedgeLagJson(job, result)},
                            {"uncertainty", wedgeUncertaintyJson(job, result)},
                            {"material", result.material.toJson()},
                            {"table",
                             {{"row", result.rows},
                              {"path_mm_as_fitted", result.path_mm},
                              {"path_mm", shifted},
                              {"transmission", result.transmission}}},
                            {"seconds", result.seconds}};
  const nlohmann::json pictures =
      html_report ? wedgePictures(job, result) : nlohmann::json(nullptr);
  CalibrationData data;
  data.path_mm = shifted;
  data.transmission = result.transmission;
  data.x_max_mm = result.x_max_mm;
  writeCalibrationOutputs(folder, result.material, materialScatterJson(result), figures, data,
                          true_curve,
                          pictures, html_report);
}

void writePartCalibration(const PartCalibrationJob& job, const PartCalibration& result,
                          const TrueCurve& true_curve, const std::filesystem::path& folder,
                          bool html_report) {
  const nlohmann::json figures = {{"kind", "part"},
                                  {"job", job.measurement().file.string()},
                                  {"initial", initialJson(job, result)},
                                  {"rounds", roundsJson(result)},
                                  {"fit", toJson(result.fit)},
                                  {"max_path_mm", result.max_path_mm},
                                  {"material", result.material.toJson()},
                                  {"poses", posesJson(result)},
                                  {"table",
                                   {{"path_mm", result.path_mm},
                                    {"transmission", result.transmission}}},
                                  {"seconds", result.seconds}};
  writeKnownPartOutputs(job, result, nullptr, figures, true_curve, folder, html_report);
}

}  // namespace xgauge
