#include "xgauge/measure/truth.h"

#include "xgauge/core/config.h"
#include "xgauge/xray/machine.h"

namespace xgauge {

DatasetTruth DatasetTruth::load(const std::filesystem::path& truth_json) {
  const ConfigNode root = ConfigNode::loadFile(truth_json);
  DatasetTruth t;
  t.folder = truth_json.parent_path();
  t.part_file = root.at("part").get<std::string>("model");
  const ConfigNode dims = root.at("part").at("dimensions");
  for (const auto& name : dims.keys()) t.dimensions[name] = dims.at(name).number();
  const auto white = root.get<std::vector<int>>("white_region");
  if (white.size() != 4) root.at("white_region").fail("expected [x, y, width, height]");
  t.white_region = {white[0], white[1], white[2], white[3]};
  t.dark = t.folder / root.get<std::string>("dark");
  t.flat = t.folder / root.get<std::string>("flat");
  t.path_mm = root.at("transmission").get<std::vector<double>>("path_mm");
  t.transmission = root.at("transmission").get<std::vector<double>>("transmission");
  t.machine = root.at("machine").json();
  const ConfigNode shots = root.at("shots");
  for (size_t i = 0; i < shots.size(); ++i) {
    const ConfigNode s = shots[i];
    TruthShot shot;
    shot.name = s.get<std::string>("name");
    shot.file = t.folder / s.get<std::string>("file");
    shot.pattern = s.get<std::string>("pattern");
    if (s.has("distance_mm")) shot.distance_mm = s.at("distance_mm").number();
    if (s.has("reference")) shot.reference = s.get<std::string>("reference");
    // The pose's 4x4 matrix is exact; the Euler angles beside it are for people.
    const auto m = s.at("pose").get<std::vector<double>>("matrix");
    if (m.size() != 16) s.at("pose").at("matrix").fail("expected 16 numbers");
    Mat4 matrix;
    for (int k = 0; k < 16; ++k) matrix(k / 4, k % 4) = m[static_cast<size_t>(k)];
    shot.pose = Pose::fromMatrix(matrix);
    t.shots.push_back(shot);
  }
  return t;  // other keys are the simulator's record, not read here
}

const TruthShot& DatasetTruth::shot(const std::string& name) const {
  for (const auto& s : shots)
    if (s.name == name) return s;
  fail("no shot named '{}' in {}", name, (folder / "truth.json").string());
}

}  // namespace xgauge
