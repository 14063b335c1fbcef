#include "calibrate_command.h"

#include "xgauge/core/error.h"
#include "xgauge/xgauge.h"

#include <cstdio>

namespace xgauge::cli {

namespace {

void addArguments(CLI::App* cmd, CalibrateArguments& args) {
  cmd->add_option("job", args.job, "Calibration job (JSON)")->required();
  cmd->add_option("-o,--output", args.output,
                  "Output folder: material.json, calibration.json, report.html")
      ->required();
  cmd->add_option("--truth", args.truth,
                  "A virtual lab's truth.json: also report the deviation from its true curve");
  cmd->add_flag("--report,!--no-report", args.report,
                "Write report.html, the calibration report (default: on)");
}

}  // namespace

void addCalibrateCommand(CLI::App& app, CalibrateArguments& wedge, CalibrateArguments& part) {
  CLI::App* cmd =
      app.add_subcommand("calibrate", "Calibrate the material curve I(x) from radiographs");
  cmd->require_subcommand(1);
  addArguments(cmd->add_subcommand("wedge",
                                   "From one radiograph of a wedge "
                                   "(thesis 3.4a, docs/method.md)"),
               wedge);
  addArguments(cmd->add_subcommand("part",
                                   "From radiographs of a part of known dimensions "
                                   "(thesis 3.4b, docs/method.md)"),
               part);
}

void runCalibrate(const CLI::App& app, const CalibrateArguments& wedge,
                  const CalibrateArguments& part) {
  const bool from_wedge = app.get_subcommand("calibrate")->got_subcommand("wedge");
  const CalibrateArguments& args = from_wedge ? wedge : part;
  CalibrationOptions options;
  options.kind = from_wedge ? CalibrationKind::kWedge : CalibrationKind::kPart;
  options.job_file = args.job;
  options.output_folder = args.output;
  options.truth_file = args.truth;
  options.write_report = args.report;
  const CalibrationSummary summary = calibrate(options);
  if (summary.termination != CalibrationTermination::kCalibrated) throw Error(summary.message);
  std::fputs(summary.FullReport().c_str(), stdout);
}

}  // namespace xgauge::cli
