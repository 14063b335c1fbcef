// The front door's production line (xgauge/production.h) over the
// production module. `xgauge inspect`, `spc` and `export` are these calls
// and a print.
#include "xgauge/production.h"

#include "guard.h"
#include "xgauge/core/atomic_file.h"
#include "xgauge/core/error.h"
#include "xgauge/core/output.h"
#include "xgauge/production/export.h"
#include "xgauge/production/inspect.h"
#include "xgauge/production/spc_report.h"
#include "xgauge/production/store.h"
#include "xgauge/report/html.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <map>

namespace xgauge {

namespace {

InspectionSummary inspectOrThrow(const InspectionOptions& options) {
  if (!options.source.empty() && !options.watch.empty())
    fail("inspect: give a source folder or --watch, not both");
  const InspectionPlan plan = InspectionPlan::load(options.plan);
  InspectOptions inspect_options;
  inspect_options.source = options.watch.empty() ? options.source : options.watch;
  inspect_options.watch = !options.watch.empty();
  inspect_options.store = options.store;
  inspect_options.output = options.output_folder;
  inspect_options.station = options.station;
  inspect_options.poll_s = options.poll_s;
  inspect_options.idle_exit_s = options.idle_exit_s;
  inspect_options.report = options.write_report;
  inspect_options.spc_baseline = options.spc_baseline;
  if (!options.shard.empty()) inspect_options.shard = Shard::parse(options.shard);
  const InspectSummary s = inspect(plan, inspect_options, [&](const std::string& line) {
    if (options.on_line) options.on_line(line);
  });
  spdlog::info(
      "inspect: {} part(s) measured here ({} not measured), {} found measured already, "
      "{} failed, {} not ready",
      s.measured, s.not_measured, s.already, s.failed, s.not_ready);
  InspectionSummary summary;
  summary.termination = RunTermination::kDone;
  summary.measured = s.measured, summary.not_measured = s.not_measured;
  summary.already = s.already, summary.failed = s.failed, summary.not_ready = s.not_ready;
  summary.failed_parts = s.failed_parts;
  summary.exit_status = s.failed > 0 ? 1 : 0;
  if (s.failed > 0)
    spdlog::error("inspect: {} part(s) failed: {}", s.failed, fmt::join(s.failed_parts, ", "));
  return summary;
}

ProcessControlSummary processControlOrThrow(const ProcessControlOptions& options) {
  checkOutputFolder(options.output_folder);
  auto store = ResultStore::open(options.store);
  SpcOptions spc_options;
  spc_options.baseline_parts = options.baseline;
  spc_options.baseline_lot = options.baseline_lot;
  if (!options.rules.empty()) {
    spc_options.rules.clear();
    for (int r : options.rules) spc_options.rules.push_back(static_cast<SpcRule>(r));
  }
  const std::vector<std::string> lots = options.lots.empty() ? store->lots() : options.lots;
  // Every analysis first: a bad lot or baseline writes nothing.
  std::vector<DimensionSpc> analyses;
  for (const auto& lot : lots)
    for (auto& a : analyseLot(*store, lot, spc_options)) analyses.push_back(std::move(a));
  const std::string now = utcTimestamp();
  OutputTransaction outputs;
  std::map<std::string, nlohmann::json> per_lot;
  std::vector<StoredAlarm> alarms;
  for (const auto& a : analyses) {
    const auto folder = options.output_folder / a.lot;
    createOutputFolder(folder);
    writeSpcPage(folder / (a.dimension + ".html"), a);
    per_lot[a.lot].push_back(a.toJson());
    for (auto& alarm : alarmsOf(a, now)) alarms.push_back(std::move(alarm));
  }
  for (const auto& [lot, json] : per_lot)
    writeFileAtomically(options.output_folder / lot / "spc.json", json.dump(1) + "\n");
  outputs.commit();
  ProcessControlSummary summary;
  summary.new_alarms = store->recordAnalysis(lots, alarms, now);  // replaces the lots' alarms
  if (options.on_alarm)
    for (const auto& a : alarms) options.on_alarm(alarmLine(a));
  spdlog::info("spc: {} page(s) in {}; {} alarm(s), {} new in the store", analyses.size(),
               options.output_folder.string(), alarms.size(), summary.new_alarms);
  summary.termination = RunTermination::kDone;
  summary.pages = analyses.size(), summary.alarms = alarms.size();
  return summary;
}

LotExportSummary exportLotOrThrow(const LotExportOptions& options) {
  if (options.dfq.empty() && options.csv.empty())
    fail("export: give --dfq FILE, --csv FILE or both");
  if (!options.dfq.empty()) checkOutputFile(options.dfq);
  if (!options.csv.empty()) checkOutputFile(options.csv);
  auto store = ResultStore::open(options.store);
  const auto parts = store->lotSeries(options.lot);
  LotExportContext context{options.lot,
                           options.part_number.empty() ? options.lot : options.part_number,
                           options.part_description};
  OutputTransaction outputs;
  if (!options.dfq.empty()) writeFileAtomically(options.dfq, lotDfq(context, parts));
  if (!options.csv.empty()) writeFileAtomically(options.csv, lotCsv(context, parts));
  outputs.commit();
  spdlog::info("export: lot {}, {} part(s)", options.lot, parts.size());
  LotExportSummary summary;
  summary.termination = RunTermination::kDone;
  summary.parts = parts.size();
  return summary;
}

}  // namespace

InspectionSummary inspect(const InspectionOptions& options) {
  return api::guarded<InspectionSummary>([&] { return inspectOrThrow(options); });
}

ProcessControlSummary processControl(const ProcessControlOptions& options) {
  return api::guarded<ProcessControlSummary>([&] { return processControlOrThrow(options); });
}

LotExportSummary exportLot(const LotExportOptions& options) {
  return api::guarded<LotExportSummary>([&] { return exportLotOrThrow(options); });
}

}  // namespace xgauge
