// Fitting the exponential-sum material model (exponential_sum.h) to a
// measured transmission curve T(x), e.g. a wedge's intensity table (thesis
// 3.4, calibration (a); docs/method.md):
//
//   min over a, mu   sum_i w_i^2 (sum_k a_k exp(-mu_k x_i) - T_i)^2
//   subject to       a_k >= 0,  sum_k a_k = 1,  mu_k >= mu_min >= 0.
//
// Method: variable projection. For fixed mu the model is linear in a, and the
// equality-constrained non-negative least-squares problem in a is solved
// exactly (the full set first; if that has a negative weight, every support
// set is tried and the best feasible one kept). The projected residual is then
// a function of mu alone, minimised over log(mu) by BOBYQA (NLopt) from
// several deterministic starting points spread geometrically over the decay
// rates seen in the data, and once more from the best point found. The same
// inputs always give the same result.
//
// Terms whose optimal weight is exactly zero are dropped, so the result may
// have fewer terms than asked for (it then fits as well as any M-term model
// with those mu). Terms are returned sorted by increasing mu.
#pragma once

#include "xgauge/material/exponential_sum.h"

#include <span>
#include <vector>

namespace xgauge {

struct ExponentialFitOptions {
  enum class Weighting {
    // w_i = 1: least squares in transmission.
    kUniform,
    // w_i = 1 / T_i: least squares in relative transmission error. A
    // transmission error dI at path x moves the path length that a pixel
    // implies by dI / |I'(x)| ~ dI / (mu_eff T), so weighting by 1 / T keeps
    // the path-length error (what sets the measured dimensions) even across
    // a radiograph whose transmission spans 1 .. 0.05; uniform weighting lets
    // the relative error at T = 0.05 grow twenty-fold.
    kRelative,
  };
  Weighting weighting = Weighting::kRelative;

  // With a free amplitude the weights are only required to be >= 0; their
  // sum A = I(0) is fitted as well. That is the model for a curve whose path
  // axis may be offset, such as a wedge's intensity table whose thin end is
  // not exactly 0 mm (thesis 3.4a): eq. 3.7 (shiftAndScale below) then moves
  // the axis so that I(0) = 1. Use fitExponentialTerms for it.
  bool free_amplitude = false;

  // Largest transmission accepted in the data. A table computed from a model
  // never exceeds 1 (beyond rounding); one measured from radiographs may,
  // by its noise, near x = 0: raise this for measured data.
  double max_transmission = 1.0 + 1e-9;

  // Lower bound of every rate mu_k (1/mm), e.g. attenuationFloorPerMm: the
  // material's attenuation at the tube's highest photon energy, below which
  // no rate of a physical curve lies. 0: rates only >= 0 (a rate that makes
  // its term constant over the data is then returned as exactly 0, and the
  // curve levels off beyond the data).
  double min_mu_per_mm = 0.0;

  // Budget of objective evaluations for each local search (each start and
  // the final polish). Must be >= 100.
  int max_evaluations_per_start = 3000;

  // Throws Error on an invalid field.
  void validate() const;
};

// How well the result fits the data; residuals r_i = I(x_i) - T_i.
struct ExponentialFitReport {
  double rms_residual = 0.0;           // sqrt(mean r_i^2)
  double max_abs_residual = 0.0;       // max |r_i|
  double max_relative_residual = 0.0;  // max |r_i| / T_i
  int terms_used = 0;                  // terms in the result (<= terms asked for)
  int evaluations = 0;                 // objective evaluations over all starts
  int starts = 0;                      // local searches run (including the polish)
};

// Fits `terms` (1 to 8) exponentials to T(x). path_mm must be finite, >= 0
// and strictly increasing; transmission must be finite and in (0, 1 + 1e-9];
// both the same size, with at least max(2, 2 * terms - 1) points (the free
// parameters). Throws Error naming the offending input otherwise. `report`,
// if given, receives the residuals of the returned model.
ExponentialSum fitExponentialSum(std::span<const double> path_mm,
                                 std::span<const double> transmission, int terms,
                                 const ExponentialFitOptions& options = {},
                                 ExponentialFitReport* report = nullptr);

// The general fit: with options.free_amplitude the weights' sum is free
// (and may exceed 1); otherwise it is 1, as in fitExponentialSum. Terms with
// positive weight, sorted by increasing mu.
std::vector<ExponentialTerm> fitExponentialTerms(std::span<const double> path_mm,
                                                 std::span<const double> transmission, int terms,
                                                 const ExponentialFitOptions& options = {},
                                                 ExponentialFitReport* report = nullptr);

// Thesis eq. 3.7 (docs/method.md), the shift and scale of a wedge fit I(x) = sum_k a_k
// exp(-mu_k x) whose sum of weights need not be 1: find x0 with I(x0) = 1
// (x0 < 0 when the thin end of the wedge was thicker than the 0 mm it was
// taken for), then
//   I*(x) = I(x (x_max - x0) / x_max + x0),
// so that I*(0) = 1 and I*(x_max) = I(x_max). I* is again an exponential sum:
// a*_k = a_k exp(-mu_k x0), mu*_k = mu_k (x_max - x0) / x_max, and its weights
// sum to I(x0) = 1 (renormalised to remove rounding). `x0_out`, if given,
// receives x0. Throws Error if x_max is not > 0, a term is invalid (a_k <= 0,
// mu_k < 0) or no x0 < x_max exists (I(x_max) >= 1, or all mu_k = 0).
ExponentialSum shiftAndScale(const std::vector<ExponentialTerm>& fitted, double x_max_mm,
                             double* x0_out = nullptr);

// Residuals of any model against a curve (fields rms, max abs and max
// relative; the rest left 0). Same input checks as fitExponentialSum.
ExponentialFitReport exponentialFitResiduals(const ExponentialSum& model,
                                             std::span<const double> path_mm,
                                             std::span<const double> transmission);

}  // namespace xgauge
