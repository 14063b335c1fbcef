#include "xgauge/calibrate/geometry.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/error.h"
#include "xgauge/image/stats.h"
#include "xgauge/measure/inputs.h"
#include "xgauge/measure/model.h"

#include <spdlog/spdlog.h>
#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <optional>

namespace xgauge {

namespace {

// An angle this close to its bound (deg) was stopped by it.
constexpr double kAtBoundDeg = 1e-3;

// The detector angles' standard uncertainties from the least squares at
// `theta`: the residuals' variance times (J'J)^-1 over every parameter the
// fit varied (the poses take up what they can of the panel's pose), on the
// full-size radiographs with the fit's samples.
// Also sets `misfit_ratio`: the largest of the radiographs' rms residual
// over their noise (each residual is scaled by 1 / sqrt(its roi's area)).
std::array<double, 3> detectorUncertainty(ForwardModel& model, const std::vector<double>& theta,
                                          double& misfit_ratio) {
  const std::vector<int> indices = model.leastSquaresIndices();
  std::vector<int> all;
  for (int r = 0; r < model.radiographCount(); ++r) all.push_back(r);
  std::vector<double> r, j;
  if (!model.residualsAndJacobian(theta, indices, 0, 2, all, r, j))
    fail("the radiographs cannot be simulated at the fitted geometry");
  misfit_ratio = 0.0;
  size_t first = 0;
  for (int k = 0; k < model.radiographCount(); ++k) {
    const PreparedRadiograph& radiograph = model.radiograph(k);
    const auto area = static_cast<size_t>(radiograph.rois[0].area());
    double squares = 0.0;
    for (size_t m = first; m < first + area && m < r.size(); ++m) squares += r[m] * r[m];
    first += area;
    const Image& image = radiograph.levels[0];
    const double noise = neighbourNoise(image, model.spec(k).white_region.intersect(image.rect()));
    if (noise > 0.0) misfit_ratio = std::max(misfit_ratio, std::sqrt(squares) / noise);
  }
  const auto m = static_cast<Eigen::Index>(r.size());
  const auto p = static_cast<Eigen::Index>(indices.size());
  if (m <= p) fail("fewer residuals than parameters");
  const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>
      jacobian(j.data(), m, p);
  const Eigen::MatrixXd normal = jacobian.transpose() * jacobian;
  // Through the correlation matrix: the columns mix degrees and millimetres.
  const Eigen::VectorXd scale = normal.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
  const Eigen::MatrixXd inverse = scale.asDiagonal() *
                                  (scale.asDiagonal() * normal * scale.asDiagonal())
                                      .ldlt()
                                      .solve(Eigen::MatrixXd::Identity(p, p)) *
                                  scale.asDiagonal();
  const double variance =
      Eigen::Map<const Eigen::VectorXd>(r.data(), m).squaredNorm() / static_cast<double>(m - p);
  std::array<double, 3> out{};
  const std::vector<int> detector = model.detectorIndices();
  for (size_t k = 0; k < 3; ++k) {
    const auto column = std::find(indices.begin(), indices.end(), detector[k]) - indices.begin();
    if (column == p) continue;  // held, not fitted
    out[k] = std::sqrt(variance * std::max(0.0, inverse(column, column)));
  }
  return out;
}

// The poses whose panel's turn a fit can see: a known pose or a turn about
// the stage's axis pins the scene; free poses take the turn up exactly.
bool posesPinTheTurn(const MeasurementJob& job) {
  bool pinned = false;
  for (const RadiographSpec& spec : job.radiographs)
    pinned |= spec.pattern == Acquisition::kKnown || spec.pattern == Acquisition::kTurned;
  return pinned;
}

// The job without radiograph `k` (references to later ones renumbered);
// nothing when another radiograph's pose refers to it.
std::optional<MeasurementInputs> withoutRadiograph(const MeasurementInputs& inputs, int k) {
  for (const RadiographSpec& spec : inputs.job.radiographs)
    if (spec.reference == k) return std::nullopt;
  MeasurementInputs out = inputs;
  out.job.radiographs.erase(out.job.radiographs.begin() + k);
  out.radiographs.erase(out.radiographs.begin() + k);
  for (RadiographSpec& spec : out.job.radiographs)
    if (spec.reference > k) --spec.reference;
  return out;
}

// A second estimate of the angles: the joint fit again without each
// radiograph in turn (the delete-one jackknife, Efron and Stein 1981), from
// the full fit's poses and angles. The least squares' u sees the noise;
// what differs from shot to shot beyond it (the lag's ghost of the frame
// before, a halo not quite the panel's, the part's place on the panel)
// moves the angles with the radiograph left out. The jackknife's variance
// (n - 1)/n sum (a_i - mean)^2 over the n left out, here (n - 1) times the
// mean square over the radiographs that can be left out (those no other
// pose refers to), needs at least three of them. It cannot see what every
// radiograph shares (the part's stated dimensions, the material's curve).
void addLeaveOneOut(const MeasurementInputs& inputs, const ForwardModel& full,
                    const std::vector<double>& theta, double reach_deg,
                    GeometryCalibration& out) {
  std::map<std::string, double> fitted;
  for (int i = 0; i < full.parameters().size(); ++i)
    fitted[full.parameters()[i].name] = theta[static_cast<size_t>(i)];
  const int n = static_cast<int>(inputs.radiographs.size());
  std::vector<int> left_out;
  for (int k = 0; k < n; ++k)
    if (withoutRadiograph(inputs, k)) left_out.push_back(k);
  if (left_out.size() < 3) return;
  for (const int k : left_out) {
    const MeasurementInputs sub = *withoutRadiograph(inputs, k);
    ForwardModel model(sub);
    std::vector<double> start = model.start();
    model.freeDetectorPose(start, reach_deg, posesPinTheTurn(sub.job));
    for (int i = 0; i < model.parameters().size(); ++i)
      start[static_cast<size_t>(i)] = fitted.at(model.parameters()[i].name);
    MeasureOptions joint;
    joint.search_poses = false;
    joint.assess = false;
    joint.judge = false;
    const MeasurementResult fit = measure(model, start, joint);
    std::array<double, 3> angles{};
    const std::vector<int> detector = model.detectorIndices();
    for (size_t a = 0; a < 3; ++a) angles[a] = fit.theta[static_cast<size_t>(detector[a])];
    out.leave_one_out.push_back({inputs.job.radiographs[static_cast<size_t>(k)].name, angles});
  }
  const auto m = static_cast<double>(out.leave_one_out.size());
  for (size_t a = 0; a < 3; ++a) {
    double mean = 0.0, squares = 0.0;
    for (const auto& l : out.leave_one_out) mean += l.angles_deg[a] / m;
    for (const auto& l : out.leave_one_out)
      squares += (l.angles_deg[a] - mean) * (l.angles_deg[a] - mean);
    out.leave_one_out_uncertainty_deg[a] = std::sqrt((n - 1) * squares / m);
  }
}

}  // namespace

GeometryCalibration calibrateGeometry(const std::filesystem::path& job_file, double reach_deg) {
  if (!(reach_deg > 0.0 && reach_deg <= 10.0))
    fail("the detector pose's reach must lie in (0, 10] degrees, got {}", reach_deg);
  const MeasurementInputs inputs = loadMeasurementInputs(job_file);
  if (!inputs.job.free_dimensions.empty())
    failAt(SourceLocation::at(job_file.string(), "/dimensions"),
           "a geometry calibration fits the detector to a part of known dimensions: give every "
           "dimension under \"fixed\" ({} is free)",
           inputs.job.free_dimensions.front());
  ForwardModel model(inputs);
  // The part's poses with the machine as stated, then the poses and the
  // detector's together by least squares from there.
  MeasureOptions first;
  first.assess = false;
  first.judge = false;
  MeasurementResult posed = measure(model, model.start(), first);
  std::vector<double> theta = posed.theta;
  // The panel's turn in its plane is a turn of the whole scene about the
  // central ray, which free poses take up exactly: it is held as stated
  // unless a pose is known (or turned about the stage's axis).
  const bool pinned = posesPinTheTurn(inputs.job);
  model.freeDetectorPose(theta, reach_deg, pinned);
  MeasureOptions joint;
  joint.search_poses = false;
  joint.assess = false;  // no dimension is free: nothing to budget
  joint.judge = false;
  GeometryCalibration out;
  out.fit = measure(model, theta, joint);
  const std::vector<int> detector = model.detectorIndices();
  static constexpr std::array<const char*, 3> kNames{"tilt_u", "tilt_v", "rotation"};
  for (size_t k = 0; k < 3; ++k) {
    const auto i = static_cast<size_t>(detector[k]);
    out.angles_deg[k] = out.fit.theta[i];
    if (model.parameters().isFree(detector[k]) &&
        std::min(out.angles_deg[k] - model.lower()[i], model.upper()[i] - out.angles_deg[k]) <
            kAtBoundDeg)
      fail("{}: the detector's {} ended at its bound ({:.3f} deg, reach +-{} deg): not a result",
           job_file.string(), kNames[k], out.angles_deg[k], reach_deg);
  }
  out.statistical_uncertainty_deg = detectorUncertainty(model, out.fit.theta, out.misfit_ratio);
  out.rotation_fitted = pinned;
  // A fit that leaves far more than the noise found the part's poses wrong
  // (or the part is not the one the job names): its angles are not a result.
  if (out.misfit_ratio > inputs.job.acceptance.max_misfit_ratio)
    fail(
        "{}: the fit leaves {:.1f} times the radiographs' noise (the job's acceptance allows "
        "{}): the part's poses or its stated dimensions are wrong: not a result, no geometry "
        "written",
        job_file.string(), out.misfit_ratio, inputs.job.acceptance.max_misfit_ratio);
  addLeaveOneOut(inputs, model, out.fit.theta, reach_deg, out);
  // Each angle's u: the larger of the two estimates of its spread.
  for (size_t k = 0; k < 3; ++k)
    out.uncertainty_deg[k] =
        std::max(out.statistical_uncertainty_deg[k], out.leave_one_out_uncertainty_deg[k]);
  if (!pinned) out.uncertainty_deg[2] = inputs.machine.detector_pose_uncertainty_deg[2];
  out.machine = inputs.machine;
  out.machine.setDetectorPose(out.angles_deg[0], out.angles_deg[1], out.angles_deg[2]);
  out.machine.detector_pose_uncertainty_deg = out.uncertainty_deg;
  // The stated machine file with the pose added: every other key (a
  // characterised detector's file, the turntable) stays as the lab wrote it.
  std::ifstream in(inputs.job.machine_file);
  out.machine_file = nlohmann::json::parse(in, nullptr, true, true);
  if (auto c = out.machine_file["detector"].find("characterization");
      c != out.machine_file["detector"].end() && c->is_string())
    *c = std::filesystem::absolute(inputs.job.machine_file.parent_path() / c->get<std::string>())
             .string();
  out.machine_file["detector"]["tilt_deg"] = {out.angles_deg[0], out.angles_deg[1]};
  out.machine_file["detector"]["rotation_deg"] = out.angles_deg[2];
  out.machine_file["uncertainty"]["detector_pose_deg"] = {
      out.uncertainty_deg[0], out.uncertainty_deg[1], out.uncertainty_deg[2]};
  spdlog::info(
      "detector pose: tilt ({:.4f}, {:.4f}) +- ({:.4f}, {:.4f}) deg, rotation {:.4f} +- "
      "{:.4f} deg; worst misfit ratio {:.2f}",
      out.angles_deg[0], out.angles_deg[1], out.uncertainty_deg[0], out.uncertainty_deg[1],
      out.angles_deg[2], out.uncertainty_deg[2], out.misfit_ratio);
  return out;
}

nlohmann::json GeometryCalibration::toJson() const {
  nlohmann::json left_out = nlohmann::json::object();
  for (const LeftOut& l : leave_one_out)
    left_out[l.radiograph] = {l.angles_deg[0], l.angles_deg[1], l.angles_deg[2]};
  nlohmann::json radiographs = nlohmann::json::array();
  for (const MeasuredRadiograph& r : fit.radiographs)
    radiographs.push_back({{"name", r.name}, {"pose", poseToJson(r.pose)}, {"loss", r.loss}});
  return {
      {"detector",
       {{"tilt_deg", {angles_deg[0], angles_deg[1]}},
        {"rotation_deg", angles_deg[2]},
        {"standard_uncertainty_deg", {uncertainty_deg[0], uncertainty_deg[1], uncertainty_deg[2]}},
        {"statistical_uncertainty_deg",
         {statistical_uncertainty_deg[0], statistical_uncertainty_deg[1],
          statistical_uncertainty_deg[2]}},
        {"leave_one_out",
         {{"uncertainty_deg",
           {leave_one_out_uncertainty_deg[0], leave_one_out_uncertainty_deg[1],
            leave_one_out_uncertainty_deg[2]}},
          {"angles_deg", left_out}}},
        {"rotation", rotation_fitted ? "fitted" : "held as the machine states it"}}},
      {"misfit_ratio", misfit_ratio},
      {"total_loss", fit.total_loss},
      {"seconds", fit.seconds},
      {"radiographs", radiographs},
      {"machine", machine.toJson()}};
}

void writeGeometryCalibration(const GeometryCalibration& calibration,
                              const std::filesystem::path& folder) {
  std::filesystem::create_directories(folder);
  writeFileAtomically(folder / "geometry.json", calibration.toJson().dump(2) + "\n");
  writeFileAtomically(folder / "machine.json", calibration.machine_file.dump(2) + "\n");
}

}  // namespace xgauge
