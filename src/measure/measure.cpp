#include "xgauge/measure/measure.h"

#include "xgauge/core/progress.h"
#include "xgauge/measure/model.h"
#include "xgauge/optimize/minimize.h"

#include <spdlog/spdlog.h>

#include <Eigen/Dense>

#include <chrono>
#include <cmath>

namespace xgauge {

namespace {

// One optimisation over a subset of the parameters.
struct StagePlan {
  std::string name;
  Method method = Method::kBobyqa;
  std::vector<int> indices;      // parameters varied
  std::vector<int> radiographs;  // radiographs in the loss
  int level = 0;
  int samples = 1;
  int evaluations = 100;
  int sampling_points = 0;                     // uniform sampling
  std::vector<double> lower = {}, upper = {};  // optional narrower bounds for `indices`
  std::vector<double> step = {};               // optional initial steps for `indices`
};

class Runner {
 public:
  Runner(ForwardModel& model, std::vector<double>& theta, MeasurementResult& result, uint64_t seed)
      : model_(model), theta_(theta), result_(result), seed_(seed) {}

  void report(const StageReport& stage) {
    result_.stages.push_back(stage);
    result_.evaluations += stage.evaluations;
  }

  // Every point evaluated by the next run() goes into `record` (theta, loss).
  void recordInto(std::vector<std::pair<double, std::vector<double>>>* record) { record_ = record; }

  double run(const StagePlan& plan) {
    const auto start = std::chrono::steady_clock::now();
    Objective objective;
    for (size_t k = 0; k < plan.indices.size(); ++k) {
      const int i = plan.indices[k];
      objective.lower.push_back(plan.lower.empty() ? model_.lower()[static_cast<size_t>(i)]
                                                   : plan.lower[k]);
      objective.upper.push_back(plan.upper.empty() ? model_.upper()[static_cast<size_t>(i)]
                                                   : plan.upper[k]);
      objective.start.push_back(std::clamp(theta_[static_cast<size_t>(i)], objective.lower.back(),
                                           objective.upper.back()));
    }
    objective.initial_step = plan.step;
    for (size_t k = 0; k < objective.initial_step.size(); ++k)
      objective.initial_step[k] =
          std::min(objective.initial_step[k], 0.5 * (objective.upper[k] - objective.lower[k]));
    std::vector<double> trial = theta_;
    ProgressBar progress(plan.name, plan.method == Method::kUniformSampling
                                        ? plan.sampling_points + 1
                                        : plan.evaluations);
    objective.f = [&](std::span<const double> x) {
      for (size_t k = 0; k < plan.indices.size(); ++k)
        trial[static_cast<size_t>(plan.indices[k])] = x[k];
      progress.advance();
      const double value = model_.loss(trial, plan.level, plan.samples, plan.radiographs);
      if (record_) record_->push_back({value, trial});
      return value;
    };
    StageReport report;
    report.name = plan.name;
    report.method = std::string(methodName(plan.method));
    report.level = plan.level;
    report.samples = plan.samples;
    report.loss_before = model_.loss(theta_, plan.level, plan.samples, plan.radiographs);
    OptimizeOptions options;
    options.method = plan.method;
    options.max_evaluations =
        plan.method == Method::kUniformSampling ? plan.sampling_points + 1 : plan.evaluations;
    options.sampling_points = std::max(1, plan.sampling_points);
    options.seed = seed_;
    options.max_restarts = 2;
    const OptimizeResult r = minimize(objective, options);
    progress.finish();
    if (r.value <= report.loss_before)
      for (size_t k = 0; k < plan.indices.size(); ++k)
        theta_[static_cast<size_t>(plan.indices[k])] = r.x[k];
    report.loss_after = std::min(r.value, report.loss_before);
    report.evaluations = r.evaluations + 1;
    report.termination = r.message;
    report.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    spdlog::info("{}: loss {:.6g} -> {:.6g} in {} evaluations, {:.2f} s ({})", plan.name,
                 report.loss_before, report.loss_after, report.evaluations, report.seconds,
                 report.termination);
    result_.stages.push_back(report);
    result_.evaluations += report.evaluations;
    return report.loss_after;
  }

 private:
  ForwardModel& model_;
  std::vector<double>& theta_;
  MeasurementResult& result_;
  uint64_t seed_;
  std::vector<std::pair<double, std::vector<double>>>* record_ = nullptr;
};

// The `count` best recorded points that differ from each other by more than
// `separation` (relative to the bounds) in some varied coordinate.
std::vector<std::vector<double>> distinctBest(
    std::vector<std::pair<double, std::vector<double>>> record, const std::vector<int>& indices,
    const ForwardModel& model, size_t count, double separation) {
  std::sort(record.begin(), record.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<std::vector<double>> out;
  for (const auto& [value, theta] : record) {
    bool distinct = true;
    for (const auto& other : out) {
      double far = 0.0;
      for (int i : indices) {
        const double span =
            model.upper()[static_cast<size_t>(i)] - model.lower()[static_cast<size_t>(i)];
        far = std::max(
            far, std::abs(theta[static_cast<size_t>(i)] - other[static_cast<size_t>(i)]) / span);
      }
      distinct &= far > separation;
    }
    if (distinct) out.push_back(theta);
    if (out.size() == count) break;
  }
  return out;
}

// Absorption-weighted centroid of a radiograph's roi at `level`, in full-size
// continuous pixel coordinates.
Vec2 shadowCentroid(const PreparedRadiograph& r, int level) {
  const Image& image = r.levels[static_cast<size_t>(level)];
  const PixelRect roi = r.rois[static_cast<size_t>(level)];
  double sw = 0, su = 0, sv = 0;
  for (int y = roi.y; y < roi.bottom(); ++y)
    for (int x = roi.x; x < roi.right(); ++x) {
      const double w = std::max(0.0, 1.0 - static_cast<double>(image(x, y)));
      sw += w, su += w * (x + 0.5), sv += w * (y + 0.5);
    }
  const double s = static_cast<double>(1 << level);
  if (!(sw > 0)) return {(roi.x + 0.5 * roi.width) * s, (roi.y + 0.5 * roi.height) * s};
  return {su / sw * s, sv / sw * s};
}

std::vector<int> range(int first, int count) {
  std::vector<int> out;
  for (int i = 0; i < count; ++i) out.push_back(first + i);
  return out;
}

// Levenberg-Marquardt on the per-pixel residuals, for the final refinement:
// where a derivative-free method crawls along a narrow valley (depth against
// size against a translation's depth component), the Gauss-Newton step goes
// straight down it. Forward-difference Jacobian with small physical steps;
// bounds are kept by clamping. With `robust`, the L1 loss is minimised by
// iteratively reweighted least squares: weights 1 / max(|r|, a tenth of the
// median |r|), recomputed at every iteration.
StageReport refineLeastSquares(ForwardModel& model, std::vector<double>& theta,
                               const std::vector<int>& indices, const std::vector<int>& radiographs,
                               int level, int samples, int max_iterations, bool robust) {
  const auto start = std::chrono::steady_clock::now();
  StageReport report;
  report.name = robust ? "joint, reweighted least squares" : "joint, least squares";
  report.method = robust ? "levenberg_marquardt_irls" : "levenberg_marquardt";
  report.level = level;
  report.samples = samples;
  const size_t n = indices.size();
  std::vector<double> r, trial_r;
  std::vector<double> weight;
  auto reweight = [&](const std::vector<double>& v) {
    weight.assign(v.size(), 1.0);
    if (!robust || v.empty()) return;
    std::vector<double> magnitude(v.size());
    for (size_t m = 0; m < v.size(); ++m) magnitude[m] = std::abs(v[m]);
    std::nth_element(magnitude.begin(), magnitude.begin() + static_cast<ptrdiff_t>(v.size() / 2),
                     magnitude.end());
    const double floor = std::max(1e-30, 0.1 * magnitude[v.size() / 2]);
    for (size_t m = 0; m < v.size(); ++m) weight[m] = 1.0 / std::max(std::abs(v[m]), floor);
  };
  auto cost = [&](const std::vector<double>& v) {
    double c = 0.0;
    for (size_t m = 0; m < v.size(); ++m) c += weight[m] * v[m] * v[m];
    return c;
  };
  if (!model.residuals(theta, level, samples, radiographs, r)) {
    report.termination = "start point invalid";
    return report;
  }
  ++report.evaluations;
  reweight(r);
  double current = cost(r);
  report.loss_before = current;
  double lambda = 1e-3;
  Eigen::MatrixXd jacobian(static_cast<Eigen::Index>(r.size()), static_cast<Eigen::Index>(n));
  report.termination = "iteration limit";
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    // Jacobian by forward differences.
    for (size_t k = 0; k < n; ++k) {
      const auto i = static_cast<size_t>(indices[k]);
      const double h = model.kind(indices[k]) == ForwardModel::Kind::kDimension ? 2e-3 : 2e-3;
      std::vector<double> shifted = theta;
      shifted[i] = theta[i] + h <= model.upper()[i] ? theta[i] + h : theta[i] - h;
      const double step = shifted[i] - theta[i];
      if (!model.residuals(shifted, level, samples, radiographs, trial_r) ||
          trial_r.size() != r.size()) {
        report.termination = "jacobian at an invalid point";
        iteration = max_iterations;
        break;
      }
      ++report.evaluations;
      for (size_t m = 0; m < r.size(); ++m)
        jacobian(static_cast<Eigen::Index>(m), static_cast<Eigen::Index>(k)) =
            (trial_r[m] - r[m]) / step;
    }
    if (iteration >= max_iterations) break;
    const Eigen::Map<const Eigen::VectorXd> residual(r.data(), static_cast<Eigen::Index>(r.size()));
    const Eigen::Map<const Eigen::VectorXd> w(weight.data(),
                                              static_cast<Eigen::Index>(weight.size()));
    const Eigen::MatrixXd weighted = w.asDiagonal() * jacobian;
    const Eigen::MatrixXd normal = jacobian.transpose() * weighted;
    const Eigen::VectorXd gradient = weighted.transpose() * residual;
    bool improved = false;
    for (int attempt = 0; attempt < 10 && !improved; ++attempt) {
      Eigen::MatrixXd damped = normal;
      damped.diagonal() += lambda * normal.diagonal().cwiseMax(1e-12);
      const Eigen::VectorXd delta = damped.ldlt().solve(-gradient);
      std::vector<double> candidate = theta;
      for (size_t k = 0; k < n; ++k) {
        const auto i = static_cast<size_t>(indices[k]);
        candidate[i] = std::clamp(theta[i] + delta(static_cast<Eigen::Index>(k)), model.lower()[i],
                                  model.upper()[i]);
      }
      ++report.evaluations;
      if (model.residuals(candidate, level, samples, radiographs, trial_r) &&
          cost(trial_r) < current) {
        const double previous = current;
        theta = candidate, r = trial_r, current = cost(r);
        lambda = std::max(1e-9, lambda / 3.0);
        improved = true;
        const bool settled = previous - current < 1e-12 * previous;
        if (robust) reweight(r), current = cost(r);
        if (settled) {
          report.termination = "converged (relative decrease below 1e-12)";
          iteration = max_iterations;
        }
      } else {
        lambda *= 4.0;
      }
    }
    if (!improved) {
      report.termination = "converged (no decreasing step)";
      break;
    }
  }
  report.loss_after = current;
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  spdlog::info("{}: {} {:.6g} -> {:.6g} in {} evaluations, {:.2f} s ({})", report.name,
               robust ? "reweighted squared residuals" : "loss", report.loss_before,
               report.loss_after, report.evaluations, report.seconds, report.termination);
  return report;
}

// The first step of a joint stage for a kind of parameter, in its physical
// unit: what remains uncertain after the stages per radiograph.
double firstStep(ForwardModel::Kind kind) {
  switch (kind) {
    case ForwardModel::Kind::kDimension:
      return 0.3;  // mm
    case ForwardModel::Kind::kRotation:
      return 1.0;  // deg
    case ForwardModel::Kind::kPosition:
      return 1.0;  // mm
    case ForwardModel::Kind::kAxis:
      return 1.0;  // deg
    case ForwardModel::Kind::kMaterial:
      return 0.02;  // fraction, or 1/mm
  }
  return 1.0;
}

void planSchedule(ForwardModel& model, std::vector<double>& theta, Runner& runner, bool thesis,
                  const MeasureOptions& options) {
  const bool search_poses = options.search_poses;
  const Machine& machine = model.machine();
  const double d = machine.source_detector_distance_mm;
  const int coarse = model.levelForWidth(256);
  const int medium = model.levelForWidth(512);
  const auto& rads = model.radiographs();

  // 1-2. Each radiograph's pose alone, the part at its starting dimensions.
  for (int r = 0; search_poses && r < static_cast<int>(rads.size()); ++r) {
    const RadiographSpec& spec = rads[static_cast<size_t>(r)].spec;
    const std::vector<int> pose = model.poseIndices(r);
    if (pose.empty()) continue;
    const int p0 = pose.front();
    const std::vector<int> only{r};
    if (spec.pattern == Acquisition::kTranslated) {
      // The axis: from the shift of the shadow's centroid (default), or by
      // sampling the whole sphere (thesis).
      const int q = spec.reference;
      if (thesis) {
        runner.run({spec.name + ": axis search", Method::kUniformSampling, pose, only, coarse, 1, 0,
                    5000});
      } else {
        const Vec2 shift = shadowCentroid(rads[static_cast<size_t>(r)], coarse) -
                           shadowCentroid(rads[static_cast<size_t>(q)], coarse);
        const Pose ref = model.pose(theta, q);
        const Vec3 centre = ref.apply(model.referenceCentre());
        const double magnification = d / (d - centre.z());
        const double dx = shift.x() * machine.pitch_u_mm / magnification;
        const double dy = -shift.y() * machine.pitch_v_mm / magnification;
        const double m = spec.distance_mm;
        const double lateral = std::min(m, std::hypot(dx, dy));
        const double dz = std::sqrt(std::max(0.0, m * m - lateral * lateral));
        double best = HUGE_VAL;
        std::vector<double> best_theta = theta;
        for (double sign : {1.0, -1.0}) {
          const double el = std::asin(std::clamp(dy / m, -1.0, 1.0)) * kRadToDeg;
          const double az = std::atan2(sign * dz, dx) * kRadToDeg;
          std::vector<double> t = theta;
          t[static_cast<size_t>(p0)] = az;
          t[static_cast<size_t>(p0) + 1] = el;
          const double loss = model.loss(t, coarse, 1, only);
          if (loss < best) best = loss, best_theta = t;
        }
        theta = best_theta;
      }
      runner.run({spec.name + ": axis",
                  thesis ? Method::kNelderMead : Method::kBobyqa,
                  pose,
                  only,
                  thesis ? coarse : coarse,
                  1,
                  thesis ? 5000 : 120,
                  0,
                  {},
                  {},
                  {5.0, 5.0}});
      if (!thesis)
        runner.run({spec.name + ": axis, finer",
                    Method::kBobyqa,
                    pose,
                    only,
                    medium,
                    1,
                    80,
                    0,
                    {},
                    {},
                    {1.0, 1.0}});
      continue;
    }
    // free and rotated: 3-DOF global search of (ry, x, y), then 6-DOF.
    const std::vector<int> search{p0 + 1, p0 + 3, p0 + 4};
    StagePlan global{
        spec.name + ": pose search", Method::kUniformSampling, search, only, coarse, 1, 0,
        thesis ? 5000 : 150};
    if (!thesis) {
      // Around the shadow's centroid seen at the middle depth.
      const Vec2 c = shadowCentroid(rads[static_cast<size_t>(r)], coarse);
      const Vec3 p = machine.detectorPoint(c.x(), c.y());
      const double z = theta[static_cast<size_t>(p0) + 5];
      const double lambda = 1.0 - z / d;
      theta[static_cast<size_t>(p0) + 3] =
          std::clamp(lambda * p.x(), model.lower()[static_cast<size_t>(p0) + 3],
                     model.upper()[static_cast<size_t>(p0) + 3]);
      theta[static_cast<size_t>(p0) + 4] =
          std::clamp(lambda * p.y(), model.lower()[static_cast<size_t>(p0) + 4],
                     model.upper()[static_cast<size_t>(p0) + 4]);
      // The centroid of the absorption is near the projected centre: search a
      // window of a quarter of the part's size around it.
      const double window = 0.25 * model.partSizeMm();
      for (int k : {1, 3, 4}) {
        const double lo = model.lower()[static_cast<size_t>(p0 + k)],
                     hi = model.upper()[static_cast<size_t>(p0 + k)];
        const double half = k == 1 ? 0.5 * (hi - lo) : window;
        global.lower.push_back(
            std::max(lo, k == 1 ? lo : theta[static_cast<size_t>(p0 + k)] - half));
        global.upper.push_back(
            std::min(hi, k == 1 ? hi : theta[static_cast<size_t>(p0 + k)] + half));
      }
    }
    const std::vector<double> steps{2.0, 5.0, 2.0, 1.0, 1.0, 10.0};
    if (thesis) {
      runner.run(global);
      runner.run({spec.name + ": pose",
                  Method::kNelderMead,
                  pose,
                  only,
                  coarse,
                  1,
                  5000,
                  0,
                  {},
                  {},
                  steps});
    } else {
      // Multi-start: refine the best few distinct samples, keep the best.
      std::vector<std::pair<double, std::vector<double>>> record;
      runner.recordInto(&record);
      runner.run(global);
      runner.recordInto(nullptr);
      double best = HUGE_VAL;
      std::vector<double> best_theta = theta;
      const auto starts = distinctBest(record, search, model, 4, 0.05);
      for (size_t k = 0; k < starts.size(); ++k) {
        theta = starts[k];
        const double loss = runner.run({fmt::format("{}: pose from start {}", spec.name, k + 1),
                                        Method::kBobyqa,
                                        pose,
                                        only,
                                        coarse,
                                        1,
                                        150,
                                        0,
                                        {},
                                        {},
                                        steps});
        if (loss < best) best = loss, best_theta = theta;
      }
      theta = best_theta;
    }
    if (!thesis)
      runner.run({spec.name + ": pose, finer",
                  Method::kBobyqa,
                  pose,
                  only,
                  medium,
                  1,
                  200,
                  0,
                  {},
                  {},
                  {0.5, 1.0, 0.5, 0.2, 0.2, 2.0}});
  }

  // 3. Everything together, coarse to fine.
  std::vector<int> all = model.freeDimensionIndices();
  std::vector<int> every_radiograph = range(0, static_cast<int>(rads.size()));
  for (int r : every_radiograph)
    for (int i : model.poseIndices(r)) all.push_back(i);
  for (int i : model.materialIndices()) all.push_back(i);
  // First steps by kind of parameter, in physical units, shrinking level by
  // level: what remains uncertain after the previous stage.
  auto steps = [&](double scale) {
    std::vector<double> s;
    for (int i : all) {
      const auto index = static_cast<size_t>(i);
      const double step = firstStep(model.kind(i));
      s.push_back(std::min(scale * step, 0.5 * (model.upper()[index] - model.lower()[index])));
    }
    return s;
  };
  if (thesis) {
    runner.run(
        {"joint", Method::kNelderMead, all, every_radiograph, 0, 1, 5000, 0, {}, {}, steps(1.0)});
    return;
  }
  // Coarse to fine, up to 2048 px wide: beyond that the loss is dominated by
  // pixel noise and a 4096^2 stage costs more than it changes (measured:
  // 16 s for a loss change of 1e-4 relative). Where the images are small,
  // several steps share a level and act as restarts with smaller steps.
  struct Step {
    int width;
    int evaluations;
    double scale;
  };
  // Each stage searches a window of ten first steps around the estimate so far:
  // the optimiser works in coordinates scaled to its bounds, and bounds of
  // similar sensitivity keep its trust region well shaped.
  int finest = model.levelForWidth(2048);
  for (const Step s : {Step{512, 1200, 1.0}, Step{1024, 700, 0.3}, Step{2048, 300, 0.1}}) {
    if (!options.joint_search) break;
    const int level = model.levelForWidth(s.width);
    StagePlan plan{
        fmt::format("joint, {} px", rads.front().levels[static_cast<size_t>(level)].width()),
        Method::kBobyqa,
        all,
        every_radiograph,
        level,
        2,
        s.evaluations,
        0};
    plan.step = steps(s.scale);
    for (size_t k = 0; k < all.size(); ++k) {
      const auto i = static_cast<size_t>(all[k]);
      plan.lower.push_back(std::max(model.lower()[i], theta[i] - 10.0 * plan.step[k]));
      plan.upper.push_back(std::min(model.upper()[i], theta[i] + 10.0 * plan.step[k]));
    }
    runner.run(plan);
    finest = level;
  }
  // Finish by (reweighted) least squares on the residuals.
  runner.report(refineLeastSquares(model, theta, all, every_radiograph, finest, 2, 30,
                                   model.job().loss == "l1"));
}

}  // namespace

MeasurementResult measure(const MeasurementJob& job) {
  ForwardModel model(job);
  return measure(model, model.start());
}

MeasurementResult measure(ForwardModel& model, std::vector<double> theta,
                          const MeasureOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  const MeasurementJob& job = model.job();
  XG_CHECK(theta.size() == static_cast<size_t>(model.size()), "theta has the wrong size");
  MeasurementResult result;
  Runner runner(model, theta, result, job.seed);
  planSchedule(model, theta, runner, job.schedule == "thesis", options);

  // Final figures at full size.
  result.theta = theta;
  const auto& dims = model.part().dimensions();
  const auto free = model.freeDimensionIndices();
  for (size_t i = 0; i < dims.size(); ++i)
    result.dimensions.push_back(
        {dims[i].name, theta[i],
         std::find(free.begin(), free.end(), static_cast<int>(i)) != free.end(), dims[i].unit});
  for (int r = 0; r < static_cast<int>(model.radiographs().size()); ++r) {
    const int only[] = {r};
    const double loss = model.loss(theta, 0, 2, only);
    result.total_loss += loss;
    const auto& spec = model.radiographs()[static_cast<size_t>(r)].spec;
    result.radiographs.push_back(
        {spec.name, std::string(acquisitionName(spec.pattern)), model.pose(theta, r), loss});
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace xgauge
