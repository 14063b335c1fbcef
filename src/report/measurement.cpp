#include "xgauge/report/measurement.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/output.h"
#include "xgauge/image/preview.h"
#include "xgauge/image/tiff.h"
#include "xgauge/loss/loss.h"
#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"
#include "xgauge/xray/machine.h"
#include "xgauge/version.h"


namespace xgauge {

void writeMeasurementOutputs(ForwardModel& model, const MeasurementResult& result,
                             const std::filesystem::path& folder) {
  createOutputFolder(folder);
  const MeasurementJob& job = model.job();

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

  // result.json.
  nlohmann::json dims = nlohmann::json::array();
  for (const auto& d : result.dimensions)
    dims.push_back({{"name", d.name}, {"value_mm", d.value}, {"free", d.free}, {"unit", d.unit}});
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
    stages.push_back({{"name", s.name}, {"method", s.method}, {"level", s.level}, {"samples", s.samples},
                      {"evaluations", s.evaluations}, {"seconds", s.seconds},
                      {"loss_before", s.loss_before}, {"loss_after", s.loss_after},
                      {"termination", s.termination}});
  // The digests of the bytes the loader parsed (measure/inputs.h), so that
  // no input is read twice.
  nlohmann::json inputs = model.inputs().sha256;
  const nlohmann::json out = {{"software", "xgauge " XGAUGE_VERSION_STRING},
                              {"job", job.file.string()},
                              {"schedule", scheduleName(job.schedule)},
                              {"loss", lossKindName(job.loss)},
                              {"dimensions", dims},
                              {"radiographs", radiographs},
                              {"total_loss", result.total_loss},
                              {"evaluations", result.evaluations},
                              {"seconds", result.seconds},
                              {"stages", stages},
                              {"inputs_sha256", inputs}};
  writeFileAtomically(folder / "result.json", out.dump(2) + "\n");
}

}  // namespace xgauge
