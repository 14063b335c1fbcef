// The material curve a calibration ends with: exponential sums with M = 1, 2,
// ... terms fitted to a measured table of (path length, intensity), the
// smallest M that fits within the noise chosen, and the figures and plot that
// show the work (thesis Figure 5.8, docs/method.md: data, fitted curve, residual).
#pragma once

#include "xgauge/core/config.h"
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

// The least attenuation a physical curve can have (docs/method.md,
// "Physically sound curves"): the material's attenuation over the tube's
// spectrum at its weakest (attenuationFloorPerMm). Calibration job key
// "rate_floor": {"compound": formula or NIST name (xraylib),
// "density_g_cm3": rho, "tube_kv": the tube's voltage}.
struct RateFloor {
  std::string compound;
  double density_g_cm3 = 0.0;
  double tube_kv = 0.0;
  double per_mm = 0.0;  // the floor itself

  static RateFloor fromConfig(const ConfigNode& node);
  nlohmann::json toJson() const;
};

struct CurveOptions {
  int max_terms = 4;             // 1 to 4
  double noise = 0.0;            // of one table value
  bool free_amplitude = false;   // a wedge whose thin end is not at 0 mm
  double rate_floor_per_mm = 0;  // every rate at least this (RateFloor); 0: none
  // The largest residual relative to the intensity a fit may leave; beyond
  // it fitCurve refuses. A provisional curve (a known-part calibration's
  // rounds, which a joint fit of poses and material follows) may allow more.
  double max_relative_residual = 0.05;
};

struct CurveFit {
  std::vector<TermsFit> fits;  // M = 1 .. max_terms
  size_t chosen = 0;           // index into fits
  std::string choice;          // why that one, in words
  double rate_floor_per_mm = 0.0;
  size_t points = 0;   // table values fitted
  double noise = 0.0;  // of one of them
  const TermsFit& best() const { return fits[chosen]; }

  // The standard uncertainty of the chosen curve that its table shows: the
  // noise carried into the fitted curve (noise sqrt(p / n) for p free
  // parameters and n table values, the rms standard deviation of a linear
  // least-squares fit's values) combined with the misfit the noise does not
  // explain (sqrt(max(0, rms^2 - noise^2))). What the table cannot show
  // (its paths' errors, the scatter taken out) a calibration adds by
  // propagation.
  double tableUncertainty() const;
};

// Fits 1 .. max_terms exponentials to the table (relative weighting; every
// rate at least the floor) and picks the smallest M whose rms residual is at
// most 1.25 x the noise; if none is, the smallest M whose rms residual is
// within 10 % of the best M's. Throws Error naming `what` if the chosen fit
// does not converge to the data: a residual above 5 % of the intensity
// somewhere, which an exponential sum through a real attenuation curve never
// needs (wrong rows, wrong white region, or not a ramp). With `tried`, the
// fits made so far are left there when it throws (a failed calibration's
// diagnostic).
CurveFit fitCurve(std::span<const double> path_mm, std::span<const double> transmission,
                  const CurveOptions& options, const std::string& what, CurveFit* tried = nullptr);

nlohmann::json toJson(const CurveFit& fit);

// The curve's freedom beyond its table (material/extrapolation.h; docs/
// method.md, "The curve beyond its calibrated range"), from the table it
// was fitted to (on the curve's own path axis) with the fit's noise and
// rate floor, set on `material` (ExponentialSum::setExtrapolation). A fit
// without a noise leaves the material without one.
void addExtrapolation(ExponentialSum& material, std::span<const double> path_mm,
                      std::span<const double> transmission, const CurveFit& fit);

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
// Its largest |a(x) - b(x)| for two materials.
double largestDifference(const ExponentialSum& a, const ExponentialSum& b, double max_path_mm);

}  // namespace xgauge
