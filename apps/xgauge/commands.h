// The CLI's subcommands, on the front door (xgauge/*.h) only: each parses
// its arguments into the front door's options; its run calls the front door,
// prints, and returns the exit status, or throws std::runtime_error with the
// front door's message when the call failed (main prints it once).
#pragma once

#include "xgauge/runtime.h"

#include <CLI/CLI.hpp>

#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace xgauge::cli {

struct Command {
  CLI::App* app;  // the subcommand: run when it was given
  std::function<int()> run;
};
using Commands = std::vector<Command>;

// The front door's summary, or its message thrown when the call failed.
template <typename Summary>
const Summary& succeeded(const Summary& summary) {
  if (summary.termination == RunTermination::kFailure) throw std::runtime_error(summary.message);
  return summary;
}

void addRenderCommand(CLI::App& app, Commands& commands);
void addGradientCommand(CLI::App& app, Commands& commands);
void addConvertCommand(CLI::App& app, Commands& commands);
void addNormalizeCommand(CLI::App& app, Commands& commands);
void addMeasureCommand(CLI::App& app, Commands& commands);
void addMaterialCommand(CLI::App& app, Commands& commands);
void addCalibrateCommand(CLI::App& app, Commands& commands);
void addStudyCommand(CLI::App& app, Commands& commands);
void addSimulateCommand(CLI::App& app, Commands& commands);
void addVerifyCommand(CLI::App& app, Commands& commands);
void addPlanCommand(CLI::App& app, Commands& commands);
void addCharacterizeCommand(CLI::App& app, Commands& commands);
void addInspectCommand(CLI::App& app, Commands& commands);
void addSpcCommand(CLI::App& app, Commands& commands);
void addExportCommand(CLI::App& app, Commands& commands);
void addPartCommand(CLI::App& app, Commands& commands);

}  // namespace xgauge::cli
