// The front door's verification on a master (xgauge/xgauge.h) over
// measure/verify.h. `xgauge verify` is this call and a print.
#include "guard.h"
#include "xgauge/core/atomic_file.h"
#include "xgauge/core/output.h"
#include "xgauge/measure/verify.h"
#include "xgauge/xgauge.h"

#include <fmt/format.h>

namespace xgauge {

namespace {

// The table `xgauge verify` prints: per dimension the certified value, the
// mean, bias, the standard uncertainties and the U a workpiece the model
// explains as well as the masters gets (u_w = 0; Student's k at its degrees
// of freedom).
std::string verificationTable(const Verification& verification) {
  std::string table =
      fmt::format("{:<18} {:>10} {:>10} {:>9} {:>8} {:>8} {:>8} {:>8} {:>9}\n", "dimension",
                  "certified", "mean", "bias", "u_cal", "u_p", "u_s", "u_b", "U (k)");
  for (const VerifiedDimension& d : verification.dimensions) {
    const Substitution s = substitute(d.mean, d.own_master, d, verification.coverage_factor);
    table += fmt::format(
        "{:<18} {:>10.4f} {:>10.4f} {:>+9.4f} {:>8.4f} {:>8.4f} {:>8.4f} {:>8.4f} {:>9.4f} "
        "({:.2f})\n",
        d.name, d.calibrated, d.mean, d.bias, d.u_cal, d.u_p, d.u_s, d.u_b, s.expanded,
        s.coverage_factor);
  }
  const int masters = verification.dimensions.empty() ? 1 : verification.dimensions[0].masters;
  table += fmt::format(
      "{} measurements of {} master{}{}; magnification {:.3f} .. {:.3f}. A workpiece's U adds "
      "its own variation u_w (docs/method.md, \"Verification on a master\").\n",
      verification.measurements.size(), masters, masters == 1 ? "" : "s",
      masters == 1 ? "" : " (certified and mean: averages over the masters)",
      verification.conditions.magnification[0], verification.conditions.magnification[1]);
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
