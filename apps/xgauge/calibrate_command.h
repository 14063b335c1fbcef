// `xgauge calibrate wedge|part`: the material curve from a wedge radiograph or
// from radiographs of a part of known dimensions (calibrate/wedge.h, part.h);
// `xgauge calibrate geometry`: the detector's pose from radiographs of a part
// of known dimensions (calibrate/geometry.h).
#pragma once

#include <CLI/CLI.hpp>

#include <string>

namespace xgauge::cli {

struct CalibrateArguments {
  std::string job;
  std::string output;
  std::string truth;  // optional truth.json: compare with the lab's true curve
  bool report = true;  // write report.html
  double reach_deg = 2.0;  // geometry: how far from the machine's pose the fit may go
};

void addCalibrateCommand(CLI::App& app, CalibrateArguments& wedge, CalibrateArguments& part,
                         CalibrateArguments& geometry);
// Runs whichever of the three subcommands was given.
void runCalibrate(const CLI::App& app, const CalibrateArguments& wedge,
                  const CalibrateArguments& part, const CalibrateArguments& geometry);

}  // namespace xgauge::cli
