#include "xgauge/measure/truth.h"

#include "xgauge/core/config.h"
#include "xgauge/core/error.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/material/exponential_fit.h"
#include "xgauge/xray/machine.h"
#include "xgauge/xray/renderer.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <optional>

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
    if (s.has("nominal_angle_deg")) shot.nominal_angle_deg = s.at("nominal_angle_deg").number();
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

double longestTruePathMm(const DatasetTruth& truth, const PartModel& part, const Machine& machine) {
  const TriangleMesh mesh = part.mesh(part.values(truth.dimensions));
  Machine binned = machine;
  const int factor = std::max(1, (std::max(machine.columns, machine.rows) + 511) / 512);
  binned.columns = (machine.columns + factor - 1) / factor;
  binned.rows = (machine.rows + factor - 1) / factor;
  binned.pitch_u_mm *= factor;
  binned.pitch_v_mm *= factor;
  binned.cx_px /= factor;
  binned.cy_px /= factor;
  double longest = 0.0;
  std::vector<Vec3> world;
  Image paths;
  for (const TruthShot& shot : truth.shots) {
    poseVertices(shot.pose, mesh.vertices, world);
    renderPathLength(binned, WorldMesh{world, mesh.triangles, mesh.csg.get()}, {}, paths);
    for (float p : paths.pixels()) longest = std::max(longest, static_cast<double>(p));
  }
  return longest;
}

ExponentialSum fitTrueCurve(const DatasetTruth& truth, double max_path_mm, int min_terms,
                            double tolerance) {
  XG_CHECK(min_terms >= 1 && min_terms <= 8, "min_terms must be 1 to 8");
  std::vector<double> path, transmission;
  for (size_t i = 0; i < truth.path_mm.size(); ++i) {
    if (truth.path_mm[i] > max_path_mm && path.size() >= 16) break;
    path.push_back(truth.path_mm[i]);
    transmission.push_back(truth.transmission[i]);
  }
  std::optional<ExponentialSum> best;
  ExponentialFitReport best_report;
  for (int terms = min_terms; terms <= 8; ++terms) {
    ExponentialFitReport report;
    ExponentialSum fitted = fitExponentialSum(path, transmission, terms, {}, &report);
    if (!best || report.max_abs_residual < best_report.max_abs_residual)
      best = std::move(fitted), best_report = report;
    // A term the fit dropped (weight 0) means more terms cannot help.
    if (best_report.max_abs_residual <= tolerance || report.terms_used < terms) break;
  }
  return ExponentialSum(
      best->terms(),
      fmt::format("{} exponentials fitted to the transmission table of {} over 0-{:.1f} mm (max "
                  "residual {:.1e})",
                  best->terms().size(), (truth.folder / "truth.json").string(), path.back(),
                  best_report.max_abs_residual));
}

}  // namespace xgauge
