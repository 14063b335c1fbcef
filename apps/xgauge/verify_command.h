// `xgauge verify`: the measuring method verified on a calibrated master.
#pragma once

#include <CLI/CLI.hpp>

#include <string>

namespace xgauge::cli {

struct VerifyArguments {
  std::string job;
  std::string output;
};

void addVerifyCommand(CLI::App& app, VerifyArguments& args);
void runVerify(const VerifyArguments& args);

}  // namespace xgauge::cli
