#include "xgauge/report/measurement.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/output.h"
#include "xgauge/image/preview.h"
#include "xgauge/image/tiff.h"
#include "xgauge/loss/loss.h"
#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"
#include "xgauge/report/html.h"
#include "xgauge/version.h"
#include "xgauge/xray/machine.h"

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <chrono>
#include <cmath>
#include <utility>

namespace xgauge {

namespace {

// Six significant digits are enough for a chart; +inf (infeasible) is null.
nlohmann::json traceJson(const std::vector<double>& trace) {
  nlohmann::json out = nlohmann::json::array();
  for (double v : trace)
    out.push_back(std::isfinite(v) ? nlohmann::json(std::stod(fmt::format("{:.6g}", v)))
                                   : nlohmann::json(nullptr));
  return out;
}

// One dimension as result.json lists it: its value, its uncertainty and
// verdict where it is measured, a verification's substitution.
nlohmann::json dimensionJson(const ForwardModel& model, const MeasuredDimension& d) {
  nlohmann::json item = {
      {"name", d.name}, {"value_mm", d.value}, {"free", d.free}, {"unit", d.unit}};
  if (d.free) {
    item["expanded_uncertainty"] =
        d.expanded_uncertainty ? nlohmann::json(*d.expanded_uncertainty) : nlohmann::json(nullptr);
    item["identifiable"] = d.expanded_uncertainty.has_value();
  }
  // The nominal this part number has: the job's, or its tolerance's (the
  // job's or the part drawing's); none when nobody stated one.
  if (const auto it = model.job().nominals.find(d.name); it != model.job().nominals.end())
    item["nominal"] = it->second;
  else if (d.tolerance)
    item["nominal"] = d.tolerance->nominal;
  if (d.tolerance)
    item["tolerance"] = {{"nominal", d.tolerance->nominal},
                         {"lower", d.tolerance->lower},
                         {"upper", d.tolerance->upper},
                         {"source", d.tolerance->source}};
  if (d.free) item["verified"] = d.verified;
  if (const auto& s = d.substitution) {
    const VerifiedDimension* v = model.inputs().verification->find(d.name);
    item["verification"] = {
        {"fitted_value", d.fitted_value},
        {"bias", v->bias},
        {"u_cal", v->u_cal},
        {"u_p", v->u_p},
        {"u_b", v->u_b},
        {"masters", v->masters},
        {"u_s", v->u_s},
        {"u_w", s->u_w},
        {"combined_standard_uncertainty", s->combined},
        {"effective_degrees_of_freedom", std::isfinite(s->effective_dof)
                                             ? nlohmann::json(s->effective_dof)
                                             : nlohmann::json(nullptr)},
        {"coverage_factor", s->coverage_factor},
        {"own_expanded_uncertainty", d.own_expanded_uncertainty
                                         ? nlohmann::json(*d.own_expanded_uncertainty)
                                         : nlohmann::json(nullptr)}};
  }
  if (d.decision) {
    item["verdict"] = std::string(verdictName(d.decision->verdict));
    item["cannot_decide"] = d.decision->cannot_decide;
    if (!d.decision->cannot_decide_reason.empty())
      item["cannot_decide_reason"] = d.decision->cannot_decide_reason;
  }
  return item;
}

// The uncertainty budget: every free dimension's components, and the
// measurable combinations.
nlohmann::json uncertaintyJson(const UncertaintyBudget& uncertainty) {
  nlohmann::json budget = nlohmann::json::array();
  for (const DimensionUncertainty& u : uncertainty.dimensions) {
    nlohmann::json components = nlohmann::json::array();
    for (const UncertaintyComponent& c : u.components)
      components.push_back({{"name", c.name},
                            {"quantity", c.quantity},
                            {"standard_uncertainty", c.standard_uncertainty},
                            {"unit", c.unit},
                            {"sensitivity", c.sensitivity},
                            {"contribution", c.contribution}});
    budget.push_back({{"name", u.name},
                      {"identifiable", u.identifiable},
                      {"combined_standard_uncertainty", u.combined},
                      {"expanded_uncertainty",
                       u.identifiable ? nlohmann::json(u.expanded) : nlohmann::json(nullptr)},
                      {"components", components}});
  }
  nlohmann::json combinations = nlohmann::json::array();
  for (const MeasurableCombination& c : uncertainty.combinations) {
    nlohmann::json terms = nlohmann::json::array();
    for (const auto& [name, coefficient] : c.terms)
      terms.push_back({{"dimension", name}, {"coefficient", coefficient}});
    nlohmann::json item = {{"expression", c.expression},
                           {"terms", terms},
                           {"value", c.value},
                           {"expanded_uncertainty", c.expanded}};
    if (!c.name.empty()) item["name"] = c.name;
    combinations.push_back(std::move(item));
  }
  return {{"coverage_factor", uncertainty.coverage_factor},
          {"method", "GUM (JCGM 100) linear propagation; docs/method.md"},
          {"level", uncertainty.level},
          {"pixels", uncertainty.pixels},
          {"dimensions", budget},
          {"combinations", combinations},
          {"notes", uncertainty.notes},
          {"unpropagated", uncertainty.unpropagated}};
}

// The material refined in situ (null when it was not).
nlohmann::json refinementJson(const ForwardModel& model, const MeasurementResult& result) {
  const auto& refined = result.uncertainty.refinement;
  if (!refined) return nullptr;
  // The curve as used: the file's uncertainty and moves belong to the
  // unscaled curve.
  nlohmann::json curve = model.materialOf(result.theta).toJson();
  curve.erase("uncertainty");
  curve["description"] = fmt::format("{}, every rate times 1 {:+.6f} (refined in situ)",
                                     model.material().description(), refined->rate_scale);
  return {{"model", "rate_scale"},
          {"rate_scale", refined->rate_scale},
          {"standard_uncertainty", refined->standard_uncertainty},
          {"prior_standard_uncertainty", refined->prior_standard_uncertainty},
          {"transmission_change", refined->transmission_change},
          {"at_path_mm", refined->at_path_mm},
          {"curve", curve}};
}

nlohmann::json regionsJson(const SelfCheck& check) {
  nlohmann::json regions = nlohmann::json::array();
  for (const ResidualRegion& r : check.regions) {
    nlohmann::json item = {{"radiograph", r.radiograph},
                           {"centre_px", {r.centre_px.x(), r.centre_px.y()}},
                           {"box_px", r.box_px},
                           {"area_mm2", r.area_mm2},
                           {"part_area_mm2", r.part_area_mm2},
                           {"peak", r.peak},
                           {"sigmas", r.sigmas},
                           {"sign", r.sign}};
    item["part_mm"] = r.part_mm ? nlohmann::json{r.part_mm->x(), r.part_mm->y(), r.part_mm->z()}
                                : nlohmann::json(nullptr);
    regions.push_back(std::move(item));
  }
  return regions;
}

nlohmann::json fitChecksJson(const SelfCheck& check) {
  nlohmann::json fits = nlohmann::json::array();
  for (const RadiographCheck& c : check.radiographs)
    fits.push_back({{"name", c.name},
                    {"noise_sigma", c.noise_sigma},
                    {"mean_abs_residual", c.mean_abs_residual},
                    {"rms_residual", c.rms_residual},
                    {"misfit_ratio", c.misfit_ratio},
                    {"shadow_area_mm2", c.shadow_area_mm2},
                    {"longest_path_mm", c.longest_path_mm},
                    {"below_range_fraction", c.below_range_fraction}});
  return fits;
}

// Each radiograph's pose, loss, roi and preparation (its lag, if any).
nlohmann::json radiographsJson(const ForwardModel& model, const MeasurementResult& result) {
  const MeasurementJob& job = model.job();
  nlohmann::json radiographs = nlohmann::json::array();
  for (size_t r = 0; r < result.radiographs.size(); ++r) {
    const auto& m = result.radiographs[r];
    const auto& spec = job.radiographs[r];
    const PreparedRadiograph& rad = model.radiograph(static_cast<int>(r));
    const PixelRect& roi = rad.rois.front();
    radiographs.push_back({{"name", m.name},
                           {"pattern", m.pattern},
                           {"pose", poseToJson(m.pose)},
                           {"loss", m.loss},
                           {"magnification", m.magnification},
                           {"roi", {roi.x, roi.y, roi.width, roi.height}},
                           {"repaired_pixels", rad.repaired_pixels},
                           {"image", spec.image.string()}});
    if (rad.lag) {
      nlohmann::json lag = {{"previous", spec.previous.string()},
                            {"fraction", rad.lag->fraction},
                            {"source", rad.lag->stated ? "machine" : "estimated"},
                            {"uncertainty", rad.lag->uncertainty}};
      if (!rad.lag->stated) lag["open_beam_pixels"] = rad.lag->pixels;
      radiographs.back()["lag"] = std::move(lag);
    }
  }
  return radiographs;
}

nlohmann::json stagesJson(const MeasurementResult& result) {
  nlohmann::json stages = nlohmann::json::array();
  for (const auto& s : result.stages)
    stages.push_back({{"name", s.name},
                      {"method", s.method},
                      {"level", s.level},
                      {"samples", s.samples},
                      {"evaluations", s.evaluations},
                      {"with_derivatives", s.with_derivatives},
                      {"seconds", s.seconds},
                      {"loss_before", s.loss_before},
                      {"loss_after", s.loss_after},
                      {"termination", s.termination},
                      {"trace", traceJson(s.trace)}});
  return stages;
}

}  // namespace

nlohmann::json measurementJson(const ForwardModel& model, const MeasurementResult& result) {
  const MeasurementJob& job = model.job();
  nlohmann::json dims = nlohmann::json::array();
  for (const auto& d : result.dimensions) dims.push_back(dimensionJson(model, d));
  bool toleranced = false;
  for (const auto& d : result.dimensions) toleranced |= d.decision.has_value();
  // The digests of the bytes the loader parsed (measure/inputs.h), so that
  // no input is read twice.
  nlohmann::json inputs = model.inputs().sha256;
  // A fit the acceptance rule refused keeps its values apart, under names
  // no reader of results takes for a measurement (measure/self_check.h).
  const bool measured = result.status == MeasurementStatus::kMeasured;
  return {{"software", "xgauge " XGAUGE_VERSION_STRING},
          {"job", job.file.string()},
          {"status", std::string(measurementStatusName(result.status))},
          {"failures", result.check.failures},
          {"attempts", result.attempts},
          {"pose_candidates",
           {{"tried", result.candidates_tried},
            {"taken", result.candidate_taken},
            {"taken_from", result.candidate_origin}}},
          {"verification", job.verification_file.empty()
                               ? nlohmann::json(nullptr)
                               : nlohmann::json(job.verification_file.string())},
          {"schedule", scheduleName(job.schedule)},
          {"loss", lossKindName(job.loss)},
          {measured ? "dimensions" : "rejected_dimensions", dims},
          {"decision_rule",
           toleranced ? nlohmann::json(std::string(kDecisionRule)) : nlohmann::json(nullptr)},
          {measured ? "uncertainty" : "rejected_uncertainty", uncertaintyJson(result.uncertainty)},
          {"material_refinement", refinementJson(model, result)},
          {"warnings", result.check.warnings},
          {"residual_regions", regionsJson(result.check)},
          {"region_share", result.check.region_share},
          {"fit_checks", fitChecksJson(result.check)},
          {"radiographs", radiographsJson(model, result)},
          {"total_loss", result.total_loss},
          {"evaluations", result.evaluations},
          {"seconds", result.seconds},
          {"stages", stagesJson(result)},
          {"inputs_sha256", inputs}};
}

MeasurementWithPictures measureWithPictures(ForwardModel& model,
                                            std::function<void(const StageReport&)> on_stage) {
  MeasureOptions options;
  options.full_size_losses = false;
  options.on_stage = std::move(on_stage);
  MeasurementWithPictures out{measure(model, model.start(), options), {}};
  out.simulated = simulateRadiographs(model, out.result.theta);
  takeFullSizeLosses(model, out.simulated, out.result);
  return out;
}

std::vector<Image> simulateRadiographs(ForwardModel& model, std::span<const double> theta) {
  std::vector<Image> out;
  for (int r = 0; r < model.radiographCount(); ++r)
    out.push_back(model.simulate(theta, r, 0, 2, model.machine().detectorRect()));
  return out;
}

nlohmann::json radiographPictures(ForwardModel& model, std::span<const double> theta,
                                  const std::vector<Image>& simulated_full) {
  // The three pictures of each radiograph cover its roi with a margin of a
  // tenth of its size, so the outline is seen against the open beam.
  std::vector<Image> measured, simulated, residuals;
  std::vector<PixelRect> crops, rois;
  const Machine& machine = model.machine();
  for (int r = 0; r < model.radiographCount(); ++r) {
    const PreparedRadiograph& rad = model.radiograph(r);
    const PixelRect roi = rad.rois.front();
    const int mx = std::max(8, roi.width / 10),
              my = std::max(roi.height > 1 ? 8 : 0, roi.height / 10);
    const int x0 = std::max(0, roi.x - mx), y0 = std::max(0, roi.y - my);
    const PixelRect crop{x0, y0, std::min(machine.columns, roi.right() + mx) - x0,
                         std::min(machine.rows, roi.y + roi.height + my) - y0};
    crops.push_back(crop);
    rois.push_back(roi);
    measured.push_back(rad.levels.front().crop(crop));
    simulated.push_back(simulated_full[static_cast<size_t>(r)].crop(crop));
    Image residual(crop.width, crop.height, 0.0f);
    for (int y = 0; y < crop.height; ++y)
      for (int x = 0; x < crop.width; ++x)
        residual(x, y) = simulated.back()(x, y) - measured.back()(x, y);
    residuals.push_back(std::move(residual));
  }
  std::vector<const Image*> in_rois;
  std::vector<Image> roi_residuals;
  for (size_t r = 0; r < residuals.size(); ++r)
    roi_residuals.push_back(residuals[r].crop(
        {rois[r].x - crops[r].x, rois[r].y - crops[r].y, rois[r].width, rois[r].height}));
  for (const Image& image : roi_residuals) in_rois.push_back(&image);
  const double scale = residualScale(in_rois);
  constexpr int kMaxSide = 640;
  nlohmann::json list = nlohmann::json::array();
  for (int r = 0; r < model.radiographCount(); ++r) {
    const auto i = static_cast<size_t>(r);
    // One grey window for the measured and simulated pictures of a radiograph.
    const GreyWindow window = autoWindow(measured[i]);
    nlohmann::json outline = nlohmann::json::array();
    for (const Segment2& s : model.outline(theta, r))
      outline.push_back({s[0].x(), s[0].y(), s[1].x(), s[1].y()});
    list.push_back({{"name", model.spec(r).name},
                    {"roi", {rois[i].x, rois[i].y, rois[i].width, rois[i].height}},
                    {"grey_window", {window.lo, window.hi}},
                    {"measured", greyPicture(measured[i], crops[i], window, kMaxSide)},
                    {"simulated", greyPicture(simulated[i], crops[i], window, kMaxSide)},
                    {"residual", residualPicture(residuals[i], crops[i], scale, kMaxSide)},
                    {"residual_scale", scale},
                    {"outline", outline}});
  }
  return {{"residual_scale", scale}, {"colour_map", divergingStops()}, {"radiographs", list}};
}

nlohmann::json measurementContext(const ForwardModel& model) {
  const MeasurementJob& job = model.job();
  nlohmann::json dimensions = nlohmann::json::array();
  for (const Dimension& d : model.part().dimensions())
    dimensions.push_back({{"name", d.name},
                          {"nominal", d.nominal},
                          {"min", d.min},
                          {"max", d.max},
                          {"unit", d.unit},
                          {"description", d.description}});
  return {
      {"part",
       {{"file", job.part_file.string()},
        {"description", model.part().description()},
        {"dimensions", dimensions}}},
      {"machine", {{"file", job.machine_file.string()}, {"settings", model.machine().toJson()}}},
      {"material", {{"file", job.material_file.string()}, {"curve", model.material().toJson()}}},
      {"job_description", job.description}};
}

void writeMeasurementOutputs(ForwardModel& model, const MeasurementResult& result,
                             const std::filesystem::path& folder, bool html_report,
                             const nlohmann::json& truth, std::vector<Image> simulated_full,
                             const nlohmann::json* result_json) {
  createOutputFolder(folder);
  auto last = std::chrono::steady_clock::now();
  const auto lap = [&last] {  // seconds since the last lap
    const auto now = std::chrono::steady_clock::now();
    return std::chrono::duration<double>(now - std::exchange(last, now)).count();
  };
  if (simulated_full.empty()) simulated_full = simulateRadiographs(model, result.theta);
  spdlog::debug("outputs: the radiographs simulated at full size in {:.2f} s", lap());

  // Final simulated radiographs and the differences over each roi, every
  // file on its own (their encoders are single-threaded: a 4096^2 pair's
  // six files took 2.6 to 3.5 s one after the other on 2 cores), beside the
  // report, which reads the model and the simulations only.
  const nlohmann::json json = result_json ? *result_json : measurementJson(model, result);
  const auto images = [&] {
    tbb::parallel_for(0, model.radiographCount(), [&](int r) {
      const PreparedRadiograph& rad = model.radiograph(r);
      const std::string& name = model.spec(r).name;
      const Image& simulated = simulated_full[static_cast<size_t>(r)];
      const PixelRect roi = rad.rois.front();
      const Image difference = differenceImage(simulated.crop(roi), rad.levels.front(), roi);
      tbb::parallel_invoke(
          [&] {
            writeTiff(folder / ("simulated_" + name + ".tif"), simulated, TiffFormat::kFloat32);
          },
          [&] {
            writeTiff(folder / ("difference_" + name + ".tif"), difference, TiffFormat::kFloat32);
          },
          [&] { writeDifferencePng(folder / ("difference_" + name + ".png"), difference); });
    });
  };
  const auto report = [&] {
    if (!html_report) return;
    const nlohmann::json data = {
        {"result", json},
        {"context", measurementContext(model)},
        {"generated", utcTimestamp()},
        {"truth", truth},
        {"pictures", radiographPictures(model, result.theta, simulated_full)}};
    writeReport(folder / "report.html", ReportKind::kMeasurement,
                "xgauge measurement: " + model.job().file.filename().string(), data);
  };
  tbb::parallel_invoke(images, report);
  spdlog::debug("outputs: the images and the report written in {:.2f} s", lap());
  writeFileAtomically(folder / "result.json", json.dump(2) + "\n");
}

}  // namespace xgauge
