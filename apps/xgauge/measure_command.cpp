#include "measure_command.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/config.h"
#include "xgauge/core/output.h"
#include "xgauge/material/exponential_fit.h"
#include "xgauge/measure/job.h"
#include "xgauge/measure/inputs.h"
#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"
#include "xgauge/measure/truth.h"
#include "xgauge/report/measurement.h"

#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <sstream>

namespace xgauge::cli {

void addMeasureCommand(CLI::App& app, MeasureArguments& args) {
  CLI::App* cmd = app.add_subcommand("measure", "Measure a part's dimensions from radiographs (a job file)");
  cmd->add_option("job", args.job, "Measurement job (JSON)")->required();
  cmd->add_option("-o,--output", args.output, "Output folder: result.json, simulated and difference images, log")
      ->required();
  cmd->add_option("--truth", args.truth, "A virtual lab's truth.json: also print the errors");
}

void runMeasure(const MeasureArguments& args) {
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
  const MeasurementResult result = measure(model, model.start());

  std::string table = fmt::format("{:<18} {:>10}", "dimension", "measured");
  if (truth) table += fmt::format(" {:>10} {:>10}", "true", "error");
  table += "\n";
  for (const auto& d : result.dimensions) {
    table += fmt::format("{:<18} {:>10.4f}", d.name + (d.free ? "" : " (fixed)"), d.value);
    if (truth && truth->dimensions.count(d.name))
      table += fmt::format(" {:>10.4f} {:>+10.4f}", truth->dimensions.at(d.name),
                           d.value - truth->dimensions.at(d.name));
    table += "\n";
  }
  std::fputs(table.c_str(), stdout);
  spdlog::info("{} evaluations in {:.1f} s; final loss {:.6g}", result.evaluations, result.seconds,
               result.total_loss);
  OutputTransaction outputs;
  writeMeasurementOutputs(model, result, args.output);
  spdlog::default_logger()->sinks().pop_back();
  writeFileAtomically(std::filesystem::path(args.output) / "measure.log", log.str() + table);
  outputs.commit();
  spdlog::info("wrote {}/result.json", args.output);
}

void addMaterialCommand(CLI::App& app, MaterialArguments& args) {
  CLI::App* cmd = app.add_subcommand(
      "material", "Fit an exponential-sum material to a virtual lab's transmission table");
  cmd->add_option("--from-truth", args.truth, "truth.json of a simulated dataset")->required();
  cmd->add_option("--terms", args.terms, "Number of exponentials M")->check(CLI::Range(1, 4));
  cmd->add_option("-o,--output", args.output, "Material file (JSON)")->required();
}

void runMaterial(const MaterialArguments& args) {
  checkOutputFile(args.output);
  const DatasetTruth truth = DatasetTruth::load(args.truth);
  ExponentialFitReport report;
  const ExponentialSum material = fitExponentialSum(truth.path_mm, truth.transmission, args.terms, {}, &report);
  nlohmann::json out = material.toJson();
  out["description"] = fmt::format("{} exponentials fitted to the transmission table of {} (RMS {:.2e}, max {:.2e})",
                                   args.terms, args.truth, report.rms_residual, report.max_abs_residual);
  writeFileAtomically(args.output, out.dump(2) + "\n");
  spdlog::info("wrote {}: RMS residual {:.2e}, max {:.2e}", args.output, report.rms_residual,
               report.max_abs_residual);
}

}  // namespace xgauge::cli
