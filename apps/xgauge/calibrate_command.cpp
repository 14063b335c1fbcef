#include "calibrate_command.h"

#include "xgauge/calibrate/geometry.h"
#include "xgauge/core/error.h"
#include "xgauge/xgauge.h"

#include <fmt/format.h>

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

void addCalibrateCommand(CLI::App& app, CalibrateArguments& wedge, CalibrateArguments& part,
                         CalibrateArguments& geometry) {
  CLI::App* cmd = app.add_subcommand(
      "calibrate", "Calibrate the material curve I(x), or the detector's pose, from radiographs");
  cmd->require_subcommand(1);
  addArguments(cmd->add_subcommand("wedge",
                                   "From one radiograph of a wedge "
                                   "(thesis 3.4a, docs/method.md)"),
               wedge);
  addArguments(cmd->add_subcommand("part",
                                   "From radiographs of a part of known dimensions "
                                   "(thesis 3.4b, docs/method.md)"),
               part);
  CLI::App* g = cmd->add_subcommand(
      "geometry", "The detector's tilt and turn from radiographs of a part of known dimensions");
  g->add_option("job", geometry.job, "Measurement job with every dimension fixed (JSON)")
      ->required();
  g->add_option("-o,--output", geometry.output, "Output folder: machine.json, geometry.json")
      ->required();
  g->add_option("--reach-deg", geometry.reach_deg,
                "How far from the machine's stated pose each angle may go (deg, default 2)")
      ->check(CLI::Range(1e-3, 10.0));
}

namespace {

void runGeometry(const CalibrateArguments& args) {
  const GeometryCalibration g = calibrateGeometry(args.job, args.reach_deg);
  writeGeometryCalibration(g, args.output);
  std::fputs(
      fmt::format("detector tilt about u  {:+.4f} deg  u {:.4f}\n"
                  "detector tilt about v  {:+.4f} deg  u {:.4f}\n"
                  "detector rotation      {:+.4f} deg  u {:.4f}\n"
                  "worst misfit ratio     {:.2f}\n"
                  "wrote {}/machine.json\n",
                  g.angles_deg[0], g.uncertainty_deg[0], g.angles_deg[1], g.uncertainty_deg[1],
                  g.angles_deg[2], g.uncertainty_deg[2], g.misfit_ratio, args.output)
          .c_str(),
      stdout);
}

}  // namespace

void runCalibrate(const CLI::App& app, const CalibrateArguments& wedge,
                  const CalibrateArguments& part, const CalibrateArguments& geometry) {
  if (app.get_subcommand("calibrate")->got_subcommand("geometry")) return runGeometry(geometry);
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
