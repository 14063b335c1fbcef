// `xgauge normalize`: a raw radiograph to normalized intensity (1 = open beam).
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace xgauge::cli {

struct NormalizeArguments {
  std::string raw;
  std::string dark;
  std::string flat;
  std::vector<int> white;  // x y width height
  std::string output;
  std::string png;
  int png_bin = 1;  // preview binned by this power of two
};

void addNormalizeCommand(CLI::App& app, NormalizeArguments& args);
void runNormalize(const NormalizeArguments& args);

}  // namespace xgauge::cli
