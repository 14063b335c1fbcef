// `xgauge spc` and `xgauge export`: a results store's lots as SPC pages,
// alarms, and Q-DAS .dfq / CSV files.
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace xgauge::cli {

struct SpcArguments {
  std::string store;
  std::vector<std::string> lots;  // empty: every lot
  std::string output;
  size_t baseline = 30;
  std::string baseline_lot;
  std::vector<int> rules;  // empty: all (1..8 and 9 for the moving range)
};

struct ExportArguments {
  std::string store, lot, dfq, csv;
  std::string part_number, part_description;
};

void addSpcCommand(CLI::App& app, SpcArguments& args);
void runSpc(const SpcArguments& args);
void addExportCommand(CLI::App& app, ExportArguments& args);
void runExport(const ExportArguments& args);

}  // namespace xgauge::cli
