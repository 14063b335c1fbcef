// The uncertainty budget from a fit's linearisation (private to measure/;
// the budget's definition and its components: xgauge/measure/uncertainty.h).
#pragma once

#include "least_squares.h"
#include "xgauge/measure/uncertainty.h"

#include <span>

namespace xgauge {

// The budget of every free dimension at the solution theta, from the
// Jacobian and residuals there (fit, over every radiograph) and one
// re-simulation per influence quantity.
UncertaintyBudget estimateUncertainty(ForwardModel& model, std::span<const double> theta,
                                      const LinearizedFit& fit);

}  // namespace xgauge
