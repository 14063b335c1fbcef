// The material curve a calibration ends with: exponential sums with M = 1, 2,
// ... terms fitted to a measured table of (path length, intensity), the
// smallest M that fits within the noise chosen, and the figures and plot that
// show the work (thesis Figure 5.8, docs/method.md: data, fitted curve, residual).
#pragma once

#include "xgauge/material/exponential_fit.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <functional>
#include <span>
#include <string>
#include <vector>

namespace xgauge {

struct TermsFit {
  int terms = 0;                        // asked for
  std::vector<ExponentialTerm> fitted;  // positive weights, sorted by mu
  ExponentialFitReport report;
};

struct CurveFit {
  std::vector<TermsFit> fits;  // M = 1 .. max_terms
  size_t chosen = 0;           // index into fits
  std::string choice;          // why that one, in words
  const TermsFit& best() const { return fits[chosen]; }
};

// Fits 1 .. max_terms (1 to 4) exponentials to the table (relative
// weighting; a free amplitude for a wedge whose thin end is not at 0 mm) and
// picks the smallest M whose rms residual is at most 1.25 x `noise` (the
// noise of one table value); if none is, the smallest M whose rms residual is
// within 10 % of the best M's. Throws Error naming `what` if the chosen fit
// does not converge to the data: a residual above 5 % of the intensity
// somewhere, which an exponential sum through a real attenuation curve never
// needs (wrong rows, wrong white region, or not a ramp). With `tried`, the
// fits made so far are left there when it throws (a failed calibration's
// diagnostic).
CurveFit fitCurve(std::span<const double> path_mm, std::span<const double> transmission,
                  int max_terms, double noise, bool free_amplitude, const std::string& what,
                  CurveFit* tried = nullptr);

nlohmann::json toJson(const CurveFit& fit);

// A tabulated curve (a simulated dataset's true transmission, DatasetTruth),
// interpolated linearly; empty when there is none.
struct TrueCurve {
  std::vector<double> path_mm, transmission;
  double operator()(double x) const;
  bool empty() const { return path_mm.empty(); }
};

// The largest |a(x) - b(x)| over [0, max_path_mm] in 0.01 mm steps, and where.
struct CurveDeviation {
  double max_abs = 0.0;
  double at_mm = 0.0;
};
CurveDeviation curveDeviation(const std::function<double(double)>& a,
                              const std::function<double(double)>& b, double max_path_mm);

}  // namespace xgauge
