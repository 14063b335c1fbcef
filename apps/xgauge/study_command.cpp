#include "study_command.h"

#include "xgauge/core/error.h"
#include "xgauge/core/output.h"
#include "xgauge/study/study.h"

#include <spdlog/spdlog.h>

#include <cstdio>

namespace xgauge::cli {

void addStudyCommand(CLI::App& app, StudyArguments& args) {
  CLI::App* cmd = app.add_subcommand(
      "study", "Measure every combination of shots of a simulated dataset; tabulate the errors");
  cmd->add_option("dataset", args.dataset, "Dataset folder with truth.json (xgauge simulate)")->required();
  cmd->add_option("-s,--settings", args.settings, "Study settings: a job without radiographs (JSON)")->required();
  cmd->add_option("-c,--combinations", args.combinations, "pairs, pairs+rotated or turned-pairs")
      ->check(CLI::IsMember({"pairs", "pairs+rotated", "turned-pairs"}));
  cmd->add_option("--limit", args.limit, "Only the first N runs (0 = all)")->check(CLI::NonNegativeNumber);
  cmd->add_flag("--images", args.images,
                "Also write each run's simulated and difference images and its report.html");
  cmd->add_flag("--report,!--no-report", args.report,
                "Write report.html, the study report (default: on)");
  cmd->add_option("-o,--output", args.output, "Output folder (resumes a study already there)")->required();
  cmd->add_option("--shard", args.shard,
                  "i/N: only every N-th run, from the i-th (array tasks sharing one output folder; "
                  "then run once without --shard to gather them)");
}

void runStudyCommand(const StudyArguments& args) {
  checkOutputFolder(args.output);
  StudyOptions options;
  options.dataset = args.dataset;
  options.settings = args.settings;
  options.combinations = args.combinations;
  options.limit = args.limit;
  options.output = args.output;
  options.images = args.images;
  options.report = args.report;
  if (!args.shard.empty()) {
    int index = 0, count = 0;
    char rest = 0;
    if (std::sscanf(args.shard.c_str(), "%d/%d%c", &index, &count, &rest) != 2 || count < 1 ||
        index < 1 || index > count)
      fail("--shard {}: expected i/N with 1 <= i <= N", args.shard);
    options.shard_index = index, options.shard_count = count;
  }
  const StudySummary summary = runStudy(options);
  if (options.shard_count > 1) {
    spdlog::info("shard {}/{}: {} run(s) in {}/runs; run the study without --shard to gather",
                 options.shard_index, options.shard_count, summary.runs.size(), args.output);
    return;
  }
  std::fputs(summary.table().c_str(), stdout);
  spdlog::info("wrote {}/study.csv, study.json{}", args.output,
               args.report ? " and report.html" : "");
}

}  // namespace xgauge::cli
