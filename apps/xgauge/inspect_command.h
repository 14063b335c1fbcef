// `xgauge inspect`: the parts of a lot measured as they come, into a
// results store.
#pragma once

#include <CLI/CLI.hpp>

#include <string>

namespace xgauge::cli {

struct InspectArguments {
  std::string plan;
  std::string source;  // a folder of part folders (overrides the plan's)
  std::string watch;   // a folder parts arrive in
  std::string store, output, station, shard;
  double poll_s = 1.0;
  double idle_exit_s = 0.0;
  size_t spc_baseline = 0;
  bool report = true;
};

void addInspectCommand(CLI::App& app, InspectArguments& args);
int runInspect(const InspectArguments& args);

}  // namespace xgauge::cli
