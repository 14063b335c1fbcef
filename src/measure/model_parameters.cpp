// The forward model's parameter layout (model.h): which entries of theta are
// the part's dimensions, each radiograph's pose (by its acquisition pattern),
// the refinement's rate scale and a calibration's free material; their names,
// bounds, starts and the index sets the stages free; and what a theta stands
// for (a pose, a material). The generic named layout is measure/parameters.h.
#include "xgauge/measure/model.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace xgauge {

namespace {

Vec3 axisFromAngles(double azimuth_deg, double elevation_deg) {
  const double az = azimuth_deg * kDegToRad, el = elevation_deg * kDegToRad;
  return {std::cos(el) * std::cos(az), std::sin(el), std::cos(el) * std::sin(az)};
}

}  // namespace

void ForwardModel::addDimensionParameters() {
  const MeasurementJob& job = inputs_.job;
  const auto& dims = part_.dimensions();
  std::vector<std::string> names;
  std::vector<double> lower, upper, start;
  for (size_t i = 0; i < dims.size(); ++i) {
    const Dimension& d = dims[i];
    const bool free = std::find(job.free_dimensions.begin(), job.free_dimensions.end(), d.name) !=
                      job.free_dimensions.end();
    double value = d.nominal;
    if (auto f = job.fixed_dimensions.find(d.name); f != job.fixed_dimensions.end())
      value = f->second;
    if (auto s = job.start.find(d.name); s != job.start.end()) value = s->second;
    double lo = value, hi = value;
    if (free) {
      free_dims_.push_back(static_cast<int>(i));
      if (auto b = job.bounds.find(d.name); b != job.bounds.end()) {
        lo = b->second[0], hi = b->second[1];
      } else {
        lo = std::max(d.min, d.nominal - 0.1 * std::abs(d.nominal));
        hi = std::min(d.max, d.nominal + 0.1 * std::abs(d.nominal));
      }
      value = std::clamp(value, lo, hi);
    }
    names.push_back(d.name), lower.push_back(lo), upper.push_back(hi), start.push_back(value);
  }
  layout_.add("dim", ParameterKind::kDimension, names, lower, upper, start);
}

void ForwardModel::addPoseParameters() {
  const MeasurementJob& job = inputs_.job;
  const size_t levels = radiograph(0).levels.size();
  for (int r = 0; r < radiographCount(); ++r) {
    const RadiographSpec& s = spec(r);
    if (radiograph(r).levels.size() != levels)
      fail("radiographs {} and {} differ in size", spec(0).name, s.name);
    pose_first_.push_back(layout_.size());
    switch (s.pattern) {
      case Acquisition::kFree:
      case Acquisition::kRotated: {
        std::vector<double> lo, hi, mid;
        for (const auto& range : job.rotation_bounds_deg)
          lo.push_back(range[0]), hi.push_back(range[1]),
              mid.push_back(0.5 * (range[0] + range[1]));
        layout_.add(s.name + "/rotation", ParameterKind::kRotation, {"rx", "ry", "rz"}, lo, hi,
                    mid);
        lo.clear(), hi.clear(), mid.clear();
        for (const auto& range : job.centre_bounds_mm)
          lo.push_back(range[0]), hi.push_back(range[1]),
              mid.push_back(0.5 * (range[0] + range[1]));
        layout_.add(s.name + "/position", ParameterKind::kPosition, {"x", "y", "z"}, lo, hi, mid);
        break;
      }
      case Acquisition::kTranslated:
        layout_.add(
            s.name + "/axis", ParameterKind::kAxis, {"azimuth", "elevation"},
            {-180.0, s.axis_elevation_bounds_deg[0]}, {180.0, s.axis_elevation_bounds_deg[1]},
            {0.0, std::clamp(0.0, s.axis_elevation_bounds_deg[0], s.axis_elevation_bounds_deg[1])});
        break;
      case Acquisition::kTurned:
        if (!machine().turntable)
          failAt(SourceLocation::at(job.file.string(), fmt::format("/radiographs/{}/pattern", r)),
                 "radiograph {} is turned, but the machine file {} states no turntable axis",
                 s.name, job.machine_file.string());
        break;
      case Acquisition::kKnown:
        break;
    }
  }
}

void ForwardModel::addRateScale() {
  // The prior is the job's material's, the same for a model built on one of
  // its moved curves (the budget's), so that every model of one measurement
  // weighs the refinement alike. Checked here, where every path to a
  // measurement (a job, a study's run, the budget's moved models) passes.
  const MeasurementJob& job = inputs_.job;
  if (!inputs_.material)
    fail("{}: /refine_material: the job names no material to refine", job.file.string());
  const ExponentialSum& stated = *inputs_.material;
  rate_scale_prior_ = stated.rateScaleFor(stated.transmissionUncertainty(), part_size_mm_);
  if (!(rate_scale_prior_ > 0.0))
    fail(
        "{}: /refine_material: the refinement is weighed by the material's stated uncertainty, "
        "and {} states none (uncertainty.transmission is 0)",
        job.file.string(), job.material_file.string());
  const double reach = std::min(kRateScaleReach * rate_scale_prior_, 0.5);
  rate_scale_index_ = layout_.add("material_refinement", ParameterKind::kMaterial, {"rate_scale"},
                                  {-reach}, {reach}, {0.0});
}

void ForwardModel::freeMaterial(const ExponentialSum& material, std::vector<double>& theta,
                                double rate_floor_per_mm) {
  XG_CHECK(material_terms_ == 0, "the material is free already");
  XG_CHECK(theta.size() == static_cast<size_t>(size()), "theta has the wrong size");
  const auto& terms = material.terms();
  const size_t m = terms.size();
  std::vector<std::string> names;
  std::vector<double> lower, upper, start;
  double rest = 1.0;
  for (size_t k = 0; k + 1 < m; ++k) {
    const double u = rest > 0.0 ? std::clamp(terms[k].weight / rest, 0.0, 1.0) : 0.0;
    rest -= terms[k].weight;
    names.push_back(fmt::format("fraction{}", k + 1));
    lower.push_back(0.0), upper.push_back(1.0), start.push_back(u);
  }
  for (size_t k = 0; k < m; ++k) {
    names.push_back(fmt::format("rate{}", k + 1));
    const double low = std::min(rate_floor_per_mm, 10.0);
    lower.push_back(low), upper.push_back(10.0);
    start.push_back(std::clamp(terms[k].mu_per_mm, low, 10.0));
  }
  layout_.add("material", ParameterKind::kMaterial, names, lower, upper, start);
  theta.insert(theta.end(), start.begin(), start.end());
  material_terms_ = static_cast<int>(m);
  setMaterial(materialOf(theta));
}

void ForwardModel::freeDetectorPose(std::vector<double>& theta, double reach_deg,
                                    bool with_rotation) {
  XG_CHECK(!layout_.hasBlock("detector"), "the detector's pose is free already");
  XG_CHECK(theta.size() == static_cast<size_t>(size()), "theta has the wrong size");
  const std::vector<double> start{machine_.detector_tilt_deg[0], machine_.detector_tilt_deg[1],
                                  machine_.detector_rotation_deg};
  std::vector<double> lower, upper;
  for (double s : start)
    lower.push_back(std::max(-10.0, s - reach_deg)), upper.push_back(std::min(10.0, s + reach_deg));
  if (!with_rotation) lower[2] = upper[2] = start[2];
  layout_.add("detector", ParameterKind::kDetector, {"tilt_u", "tilt_v", "rotation"}, lower, upper,
              start);
  theta.insert(theta.end(), start.begin(), start.end());
}

ExponentialSum ForwardModel::materialOf(std::span<const double> theta) const {
  if (rate_scale_index_ >= 0)
    return base_material_.withScaledRates(theta[static_cast<size_t>(rate_scale_index_)]);
  if (material_terms_ == 0) return material_;
  const int m = material_terms_;
  const double* u = theta.data() + layout_.block("material").front();
  const double* mu = u + (m - 1);
  std::vector<ExponentialTerm> terms;
  double rest = 1.0;
  for (int k = 0; k < m; ++k) {
    const double a = k + 1 < m ? rest * std::clamp(u[k], 0.0, 1.0) : rest;
    rest -= a;
    if (a > 0.0) terms.push_back({a, std::max(0.0, mu[k])});
  }
  double sum = 0.0;
  for (const auto& t : terms) sum += t.weight;
  for (auto& t : terms) t.weight /= sum;
  return ExponentialSum(std::move(terms), "free in the fit");
}

std::vector<int> ForwardModel::poseIndices(int r) const {
  switch (spec(r).pattern) {
    case Acquisition::kFree:
    case Acquisition::kRotated: {
      std::vector<int> out = layout_.block(spec(r).name + "/rotation");
      for (int i : layout_.block(spec(r).name + "/position")) out.push_back(i);
      return out;
    }
    case Acquisition::kTranslated:
      return layout_.block(spec(r).name + "/axis");
    case Acquisition::kTurned:
    case Acquisition::kKnown:
      break;
  }
  return {};
}

std::vector<int> ForwardModel::jointIndices() const {
  std::vector<int> all = free_dims_;
  // A pose parameter the job's bounds fix (lower == upper: a part's axis of
  // symmetry, a height a line detector cannot see) is left where it is.
  for (int r = 0; r < radiographCount(); ++r)
    for (int i : poseIndices(r))
      if (layout_.isFree(i)) all.push_back(i);
  for (int i : materialIndices()) all.push_back(i);
  for (int i : detectorIndices())
    if (layout_.isFree(i)) all.push_back(i);
  return all;
}

std::vector<int> ForwardModel::leastSquaresIndices() const {
  std::vector<int> all = jointIndices();
  if (rate_scale_index_ >= 0) all.push_back(rate_scale_index_);
  return all;
}

Pose ForwardModel::pose(std::span<const double> theta, int radiograph) const {
  const RadiographSpec& s = spec(radiograph);
  // The hot path: the pose block's first index was found once, at construction
  // (rotation then position, or the axis: model.h).
  const double* p = theta.data() + pose_first_[static_cast<size_t>(radiograph)];
  switch (s.pattern) {
    case Acquisition::kFree:
    case Acquisition::kRotated: {
      Pose out = Pose::fromEulerDeg(Vec3(p[0], p[1], p[2]), Vec3::Zero());
      out.translation_mm = Vec3(p[3], p[4], p[5]) - out.rotation * centre_part_;
      return out;
    }
    case Acquisition::kTranslated: {
      Pose out = pose(theta, s.reference);
      out.translation_mm += s.distance_mm * axisFromAngles(p[0], p[1]);
      return out;
    }
    case Acquisition::kTurned:
      return machine().turntable->turn(pose(theta, s.reference), s.angle_deg);
    case Acquisition::kKnown:
      return s.known_pose;
  }
  return {};
}

}  // namespace xgauge
