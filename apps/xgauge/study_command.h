// `xgauge study`: measurement statistics over a simulated dataset.
#pragma once

#include <CLI/CLI.hpp>

#include <string>

namespace xgauge::cli {

struct StudyArguments {
  std::string dataset;
  std::string settings;
  std::string combinations = "pairs";
  int limit = 0;
  std::string output;
  bool images = false;
  bool report = true;
  std::string shard;
};

void addStudyCommand(CLI::App& app, StudyArguments& args);
void runStudyCommand(const StudyArguments& args);

}  // namespace xgauge::cli
