#include "inspect_command.h"

#include "xgauge/core/error.h"
#include "xgauge/production/inspect.h"

#include <spdlog/spdlog.h>

#include <cstdio>

namespace xgauge::cli {

void addInspectCommand(CLI::App& app, InspectArguments& args) {
  CLI::App* cmd = app.add_subcommand(
      "inspect",
      "Measure every part of a lot as it comes (an inspection plan), into a results store");
  cmd->add_option("plan", args.plan, "Inspection plan (JSON)")->required();
  cmd->add_option("source", args.source, "Folder of part folders (default: the plan's \"source\")");
  cmd->add_option("--watch", args.watch,
                  "Folder that parts arrive in: keep measuring them as they come");
  cmd->add_option("--store", args.store,
                  "Results store: an SQLite file or a postgresql:// URL (default: the plan's)");
  cmd->add_option("-o,--output", args.output,
                  "Folder for each part's outputs, <output>/<lot>/<part> (default: the plan's)");
  cmd->add_option("--station", args.station,
                  "This station's name (default: the plan's, or the host)");
  cmd->add_option("--shard", args.shard, "i/N: take only this process's share of the parts");
  cmd->add_option("--poll", args.poll_s, "--watch: seconds between looks at the folder")
      ->check(CLI::Range(0.01, 3600.0));
  cmd->add_option("--idle-exit", args.idle_exit_s,
                  "--watch: stop after this many seconds without a new part (default: never)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--spc", args.spc_baseline,
                  "SPC after each part, phase I the first N parts of the lot; alarms printed as "
                  "they happen (default: off)");
  cmd->add_flag("--report,!--no-report", args.report, "Write report.html per part (default: on)");
}

int runInspect(const InspectArguments& args) {
  if (!args.source.empty() && !args.watch.empty())
    fail("inspect: give a source folder or --watch, not both");
  const InspectionPlan plan = InspectionPlan::load(args.plan);
  InspectOptions options;
  options.source = args.watch.empty() ? args.source : args.watch;
  options.watch = !args.watch.empty();
  options.store = args.store;
  options.output = args.output;
  options.station = args.station;
  options.poll_s = args.poll_s;
  options.idle_exit_s = args.idle_exit_s;
  options.report = args.report;
  options.spc_baseline = args.spc_baseline;
  if (!args.shard.empty()) options.shard = Shard::parse(args.shard);
  const InspectSummary s = inspect(plan, options, [](const std::string& line) {
    std::fputs((line + "\n").c_str(), stdout);
    std::fflush(stdout);
  });
  spdlog::info(
      "inspect: {} part(s) measured here ({} not measured), {} found measured already, "
      "{} failed, {} not ready",
      s.measured, s.not_measured, s.already, s.failed, s.not_ready);
  return s.failed > 0 ? 1 : 0;
}

}  // namespace xgauge::cli
