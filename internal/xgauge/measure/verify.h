// `xgauge verify`: the measuring method verified on a calibrated master
// (measure/verification.h has the equations and the verification file).
#pragma once

#include "xgauge/measure/measure.h"
#include "xgauge/measure/verification.h"

#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace xgauge {

// A verification job (docs/formats.md, "Verification job"): the master's
// certificate and the measurement jobs that measured it under the
// production conditions.
//
// Keys (paths relative to the job file; unknown keys are errors):
//   description   free text
//   master        {"certificate": {name: {"value", "standard_uncertainty"}}}: a CMM's
//                 certificate (standard uncertainties, k = 1, in the dimension's unit);
//                 or {"truth": a virtual lab's truth.json, "standard_uncertainty": u}:
//                 every dimension of the lab's part, each with u
//   measurements  at least kMinVerificationMeasurements measurement jobs of the master
//                 (measure/job.h), each naming no verification of its own
// or, for several masters (verification.h):
//   masters       [{certificate or truth as "master" has, "measurements": [at least
//                 one job]}, ...], at least kMinVerificationMeasurements jobs in all
struct VerificationJob {
  struct Master {
    std::map<std::string, CertifiedValue> certificate;
    std::vector<std::filesystem::path> measurements;
  };
  std::filesystem::path file;
  std::string description;
  std::vector<Master> masters;
  static VerificationJob load(const std::filesystem::path& file);
};

// Measures the master with each of the job's measurement jobs and builds the
// verification. Error when a measurement is not measured (naming the job and
// why), when the jobs differ in part model, machine or material (their
// files' SHA-256), or when the certificate names no dimension the jobs
// measured. The verification records each measurement (its job, values,
// own uncertainties and magnifications).
Verification verifyMethod(const VerificationJob& job);

}  // namespace xgauge
