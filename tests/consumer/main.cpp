// Consumer of the installed xgauge library (see CMakeLists.txt): measures a
// job through the front door, xgauge/xgauge.h (with the headers beside it,
// the only ones it may use),
// and checks what the virtual lab's truth tells: the fit is a measurement,
// every measured dimension lies within 0.05 mm of its true value, the
// result's JSON and reports are there, a stage callback ran, and bad
// options and a missing job come back as failures with their reasons, and
// xgauge/part.h lists the faces of the STEP Prism A beside the job and checks
// the dimensions named on them.
// Exit status 0 when every check passes.
//   xgauge_consumer JOB TRUTH OUTPUT_FOLDER
#include "xgauge/lab.h"
#include "xgauge/part.h"
#include "xgauge/production.h"
#include "xgauge/radiographs.h"
#include "xgauge/runtime.h"
#include "xgauge/version.h"
#include "xgauge/xgauge.h"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>

namespace {

int failures = 0;

void check(bool ok, const std::string& what) {
  std::printf("%s: %s\n", ok ? "ok" : "FAILED", what.c_str());
  if (!ok) ++failures;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: %s JOB TRUTH OUTPUT_FOLDER\n", argv[0]);
    return 2;
  }
  std::printf("xgauge %s (package version %s)\n", XGAUGE_VERSION_STRING, XGAUGE_PACKAGE_VERSION);
  check(std::strcmp(XGAUGE_VERSION_STRING, XGAUGE_PACKAGE_VERSION) == 0,
        "xgauge/version.h matches the CMake package version");

  xgauge::MeasurementOptions options;
  options.job_file = argv[1];
  options.truth_file = argv[2];
  options.output_folder = argv[3];
  int stages = 0;
  options.on_stage = [&stages](const xgauge::StageSummary& s) {
    ++stages;
    std::printf("  stage %-24s loss %.6g -> %.6g\n", s.name.c_str(), s.loss_before, s.loss_after);
  };
  std::string why;
  const bool valid = options.IsValid(&why);
  check(valid, "the options are valid " + why);

  const xgauge::MeasurementSummary summary = xgauge::measure(options);
  std::printf("%s\n%s", summary.BriefReport().c_str(), summary.FullReport().c_str());
  check(summary.termination == xgauge::TerminationType::kMeasured, "measured");
  int compared = 0;
  for (const auto& d : summary.dimensions) {
    if (!d.free || !d.true_value) continue;
    ++compared;
    check(std::abs(d.value - *d.true_value) <= 0.05, d.name + " within 0.05 mm of the truth");
    check(d.expanded_uncertainty.has_value() && *d.expanded_uncertainty > 0.0,
          d.name + " has its U");
  }
  check(compared >= 5, "at least 5 dimensions compared with the truth");
  check(stages >= 2 && stages >= static_cast<int>(summary.stages.size()),
        "the stage callback ran for every stage");
  check(summary.ToJson().rfind("{", 0) == 0 &&
            summary.ToJson().find("\"dimensions\"") != std::string::npos,
        "ToJson is result.json");

  xgauge::MeasurementOptions both = options;
  both.job_json = "{}";
  const bool refused = !both.IsValid(&why);
  check(refused && !why.empty(), "two forms of the job are refused: " + why);
  xgauge::MeasurementOptions missing;
  missing.job_file = std::string(argv[1]) + ".missing";
  const xgauge::MeasurementSummary failed = xgauge::measure(missing);
  check(failed.termination == xgauge::TerminationType::kFailure &&
            failed.message.find(".missing") != std::string::npos && failed.exit_status == 1,
        "a missing job is a failure naming the file: " + failed.message);

  // The rest of the front door fails softly too, naming what it could not use.
  xgauge::ConversionOptions conversion;
  conversion.input = std::string(argv[1]) + ".missing.tif";
  conversion.output = std::string(argv[3]) + "/converted.tif";
  const xgauge::ConversionSummary converted = xgauge::convert(conversion);
  check(converted.termination == xgauge::RunTermination::kFailure &&
            converted.message.find(".missing.tif") != std::string::npos,
        "a missing radiograph is a conversion failure: " + converted.message);
  xgauge::SimulationOptions simulation;
  simulation.recipe = std::string(argv[1]) + ".missing";
  simulation.output_folder = std::string(argv[3]) + "/simulated";
  check(xgauge::simulate(simulation).termination == xgauge::RunTermination::kFailure,
        "a missing recipe is a simulation failure");
  xgauge::LotExportOptions lot_export;
  check(xgauge::exportLot(lot_export).termination == xgauge::RunTermination::kFailure,
        "an export without files is a failure");

  // A part before any radiograph (xgauge/part.h): the faces of the STEP
  // solid beside the job, and the dimensions named on them.
  const std::filesystem::path step_folder = std::filesystem::path(argv[1]).parent_path() / "step";
  xgauge::PartFacesOptions faces;
  faces.step_file = step_folder / "prism_a.step";
  faces.output_folder = std::filesystem::path(argv[3]) / "faces";
  const xgauge::PartFacesSummary listed = xgauge::listFaces(faces);
  check(listed.termination == xgauge::RunTermination::kDone && listed.faces == 12,
        "Prism A's STEP solid has its 12 faces: " + listed.message);
  xgauge::PartCheckOptions part_check;
  part_check.part_file = step_folder / "prism_a.json";
  part_check.output_folder = std::filesystem::path(argv[3]) / "part_check";
  const xgauge::PartCheckSummary checked = xgauge::checkPart(part_check);
  check(checked.termination == xgauge::RunTermination::kDone && checked.dimensions == 8,
        "Prism A's 8 dimensions on its faces check: " + checked.message);
  part_check.step_mm = 0.0;
  check(xgauge::checkPart(part_check).termination == xgauge::RunTermination::kFailure,
        "a part check with a zero step is a failure");

  std::printf("%s\n", failures == 0 ? "all checks passed" : "some checks FAILED");
  return failures == 0 ? 0 : 1;
}
