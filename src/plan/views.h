// The candidate views simulated once, and a set of them as the measurement
// would take it: its job, its patterns, its model's parameters at the
// nominal part (private to plan/).
#pragma once

#include "xgauge/measure/model.h"
#include "xgauge/measure/prediction.h"
#include "xgauge/plan/plan.h"

#include <memory>
#include <vector>

namespace xgauge::plan_internal {

// How a view of a set is taken relative to the set's first: moved by the
// stage alone (translated), turned by the turntable alone (turned), or
// placed anew (free).
struct Relation {
  Acquisition pattern = Acquisition::kFree;
  double distance_mm = 0.0;    // translated
  Vec3 direction = Vec3::Zero();  // translated: unit, from the first view's pose to this one's
  double angle_deg = 0.0;      // turned
};
Relation relationOf(const PlanJob& job, int first, int view);

// The measurement job of a set: the plan's job with one radiograph per view
// (image "<view>.tif", its white region, pattern and reference).
nlohmann::json measurementJobFrom(const PlanJob& job, const std::vector<int>& views,
                                  const std::vector<PixelRect>& white);

// A view simulated at the nominal part with the shot's noise, prepared as
// the measurement prepares a radiograph, and its share of the budget's
// linearisation as a one-view measurement with a free pose.
struct SimulatedView {
  std::shared_ptr<const PreparedRadiograph> radiograph;
  PixelRect white_region;
  ViewInformation information;
  Image image;  // the noisy normalized radiograph, full size (for the report)
  double longest_path_mm = 0.0;  // through the nominal part, at a pixel's centre
};
SimulatedView simulateView(const PlanJob& job, int view);

// The measurement inputs of a set (the plan's, with the set's job and the
// views' radiographs).
MeasurementInputs inputsFor(const PlanJob& job, const std::vector<int>& views,
                            const std::vector<SimulatedView>& simulated);

// The model's parameters at the nominal part with every view where the plan
// placed it (the translated views' axis along the stage's).
std::vector<double> nominalTheta(const PlanJob& job, const ForwardModel& model,
                                 const std::vector<int>& views);

}  // namespace xgauge::plan_internal
