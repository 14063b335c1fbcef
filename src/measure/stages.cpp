#include "stages.h"

#include "xgauge/core/progress.h"

#include <spdlog/spdlog.h>

#include <Eigen/Dense>

#include <chrono>
#include <cmath>
#include <limits>

namespace xgauge {

void Runner::report(const StageReport& stage) {
  result_.stages.push_back(stage);
  result_.evaluations += stage.evaluations;
}

double Runner::run(const StagePlan& plan) {
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
    // An infeasible point is +inf for the optimiser (optimize/minimize.h).
    const double value = model_.loss(trial, plan.level, plan.samples, plan.radiographs)
                             .value_or(std::numeric_limits<double>::infinity());
    if (record_) record_->push_back({value, trial});
    return value;
  };
  StageReport report;
  report.name = plan.name;
  report.method = std::string(methodName(plan.method));
  report.level = plan.level;
  report.samples = plan.samples;
  report.loss_before = model_.loss(theta_, plan.level, plan.samples, plan.radiographs)
                           .value_or(std::numeric_limits<double>::infinity());
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
      const double h = 2e-3;  // mm or deg: small against the tolerances, large against noise
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

}  // namespace xgauge
