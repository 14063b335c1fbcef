// The uncertainty budget from a fit's linearisation (private to measure/;
// the budget's definition and its components: xgauge/measure/uncertainty.h).
#pragma once

#include "least_squares.h"
#include "xgauge/measure/self_check.h"
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

// The curve beyond its calibrated range (budget_extrapolation.cpp): where
// the material has an extrapolation envelope e(x) (ExponentialSum::
// extrapolation) and pixels of the fit see paths through the part beyond
// its start, each identifiable dimension's linearised shift with those
// pixels moved by e(path), over sqrt(3) (rectangular), becomes a component
// "material: curve beyond its calibrated range", and u_c and U grow by it.
// Nothing where no path goes beyond.
// `check` is the self-checks' of the same fit (checkMeasurement, checks.h):
// its radiographs' longest paths say which need their paths rendered again.
void addExtrapolationTerm(ForwardModel& model, std::span<const double> theta,
                          const LinearizedFit& fit, const SelfCheck& check,
                          UncertaintyBudget& budget);

}  // namespace xgauge
