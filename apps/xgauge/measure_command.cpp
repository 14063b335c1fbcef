#include "measure_command.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/config.h"
#include "xgauge/core/error.h"
#include "xgauge/core/output.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/measure/truth.h"
#include "xgauge/xgauge.h"
#include "xgauge/xray/machine.h"

#include <spdlog/spdlog.h>

#include <cstdio>

namespace xgauge::cli {

void addMeasureCommand(CLI::App& app, MeasureArguments& args) {
  CLI::App* cmd =
      app.add_subcommand("measure", "Measure a part's dimensions from radiographs (a job file)");
  cmd->add_option("job", args.job, "Measurement job (JSON)")->required();
  cmd->add_option("-o,--output", args.output,
                  "Output folder: result.json, simulated and difference images, log")
      ->required();
  cmd->add_option("--truth", args.truth, "A virtual lab's truth.json: also print the errors");
  cmd->add_flag("--report,!--no-report", args.report,
                "Write report.html, the inspection report (default: on)");
}

int runMeasure(const MeasureArguments& args) {
  MeasurementOptions options;
  options.job_file = args.job;
  options.output_folder = args.output;
  options.truth_file = args.truth;
  options.write_report = args.report;
  const MeasurementSummary summary = measure(options);
  if (summary.termination == TerminationType::kFailure) throw Error(summary.message);
  std::fputs(summary.FullReport().c_str(), stdout);
  return summary.exit_status;
}

void addMaterialCommand(CLI::App& app, MaterialArguments& args) {
  CLI::App* cmd = app.add_subcommand(
      "material", "Fit an exponential-sum material to a virtual lab's transmission table");
  cmd->add_option("--from-truth", args.truth, "truth.json of a simulated dataset")->required();
  cmd->add_option("--terms", args.terms,
                  "Fewest exponentials M; more are added, up to 8, until the largest residual "
                  "over the paths the shots show is at most 1e-4")
      ->check(CLI::Range(1, 8));
  cmd->add_option("-o,--output", args.output, "Material file (JSON)")->required();
}

void runMaterial(const MaterialArguments& args) {
  checkOutputFile(args.output);
  const DatasetTruth truth = DatasetTruth::load(args.truth);
  const PartModel part = PartModel::load(truth.part_file);
  const ConfigNode node = ConfigNode::fromJson(truth.machine, args.truth + " (machine)");
  const Machine machine = Machine::fromConfig(node);
  node.finish();
  const double longest = longestTruePathMm(truth, part, machine);
  const ExponentialSum material = fitTrueCurve(truth, 1.05 * longest + 0.5, args.terms);
  writeFileAtomically(args.output, material.toJson().dump(2) + "\n");
  spdlog::info("wrote {}: {}", args.output, material.description());
}

}  // namespace xgauge::cli
