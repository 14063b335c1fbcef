#include "xgauge/core/atomic_file.h"
#include "xgauge/image/preview.h"
#include "xgauge/image/tiff.h"
#include "xgauge/loss/loss.h"
#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"
#include "xgauge/xray/machine.h"

#include <openssl/evp.h>

#include <fstream>

namespace xgauge {

namespace {

// SHA-256 of a file, hex, via OpenSSL's libcrypto.
std::string sha256File(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error("cannot open file", SourceLocation::inFile(path.string()));
  std::unique_ptr<EVP_MD_CTX, decltype(&EVP_MD_CTX_free)> ctx(EVP_MD_CTX_new(), EVP_MD_CTX_free);
  XG_CHECK(ctx && EVP_DigestInit_ex(ctx.get(), EVP_sha256(), nullptr) == 1);
  std::vector<char> buffer(1 << 20);
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    XG_CHECK(EVP_DigestUpdate(ctx.get(), buffer.data(), static_cast<size_t>(in.gcount())) == 1);
  }
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  XG_CHECK(EVP_DigestFinal_ex(ctx.get(), digest, &length) == 1);
  std::string hex;
  for (unsigned int i = 0; i < length; ++i) hex += fmt::format("{:02x}", digest[i]);
  return hex;
}

}  // namespace

void writeMeasurementOutputs(const MeasurementJob& job, const MeasurementResult& result,
                             const std::filesystem::path& folder) {
  std::filesystem::create_directories(folder);
  ForwardModel model(job);

  // Final simulated radiographs and the differences over each roi.
  for (int r = 0; r < static_cast<int>(model.radiographs().size()); ++r) {
    const PreparedRadiograph& rad = model.radiographs()[static_cast<size_t>(r)];
    const std::string& name = rad.spec.name;
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
    radiographs.push_back({{"name", m.name},
                           {"pattern", m.pattern},
                           {"pose", poseToJson(m.pose)},
                           {"loss", m.loss},
                           {"roi", {model.radiographs()[r].rois.front().x, model.radiographs()[r].rois.front().y,
                                    model.radiographs()[r].rois.front().width, model.radiographs()[r].rois.front().height}},
                           {"repaired_pixels", model.radiographs()[r].repaired_pixels},
                           {"image", spec.image.string()}});
  }
  nlohmann::json stages = nlohmann::json::array();
  for (const auto& s : result.stages)
    stages.push_back({{"name", s.name}, {"method", s.method}, {"level", s.level}, {"samples", s.samples},
                      {"evaluations", s.evaluations}, {"seconds", s.seconds},
                      {"loss_before", s.loss_before}, {"loss_after", s.loss_after},
                      {"termination", s.termination}});
  nlohmann::json inputs = nlohmann::json::object();
  auto hash = [&](const std::filesystem::path& p) { inputs[p.string()] = sha256File(p); };
  hash(job.file), hash(job.part_file), hash(job.machine_file), hash(job.material_file);
  for (const auto& spec : job.radiographs) {
    hash(spec.image);
    if (!spec.dark.empty()) hash(spec.dark), hash(spec.flat);
  }
  const nlohmann::json out = {{"software", "xgauge 0.1.0"},
                              {"job", job.file.string()},
                              {"schedule", job.schedule},
                              {"loss", job.loss},
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
