// The self-checks of a fit (private to measure/; what they are:
// xgauge/measure/self_check.h).
#pragma once

#include "least_squares.h"
#include "xgauge/measure/self_check.h"

#include <span>

namespace xgauge {

// Checks the solution theta of `model` from the fit's linearisation there
// (residuals over every radiograph at the fit's level); what `rule` makes a
// failure goes into SelfCheck::failures.
SelfCheck checkMeasurement(ForwardModel& model, std::span<const double> theta,
                           const LinearizedFit& fit, const AcceptanceRule& rule);

}  // namespace xgauge
