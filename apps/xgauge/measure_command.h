// `xgauge measure` and `xgauge material`: dimensions from radiographs, and a
// material from a virtual lab's transmission table.
#pragma once

#include <CLI/CLI.hpp>

#include <string>

namespace xgauge::cli {

struct MeasureArguments {
  std::string job;
  std::string output;
  std::string truth;  // optional truth.json: print errors against it
  bool report = true;  // write report.html
};

struct MaterialArguments {
  std::string truth;
  int terms = 3;
  std::string output;
};

void addMeasureCommand(CLI::App& app, MeasureArguments& args);
// Returns the exit status (measure/tolerance.h: 0 conforms, 2 inconclusive,
// 3 does not conform; errors throw).
int runMeasure(const MeasureArguments& args);
void addMaterialCommand(CLI::App& app, MaterialArguments& args);
void runMaterial(const MaterialArguments& args);

}  // namespace xgauge::cli
