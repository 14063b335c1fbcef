#include "xgauge/measure/verify.h"

#include "xgauge/core/config.h"
#include "xgauge/core/error.h"
#include "xgauge/measure/inputs.h"
#include "xgauge/measure/model.h"
#include "xgauge/measure/truth.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

namespace xgauge {

namespace {

// A master's certificate: a CMM's, or a virtual lab's truth with one u.
std::map<std::string, CertifiedValue> certificateOf(const ConfigNode& master,
                                                    const std::filesystem::path& folder) {
  std::map<std::string, CertifiedValue> out;
  if (master.has("certificate") == master.has("truth"))
    master.fail("expected either \"certificate\" (a CMM's) or \"truth\" (a virtual lab's)");
  if (auto certificate = master.find("certificate")) {
    for (const std::string& name : certificate->keys()) {
      const ConfigNode c = certificate->at(name);
      out[name] = {c.at("value").number(), c.at("standard_uncertainty").number(0.0, 1e3)};
    }
  } else {
    const DatasetTruth truth = DatasetTruth::load(folder / master.at("truth").string());
    const double u = master.at("standard_uncertainty").number(0.0, 1e3);
    for (const auto& [name, value] : truth.dimensions) out[name] = {value, u};
  }
  if (out.empty()) master.fail("the master's certificate names no dimension");
  return out;
}

std::vector<std::filesystem::path> jobsOf(const ConfigNode& measurements,
                                          const std::filesystem::path& folder) {
  std::vector<std::filesystem::path> out;
  for (size_t k = 0; k < measurements.size(); ++k) out.push_back(folder / measurements[k].string());
  if (out.empty()) measurements.fail("a master needs at least one measurement");
  return out;
}

}  // namespace

VerificationJob VerificationJob::load(const std::filesystem::path& file) {
  const ConfigNode root = ConfigNode::loadFile(file);
  const std::filesystem::path folder = file.parent_path();
  VerificationJob job;
  job.file = file;
  job.description = root.get<std::string>("description", "");
  if (root.has("master") == root.has("masters"))
    root.fail("expected either \"master\" with \"measurements\", or \"masters\"");
  size_t count = 0;
  if (auto master = root.find("master")) {
    job.masters.push_back(
        {certificateOf(*master, folder), jobsOf(root.at("measurements"), folder)});
  } else {
    const ConfigNode masters = root.at("masters");
    if (masters.size() == 0) masters.fail("expected at least one master");
    for (size_t j = 0; j < masters.size(); ++j) {
      const ConfigNode m = masters[j];
      job.masters.push_back({certificateOf(m, folder), jobsOf(m.at("measurements"), folder)});
    }
  }
  for (const Master& m : job.masters) count += m.measurements.size();
  if (static_cast<int>(count) < kMinVerificationMeasurements)
    root.fail(fmt::format("a verification needs at least {} measurements of its masters, got {}",
                          kMinVerificationMeasurements, count));
  root.finish();
  return job;
}

Verification verifyMethod(const VerificationJob& job) {
  std::vector<MasterMeasurement> measured;
  std::vector<std::map<std::string, CertifiedValue>> certificates;
  std::vector<std::pair<int, std::filesystem::path>> jobs;
  for (size_t j = 0; j < job.masters.size(); ++j) {
    certificates.push_back(job.masters[j].certificate);
    for (const std::filesystem::path& file : job.masters[j].measurements)
      jobs.emplace_back(static_cast<int>(j), file);
  }
  VerificationConditions conditions;
  for (size_t k = 0; k < jobs.size(); ++k) {
    const auto& [master, file] = jobs[k];
    spdlog::info("master {} of {}, measurement {} of {}: {}", master + 1, job.masters.size(), k + 1,
                 jobs.size(), file.string());
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
    m.master = master;
    for (const MeasuredDimension& d : result.dimensions) {
      if (!d.free) continue;
      for (const DimensionUncertainty& u : result.uncertainty.dimensions)
        if (u.name == d.name && u.identifiable) m.dimensions[d.name] = {d.value, u.combined};
    }
    for (const MeasuredRadiograph& r : result.radiographs)
      m.magnifications.push_back(r.magnification);
    measured.push_back(std::move(m));
  }
  return verifyOnMasters(measured, certificates, std::move(conditions));
}

}  // namespace xgauge
