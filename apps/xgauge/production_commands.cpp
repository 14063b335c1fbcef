// `xgauge inspect`, `spc` and `export`: xgauge/production.h's calls and a
// print.
#include "commands.h"
#include "xgauge/production.h"

#include <array>
#include <cstdio>
#include <memory>
#include <string>

namespace xgauge::cli {

namespace {

void printLine(const std::string& line) {
  std::fputs((line + "\n").c_str(), stdout);
  std::fflush(stdout);
}

}  // namespace

void addInspectCommand(CLI::App& app, Commands& commands) {
  auto options = std::make_shared<InspectionOptions>();
  auto paths = std::make_shared<std::array<std::string, 4>>();  // plan, source, watch, output
  CLI::App* cmd = app.add_subcommand(
      "inspect",
      "Measure every part of a lot as it comes (an inspection plan), into a results store");
  cmd->add_option("plan", (*paths)[0], "Inspection plan (JSON)")->required();
  cmd->add_option("source", (*paths)[1], "Folder of part folders (default: the plan's \"source\")");
  cmd->add_option("--watch", (*paths)[2],
                  "Folder that parts arrive in: keep measuring them as they come");
  cmd->add_option("--store", options->store,
                  "Results store: an SQLite file or a postgresql:// URL (default: the plan's)");
  cmd->add_option("-o,--output", (*paths)[3],
                  "Folder for each part's outputs, <output>/<lot>/<part> (default: the plan's)");
  cmd->add_option("--station", options->station,
                  "This station's name (default: the plan's, or the host)");
  cmd->add_option("--shard", options->shard, "i/N: take only this process's share of the parts");
  cmd->add_option("--poll", options->poll_s, "--watch: seconds between looks at the folder")
      ->check(CLI::Range(0.01, 3600.0));
  cmd->add_option("--idle-exit", options->idle_exit_s,
                  "--watch: stop after this many seconds without a new part (default: never)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--spc", options->spc_baseline,
                  "SPC after each part, phase I the first N parts of the lot; alarms printed as "
                  "they happen (default: off)");
  cmd->add_flag("--report,!--no-report", options->write_report,
                "Write report.html per part (default: on)");
  commands.push_back({cmd, [options, paths] {
                        options->plan = (*paths)[0];
                        options->source = (*paths)[1];
                        options->watch = (*paths)[2];
                        options->output_folder = (*paths)[3];
                        options->on_line = printLine;
                        return succeeded(inspect(*options)).exit_status;
                      }});
}

void addSpcCommand(CLI::App& app, Commands& commands) {
  auto options = std::make_shared<ProcessControlOptions>();
  auto output = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "spc", "Control charts, run rules and capability per lot and dimension of a results store");
  cmd->add_option("store", options->store, "Results store: an SQLite file or a postgresql:// URL")
      ->required();
  cmd->add_option("--lot", options->lots, "Only these lots (default: every lot)");
  cmd->add_option("-o,--output", *output, "Folder for the pages: <output>/<lot>/<dimension>.html")
      ->required();
  cmd->add_option("--baseline", options->baseline,
                  "Phase I: the first N parts of each lot (a lot with fewer is refused)")
      ->check(CLI::Range(size_t{2}, size_t{1000000}))
      ->capture_default_str();
  cmd->add_option("--baseline-lot", options->baseline_lot,
                  "Phase I: every part of this lot instead of the first N");
  cmd->add_option("--rules", options->rules,
                  "Nelson rules to apply, 1..8, and 9 for the moving range (default: all)")
      ->check(CLI::Range(1, 9))
      ->delimiter(',');
  commands.push_back({cmd, [options, output] {
                        options->output_folder = *output;
                        options->on_alarm = printLine;
                        succeeded(processControl(*options));
                        return 0;
                      }});
}

void addExportCommand(CLI::App& app, Commands& commands) {
  auto options = std::make_shared<LotExportOptions>();
  auto files = std::make_shared<std::pair<std::string, std::string>>();  // dfq, csv
  CLI::App* cmd = app.add_subcommand(
      "export", "A lot of a results store as a Q-DAS AQDEF file (.dfq) and/or CSV");
  cmd->add_option("store", options->store, "Results store: an SQLite file or a postgresql:// URL")
      ->required();
  cmd->add_option("--lot", options->lot, "The lot")->required();
  cmd->add_option("--dfq", files->first, "Write the AQDEF file here");
  cmd->add_option("--csv", files->second, "Write the CSV file here");
  cmd->add_option("--part-number", options->part_number, "K1001 (default: the lot's name)");
  cmd->add_option("--part-description", options->part_description, "K1002");
  commands.push_back({cmd, [options, files] {
                        options->dfq = files->first;
                        options->csv = files->second;
                        succeeded(exportLot(*options));
                        return 0;
                      }});
}

}  // namespace xgauge::cli
