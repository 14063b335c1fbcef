// The front door's verification on a master (xgauge/xgauge.h) over
// measure/verify.h. `xgauge verify` is this call and a print.
#include "guard.h"
#include "xgauge/core/atomic_file.h"
#include "xgauge/core/output.h"
#include "xgauge/measure/verify.h"
#include "xgauge/xgauge.h"

#include <fmt/format.h>

#include <cmath>

namespace xgauge {

namespace {

// The table `xgauge verify` prints: per dimension the certified value, the
// mean, bias, the standard uncertainties and the master's U.
std::string verificationTable(const Verification& verification) {
  std::string table =
      fmt::format("{:<18} {:>10} {:>10} {:>9} {:>8} {:>8} {:>8} {:>9}\n", "dimension", "certified",
                  "mean", "bias", "u_cal", "u_p", "u_b", "U master");
  for (const VerifiedDimension& d : verification.dimensions)
    table +=
        fmt::format("{:<18} {:>10.4f} {:>10.4f} {:>+9.4f} {:>8.4f} {:>8.4f} {:>8.4f} {:>9.4f}\n",
                    d.name, d.calibrated, d.mean, d.bias, d.u_cal, d.u_p, d.u_b,
                    verification.coverage_factor *
                        std::sqrt(d.u_cal * d.u_cal + d.u_p * d.u_p + d.u_b * d.u_b));
  table += fmt::format(
      "{} measurements of the master; magnification {:.3f} .. {:.3f}. A workpiece's U adds its "
      "own variation u_w (docs/method.md, \"Verification on a master\").\n",
      verification.measurements.size(), verification.conditions.magnification[0],
      verification.conditions.magnification[1]);
  return table;
}

VerificationSummary verifyOrThrow(const VerificationOptions& options) {
  checkOutputFolder(options.output_folder);
  const VerificationJob job = VerificationJob::load(options.job_file);
  const Verification verification = verifyMethod(job);
  VerificationSummary summary;
  summary.report = verificationTable(verification);
  summary.measurements = verification.measurements.size();
  OutputTransaction outputs;
  createOutputFolder(options.output_folder);
  writeFileAtomically(options.output_folder / "verification.json",
                      verification.toJson().dump(2) + "\n");
  outputs.commit();
  summary.termination = RunTermination::kDone;
  summary.message = "wrote " + options.output_folder.string() + "/verification.json";
  return summary;
}

}  // namespace

VerificationSummary verify(const VerificationOptions& options) {
  return api::guarded<VerificationSummary>([&] { return verifyOrThrow(options); });
}

}  // namespace xgauge
