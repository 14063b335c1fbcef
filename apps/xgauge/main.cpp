// xgauge: measure parts from a few X-ray radiographs.
// The CLI only parses arguments and calls the library's front door
// (xgauge/*.h); a failure surfaces here as the front door's message,
// printed once, with a non-zero exit status.
#include "commands.h"
#include "xgauge/runtime.h"
#include "xgauge/version.h"

#include <CLI/CLI.hpp>

#include <cstdint>
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

namespace {

// The first word that is neither an option nor an option's value, when it
// names no command ("" otherwise). Checked before CLI11 parses, so that
// `xgauge nonsense` and `xgauge nonsense --help` both name "nonsense" and
// fail, where CLI11 would ask for a subcommand or print the help.
std::string unknownCommand(const CLI::App& app, int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string word = argv[i];
    if (word.starts_with("-")) {
      // Global options that take a value as the next word.
      if (word == "-j" || word == "--threads" || word == "--max-image-mb") ++i;
      continue;
    }
    for (const CLI::App* sub : app.get_subcommands({}))
      if (sub->check_name(word)) return "";
    return word;
  }
  return "";
}

}  // namespace

int main(int argc, char** argv) {
  // First: before any worker thread exists, before the work allocates.
  xgauge::PrepareProcess();
  CLI::App app{"xgauge: dimensional measurement of parts from a few X-ray radiographs"};
  app.set_version_flag("--version", "xgauge " XGAUGE_VERSION_STRING);
  app.require_subcommand(1);
  app.fallthrough();  // global flags (-q, -j) may follow the subcommand too
  bool quiet = false, verbose = false;
  int threads = 0;
  app.add_flag("-q,--quiet", quiet, "Only errors; no progress bars (warnings stay in each result.json and report)");
  app.add_flag("-v,--verbose", verbose, "Debug messages");
  app.add_option("-j,--threads", threads, "Worker threads (0 = all cores)")->check(CLI::NonNegativeNumber);
  uint64_t max_image_mb = xgauge::kDefaultMaxImageBytes >> 20;
  app.add_option(
         "--max-image-mb", max_image_mb,
         "Refuse radiograph files (any format) that would need more memory than this to read (MiB)")
      ->check(CLI::Range(uint64_t{1}, uint64_t{1} << 20))
      ->capture_default_str();

  namespace cli = xgauge::cli;
  cli::Commands commands;
  for (auto add : {cli::addRenderCommand, cli::addGradientCommand, cli::addConvertCommand,
                   cli::addNormalizeCommand, cli::addMeasureCommand, cli::addMaterialCommand,
                   cli::addCalibrateCommand, cli::addStudyCommand, cli::addSimulateCommand,
                   cli::addVerifyCommand, cli::addPlanCommand, cli::addCharacterizeCommand, cli::addInspectCommand,
                   cli::addSpcCommand, cli::addExportCommand, cli::addPartCommand})
    add(app, commands);

  if (const std::string unknown = unknownCommand(app, argc, argv); !unknown.empty()) {
    std::vector<std::string> names;
    for (const CLI::App* sub : app.get_subcommands({})) names.push_back(sub->get_name());
    std::string known;
    for (const std::string& n : names) known += (known.empty() ? "" : ", ") + n;
    const std::string nearest = xgauge::NearestName(unknown, names);
    std::fprintf(stderr, "xgauge: error: unknown command '%s'%s\ncommands: %s\n", unknown.c_str(),
                 nearest.empty() ? "" : ("; did you mean '" + nearest + "'?").c_str(), known.c_str());
    return 2;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }

  xgauge::RuntimeOptions runtime;
  runtime.log_level = quiet     ? xgauge::LogLevel::kQuiet
                      : verbose ? xgauge::LogLevel::kVerbose
                                : xgauge::LogLevel::kNormal;
  runtime.progress = !quiet;
  runtime.threads = threads;
  runtime.max_image_bytes = max_image_mb << 20;
  try {
    const xgauge::RuntimeScope scope(runtime);
    for (const cli::Command& command : commands)
      if (command.app->parsed()) return command.run();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "xgauge: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
