// The self-checks of a fit (private to measure/; what they are:
// xgauge/measure/self_check.h).
#pragma once

#include "least_squares.h"
#include "xgauge/measure/self_check.h"
#include "xgauge/measure/tolerance.h"
#include "xgauge/measure/uncertainty.h"

#include <span>

namespace xgauge {

// Checks the solution theta of `model` from the fit's linearisation there
// (residuals over every radiograph at the fit's level); what `rule` makes a
// failure goes into SelfCheck::failures.
// `region_pixels` (optional) gets one flag per residual of the fit: 1 where
// the pixel belongs to a reported residual region.
SelfCheck checkMeasurement(ForwardModel& model, std::span<const double> theta,
                           const LinearizedFit& fit, const AcceptanceRule& rule,
                           std::vector<char>* region_pixels = nullptr);

// Why a dimension's U exceeds a third of its tolerance where the model
// discrepancy alone makes it so: U without the component "misfit" (the
// dimension's shift when the residual regions are left out, budget.h) would
// be at most T / 3. Names the strongest residual regions (as the report
// draws them); empty where the discrepancy is not the cause.
std::string discrepancyReason(const DimensionUncertainty& u, double coverage_factor,
                              const Tolerance& tolerance, const SelfCheck& check);

}  // namespace xgauge
