// `xgauge simulate`, `material` and `study`: xgauge/lab.h's calls and a print.
#include "commands.h"
#include "xgauge/lab.h"
#include "xgauge/runtime.h"

#include <array>
#include <cstdio>
#include <memory>
#include <string>

namespace xgauge::cli {

void addSimulateCommand(CLI::App& app, Commands& commands) {
  auto args = std::make_shared<std::pair<std::string, std::string>>();  // recipe, output
  CLI::App* cmd = app.add_subcommand(
      "simulate", "Simulate a dataset (raw radiographs, dark, flat, truth.json) from a recipe");
  cmd->add_option("recipe", args->first, "Dataset recipe (JSON), e.g. datasets/prism_a.json")
      ->required();
  cmd->add_option("-o,--output", args->second, "Output folder (created if missing)")->required();
  commands.push_back({cmd, [args] {
                        succeeded(simulate({args->first, args->second}));
                        return 0;
                      }});
}

void addMaterialCommand(CLI::App& app, Commands& commands) {
  auto args = std::make_shared<std::pair<std::string, std::string>>();  // truth, output
  auto options = std::make_shared<MaterialFitOptions>();
  CLI::App* cmd = app.add_subcommand(
      "material", "Fit an exponential-sum material to a virtual lab's transmission table");
  cmd->add_option("--from-truth", args->first, "truth.json of a simulated dataset")->required();
  cmd->add_option("--terms", options->terms,
                  "Fewest exponentials M; more are added, up to 8, until the largest residual "
                  "over the paths the shots show is at most 1e-4")
      ->check(CLI::Range(1, 8));
  cmd->add_option("-o,--output", args->second, "Material file (JSON)")->required();
  commands.push_back({cmd, [args, options] {
                        options->truth_file = args->first;
                        options->output_file = args->second;
                        succeeded(fitMaterial(*options));
                        return 0;
                      }});
}

void addStudyCommand(CLI::App& app, Commands& commands) {
  auto options = std::make_shared<MeasurementStudyOptions>();
  auto paths = std::make_shared<std::array<std::string, 3>>();  // dataset, settings, output
  CLI::App* cmd = app.add_subcommand(
      "study", "Measure every combination of shots of a simulated dataset; tabulate the errors");
  cmd->add_option("dataset", (*paths)[0], "Dataset folder with truth.json (xgauge simulate)")
      ->required();
  cmd->add_option("-s,--settings", (*paths)[1], "Study settings: a job without radiographs (JSON)")
      ->required();
  cmd->add_option("-c,--combinations", options->combinations,
                  "pairs, pairs+rotated or turned-pairs")
      ->check(CLI::IsMember({"pairs", "pairs+rotated", "turned-pairs"}));
  cmd->add_option("--limit", options->limit, "Only the first N runs (0 = all)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--images", options->images,
                "Also write each run's simulated and difference images and its report.html");
  cmd->add_flag("--report,!--no-report", options->report,
                "Write report.html, the study report (default: on)");
  cmd->add_option("-o,--output", (*paths)[2], "Output folder (resumes a study already there)")
      ->required();
  cmd->add_option("--shard", options->shard,
                  "i/N: only every N-th run, from the i-th (array tasks sharing one output folder; "
                  "then run once without --shard to gather them)");
  commands.push_back({cmd, [options, paths] {
                        options->dataset = (*paths)[0];
                        options->settings = (*paths)[1];
                        options->output_folder = (*paths)[2];
                        const MeasurementStudySummary summary = succeeded(study(*options));
                        std::fputs(summary.table.c_str(), stdout);
                        LogMessage(Severity::kInfo, summary.message);
                        return 0;
                      }});
}

}  // namespace xgauge::cli
