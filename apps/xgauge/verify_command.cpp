#include "verify_command.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/output.h"
#include "xgauge/measure/verify.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <cstdio>

namespace xgauge::cli {

void addVerifyCommand(CLI::App& app, VerifyArguments& args) {
  CLI::App* cmd = app.add_subcommand(
      "verify",
      "Verify the measuring method on a calibrated master (ISO 15530-3): its bias and "
      "repeatability per dimension, for measurement jobs to name");
  cmd->add_option("job", args.job,
                  "Verification job (JSON): the master's certificate and its "
                  "measurement jobs")
      ->required();
  cmd->add_option("-o,--output", args.output, "Output folder: verification.json")->required();
}

void runVerify(const VerifyArguments& args) {
  checkOutputFolder(args.output);
  const VerificationJob job = VerificationJob::load(args.job);
  const Verification verification = verifyMethod(job);
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
  std::fputs(table.c_str(), stdout);
  OutputTransaction outputs;
  createOutputFolder(args.output);
  writeFileAtomically(std::filesystem::path(args.output) / "verification.json",
                      verification.toJson().dump(2) + "\n");
  outputs.commit();
  spdlog::info("wrote {}/verification.json", args.output);
}

}  // namespace xgauge::cli
