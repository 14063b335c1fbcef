#include "spc_command.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/error.h"
#include "xgauge/core/output.h"
#include "xgauge/production/export.h"
#include "xgauge/production/spc_report.h"
#include "xgauge/production/store.h"
#include "xgauge/report/html.h"

#include <spdlog/spdlog.h>

#include <cstdio>
#include <filesystem>
#include <map>

namespace xgauge::cli {

void addSpcCommand(CLI::App& app, SpcArguments& args) {
  CLI::App* cmd = app.add_subcommand(
      "spc", "Control charts, run rules and capability per lot and dimension of a results store");
  cmd->add_option("store", args.store, "Results store: an SQLite file or a postgresql:// URL")
      ->required();
  cmd->add_option("--lot", args.lots, "Only these lots (default: every lot)");
  cmd->add_option("-o,--output", args.output,
                  "Folder for the pages: <output>/<lot>/<dimension>.html")
      ->required();
  cmd->add_option("--baseline", args.baseline, "Phase I: the first N parts of each lot")
      ->check(CLI::Range(size_t{2}, size_t{1000000}))
      ->capture_default_str();
  cmd->add_option("--baseline-lot", args.baseline_lot,
                  "Phase I: every part of this lot instead of the first N");
  cmd->add_option("--rules", args.rules,
                  "Nelson rules to apply, 1..8, and 9 for the moving range (default: all)")
      ->check(CLI::Range(1, 9))
      ->delimiter(',');
}

void runSpc(const SpcArguments& args) {
  checkOutputFolder(args.output);
  auto store = ResultStore::open(args.store);
  SpcOptions options;
  options.baseline_parts = args.baseline;
  options.baseline_lot = args.baseline_lot;
  if (!args.rules.empty()) {
    options.rules.clear();
    for (int r : args.rules) options.rules.push_back(static_cast<SpcRule>(r));
  }
  const std::vector<std::string> lots = args.lots.empty() ? store->lots() : args.lots;
  // Every analysis first: a bad lot or baseline writes nothing.
  std::vector<DimensionSpc> analyses;
  for (const auto& lot : lots)
    for (auto& a : analyseLot(*store, lot, options)) analyses.push_back(std::move(a));
  const std::string now = utcTimestamp();
  OutputTransaction outputs;
  std::map<std::string, nlohmann::json> per_lot;
  std::vector<StoredAlarm> alarms;
  for (const auto& a : analyses) {
    const auto folder = std::filesystem::path(args.output) / a.lot;
    createOutputFolder(folder);
    writeSpcPage(folder / (a.dimension + ".html"), a);
    per_lot[a.lot].push_back(a.toJson());
    for (auto& alarm : alarmsOf(a, now)) alarms.push_back(std::move(alarm));
  }
  for (const auto& [lot, json] : per_lot)
    writeFileAtomically(std::filesystem::path(args.output) / lot / "spc.json", json.dump(1) + "\n");
  outputs.commit();
  const int added = store->addAlarms(alarms);
  for (const auto& a : alarms) std::fputs((alarmLine(a) + "\n").c_str(), stdout);
  spdlog::info("spc: {} page(s) in {}; {} alarm(s), {} new in the store", analyses.size(),
               args.output, alarms.size(), added);
}

void addExportCommand(CLI::App& app, ExportArguments& args) {
  CLI::App* cmd = app.add_subcommand(
      "export", "A lot of a results store as a Q-DAS AQDEF file (.dfq) and/or CSV");
  cmd->add_option("store", args.store, "Results store: an SQLite file or a postgresql:// URL")
      ->required();
  cmd->add_option("--lot", args.lot, "The lot")->required();
  cmd->add_option("--dfq", args.dfq, "Write the AQDEF file here");
  cmd->add_option("--csv", args.csv, "Write the CSV file here");
  cmd->add_option("--part-number", args.part_number, "K1001 (default: the lot's name)");
  cmd->add_option("--part-description", args.part_description, "K1002");
}

void runExport(const ExportArguments& args) {
  if (args.dfq.empty() && args.csv.empty()) fail("export: give --dfq FILE, --csv FILE or both");
  if (!args.dfq.empty()) checkOutputFile(args.dfq);
  if (!args.csv.empty()) checkOutputFile(args.csv);
  auto store = ResultStore::open(args.store);
  const auto parts = store->lotSeries(args.lot);
  LotExportContext context{args.lot, args.part_number.empty() ? args.lot : args.part_number,
                           args.part_description};
  OutputTransaction outputs;
  if (!args.dfq.empty()) writeFileAtomically(args.dfq, lotDfq(context, parts));
  if (!args.csv.empty()) writeFileAtomically(args.csv, lotCsv(context, parts));
  outputs.commit();
  spdlog::info("export: lot {}, {} part(s)", args.lot, parts.size());
}

}  // namespace xgauge::cli
