// `xgauge calibrate wedge|part`: the material curve from a wedge radiograph or
// from radiographs of a part of known dimensions (calibrate/wedge.h, part.h).
#pragma once

#include <CLI/CLI.hpp>

#include <string>

namespace xgauge::cli {

struct CalibrateArguments {
  std::string job;
  std::string output;
  std::string truth;  // optional truth.json: compare with the lab's true curve
  bool report = true;  // write report.html
};

void addCalibrateCommand(CLI::App& app, CalibrateArguments& wedge, CalibrateArguments& part);
// Runs whichever of the two subcommands was given.
void runCalibrate(const CLI::App& app, const CalibrateArguments& wedge,
                  const CalibrateArguments& part);

}  // namespace xgauge::cli
