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

// The misfit term (budget_misfit.cpp): where the self-checks found residual
// regions (region_pixels[i] for fit.residuals(i)), each identifiable
// dimension's shift when their pixels are left out of the linearised fit
// becomes a component "misfit" of its budget, and u_c and U grow by it.
void addMisfitTerm(const ForwardModel& model, const LinearizedFit& fit,
                   const std::vector<char>& region_pixels, UncertaintyBudget& budget);

}  // namespace xgauge
