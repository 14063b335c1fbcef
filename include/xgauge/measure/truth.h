// The ground truth of a simulated dataset (lab/dataset.h writes it), as the
// measurement side reads it: for studies, materials and error tables.
#pragma once

#include "xgauge/core/transform.h"
#include "xgauge/image/image.h"

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

}  // namespace xgauge
