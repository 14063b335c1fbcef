#include "stages.h"

#include "xgauge/core/progress.h"

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>

namespace xgauge {

void Runner::report(const StageReport& stage) {
  result_.stages.push_back(stage);
  result_.evaluations += stage.evaluations;
  if (on_stage_) on_stage_(stage);
}

namespace {

// `plan` without the parameters the job's bounds fix (lower == upper).
StagePlan withoutFixed(const StagePlan& plan, const ForwardModel& model) {
  StagePlan out = plan;
  out.indices.clear(), out.lower.clear(), out.upper.clear(), out.step.clear();
  for (size_t k = 0; k < plan.indices.size(); ++k) {
    if (!model.parameters().isFree(plan.indices[k])) continue;
    out.indices.push_back(plan.indices[k]);
    if (!plan.lower.empty()) out.lower.push_back(plan.lower[k]), out.upper.push_back(plan.upper[k]);
    if (!plan.step.empty()) out.step.push_back(plan.step[k]);
  }
  return out;
}

}  // namespace

double Runner::run(const StagePlan& given) {
  const auto start = std::chrono::steady_clock::now();
  const StagePlan plan = withoutFixed(given, model_);
  if (plan.indices.empty())
    return model_.loss(theta_, plan.level, plan.samples, plan.radiographs)
        .value_or(std::numeric_limits<double>::infinity());
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
  std::optional<ProgressBar> progress;
  if (progress_)
    progress.emplace(plan.name, plan.method == Method::kUniformSampling ? plan.sampling_points + 1
                                                                        : plan.evaluations);
  StageReport report;
  objective.f = [&](std::span<const double> x) {
    for (size_t k = 0; k < plan.indices.size(); ++k)
      trial[static_cast<size_t>(plan.indices[k])] = x[k];
    if (progress) progress->advance();
    // An infeasible point is +inf for the optimiser (optimize/minimize.h).
    const double value = model_.loss(trial, plan.level, plan.samples, plan.radiographs)
                             .value_or(std::numeric_limits<double>::infinity());
    if (record_) record_->push_back({value, trial});
    report.trace.push_back(value);
    return value;
  };
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
  if (progress) progress->finish();
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
  this->report(report);
  return report.loss_after;
}

std::vector<double> Runner::refineEach(std::vector<std::vector<double>>& thetas, StagePlan plan,
                                       const std::vector<std::string>& names) {
  XG_CHECK(names.size() == thetas.size(), "a name for each start");
  std::vector<MeasurementResult> reports(thetas.size());
  std::vector<double> losses(thetas.size(), std::numeric_limits<double>::infinity());
  tbb::parallel_for(size_t{0}, thetas.size(), [&](size_t k) {
    ForwardModel own = model_;
    Runner side(own, thetas[k], reports[k], seed_, /*progress=*/false);
    StagePlan named = plan;
    named.name = names[k];
    losses[k] = side.run(named);
  });
  for (const MeasurementResult& one : reports)
    for (const StageReport& stage : one.stages) report(stage);
  return losses;
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

namespace {
constexpr int kLineDetectorRows = 8;
}  // namespace

int leastSquaresLevel(const ForwardModel& model, const Schedule& schedule) {
  const LeastSquaresStage& ls = schedule.least_squares;
  int level = model.levelForWidth(ls.min_width_px);
  const auto narrowest = [&](int l) {
    int side = std::numeric_limits<int>::max();
    for (int r = 0; r < model.radiographCount(); ++r) {
      const PixelRect& roi = model.radiograph(r).rois[static_cast<size_t>(l)];
      side = std::min(side, std::min(roi.width, roi.height));
    }
    return side;
  };
  // (A line detector's radiographs have one level: inputs.cpp builds levels
  // while both sides keep 64 px.)
  while (level > 0 && narrowest(level) < ls.min_roi_px) --level;
  return level;
}

bool onLineDetector(const ForwardModel& model, const Schedule& schedule) {
  return model.radiograph(0)
             .levels[static_cast<size_t>(model.levelForWidth(schedule.least_squares.min_width_px))]
             .height() < kLineDetectorRows;
}

LeastSquaresStage leastSquaresStage(const ForwardModel& model, const Schedule& schedule) {
  LeastSquaresStage stage = schedule.least_squares;
  if (onLineDetector(model, schedule)) stage.render_derivatives = false;
  return stage;
}

}  // namespace xgauge
