#include "xgauge/measure/verify.h"

#include "xgauge/core/config.h"
#include "xgauge/core/error.h"
#include "xgauge/measure/inputs.h"
#include "xgauge/measure/model.h"
#include "xgauge/measure/truth.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

namespace xgauge {

VerificationJob VerificationJob::load(const std::filesystem::path& file) {
  const ConfigNode root = ConfigNode::loadFile(file);
  const std::filesystem::path folder = file.parent_path();
  VerificationJob job;
  job.file = file;
  job.description = root.get<std::string>("description", "");
  const ConfigNode master = root.at("master");
  if (master.has("certificate") == master.has("truth"))
    master.fail("expected either \"certificate\" (a CMM's) or \"truth\" (a virtual lab's)");
  if (auto certificate = master.find("certificate")) {
    for (const std::string& name : certificate->keys()) {
      const ConfigNode c = certificate->at(name);
      job.certificate[name] = {c.at("value").number(),
                               c.at("standard_uncertainty").number(0.0, 1e3)};
    }
  } else {
    const DatasetTruth truth = DatasetTruth::load(folder / master.at("truth").string());
    const double u = master.at("standard_uncertainty").number(0.0, 1e3);
    for (const auto& [name, value] : truth.dimensions) job.certificate[name] = {value, u};
  }
  if (job.certificate.empty()) master.fail("the master's certificate names no dimension");
  const ConfigNode measurements = root.at("measurements");
  for (size_t k = 0; k < measurements.size(); ++k)
    job.measurements.push_back(folder / measurements[k].string());
  if (static_cast<int>(job.measurements.size()) < kMinVerificationMeasurements)
    measurements.fail(fmt::format("a verification needs at least {} measurements of the master",
                                  kMinVerificationMeasurements));
  root.finish();
  return job;
}

Verification verifyMethod(const VerificationJob& job) {
  std::vector<MasterMeasurement> measured;
  VerificationConditions conditions;
  for (size_t k = 0; k < job.measurements.size(); ++k) {
    const std::filesystem::path& file = job.measurements[k];
    spdlog::info("master measurement {} of {}: {}", k + 1, job.measurements.size(), file.string());
    const MeasurementInputs inputs = loadMeasurementInputs(file);
    if (inputs.verification)
      fail("{}: a measurement of the master names a verification of its own; verify without it",
           file.string());
    auto digest = [&](const std::filesystem::path& f) { return inputs.sha256.at(f.string()); };
    const MeasurementJob& mj = inputs.job;
    if (k == 0) {
      conditions.part_file = mj.part_file.string(), conditions.part_sha256 = digest(mj.part_file);
      conditions.machine_file = mj.machine_file.string(),
      conditions.machine_sha256 = digest(mj.machine_file);
      conditions.material_file = mj.material_file.string(),
      conditions.material_sha256 = digest(mj.material_file);
    } else if (digest(mj.part_file) != conditions.part_sha256 ||
               digest(mj.machine_file) != conditions.machine_sha256 ||
               digest(mj.material_file) != conditions.material_sha256) {
      fail(
          "{}: its part model, machine or material differs from the first measurement's ({}, "
          "{}, {}): a verification holds for one set of conditions",
          file.string(), conditions.part_file, conditions.machine_file, conditions.material_file);
    }
    ForwardModel model(inputs);
    const MeasurementResult result = measure(model, model.start());
    if (result.status != MeasurementStatus::kMeasured)
      fail("{}: the master was not measured ({}); a verification takes only measurements",
           file.string(), result.check.failures.front());
    MasterMeasurement m;
    m.job = file.string();
    for (const MeasuredDimension& d : result.dimensions) {
      if (!d.free) continue;
      for (const DimensionUncertainty& u : result.uncertainty.dimensions)
        if (u.name == d.name && u.identifiable) m.dimensions[d.name] = {d.value, u.combined};
    }
    for (const MeasuredRadiograph& r : result.radiographs)
      m.magnifications.push_back(r.magnification);
    measured.push_back(std::move(m));
  }
  return verifyOnMaster(measured, job.certificate, std::move(conditions));
}

}  // namespace xgauge
