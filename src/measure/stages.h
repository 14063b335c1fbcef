// The stages a measurement schedule is made of (private to measure/): one
// optimisation over a named subset of the parameters (Runner), the final
// (reweighted) least squares, and the image measures the default schedule
// starts its pose searches from.
#pragma once

#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"
#include "xgauge/measure/schedule.h"
#include "xgauge/optimize/minimize.h"

#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace xgauge {

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

// Runs stages on one parameter vector, keeping a stage's result only when it
// does not increase the loss, and records each stage's report.
class Runner {
 public:
  // `progress`: a progress bar per stage (not for stages run side by side).
  // `on_stage` (may be empty) is called as each stage's report is added;
  // side runners (refineEach) get none: their reports reach it in order.
  Runner(ForwardModel& model, std::vector<double>& theta, MeasurementResult& result, uint64_t seed,
         bool progress = true, std::function<void(const StageReport&)> on_stage = {})
      : model_(model),
        theta_(theta),
        result_(result),
        seed_(seed),
        progress_(progress),
        on_stage_(std::move(on_stage)) {}

  uint64_t seed() const { return seed_; }

  void report(const StageReport& stage);
  // Every point evaluated by the next run() goes into `record` (loss, theta).
  void recordInto(std::vector<std::pair<double, std::vector<double>>>* record) { record_ = record; }
  // Runs the stage; returns the loss after it (+inf when no feasible point).
  double run(const StagePlan& plan);
  // Runs `plan`, named names[k], from each of `thetas` (refined in place)
  // side by side, each on a model of its own (its scratch is not shared): a
  // pose stage's renders are too small to keep two cores busy. Each one's
  // result is the same whichever thread runs it; their reports follow in
  // order. Returns each one's loss after it.
  std::vector<double> refineEach(std::vector<std::vector<double>>& thetas, StagePlan plan,
                                 const std::vector<std::string>& names);

 private:
  ForwardModel& model_;
  std::vector<double>& theta_;
  MeasurementResult& result_;
  uint64_t seed_;
  bool progress_;
  std::function<void(const StageReport&)> on_stage_;
  std::vector<std::pair<double, std::vector<double>>>* record_ = nullptr;
};

// The `count` best recorded points that differ from each other by more than
// `separation` (relative to the bounds) in some varied coordinate.
std::vector<std::vector<double>> distinctBest(
    std::vector<std::pair<double, std::vector<double>>> record, const std::vector<int>& indices,
    const ForwardModel& model, size_t count, double separation);

// Absorption-weighted centroid of a radiograph's roi at `level`, in full-size
// continuous pixel coordinates.
Vec2 shadowCentroid(const PreparedRadiograph& r, int level);

// Whether the model's radiographs are a line detector's (fewer than 8 rows
// on the least-squares stage's level).
bool onLineDetector(const ForwardModel& model, const Schedule& schedule);

// The schedule's least-squares stage as the fit and the budget run it for
// this model: on a line detector its Jacobian by forward differences
// wherever the schedule takes it from the render's derivatives (a row of
// 2 x 2 point samples across a cylinder's silhouette gave derivatives the
// trust region could not follow: measure_test's one-row cylinder ended at
// about 300 times the loss BOBYQA reaches, the diameter 0.05 mm off; the
// joint fit there is BOBYQA's, measure.cpp).
LeastSquaresStage leastSquaresStage(const ForwardModel& model, const Schedule& schedule);

}  // namespace xgauge
