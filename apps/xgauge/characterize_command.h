// `xgauge characterize`: the detector's halo, lag, crosstalk and bad pixels
// from dedicated shots (characterize/characterize.h).
#pragma once

#include <CLI/CLI.hpp>

#include <string>

namespace xgauge::cli {

struct CharacterizeArguments {
  std::string job;
  std::string output;
};

void addCharacterizeCommand(CLI::App& app, CharacterizeArguments& args);
void runCharacterize(const CharacterizeArguments& args);

}  // namespace xgauge::cli
