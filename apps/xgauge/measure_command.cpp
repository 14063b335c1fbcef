#include "measure_command.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/config.h"
#include "xgauge/core/output.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/measure/inputs.h"
#include "xgauge/measure/job.h"
#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"
#include "xgauge/measure/truth.h"
#include "xgauge/report/measurement.h"
#include "xgauge/xray/machine.h"

#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <sstream>

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
  checkOutputFolder(args.output);
  const MeasurementInputs inputs = loadMeasurementInputs(args.job);
  std::optional<DatasetTruth> truth;
  if (!args.truth.empty()) truth = DatasetTruth::load(args.truth);

  // Keep a copy of the log for the output folder.
  std::ostringstream log;
  auto sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(log);
  sink->set_pattern("[%Y-%m-%d %H:%M:%S.%e] [%l] %v");
  spdlog::default_logger()->sinks().push_back(sink);
  ForwardModel model(inputs);
  auto [result, simulated] = measureWithPictures(model);

  bool toleranced = false, withheld = false;
  std::vector<Decision> decisions;
  for (const auto& d : result.dimensions) {
    if (d.decision) toleranced = true, decisions.push_back(*d.decision);
    withheld |= d.tolerance && !d.decision;  // an unverified U: no verdict
  }
  const bool measured = result.status == MeasurementStatus::kMeasured;
  std::string table;
  if (!measured) {
    table += fmt::format(
        "NOT MEASURED: after {} attempt(s) the fit does not explain the radiographs; the values "
        "below are the rejected fit's, not results, and no verdict is given:\n",
        result.attempts);
    for (const auto& f : result.check.failures) table += "  - " + f + "\n";
  }
  table += fmt::format("{:<18} {:>10} {:>9} {:<10}", "dimension",
                       measured ? "measured" : "rejected", "U (k=2)", " U is");
  if (toleranced) table += fmt::format(" {:>19} {:<16}", "tolerance zone", " verdict");
  if (truth) table += fmt::format(" {:>10} {:>10}", "true", "error");
  table += "\n";
  for (const auto& d : result.dimensions) {
    table += fmt::format("{:<18} {:>10.4f} {:>9}", d.name + (d.free ? "" : " (fixed)"), d.value,
                         !d.free                  ? ""
                         : d.expanded_uncertainty ? fmt::format("{:.4f}", *d.expanded_uncertainty)
                                                  : "n/a");
    table += fmt::format(" {:<10}", !d.free ? "" : d.verified ? " verified" : " unverified");
    if (toleranced)
      table += d.tolerance ? fmt::format(" [{:>8.4f},{:>9.4f}]  {:<16}", d.tolerance->lowerLimit(),
                                         d.tolerance->upperLimit(),
                                         std::string(verdictName(d.decision->verdict)))
                           : fmt::format(" {:>19} {:<16}", "", "");
    if (truth && truth->dimensions.count(d.name))
      table += fmt::format(" {:>10.4f} {:>+10.4f}", truth->dimensions.at(d.name),
                           d.value - truth->dimensions.at(d.name));
    table += "\n";
  }
  for (const auto& c : result.uncertainty.combinations)
    table += c.name.empty()
                 ? fmt::format(
                       "{:<18} {:>10.4f} {:>9.4f}  (measurable combination of dimensions "
                       "that are not determined alone)\n",
                       c.expression, c.value, c.expanded)
                 : fmt::format("{:<18} {:>10.4f} {:>9.4f}  (the part's combination {})\n", c.name,
                               c.value, c.expanded, c.expression);
  if (const auto& refined = result.uncertainty.refinement)
    table += fmt::format(
        "material refined in situ: rates x (1 {:+.5f}), u {:.5f} (prior {:.5f}); the curve "
        "{:+.4f} at {:.1f} mm\n",
        refined->rate_scale, refined->standard_uncertainty, refined->prior_standard_uncertainty,
        refined->transmission_change, refined->at_path_mm);
  if (toleranced) table += fmt::format("Verdicts: {}.\n", kDecisionRule);
  if (!result.check.warnings.empty()) {
    table += fmt::format("{} warning(s):\n", result.check.warnings.size());
    for (const auto& w : result.check.warnings) table += "  - " + w + "\n";
  }
  std::fputs(table.c_str(), stdout);
  spdlog::info("{} evaluations in {:.1f} s; final loss {:.6g}", result.evaluations, result.seconds,
               result.total_loss);
  OutputTransaction outputs;
  nlohmann::json true_values = nullptr;
  if (truth)
    for (const auto& [name, value] : truth->dimensions) true_values[name] = value;
  writeMeasurementOutputs(model, result, args.output, args.report, true_values,
                          std::move(simulated));
  spdlog::default_logger()->sinks().pop_back();
  writeFileAtomically(std::filesystem::path(args.output) / "measure.log", log.str() + table);
  outputs.commit();
  spdlog::info("wrote {}/result.json", args.output);
  if (!measured) return kExitCouldNotMeasure;
  // A tolerance whose verdict was withheld (its U unverified) cannot be
  // taken as conforming.
  return std::max(exitCodeFor(decisions), withheld ? kExitInconclusive : kExitConforms);
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
