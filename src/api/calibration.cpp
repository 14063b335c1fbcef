// The front door's calibration (xgauge/xgauge.h): a material's curve from a
// wedge or from a part of known dimensions, its outputs written, what it
// found and why it stopped in the summary. `xgauge calibrate` is this and
// a print.
#include "xgauge/xgauge.h"

#include "xgauge/calibrate/geometry.h"
#include "xgauge/calibrate/part.h"
#include "xgauge/calibrate/wedge.h"
#include "xgauge/core/error.h"
#include "xgauge/core/output.h"
#include "xgauge/measure/truth.h"
#include "xgauge/report/calibration.h"

#include <fmt/format.h>

#include <array>
#include <new>

namespace xgauge {

// Sets the summary's private parts (the report and material.json's text).
class CalibrationSummaryBuilder {
 public:
  static void set(CalibrationSummary& s, std::string full_report, std::string json) {
    s.full_report_ = std::move(full_report);
    s.json_ = std::move(json);
  }
};

namespace {

TrueCurve trueCurve(const std::filesystem::path& truth_file) {
  if (truth_file.empty()) return {};
  const DatasetTruth truth = DatasetTruth::load(truth_file);
  return {truth.path_mm, truth.transmission};
}

std::string materialText(const ExponentialSum& material, const CalibrationOptions& options) {
  std::string text = "I(x) =";
  for (size_t k = 0; k < material.terms().size(); ++k)
    text += fmt::format("{} {:.5f} exp(-{:.5f} x)", k ? " +" : "", material.terms()[k].weight,
                        material.terms()[k].mu_per_mm);
  text += fmt::format("\nstandard uncertainty of I(x): {:.2g}", material.transmissionUncertainty());
  if (material.calibratedRange())
    text += fmt::format(" over the calibrated paths {:.2f} .. {:.2f} mm",
                        (*material.calibratedRange())[0], (*material.calibratedRange())[1]);
  return text + fmt::format("\nwrote {}/material.json, calibration.json{}\n",
                            options.output_folder.string(),
                            options.write_report ? ", report.html" : "");
}

// What a wedge calibration found, before its material: the ramp or the
// pose, the fits by number of terms, the curve's uncertainty.
std::string wedgeText(const WedgeCalibration& result) {
  std::string text;
  if (result.part) {
    const Pose& pose = result.part->measurement.radiographs.front().pose;
    const Vec3 angles = pose.eulerDeg();
    text += fmt::format(
        "wedge fitted as a known part: rotation ({:.3f}, {:.3f}, {:.3f}) deg, part origin at "
        "({:.3f}, {:.3f}, {:.3f}) mm, magnification {:.4f} (its centre), {} rounds\n",
        angles.x(), angles.y(), angles.z(), pose.translation_mm.x(), pose.translation_mm.y(),
        pose.translation_mm.z(), result.magnification, result.part->rounds.size());
  } else {
    text +=
        fmt::format("ramp: columns {}..{}, thin end at row {:.2f}, thick end at row {:.2f} ({})\n",
                    result.ramp.column_begin, result.ramp.column_end - 1, result.ramp.thin_row,
                    result.ramp.thick_row, result.ramp.automatic_rows ? "found" : "given");
  }
  text += fmt::format("{:<6} {:>12} {:>12} {:>12}\n", "terms", "rms", "max |r|", "max |r|/I");
  for (const TermsFit& f : result.fit.fits)
    text += fmt::format("{:<6} {:>12.3e} {:>12.3e} {:>12.3e}{}\n", f.terms, f.report.rms_residual,
                        f.report.max_abs_residual, f.report.max_relative_residual,
                        &f == &result.fit.best() ? "  <- chosen" : "");
  if (!result.part)
    text +=
        fmt::format("eq. 3.7: x0 = {:.4f} mm, x_max = {:.4f} mm\n", result.x0_mm, result.x_max_mm);
  text += fmt::format("uncertainty of the curve: {:.2g} from its table", result.table_uncertainty);
  for (const CurveInfluence& i : result.influences)
    text += i.uncertainty > 0.0
                ? fmt::format(", {:.2g} from the {} (u = {:.3g})", i.change, i.name, i.uncertainty)
                : fmt::format(", {:.2g} from the {}", i.change, i.name);
  return text + "\n";
}

CalibrationSummary summarize(const ExponentialSum& material, std::string step, double seconds,
                             std::string report) {
  CalibrationSummary s;
  s.termination = CalibrationTermination::kCalibrated;
  s.step = std::move(step);
  for (const auto& t : material.terms()) s.terms.push_back({t.weight, t.mu_per_mm});
  s.transmission_uncertainty = material.transmissionUncertainty();
  if (const auto range = material.calibratedRange())
    s.calibrated_range_mm = std::make_pair((*range)[0], (*range)[1]);
  s.seconds = seconds;
  CalibrationSummaryBuilder::set(s, std::move(report), material.toJson().dump(2) + "\n");
  return s;
}

CalibrationSummary stepFailed(const std::string& step, const Error& e,
                              const CalibrationOptions& options) {
  CalibrationSummary s;
  s.termination = CalibrationTermination::kStepFailed;
  s.step = step;
  // The failure's location (a file, a key) first, as the error gave it.
  s.message =
      Error(fmt::format("the calibration failed at its step \"{}\": {} (what it found: "
                        "{}/{})",
                        step, e.message(), options.output_folder.string(),
                        options.write_report ? "failed_calibration.html, failed_calibration.json"
                                             : "failed_calibration.json"),
            e.where())
          .what();
  return s;
}

// Runs a calibration (calibrateFromWedge or calibrateFromPart) into the
// output folder: its outputs on success; on a failure only what the steps
// found, under names that say failure, so that the user sees why and no
// file can be taken for a calibration.
template <typename Job, typename Result, typename Calibrate, typename Write, typename WriteFailed,
          typename Describe>
CalibrationSummary run(const CalibrationOptions& options, Calibrate calibrate_from, Write write,
                       WriteFailed write_failed, Describe describe) {
  checkOutputFolder(options.output_folder);
  const Job job = Job::load(options.job_file);
  const TrueCurve truth = trueCurve(options.truth_file);
  // An earlier run's outputs that this run's would contradict go when this
  // run's files arrive.
  OutputTransaction outputs;
  auto replaceEarlierRun = [&](bool failed) {
    static constexpr std::array<const char*, 3> kSucceeded{"material.json", "calibration.json",
                                                           "report.html"};
    static constexpr std::array<const char*, 2> kFailed{"failed_calibration.json",
                                                        "failed_calibration.html"};
    if (failed)
      for (const char* name : kSucceeded) outputs.removeOnCommit(options.output_folder / name);
    else
      for (const char* name : kFailed) outputs.removeOnCommit(options.output_folder / name);
  };
  Result result;
  try {
    calibrate_from(job, result);
  } catch (const Error& e) {
    write_failed(job, result, e.what(), options.output_folder, options.write_report);
    replaceEarlierRun(true);
    outputs.commit();
    return stepFailed(result.step, e, options);
  }
  write(job, result, truth, options.output_folder, options.write_report);
  replaceEarlierRun(false);
  outputs.commit();
  return summarize(result.material, result.step, result.seconds,
                   describe(result) + materialText(result.material, options));
}

// The detector's pose from a part of known dimensions: machine.json and
// geometry.json written, the angles in the summary.
CalibrationSummary calibrateGeometryOrThrow(const CalibrationOptions& options) {
  const GeometryCalibration g = calibrateGeometry(options.job_file, options.reach_deg);
  writeGeometryCalibration(g, options.output_folder);
  CalibrationSummary summary;
  summary.termination = CalibrationTermination::kCalibrated;
  summary.step = "geometry";
  summary.detector_angles_deg.assign(g.angles_deg.begin(), g.angles_deg.end());
  summary.detector_angle_uncertainties_deg.assign(g.uncertainty_deg.begin(),
                                                  g.uncertainty_deg.end());
  summary.misfit_ratio = g.misfit_ratio;
  CalibrationSummaryBuilder::set(
      summary,
      fmt::format("detector tilt about u  {:+.4f} deg  u {:.4f}  (least squares {:.4f}, "
                  "leave-one-out {:.4f})\n"
                  "detector tilt about v  {:+.4f} deg  u {:.4f}  (least squares {:.4f}, "
                  "leave-one-out {:.4f})\n"
                  "detector rotation      {:+.4f} deg  u {:.4f}\n"
                  "worst misfit ratio     {:.2f}\n"
                  "wrote {}/machine.json\n",
                  g.angles_deg[0], g.uncertainty_deg[0], g.statistical_uncertainty_deg[0],
                  g.leave_one_out_uncertainty_deg[0], g.angles_deg[1], g.uncertainty_deg[1],
                  g.statistical_uncertainty_deg[1], g.leave_one_out_uncertainty_deg[1],
                  g.angles_deg[2], g.uncertainty_deg[2], g.misfit_ratio,
                  options.output_folder.string()),
      std::string());
  return summary;
}

CalibrationSummary calibrateOrThrow(const CalibrationOptions& options) {
  if (options.kind == CalibrationKind::kGeometry) return calibrateGeometryOrThrow(options);
  if (options.kind == CalibrationKind::kWedge)
    return run<WedgeCalibrationJob, WedgeCalibration>(
        options, [](const auto& job, auto& result) { calibrateFromWedge(job, result); },
        [](auto&&... a) { writeWedgeCalibration(a...); },
        [](auto&&... a) { writeFailedWedgeCalibration(a...); }, wedgeText);
  return run<PartCalibrationJob, PartCalibration>(
      options, [](const auto& job, auto& result) { calibrateFromPart(job, result); },
      [](auto&&... a) { writePartCalibration(a...); },
      [](auto&&... a) { writeFailedPartCalibration(a...); },
      [](const PartCalibration&) { return std::string(); });
}

}  // namespace

const char* CalibrationTerminationToString(CalibrationTermination type) {
  switch (type) {
    case CalibrationTermination::kCalibrated:
      return "calibrated";
    case CalibrationTermination::kStepFailed:
      return "step failed";
    case CalibrationTermination::kFailure:
      return "failure";
  }
  return "unknown";
}

bool CalibrationOptions::IsValid(std::string* error) const {
  const auto invalid = [error](std::string why) {
    if (error) *error = std::move(why);
    return false;
  };
  if (job_file.empty()) return invalid("job_file: empty (the calibration job)");
  if (output_folder.empty()) return invalid("output_folder: empty (where the material goes)");
  if (kind != CalibrationKind::kWedge && kind != CalibrationKind::kPart &&
      kind != CalibrationKind::kGeometry)
    return invalid("kind: kWedge, kPart or kGeometry");
  if (kind == CalibrationKind::kGeometry && !(reach_deg > 0.0 && reach_deg <= 10.0))
    return invalid("reach_deg: more than 0 and at most 10 (deg)");
  return true;
}

std::string CalibrationSummary::BriefReport() const {
  if (termination != CalibrationTermination::kCalibrated)
    return std::string(CalibrationTerminationToString(termination)) + ": " + message;
  if (detector_angles_deg.size() == 3)
    return fmt::format(
        "calibrated: detector tilt {:+.4f}, {:+.4f} deg, rotation {:+.4f} deg, "
        "worst misfit ratio {:.2f}",
        detector_angles_deg[0], detector_angles_deg[1], detector_angles_deg[2], misfit_ratio);
  std::string line = fmt::format("calibrated: {} term(s), u of I(x) {:.2g}", terms.size(),
                                 transmission_uncertainty);
  if (calibrated_range_mm)
    line += fmt::format(" over {:.2f} .. {:.2f} mm", calibrated_range_mm->first,
                        calibrated_range_mm->second);
  return line + fmt::format(", {:.1f} s", seconds);
}

std::string CalibrationSummary::FullReport() const {
  if (termination != CalibrationTermination::kCalibrated) return BriefReport() + "\n";
  return full_report_;
}

std::string CalibrationSummary::ToJson() const { return json_; }

CalibrationSummary calibrate(const CalibrationOptions& options) {
  std::string why;
  CalibrationSummary failed;
  if (!options.IsValid(&why)) {
    failed.message = why;
    return failed;
  }
  try {
    return calibrateOrThrow(options);
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception& e) {
    failed.message = e.what();
    return failed;
  }
}

}  // namespace xgauge
