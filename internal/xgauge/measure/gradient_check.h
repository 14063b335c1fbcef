// The fit's Jacobian checked against central differences of its residuals,
// the way Ceres's GradientChecker probes a cost function: for anyone who
// changes the forward model (a new pattern, a scatter form, a part model)
// and for the tests. It compares ForwardModel::residualsAndJacobian with
// (r(theta + h e_k) - r(theta - h e_k)) / 2h from ForwardModel::residuals.
#pragma once

#include "xgauge/measure/model.h"
#include "xgauge/xray/derivatives.h"

#include <span>
#include <vector>

namespace xgauge {

struct ModelGradientOptions {
  int level = 0;    // pyramid level of the residuals
  int samples = 2;  // samples per pixel axis (the render with derivatives uses them too)
  // Step per checked parameter (mm, deg or the material's units); empty:
  // kDefaultStep each. Large against the float images' rounding (about 1e-5
  // of a residual), small against a pixel.
  std::vector<double> steps;
  static constexpr double kDefaultStep = 4e-3;
  // A residual is well conditioned when the differences with steps h and
  // h / 2 agree to this fraction of the column's largest: elsewhere a sample
  // met an edge within the step and no finite difference tells its
  // derivative.
  double agreement = 1e-3;
};

// Checks d r / d theta[indices[k]] over `radiographs` at `theta`, one column
// per index (GradientColumn: its scale, worst and norm errors over the well
// conditioned residuals, how many were left out). Throws Error when theta, or
// theta moved by a step, cannot be simulated. The model's edge refinement is
// switched off during the check (the render with derivatives does not
// refine) and restored after.
GradientCheck checkModelGradients(ForwardModel& model, std::span<const double> theta,
                                  std::span<const int> indices, std::span<const int> radiographs,
                                  const ModelGradientOptions& options = {});

}  // namespace xgauge
