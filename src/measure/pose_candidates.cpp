#include "pose_candidates.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>

namespace xgauge {

namespace {

// The smallest angle (deg) of the rotation from a to b.
double angleBetweenDeg(const Mat3& a, const Mat3& b) {
  const double c = std::clamp(0.5 * ((a.transpose() * b).trace() - 1.0), -1.0, 1.0);
  return std::acos(c) * kRadToDeg;
}

}  // namespace

std::vector<double> poseValues(const ForwardModel& model, const std::vector<double>& theta, int r) {
  std::vector<double> out;
  for (int i : model.poseIndices(r)) out.push_back(theta[static_cast<size_t>(i)]);
  return out;
}

void setPose(const ForwardModel& model, std::vector<double>& theta, int r,
             const std::vector<double>& pose) {
  const std::vector<int> indices = model.poseIndices(r);
  XG_CHECK(indices.size() == pose.size(), "a value for each pose parameter");
  for (size_t k = 0; k < indices.size(); ++k) theta[static_cast<size_t>(indices[k])] = pose[k];
}

std::vector<PoseCandidate> distinctCandidates(const ForwardModel& model, int r,
                                              const std::vector<PoseCandidate>& candidates,
                                              double separation_deg) {
  std::vector<double> theta = model.start();
  auto rotation = [&](const PoseCandidate& c) {
    setPose(model, theta, r, c.pose);
    return model.pose(theta, r).rotation;
  };
  std::vector<PoseCandidate> out;
  std::vector<Mat3> kept;
  for (const PoseCandidate& c : candidates) {
    const Mat3 m = rotation(c);
    const bool distinct = std::all_of(kept.begin(), kept.end(), [&](const Mat3& other) {
      return angleBetweenDeg(m, other) > separation_deg;
    });
    if (!distinct) continue;
    out.push_back(c);
    kept.push_back(m);
  }
  return out;
}

std::vector<PoseCandidate> mirroredCandidates(ForwardModel& model, const std::vector<double>& theta,
                                              int r, const StagePlan& local, Runner& runner) {
  const std::vector<int> pose = model.poseIndices(r);
  const Mat3 rotation = model.pose(theta, r).rotation;
  Mat3 beam_mirror = Mat3::Identity();
  beam_mirror(2, 2) = -1.0;
  static constexpr std::array<const char*, 3> kAxes{"x", "y", "z"};
  std::vector<std::vector<double>> starts;
  std::vector<std::string> names, origins;
  for (int axis = 0; axis < 3; ++axis) {
    Mat3 part_mirror = Mat3::Identity();
    part_mirror(axis, axis) = -1.0;
    Pose mirrored;
    mirrored.rotation = beam_mirror * rotation * part_mirror;
    const Vec3 angles = mirrored.eulerDeg();
    std::vector<double> start = theta;
    bool inside = true;
    for (int k = 0; k < 3; ++k) {
      const auto i = static_cast<size_t>(pose[static_cast<size_t>(k)]);
      inside &= model.lower()[i] <= angles[k] && angles[k] <= model.upper()[i];
      start[i] = angles[k];
    }
    if (!inside) continue;
    starts.push_back(std::move(start));
    origins.push_back(
        fmt::format("mirrored normal to the part's {} axis", kAxes.at(static_cast<size_t>(axis))));
    names.push_back(fmt::format("{}: pose {}", model.spec(r).name, origins.back()));
  }
  const std::vector<double> losses = runner.refineEach(starts, local, names);
  std::vector<PoseCandidate> out;
  for (size_t k = 0; k < starts.size(); ++k)
    out.push_back({poseValues(model, starts[k], r), losses[k], origins[k]});
  return out;
}

}  // namespace xgauge
