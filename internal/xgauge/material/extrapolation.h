// How far a calibrated curve may be off beyond its calibrated range
// (docs/method.md, "The curve beyond its calibrated range"): the envelope of
// every non-negative sum of exponentials, rates at least the material's
// floor, that fits the calibration's table about as well as the best such
// sum does.
//
// A table of n values (x_i, T_i), each with the noise sigma, is fitted by
// T_a(x) = sum_j a_j exp(-mu_j x) over a fixed grid of rates mu_j (64, log-
// spaced from the floor, or 0 without one, to 10 / x_1), a_j >= 0, their sum
// free (the table's normalisation and thin end are not exact: a table that
// starts 7e-4 above the curve through I(0) = 1 would otherwise be refused by
// every sum). With chi2(a) = sum_i ((T_a(x_i) - T_i) / sigma)^2, a0 its
// minimum, k0 the positive weights there and s2 = max(1, chi2(a0) / (n - 2
// k0)) (the misfit the noise does not explain, Birge's ratio), the admitted
// sums are those with chi2(a) <= chi2(a0) + delta^2 s2 (delta = 2: about
// 95 % for one value). At a path x their values span [lo(x), hi(x)]: the
// largest and smallest c.a with c_j = exp(-mu_j x) subject to that bound,
// each found by bisection on the multiplier lambda of
// min chi2(a) - lambda (+-c).a, a >= 0 (Lawson and Hanson's active set with a
// linear term). The curve's own distance from them,
//   h(x) = max(hi(x) - I(x), I(x) - lo(x)),
// counts its own model's bias as well (a 4-term fit under-hardens beyond its
// table where a spectrum keeps hardening); e(x) = max(0, h(x) - h(L)) with L
// the table's longest path is what the range's own uncertainty (h(L), of the
// order of the table's noise) does not already cover.
#pragma once

#include "xgauge/material/exponential_sum.h"

#include <span>
#include <vector>

namespace xgauge {

struct ExtrapolationOptions {
  // The paths, as multiples of the table's longest path L, where e(x) is
  // found (the first must be 1).
  std::vector<double> factors = {1.0, 1.1, 1.25, 1.5, 1.75, 2.0, 2.5, 3.0};
  double delta = 2.0;  // the admitted chi2 rise, in (Birge-scaled) sigmas
  int rates = 64;      // of the grid
};

struct ExtrapolationEnvelope {
  std::vector<ExtrapolationPoint> points;  // (x, e(x)): ExponentialSum::setExtrapolation
  std::vector<double> lower, upper;        // lo(x), hi(x) at the same paths
  double chi2_min = 0.0;                   // chi2(a0)
  double birge = 1.0;                      // s2
  int support = 0;                         // k0
};

// The envelope of `curve` from its table (path_mm increasing, on the
// curve's path axis; transmission; the noise of one value, > 0) with every
// rate at least rate_floor_per_mm (0: none, a constant term admitted).
// Throws Error on a table of fewer than 4 values or a non-positive noise.
ExtrapolationEnvelope extrapolationEnvelope(std::span<const double> path_mm,
                                            std::span<const double> transmission, double noise,
                                            double rate_floor_per_mm, const ExponentialSum& curve,
                                            const ExtrapolationOptions& options = {});

}  // namespace xgauge
