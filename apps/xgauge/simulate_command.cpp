#include "simulate_command.h"

#include "xgauge/core/output.h"
#include "xgauge/lab/dataset.h"
#include "xgauge/lab/lot.h"
#include "xgauge/lab/recipe.h"

#include <spdlog/spdlog.h>

namespace xgauge::cli {

void addSimulateCommand(CLI::App& app, SimulateArguments& args) {
  CLI::App* cmd = app.add_subcommand(
      "simulate", "Simulate a dataset (raw radiographs, dark, flat, truth.json) from a recipe");
  cmd->add_option("recipe", args.recipe, "Dataset recipe (JSON), e.g. datasets/prism_a.json")
      ->required();
  cmd->add_option("-o,--output", args.output, "Output folder (created if missing)")->required();
}

void runSimulate(const SimulateArguments& args) {
  const Recipe recipe = Recipe::load(args.recipe);
  checkOutputFolder(args.output);
  if (isLotRecipe(recipe)) {
    // Part by part, each folder complete when its manifest appears: no
    // transaction holds them back (an interrupted lot resumes).
    const LotReport lot = simulateLot(recipe, args.output);
    spdlog::info("lot in {}: {} parts ({} made now) in {:.1f} s", args.output, lot.parts,
                 lot.simulated, lot.seconds);
    return;
  }
  OutputTransaction outputs;
  spdlog::info("simulating {} shots of {} into {}", recipe.shots.size(),
               recipe.part_file.filename().string(), args.output);
  const DatasetReport report = simulateDataset(recipe, args.output);
  spdlog::info("wrote {} shots, dark, flat and truth.json in {:.1f} s ({:.2f} s per shot); "
               "white region x={} y={} {}x{}",
               report.shots, report.seconds, report.seconds_per_shot, report.white_region.x,
               report.white_region.y, report.white_region.width, report.white_region.height);
  outputs.commit();
}

}  // namespace xgauge::cli
