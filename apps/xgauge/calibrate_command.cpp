#include "calibrate_command.h"

#include "xgauge/calibrate/part.h"
#include "xgauge/calibrate/wedge.h"
#include "xgauge/core/error.h"
#include "xgauge/core/output.h"
#include "xgauge/measure/truth.h"
#include "xgauge/report/calibration.h"

#include <spdlog/spdlog.h>

#include <array>
#include <cstdio>

namespace xgauge::cli {

namespace {

void addArguments(CLI::App* cmd, CalibrateArguments& args) {
  cmd->add_option("job", args.job, "Calibration job (JSON)")->required();
  cmd->add_option("-o,--output", args.output,
                  "Output folder: material.json, calibration.json, report.html")
      ->required();
  cmd->add_option("--truth", args.truth,
                  "A virtual lab's truth.json: also report the deviation from its true curve");
  cmd->add_flag("--report,!--no-report", args.report,
                "Write report.html, the calibration report (default: on)");
}

TrueCurve trueCurve(const std::string& truth_file) {
  if (truth_file.empty()) return {};
  const DatasetTruth truth = DatasetTruth::load(truth_file);
  return {truth.path_mm, truth.transmission};
}

void printMaterial(const ExponentialSum& material, const CalibrateArguments& args) {
  std::string text = "I(x) =";
  for (size_t k = 0; k < material.terms().size(); ++k)
    text += fmt::format("{} {:.5f} exp(-{:.5f} x)", k ? " +" : "", material.terms()[k].weight,
                        material.terms()[k].mu_per_mm);
  text += fmt::format("\nstandard uncertainty of I(x): {:.2g}", material.transmissionUncertainty());
  if (material.calibratedRange())
    text += fmt::format(" over the calibrated paths {:.2f} .. {:.2f} mm",
                        (*material.calibratedRange())[0], (*material.calibratedRange())[1]);
  std::printf("%s\nwrote %s/material.json, calibration.json%s\n", text.c_str(), args.output.c_str(),
              args.report ? ", report.html" : "");
}

// The error of a calibration that failed at `step`, naming the diagnostic it
// left.
Error failedAt(const std::string& step, const Error& e, const CalibrateArguments& args) {
  return Error(fmt::format("the calibration failed at its step \"{}\": {} (what it found: {}/{})",
                           step, e.message(), args.output,
                           args.report ? "failed_calibration.html, failed_calibration.json"
                                       : "failed_calibration.json"),
               e.where());
}

}  // namespace

void addCalibrateCommand(CLI::App& app, CalibrateArguments& wedge, CalibrateArguments& part) {
  CLI::App* cmd =
      app.add_subcommand("calibrate", "Calibrate the material curve I(x) from radiographs");
  cmd->require_subcommand(1);
  addArguments(cmd->add_subcommand("wedge",
                                   "From one radiograph of a wedge "
                                   "(thesis 3.4a, docs/method.md)"),
               wedge);
  addArguments(cmd->add_subcommand("part",
                                   "From radiographs of a part of known dimensions "
                                   "(thesis 3.4b, docs/method.md)"),
               part);
}

void runCalibrate(const CLI::App& app, const CalibrateArguments& wedge,
                  const CalibrateArguments& part) {
  const CLI::App* cmd = app.get_subcommand("calibrate");
  const std::filesystem::path folder = cmd->got_subcommand("wedge") ? wedge.output : part.output;
  checkOutputFolder(folder);
  // An earlier run's outputs that this run's would contradict go when this
  // run's files arrive: a failure's diagnostic beside a new material, or a
  // material beside a new failure's diagnostic.
  OutputTransaction outputs;
  auto replaceEarlierRun = [&](bool failed) {
    static constexpr std::array<const char*, 3> kSucceeded{"material.json", "calibration.json",
                                                           "report.html"};
    static constexpr std::array<const char*, 2> kFailed{"failed_calibration.json",
                                                        "failed_calibration.html"};
    if (failed)
      for (const char* name : kSucceeded) outputs.removeOnCommit(folder / name);
    else
      for (const char* name : kFailed) outputs.removeOnCommit(folder / name);
  };
  if (cmd->got_subcommand("wedge")) {
    const WedgeCalibrationJob job = WedgeCalibrationJob::load(wedge.job);
    const TrueCurve truth = trueCurve(wedge.truth);
    WedgeCalibration result;
    try {
      calibrateFromWedge(job, result);
    } catch (const Error& e) {
      // What the steps found goes into the folder under names that say
      // failure, and only that: the user can see why (the ramp, the table,
      // the fits tried), and no file can be taken for a calibration.
      writeFailedWedgeCalibration(job, result, e.what(), wedge.output, wedge.report);
      replaceEarlierRun(true);
      outputs.commit();
      throw failedAt(result.step, e, wedge);
    }
    if (result.part) {
      const Pose& pose = result.part->measurement.radiographs.front().pose;
      const Vec3 angles = pose.eulerDeg();
      std::printf(
          "wedge fitted as a known part: rotation (%.3f, %.3f, %.3f) deg, part origin at (%.3f, "
          "%.3f, %.3f) mm, magnification %.4f (its centre), %zu rounds\n",
          angles.x(), angles.y(), angles.z(), pose.translation_mm.x(), pose.translation_mm.y(),
          pose.translation_mm.z(), result.magnification, result.part->rounds.size());
    } else {
      std::printf("ramp: columns %d..%d, thin end at row %.2f, thick end at row %.2f (%s)\n",
                  result.ramp.column_begin, result.ramp.column_end - 1, result.ramp.thin_row,
                  result.ramp.thick_row, result.ramp.automatic_rows ? "found" : "given");
    }
    std::printf("%-6s %12s %12s %12s\n", "terms", "rms", "max |r|", "max |r|/I");
    for (const TermsFit& f : result.fit.fits)
      std::printf("%-6d %12.3e %12.3e %12.3e%s\n", f.terms, f.report.rms_residual,
                  f.report.max_abs_residual, f.report.max_relative_residual,
                  &f == &result.fit.best() ? "  <- chosen" : "");
    if (!result.part)
      std::printf("eq. 3.7: x0 = %.4f mm, x_max = %.4f mm\n", result.x0_mm, result.x_max_mm);
    std::printf("uncertainty of the curve: %.2g from its table", result.table_uncertainty);
    for (const CurveInfluence& i : result.influences)
      std::printf(i.uncertainty > 0.0 ? ", %.2g from the %s (u = %.3g)" : ", %.2g from the %s",
                  i.change, i.name.c_str(), i.uncertainty);
    std::printf("\n");
    writeWedgeCalibration(job, result, truth, wedge.output, wedge.report);
    printMaterial(result.material, wedge);
  } else {
    const PartCalibrationJob job = PartCalibrationJob::load(part.job);
    const TrueCurve truth = trueCurve(part.truth);
    PartCalibration result;
    try {
      calibrateFromPart(job, result);
    } catch (const Error& e) {
      writeFailedPartCalibration(job, result, e.what(), part.output, part.report);
      replaceEarlierRun(true);
      outputs.commit();
      throw failedAt(result.step, e, part);
    }
    writePartCalibration(job, result, truth, part.output, part.report);
    printMaterial(result.material, part);
  }
  replaceEarlierRun(false);
  outputs.commit();
}

}  // namespace xgauge::cli
