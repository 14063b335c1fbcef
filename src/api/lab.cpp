// The front door's virtual lab (xgauge/lab.h) over the lab, measure and
// study modules. `xgauge simulate`, `material` and `study` are these calls
// and a print.
#include "xgauge/lab.h"

#include "guard.h"
#include "xgauge/core/atomic_file.h"
#include "xgauge/core/config.h"
#include "xgauge/core/error.h"
#include "xgauge/core/output.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/lab/dataset.h"
#include "xgauge/lab/lot.h"
#include "xgauge/lab/recipe.h"
#include "xgauge/measure/truth.h"
#include "xgauge/study/study.h"
#include "xgauge/xray/machine.h"

#include <spdlog/spdlog.h>

#include <cstdio>

namespace xgauge {

namespace {

SimulationSummary simulateOrThrow(const SimulationOptions& options) {
  const Recipe recipe = Recipe::load(options.recipe);
  checkOutputFolder(options.output_folder);
  SimulationSummary summary;
  summary.termination = RunTermination::kDone;
  if (isLotRecipe(recipe)) {
    // Part by part, each folder complete when its manifest appears: no
    // transaction holds them back (an interrupted lot resumes).
    const LotReport lot = simulateLot(recipe, options.output_folder);
    spdlog::info("lot in {}: {} parts ({} made now) in {:.1f} s", options.output_folder.string(),
                 lot.parts, lot.simulated, lot.seconds);
    summary.lot = true;
    summary.parts = lot.parts, summary.parts_simulated = lot.simulated;
    summary.seconds = lot.seconds;
    return summary;
  }
  OutputTransaction outputs;
  spdlog::info("simulating {} shots of {} into {}", recipe.shots.size(),
               recipe.part_file.filename().string(), options.output_folder.string());
  const DatasetReport report = simulateDataset(recipe, options.output_folder);
  spdlog::info(
      "wrote {} shots, dark, flat and truth.json in {:.1f} s ({:.2f} s per shot); "
      "white region x={} y={} {}x{}",
      report.shots, report.seconds, report.seconds_per_shot, report.white_region.x,
      report.white_region.y, report.white_region.width, report.white_region.height);
  outputs.commit();
  summary.shots = report.shots;
  summary.seconds = report.seconds;
  return summary;
}

MaterialFitSummary fitMaterialOrThrow(const MaterialFitOptions& options) {
  checkOutputFile(options.output_file);
  const DatasetTruth truth = DatasetTruth::load(options.truth_file);
  const PartModel part = PartModel::load(truth.part_file);
  const ConfigNode node =
      ConfigNode::fromJson(truth.machine, options.truth_file.string() + " (machine)");
  const Machine machine = Machine::fromConfig(node);
  node.finish();
  const double longest = longestTruePathMm(truth, part, machine);
  const ExponentialSum material = fitTrueCurve(truth, 1.05 * longest + 0.5, options.terms);
  writeFileAtomically(options.output_file, material.toJson().dump(2) + "\n");
  spdlog::info("wrote {}: {}", options.output_file.string(), material.description());
  MaterialFitSummary summary;
  summary.termination = RunTermination::kDone;
  summary.description = material.description();
  return summary;
}

MeasurementStudySummary studyOrThrow(const MeasurementStudyOptions& options) {
  checkOutputFolder(options.output_folder);
  StudyOptions study_options;
  study_options.dataset = options.dataset;
  study_options.settings = options.settings;
  study_options.combinations = options.combinations;
  study_options.limit = options.limit;
  study_options.output = options.output_folder;
  study_options.images = options.images;
  study_options.report = options.report;
  if (!options.shard.empty()) {
    int index = 0, count = 0;
    char rest = 0;
    if (std::sscanf(options.shard.c_str(), "%d/%d%c", &index, &count, &rest) != 2 || count < 1 ||
        index < 1 || index > count)
      fail("--shard {}: expected i/N with 1 <= i <= N", options.shard);
    study_options.shard_index = index, study_options.shard_count = count;
  }
  const StudySummary result = runStudy(study_options);
  MeasurementStudySummary summary;
  summary.termination = RunTermination::kDone;
  summary.runs = result.runs.size();
  const std::string folder = options.output_folder.string();
  if (study_options.shard_count > 1) {
    summary.message = fmt::format(
        "shard {}/{}: {} run(s) in {}/runs; run the study without --shard to gather",
        study_options.shard_index, study_options.shard_count, result.runs.size(), folder);
    return summary;
  }
  summary.table = result.table();
  summary.message = fmt::format("wrote {}/study.csv, study.json{}", folder,
                                options.report ? " and report.html" : "");
  return summary;
}

}  // namespace

SimulationSummary simulate(const SimulationOptions& options) {
  return api::guarded<SimulationSummary>([&] { return simulateOrThrow(options); });
}

MaterialFitSummary fitMaterial(const MaterialFitOptions& options) {
  return api::guarded<MaterialFitSummary>([&] { return fitMaterialOrThrow(options); });
}

MeasurementStudySummary study(const MeasurementStudyOptions& options) {
  return api::guarded<MeasurementStudySummary>([&] { return studyOrThrow(options); });
}

}  // namespace xgauge
