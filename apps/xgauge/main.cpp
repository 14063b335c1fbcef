// xgauge: measure parts from a few X-ray radiographs.
// The CLI only parses arguments and calls the library; bad input surfaces
// here as xgauge::Error, printed once, with a non-zero exit status.
#include "calibrate_command.h"
#include "characterize_command.h"
#include "convert_command.h"
#include "inspect_command.h"
#include "measure_command.h"
#include "normalize_command.h"
#include "render_command.h"
#include "simulate_command.h"
#include "spc_command.h"
#include "study_command.h"
#include "verify_command.h"

#include "xgauge/core/error.h"
#include "xgauge/core/log.h"
#include "xgauge/core/memory.h"
#include "xgauge/core/output.h"
#include "xgauge/core/parallel.h"
#include "xgauge/core/progress.h"
#include "xgauge/image/tiff.h"
#include "xgauge/version.h"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <optional>

int main(int argc, char** argv) {
  // First: before any worker thread exists (core/output.h), before the work
  // allocates (core/memory.h).
  xgauge::installInterruptCleanup();
  xgauge::keepLargeBlocksInHeap();
  CLI::App app{"xgauge: dimensional measurement of parts from a few X-ray radiographs"};
  app.set_version_flag("--version", "xgauge " XGAUGE_VERSION_STRING);
  app.require_subcommand(1);
  app.fallthrough();  // global flags (-q, -j) may follow the subcommand too
  bool quiet = false, verbose = false;
  int threads = 0;
  app.add_flag("-q,--quiet", quiet, "Only warnings and errors; no progress bars");
  app.add_flag("-v,--verbose", verbose, "Debug messages");
  app.add_option("-j,--threads", threads, "Worker threads (0 = all cores)")->check(CLI::NonNegativeNumber);
  uint64_t max_image_mb = xgauge::kDefaultTiffMemoryLimit >> 20;
  app.add_option(
         "--max-image-mb", max_image_mb,
         "Refuse radiograph files (any format) that would need more memory than this to read (MiB)")
      ->check(CLI::Range(uint64_t{1}, uint64_t{1} << 20))
      ->capture_default_str();

  xgauge::cli::RenderArguments render;
  xgauge::cli::addRenderCommand(app, render);
  xgauge::cli::GradientArguments gradients;
  xgauge::cli::addGradientCommand(app, gradients);
  xgauge::cli::ConvertArguments convert;
  xgauge::cli::addConvertCommand(app, convert);
  xgauge::cli::NormalizeArguments normalize;
  xgauge::cli::addNormalizeCommand(app, normalize);
  xgauge::cli::MeasureArguments measure;
  xgauge::cli::addMeasureCommand(app, measure);
  xgauge::cli::MaterialArguments material;
  xgauge::cli::addMaterialCommand(app, material);
  xgauge::cli::CalibrateArguments calibrate_wedge, calibrate_part, calibrate_geometry;
  xgauge::cli::addCalibrateCommand(app, calibrate_wedge, calibrate_part, calibrate_geometry);
  xgauge::cli::StudyArguments study;
  xgauge::cli::addStudyCommand(app, study);
  xgauge::cli::SimulateArguments simulate;
  xgauge::cli::addSimulateCommand(app, simulate);
  xgauge::cli::VerifyArguments verify;
  xgauge::cli::addVerifyCommand(app, verify);
  xgauge::cli::CharacterizeArguments characterize;
  xgauge::cli::addCharacterizeCommand(app, characterize);
  xgauge::cli::InspectArguments inspect;
  xgauge::cli::addInspectCommand(app, inspect);
  xgauge::cli::SpcArguments spc;
  xgauge::cli::addSpcCommand(app, spc);
  xgauge::cli::ExportArguments exporting;
  xgauge::cli::addExportCommand(app, exporting);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }

  xgauge::setupLogging(quiet ? xgauge::Verbosity::kQuiet
                             : (verbose ? xgauge::Verbosity::kVerbose : xgauge::Verbosity::kNormal));
  xgauge::setProgressEnabled(!quiet);
  try {
    xgauge::ThreadLimit limit(threads);
    xgauge::setTiffMemoryLimit(max_image_mb << 20);
    if (app.got_subcommand("render")) xgauge::cli::runRender(render);
    if (app.got_subcommand("check-gradients")) return xgauge::cli::runGradientCheck(gradients);
    if (app.got_subcommand("simulate")) xgauge::cli::runSimulate(simulate);
    if (app.got_subcommand("normalize")) xgauge::cli::runNormalize(normalize);
    if (app.got_subcommand("convert")) xgauge::cli::runConvert(convert);
    if (app.got_subcommand("measure")) return xgauge::cli::runMeasure(measure);
    if (app.got_subcommand("material")) xgauge::cli::runMaterial(material);
    if (app.got_subcommand("study")) xgauge::cli::runStudyCommand(study);
    if (app.got_subcommand("verify")) xgauge::cli::runVerify(verify);
    if (app.got_subcommand("characterize")) xgauge::cli::runCharacterize(characterize);
    if (app.got_subcommand("inspect")) return xgauge::cli::runInspect(inspect);
    if (app.got_subcommand("spc")) xgauge::cli::runSpc(spc);
    if (app.got_subcommand("export")) xgauge::cli::runExport(exporting);
    if (app.got_subcommand("calibrate"))
      xgauge::cli::runCalibrate(app, calibrate_wedge, calibrate_part, calibrate_geometry);
  } catch (const xgauge::Error& e) {
    std::fprintf(stderr, "xgauge: error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "xgauge: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
