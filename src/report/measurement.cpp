#include "xgauge/report/measurement.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/output.h"
#include "xgauge/image/preview.h"
#include "xgauge/image/tiff.h"
#include "xgauge/loss/loss.h"
#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"
#include "xgauge/version.h"
#include "xgauge/xray/machine.h"

namespace xgauge {

nlohmann::json measurementJson(const ForwardModel& model, const MeasurementResult& result) {
  const MeasurementJob& job = model.job();
  nlohmann::json dims = nlohmann::json::array();
  for (const auto& d : result.dimensions) {
    nlohmann::json item = {
        {"name", d.name}, {"value_mm", d.value}, {"free", d.free}, {"unit", d.unit}};
    if (d.free) {
      item["expanded_uncertainty"] = d.expanded_uncertainty
                                         ? nlohmann::json(*d.expanded_uncertainty)
                                         : nlohmann::json(nullptr);
      item["identifiable"] = d.expanded_uncertainty.has_value();
    }
    if (d.tolerance)
      item["tolerance"] = {{"nominal", d.tolerance->nominal},
                           {"lower", d.tolerance->lower},
                           {"upper", d.tolerance->upper},
                           {"source", d.tolerance->source}};
    if (d.decision) {
      item["verdict"] = std::string(verdictName(d.decision->verdict));
      item["cannot_decide"] = d.decision->cannot_decide;
    }
    dims.push_back(std::move(item));
  }
  nlohmann::json budget = nlohmann::json::array();
  for (const DimensionUncertainty& u : result.uncertainty.dimensions) {
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
  for (const MeasurableCombination& c : result.uncertainty.combinations) {
    nlohmann::json terms = nlohmann::json::array();
    for (const auto& [name, coefficient] : c.terms)
      terms.push_back({{"dimension", name}, {"coefficient", coefficient}});
    combinations.push_back({{"expression", c.expression},
                            {"terms", terms},
                            {"value", c.value},
                            {"expanded_uncertainty", c.expanded}});
  }
  const nlohmann::json uncertainty = {
      {"coverage_factor", result.uncertainty.coverage_factor},
      {"method", "GUM (JCGM 100) linear propagation; docs/method.md"},
      {"level", result.uncertainty.level},
      {"pixels", result.uncertainty.pixels},
      {"dimensions", budget},
      {"combinations", combinations},
      {"notes", result.uncertainty.notes}};
  nlohmann::json regions = nlohmann::json::array();
  for (const ResidualRegion& r : result.check.regions) {
    nlohmann::json item = {{"radiograph", r.radiograph},
                           {"centre_px", {r.centre_px.x(), r.centre_px.y()}},
                           {"box_px", r.box_px},
                           {"area_mm2", r.area_mm2},
                           {"peak", r.peak},
                           {"sigmas", r.sigmas},
                           {"sign", r.sign}};
    item["part_mm"] = r.part_mm ? nlohmann::json{r.part_mm->x(), r.part_mm->y(), r.part_mm->z()}
                                : nlohmann::json(nullptr);
    regions.push_back(std::move(item));
  }
  nlohmann::json fits = nlohmann::json::array();
  for (const RadiographCheck& c : result.check.radiographs)
    fits.push_back({{"name", c.name},
                    {"noise_sigma", c.noise_sigma},
                    {"mean_abs_residual", c.mean_abs_residual},
                    {"rms_residual", c.rms_residual},
                    {"misfit_ratio", c.misfit_ratio}});
  bool toleranced = false;
  for (const auto& d : result.dimensions) toleranced |= d.decision.has_value();
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
                           {"roi", {roi.x, roi.y, roi.width, roi.height}},
                           {"repaired_pixels", rad.repaired_pixels},
                           {"image", spec.image.string()}});
  }
  nlohmann::json stages = nlohmann::json::array();
  for (const auto& s : result.stages)
    stages.push_back({{"name", s.name},
                      {"method", s.method},
                      {"level", s.level},
                      {"samples", s.samples},
                      {"evaluations", s.evaluations},
                      {"seconds", s.seconds},
                      {"loss_before", s.loss_before},
                      {"loss_after", s.loss_after},
                      {"termination", s.termination}});
  // The digests of the bytes the loader parsed (measure/inputs.h), so that
  // no input is read twice.
  nlohmann::json inputs = model.inputs().sha256;
  return {{"software", "xgauge " XGAUGE_VERSION_STRING},
          {"job", job.file.string()},
          {"schedule", scheduleName(job.schedule)},
          {"loss", lossKindName(job.loss)},
          {"dimensions", dims},
          {"decision_rule",
           toleranced ? nlohmann::json(std::string(kDecisionRule)) : nlohmann::json(nullptr)},
          {"uncertainty", uncertainty},
          {"warnings", result.check.warnings},
          {"residual_regions", regions},
          {"fit_checks", fits},
          {"radiographs", radiographs},
          {"total_loss", result.total_loss},
          {"evaluations", result.evaluations},
          {"seconds", result.seconds},
          {"stages", stages},
          {"inputs_sha256", inputs}};
}

void writeMeasurementOutputs(ForwardModel& model, const MeasurementResult& result,
                             const std::filesystem::path& folder) {
  createOutputFolder(folder);

  // Final simulated radiographs and the differences over each roi.
  for (int r = 0; r < model.radiographCount(); ++r) {
    const PreparedRadiograph& rad = model.radiograph(r);
    const std::string& name = model.spec(r).name;
    const Image simulated = model.simulate(result.theta, r, 0, 2, model.machine().detectorRect());
    writeTiff(folder / ("simulated_" + name + ".tif"), simulated, TiffFormat::kFloat32);
    const PixelRect roi = rad.rois.front();
    const Image difference = differenceImage(simulated.crop(roi), rad.levels.front(), roi);
    writeTiff(folder / ("difference_" + name + ".tif"), difference, TiffFormat::kFloat32);
    writeDifferencePng(folder / ("difference_" + name + ".png"), difference);
  }

  writeFileAtomically(folder / "result.json", measurementJson(model, result).dump(2) + "\n");
}

}  // namespace xgauge
