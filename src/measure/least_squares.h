// The final least-squares stage of a measurement on Ceres Solver (private to
// measure/): per-pixel residuals of every radiograph, bounds on every
// parameter, and the Jacobian at the solution for the uncertainty budget
// (measure/uncertainty.h).
#pragma once

#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"

#include <Eigen/Dense>

#include <vector>

namespace xgauge {

// What the robust loss of a least-squares stage does with the residuals of
// one radiograph: Huber's loss with threshold `threshold` (in residual units;
// +inf = plain least squares). Each radiograph has its own, since each one's
// residuals are scaled by 1 / sqrt(its pixel count).
struct ResidualSegment {
  int radiograph = 0;
  PixelRect roi;  // pixels of the level, in the residual vector's order (rows)
  size_t first = 0;
  double threshold = 0.0;
};

// The residuals and their Jacobian at one point.
struct LinearizedFit {
  std::vector<int> indices;  // parameters (columns of jacobian)
  std::vector<ResidualSegment> segments;
  int level = 0, samples = 1;
  Eigen::VectorXd residuals;  // simulated - measured, scaled as ForwardModel::residuals
  Eigen::MatrixXd jacobian;   // d residual / d theta[indices[k]]
  // Huber's psi(r) / r per residual: 1 inside the threshold, threshold / |r| beyond.
  Eigen::VectorXd weights() const;
};

// The segments and thresholds of the radiographs at `level`: `robust` sets
// each threshold to 1.345 robust sigmas (1.4826 * median |r|) of the
// residuals at theta (at least 1e-4 in intensity, so that a noise-free
// simulation is fitted by plain least squares), the usual 95 %-efficient
// choice for Gaussian noise (Huber 1981), which keeps a dust speck or a
// defect from pulling the fit.
std::vector<ResidualSegment> residualSegments(ForwardModel& model, std::span<const double> theta,
                                              std::span<const int> radiographs, int level,
                                              int samples, bool robust);

// The residuals at theta and their Jacobian from the render with
// derivatives (ForwardModel::residualsAndJacobian). Its columns are exact
// for the sampled image, so a parameter combination the radiographs cannot
// see (two edges that move with the part) gives exactly dependent columns.
// Central differences with steps that moved the outline by 0.2 pixels came
// before: their columns carried the kinks of samples crossing edges within
// the step, and an exact degeneracy showed as a direction with a small but
// non-zero eigenvalue. False where theta cannot be simulated.
bool linearize(ForwardModel& model, std::span<const double> theta, const std::vector<int>& indices,
               std::vector<ResidualSegment> segments, int level, int samples, LinearizedFit& out);

// Gauss-Newton / Levenberg-Marquardt (Ceres' trust region with bounds) on the
// per-pixel residuals of `radiographs` over `indices`, with the Jacobian of
// the render with derivatives (ForwardModel::residualsAndJacobian), from
// theta; theta is
// updated in place when the loss decreases. The robust loss is Huber's (see
// residualSegments), applied per pixel inside the one residual block by
// taking the square root of the loss: r -> sign(r) sqrt(2 a |r| - a^2)
// beyond the threshold a, whose squared sum is Huber's loss and whose
// Gauss-Newton step is that of the reweighted least squares.
// `quiet`: no progress bar and no log line (a re-solve inside the budget);
// `label` starts the stage's name.
StageReport solveLeastSquares(ForwardModel& model, std::vector<double>& theta,
                              const std::vector<int>& indices, const std::vector<int>& radiographs,
                              int level, int samples, int max_iterations, bool robust,
                              bool quiet = false, std::string_view label = "joint");

}  // namespace xgauge
