// Rotated shots whose pose the measurement must find (issue 45): a reference
// part's reference and translated shots plus one turned on a rotary stage
// about a tilted axis, simulated by xgauge's own lab on a small detector and
// measured from the drawing's round values (examples/study_<part>.json).
// Shared by tests/pose_cases_test.cpp (a few cases that could fail) and
// bench/pose_sweep.cpp (the sweep over turns of 0 to 90 degrees).
#pragma once

#include "xgauge/core/config.h"
#include "xgauge/core/progress.h"
#include "xgauge/lab/dataset.h"
#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"
#include "xgauge/measure/schedule.h"
#include "xgauge/study/study.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

namespace xgauge::pose_cases {

namespace fs = std::filesystem;

// A reference part and the settings that measure it.
struct PartSetup {
  std::string name;      // "prism", "bracket", "shaft"
  std::string recipe;    // the replica recipe, relative to the source tree
  std::string settings;  // the study settings, relative to the source tree
  // The reference shots' turn about the vertical (deg), replacing the
  // recipe's where given: the replica prism faces the beam (0), and a turn
  // of 90 degrees from there would end edge on, where the Euler angles'
  // rx and rz become one (gimbal lock) and leave any bounds.
  std::optional<double> reference_ry_deg = std::nullopt;
  // Turns of the part (part frame) it is the same after: the shaft turned
  // half a turn about its axis, the cross hole through the axis included.
  std::vector<Mat3> symmetries = {Mat3::Identity()};
};

inline const std::vector<PartSetup>& parts() {
  static const std::vector<PartSetup> kParts{
      {"prism", "datasets/prism_a_small.json", "examples/study_prism_a.json", -40.0},
      {"bracket", "datasets/bracket_a_small.json", "examples/study_bracket_a.json"},
      {"shaft",
       "datasets/shaft_a_small.json",
       "examples/study_shaft_a.json",
       std::nullopt,
       {Mat3::Identity(), Mat3(Vec3(-1.0, 1.0, -1.0).asDiagonal())}}};
  return kParts;
}

struct PoseCase {
  int part = 0;              // index into parts()
  double angle_deg = 0.0;    // the stage's turn (its sign keeps ry within +-90)
  double tilt_deg = 0.0;     // the stage axis's tilt from the world's y axis
  double azimuth_deg = 0.0;  // the direction of that tilt, about y from x
  uint64_t seed = 1;         // the lab's (noise, stage jitter and wobble)
};

// Case `index` of `count` for `part`: turns spread evenly over 0..90
// degrees, axes tilted 4 to 14 degrees in directions of the golden angle.
inline PoseCase sweepCase(int part, int index, int count) {
  PoseCase c;
  c.part = part;
  c.angle_deg = 90.0 * (index + 0.5) / count;
  c.tilt_deg = 4.0 + 10.0 * std::fmod(0.618034 * (index + 1), 1.0);
  c.azimuth_deg = std::fmod(137.508 * (index + 1 + 7 * part), 360.0);
  c.seed = 4500 + 100 * static_cast<uint64_t>(part) + static_cast<uint64_t>(index);
  return c;
}

// The smallest angle (deg) of the rotation between two orientations.
inline double rotationAngleDeg(const Mat3& a, const Mat3& b) {
  const double c = std::clamp(0.5 * ((a.transpose() * b).trace() - 1.0), -1.0, 1.0);
  return std::acos(c) * 180.0 / std::numbers::pi;
}

struct PoseOutcome {
  bool in_bounds = true;            // the true rotations lie within the settings' bounds
  bool measured = false;            // the acceptance rule passed
  // Worst over the free and rotated shots, the nearest of the part's
  // symmetric orientations.
  double rotation_error_deg = 0.0;
  double max_dimension_error_mm = 0.0;
  double worst_misfit_ratio = 0.0;
  int candidates_tried = 1;
  int attempts = 1;
  double seconds = 0.0;  // the measurement alone
  std::string summary;

  // The true pose found: the rotation within 0.5 deg, every dimension
  // within `dimension_tolerance_mm`, and a measurement the rule accepts
  // (every misfit ratio within its factor).
  bool found(double dimension_tolerance_mm = 0.1) const {
    return measured && rotation_error_deg <= 0.5 &&
           max_dimension_error_mm <= dimension_tolerance_mm;
  }
};

// The pose bounds of a case: the study's positions, the turn about the
// vertical over +-90 degrees and the tilts about x and z over +-30, as for a
// stage whose tilt nobody measured: wide enough for a stage axis tilted up
// to 14 degrees, and for the mirrored poses (rx and ry of the other sign)
// a symmetric part admits.
inline nlohmann::json widenedBounds(nlohmann::json bounds) {
  bounds["rotation_deg"] = {{-30.0, 30.0}, {-90.0, 90.0}, {-30.0, 30.0}};
  return bounds;
}

// Simulates the case into `folder` (a 256^2 detector, the replica's beam
// and detector effects), measures t00 (free), t01 (translated 10 mm) and
// r00 (rotated) and compares with the truth.
// `candidates`: the schedule's PoseSchedule::candidates instead of its
// own where given (1: the search's best alone, as before issue 45).
inline PoseOutcome runCase(const PoseCase& c, const fs::path& source, const fs::path& folder,
                           std::optional<int> candidates = std::nullopt, int detector_px = 256) {
  const PartSetup& setup = parts().at(static_cast<size_t>(c.part));
  fs::create_directories(folder);
  nlohmann::json recipe = ConfigNode::loadFile(source / setup.recipe).json();
  const double pitch_mm = 409.6 / detector_px;
  const nlohmann::json machine = {
      {"description", "the replica cabinet binned to a small detector"},
      {"source_detector_distance_mm", 1000.0},
      {"detector",
       {{"columns", detector_px},
        {"rows", detector_px},
        {"pixel_pitch_mm", {pitch_mm, pitch_mm}},
        {"principal_point_px", {0.5 * detector_px, 0.5 * detector_px}}}}};
  std::ofstream(folder / "machine.json") << machine.dump(2);
  recipe["machine"] = fs::absolute(folder / "machine.json").string();
  recipe["part"]["model"] =
      fs::absolute(source / "datasets" / recipe["part"]["model"].get<std::string>()).string();
  recipe["seed"] = c.seed;
  // The scintillator's scatter keeps its width in mm (the settings' 50 mm;
  // the replica's 1024^2 pixels are 0.4 mm).
  auto& scatter = recipe["detector"]["scatter"];
  scatter["sigma_px"] = scatter["sigma_px"].get<double>() * 0.4 / pitch_mm;
  recipe["shots"]["translations"]["count"] = 2;
  auto& shots = recipe["shots"];
  if (setup.reference_ry_deg)
    shots["base_pose"]["rotation_deg"][1] = shots["rotations"]["base_pose"]["rotation_deg"][1] =
        *setup.reference_ry_deg;
  // Turned towards the other side of the beam, so that ry stays within +-90.
  const double sign = shots["base_pose"]["rotation_deg"][1].get<double>() > 0.0 ? -1.0 : 1.0;
  const double tilt = c.tilt_deg * std::numbers::pi / 180.0;
  const double azimuth = c.azimuth_deg * std::numbers::pi / 180.0;
  auto& rotations = recipe["shots"]["rotations"];
  rotations["angles_deg"] = {sign * c.angle_deg};
  rotations["axis"] = {std::sin(tilt) * std::cos(azimuth), std::cos(tilt),
                       std::sin(tilt) * std::sin(azimuth)};
  std::ofstream(folder / "recipe.json") << recipe.dump(2);
  setProgressEnabled(false);
  simulateDataset(Recipe::load(folder / "recipe.json"), folder / "data");

  const DatasetTruth truth = DatasetTruth::load(folder / "data" / "truth.json");
  const fs::path settings_file = source / setup.settings;
  nlohmann::json settings = ConfigNode::loadFile(settings_file).json();
  settings["pose_bounds"] = widenedBounds(settings["pose_bounds"]);
  const std::vector<std::string> measured{"t00", "t01", "r00"};
  PoseOutcome out;
  for (const char* name : {"t00", "r00"}) {
    const Vec3 e = truth.shot(name).pose.eulerDeg();
    const auto& b = settings["pose_bounds"]["rotation_deg"];
    for (int k = 0; k < 3; ++k)
      out.in_bounds &= b[k][0].get<double>() < e[k] && e[k] < b[k][1].get<double>();
  }
  const StudyInputs inputs = prepareStudyInputs(truth, settings, settings_file);
  PreparedShots prepared(inputs.machine);
  const nlohmann::json job =
      studyJob(settings, truth, truth.part_file, measured, "case", "machine.json", "material.json");
  const MeasurementInputs run_inputs = studyRunInputs(job, inputs, settings_file, prepared);
  const auto start = std::chrono::steady_clock::now();
  ForwardModel model(run_inputs);
  Schedule schedule = scheduleFor(run_inputs.job.schedule);
  if (candidates) schedule.pose.candidates = *candidates;
  MeasureOptions options;
  options.schedule = &schedule;
  const MeasurementResult result = measure(model, model.start(), options);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  out.measured = result.status == MeasurementStatus::kMeasured;
  out.worst_misfit_ratio = result.check.worstMisfitRatio();
  out.candidates_tried = result.candidates_tried;
  out.attempts = result.attempts;
  for (const MeasuredRadiograph& r : result.radiographs)
    if (r.name != "t01") {
      double error = 180.0;
      for (const Mat3& same : setup.symmetries)
        error = std::min(
            error, rotationAngleDeg(r.pose.rotation, truth.shot(r.name).pose.rotation * same));
      out.rotation_error_deg = std::max(out.rotation_error_deg, error);
    }
  for (const MeasuredDimension& d : result.dimensions)
    if (d.free)
      out.max_dimension_error_mm =
          std::max(out.max_dimension_error_mm, std::abs(d.value - truth.dimensions.at(d.name)));
  const Vec3 e = truth.shot("r00").pose.eulerDeg();
  out.summary = fmt::format(
      "{} turn {:+.1f} deg, axis tilt {:.1f} at {:.0f} deg, seed {} (r00 true euler {:.1f} "
      "{:.1f} {:.1f}): {}, rotation error {:.3f} deg, dimensions {:.4f} mm, misfit {:.2f}, "
      "{} candidate(s), {} attempt(s), {:.1f} s",
      setup.name, sign * c.angle_deg, c.tilt_deg, c.azimuth_deg, c.seed, e.x(), e.y(), e.z(),
      out.measured ? "measured" : "not measured", out.rotation_error_deg,
      out.max_dimension_error_mm, out.worst_misfit_ratio, out.candidates_tried, out.attempts,
      out.seconds);
  return out;
}

}  // namespace xgauge::pose_cases
