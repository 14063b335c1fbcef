// `xgauge measure`, `calibrate wedge|part|geometry`, `characterize` and
// `verify`, `plan`: xgauge/xgauge.h's calls and a print.
#include "commands.h"
#include "xgauge/runtime.h"
#include "xgauge/xgauge.h"

#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>

namespace xgauge::cli {

namespace {

// The arguments of measure and calibrate wedge|part (and a few of geometry).
struct JobArguments {
  std::string job;
  std::string output;
  std::string truth;   // optional truth.json
  bool report = true;  // write report.html
  double reach_deg = 2.0;
};

void addCalibrationArguments(CLI::App* cmd, JobArguments& args) {
  cmd->add_option("job", args.job, "Calibration job (JSON)")->required();
  cmd->add_option("-o,--output", args.output,
                  "Output folder: material.json, calibration.json, report.html")
      ->required();
  cmd->add_option("--truth", args.truth,
                  "A virtual lab's truth.json: also report the deviation from its true curve");
  cmd->add_flag("--report,!--no-report", args.report,
                "Write report.html, the calibration report (default: on)");
}

int runCalibration(const JobArguments& args, CalibrationKind kind) {
  CalibrationOptions options;
  options.kind = kind;
  options.job_file = args.job;
  options.output_folder = args.output;
  options.truth_file = args.truth;
  options.write_report = args.report;
  options.reach_deg = args.reach_deg;
  const CalibrationSummary summary = calibrate(options);
  if (summary.termination != CalibrationTermination::kCalibrated)
    throw std::runtime_error(summary.message);
  std::fputs(summary.FullReport().c_str(), stdout);
  return 0;
}

}  // namespace

void addMeasureCommand(CLI::App& app, Commands& commands) {
  auto args = std::make_shared<JobArguments>();
  CLI::App* cmd =
      app.add_subcommand("measure", "Measure a part's dimensions from radiographs (a job file)");
  cmd->add_option("job", args->job, "Measurement job (JSON)")->required();
  cmd->add_option("-o,--output", args->output,
                  "Output folder: result.json, simulated and difference images, log")
      ->required();
  cmd->add_option("--truth", args->truth, "A virtual lab's truth.json: also print the errors");
  cmd->add_flag("--report,!--no-report", args->report,
                "Write report.html, the inspection report (default: on)");
  commands.push_back({cmd, [args] {
                        MeasurementOptions options;
                        options.job_file = args->job;
                        options.output_folder = args->output;
                        options.truth_file = args->truth;
                        options.write_report = args->report;
                        const MeasurementSummary summary = measure(options);
                        if (summary.termination == TerminationType::kFailure)
                          throw std::runtime_error(summary.message);
                        std::fputs(summary.FullReport().c_str(), stdout);
                        return summary.exit_status;
                      }});
}

void addCalibrateCommand(CLI::App& app, Commands& commands) {
  CLI::App* cmd = app.add_subcommand(
      "calibrate", "Calibrate the material curve I(x), or the detector's pose, from radiographs");
  cmd->require_subcommand(1);
  auto wedge = std::make_shared<JobArguments>();
  CLI::App* w = cmd->add_subcommand("wedge",
                                    "From one radiograph of a wedge "
                                    "(thesis 3.4a, docs/method.md)");
  addCalibrationArguments(w, *wedge);
  commands.push_back({w, [wedge] { return runCalibration(*wedge, CalibrationKind::kWedge); }});
  auto part = std::make_shared<JobArguments>();
  CLI::App* p = cmd->add_subcommand("part",
                                    "From radiographs of a part of known dimensions "
                                    "(thesis 3.4b, docs/method.md)");
  addCalibrationArguments(p, *part);
  commands.push_back({p, [part] { return runCalibration(*part, CalibrationKind::kPart); }});
  auto geometry = std::make_shared<JobArguments>();
  CLI::App* g = cmd->add_subcommand(
      "geometry", "The detector's tilt and turn from radiographs of a part of known dimensions");
  g->add_option("job", geometry->job, "Measurement job with every dimension fixed (JSON)")
      ->required();
  g->add_option("-o,--output", geometry->output, "Output folder: machine.json, geometry.json")
      ->required();
  g->add_option("--reach-deg", geometry->reach_deg,
                "How far from the machine's stated pose each angle may go (deg, default 2)")
      ->check(CLI::Range(1e-3, 10.0));
  geometry->report = false;
  commands.push_back(
      {g, [geometry] { return runCalibration(*geometry, CalibrationKind::kGeometry); }});
}

void addCharacterizeCommand(CLI::App& app, Commands& commands) {
  auto job = std::make_shared<std::string>(), output = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "characterize",
      "Characterise the detector from dark and flat series and shots of an opaque edge, a lag "
      "pair and a covered quadrant: halo (shape, weight, width, border), lag, crosstalk, bad "
      "pixels");
  cmd->add_option("job", *job, "Characterisation job (JSON, docs/formats.md)")->required();
  cmd->add_option("-o,--output", *output, "Output folder: detector.json, bad_pixels.json")
      ->required();
  commands.push_back(
      {cmd, [job, output] {
         const CharacterizationSummary summary = succeeded(characterize({*job, *output}));
         std::fputs(summary.report.c_str(), stdout);
         LogMessage(Severity::kInfo, summary.message);
         return 0;
       }});
}

void addVerifyCommand(CLI::App& app, Commands& commands) {
  auto job = std::make_shared<std::string>(), output = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "verify",
      "Verify the measuring method on a calibrated master (ISO 15530-3): its bias and "
      "repeatability per dimension, for measurement jobs to name");
  cmd->add_option("job", *job,
                  "Verification job (JSON): the master's certificate and its "
                  "measurement jobs")
      ->required();
  cmd->add_option("-o,--output", *output, "Output folder: verification.json")->required();
  commands.push_back({cmd, [job, output] {
                        const VerificationSummary summary = succeeded(verify({*job, *output}));
                        std::fputs(summary.report.c_str(), stdout);
                        LogMessage(Severity::kInfo, summary.message);
                        return 0;
                      }});
}

void addPlanCommand(CLI::App& app, Commands& commands) {
  auto job = std::make_shared<std::string>(), output = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "plan",
      "Where to put the part: predict each dimension's U for every set of candidate views and "
      "rank the sets (before a shot is taken)");
  cmd->add_option("job", *job, "Plan job (JSON): the measurement job, the shot's noise, the "
                               "candidate views")
      ->required();
  cmd->add_option("-o,--output", *output, "Output folder: plan.json, job.json, report.html")
      ->required();
  commands.push_back({cmd, [job, output] {
                        const PlanSummary summary = succeeded(plan({*job, *output}));
                        std::fputs(summary.report.c_str(), stdout);
                        LogMessage(Severity::kInfo, summary.message);
                        return 0;
                      }});
}

}  // namespace xgauge::cli
