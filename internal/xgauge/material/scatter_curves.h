// How a wedge-calibrated curve moves with the detector scatter its
// calibration removed. The calibration reads the curve from a radiograph
// with the scatter taken off; a measurement that takes the same scatter
// from the material file takes the same scatter off its own radiographs. An
// error in that scatter moves both the curve and the measurement's forward
// model, and the two largely cancel: counted as independent components (the
// curve's uncertainty from the scatter, then the measurement's own scatter
// components), a 12 mm thickness carried a U of 0.45 mm for an error of
// 0.005. With these curves the budget moves the scatter and the curve
// together (measure/budget.cpp).
//
// In material.json, under "scatter" (docs/formats.md):
//   "curve_moves": {"transmission_uncertainty_besides": u,
//                   "weight_plus_u": {"terms": [...]},
//                   "sigma_mm_plus_u": {"terms": [...]},
//                   "equivalent_end": {"terms": [...]},
//                   "kernel_choice": {"terms": [...]}}
#pragma once

#include "xgauge/core/config.h"
#include "xgauge/material/exponential_sum.h"

#include <optional>

namespace xgauge {

struct ScatterCurves {
  // The curve calibrated with the scatter's weight (width) moved by its
  // standard uncertainty; absent when the calibration did not move it.
  std::optional<ExponentialSum> weight_plus_u, sigma_plus_u;
  // The curve calibrated with the halo at its kernel's equivalent_end, or
  // its kernel_choice (image/scatter.h), where the scatter has them.
  std::optional<ExponentialSum> equivalent_end, kernel_choice;
  // The curve's standard uncertainty from everything but those.
  double transmission_uncertainty_besides = 0.0;

  nlohmann::json toJson() const;
  // Reads the "curve_moves" object; throws naming the key.
  static ScatterCurves fromConfig(const ConfigNode& node);
};

}  // namespace xgauge
