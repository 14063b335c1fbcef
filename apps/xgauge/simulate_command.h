// `xgauge simulate`: a dataset of raw radiographs with ground truth.
#pragma once

#include <CLI/CLI.hpp>

#include <string>

namespace xgauge::cli {

struct SimulateArguments {
  std::string recipe;  // dataset recipe (JSON)
  std::string output;  // folder
};

void addSimulateCommand(CLI::App& app, SimulateArguments& args);
void runSimulate(const SimulateArguments& args);

}  // namespace xgauge::cli
