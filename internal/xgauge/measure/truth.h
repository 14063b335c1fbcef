// The ground truth of a simulated dataset (lab/dataset.h writes it), as the
// measurement side reads it: for studies, materials and error tables.
#pragma once

#include "xgauge/core/transform.h"
#include "xgauge/image/image.h"
#include "xgauge/material/exponential_sum.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace xgauge {

struct TruthShot {
  std::string name;
  std::filesystem::path file;
  std::string pattern;       // "free", "translated", "rotated"
  double distance_mm = 0.0;  // translated: from the reference
  std::string reference;     // translated: the shot it was moved from
  double nominal_angle_deg = 0.0;  // rotated: the stage's nominal angle
  Pose pose;
};

struct DatasetTruth {
  std::filesystem::path folder;
  std::filesystem::path part_file;
  std::map<std::string, double> dimensions;
  PixelRect white_region;
  std::filesystem::path dark, flat;
  std::vector<double> path_mm, transmission;
  std::vector<TruthShot> shots;
  nlohmann::json machine;

  static DatasetTruth load(const std::filesystem::path& truth_json);
  const TruthShot& shot(const std::string& name) const;
};

class PartModel;
struct Machine;

// The longest path (mm) through the part at its true dimensions over every
// shot's true pose: the largest value of a path-length render of each shot
// on the machine binned to at most 512 pixels a side. Point samples at the
// binned pixels' centres may miss the longest chord by a little; callers
// add a margin.
double longestTruePathMm(const DatasetTruth& truth, const PartModel& part, const Machine& machine);

// The dataset's true material curve as an exponential sum, for studies that
// measure with it: the transmission table fitted over 0 .. max_path_mm only
// (a table runs to the part's bounding-box diagonal, and one fit over all of
// it leaves errors of 0.01 at the thin paths a part shows, which a
// measurement reads as 0.1 mm), with the fewest terms, from `min_terms` to
// 8, whose largest residual there is at most `tolerance`; the best fit found
// otherwise. The description names the file, range, terms and residual.
ExponentialSum fitTrueCurve(const DatasetTruth& truth, double max_path_mm, int min_terms = 3,
                            double tolerance = 1e-4);

}  // namespace xgauge
