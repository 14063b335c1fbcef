// The final least-squares stage of a measurement on Ceres Solver (private to
// measure/): per-pixel residuals of every radiograph, bounds on every
// parameter, and the Jacobian at the solution for the uncertainty budget
// (measure/uncertainty.h).
#pragma once

#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"

#include <Eigen/Dense>

#include <optional>
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
  // The residuals' robust scale at the start (1.4826 median |r|, in
  // residual units, at least kNoiseFloor unscaled); 0 where not estimated.
  double scale = 0.0;
};

// The prior of the material's in-situ rate scale (ForwardModel::
// rateScaleIndex) as one more residual, lambda * e: with every radiograph's
// residuals scaled by 1 / sqrt(its pixels), a pixel's squared residual
// weighs sigma^2 / pixels of its likelihood, so lambda = tau / u with tau^2
// the mean over the radiographs of scale^2 and u the prior's standard
// uncertainty. (The pixels are taken as independent here; their correlation
// makes the data count for less than this, which the budget's sandwich
// accounts for and the fit does not need to.)
struct RateScalePrior {
  int column = -1;  // of the rate scale among a stage's parameters
  double lambda = 0.0;
};
// The prior for a stage over `indices`; nullopt when the rate scale is not
// among them.
std::optional<RateScalePrior> rateScalePrior(const ForwardModel& model,
                                             const std::vector<int>& indices,
                                             const std::vector<ResidualSegment>& segments);

// The residuals and their Jacobian by central differences, at one point.
struct LinearizedFit {
  std::vector<int> indices;  // parameters (columns of jacobian)
  std::vector<ResidualSegment> segments;
  int level = 0, samples = 1;
  Eigen::VectorXd residuals;  // simulated - measured, scaled as ForwardModel::residuals
  Eigen::MatrixXd jacobian;   // d residual / d theta[indices[k]]
  std::vector<double> steps;  // the step of each column's difference
  std::optional<RateScalePrior> prior;  // a row lambda e_column besides the pixels'
  // Huber's psi(r) / r per residual: 1 inside the threshold, threshold / |r| beyond.
  Eigen::VectorXd weights() const;
};

// The segments and thresholds of the radiographs at `level`, from
// `residuals`, theirs at theta (ForwardModel::residuals over `radiographs`):
// `robust` sets each threshold to 1.345 robust sigmas (1.4826 * median |r|)
// of them (at least 1e-4 in intensity, so that a noise-free simulation is
// fitted by plain least squares), the usual 95 %-efficient choice for
// Gaussian noise (Huber 1981), which keeps a dust speck or a defect from
// pulling the fit. The robust sigma is the segment's scale, estimated when
// `robust` or when the model refines the material (its prior is weighed by
// it), and left at 0 (the thresholds at +inf) when `residuals` do not
// cover the segments.
std::vector<ResidualSegment> residualSegments(const ForwardModel& model,
                                              std::span<const int> radiographs, int level,
                                              std::span<const double> residuals, bool robust);

// The residuals at theta and their Jacobian by central differences
// (one-sided at a bound), each parameter's step chosen so that the part's
// projected outline moves by about 0.2 pixels of the level: the sample rays
// an edge crosses (jumps of the rendered image) then average out along the
// edge while the image is still linear in the step. With one step for all
// (2e-3 mm or deg), a depth or an angle moved the outline by a few
// thousandths of a pixel, its column came out as a handful of jumps, and the
// budget of a cuboid traded the pose for the sizes (measured: a 0.5 mm
// source-detector distance "moved" the sides by 5 um where a re-solve moves
// them by none). The render's exact derivatives (xray/derivatives.h) are not
// used here: a wall seen along the beam changes the sampled image only in a
// strip of samples, and where the strip is narrower than the sample spacing
// and holds none, the exact derivative of the edge's position is zero (a
// single face-on view of a box then made its width look undetermined). A
// step of 0.2 pixels lets the strip cross samples. False where theta or a
// step cannot be simulated.
// A column whose parameter moves the part of only some radiographs (the
// pose of a radiograph whose part no other pose places) renders those
// alone; the others' rows are exactly zero, as their differences would be.
// The segments' thresholds are residualSegments' at theta (`robust`).
bool linearize(ForwardModel& model, std::span<const double> theta, const std::vector<int>& indices,
               std::span<const int> radiographs, int level, int samples, bool robust,
               LinearizedFit& out);

// Where a least-squares stage's Jacobian comes from: forward differences of
// 2e-3 (mm or deg), one render per parameter, or the render with derivatives
// (ForwardModel::residualsAndJacobian), one render for all; see
// docs/method.md, "Derivatives of the radiograph", for when the second is
// blind (a wall's strip that holds no sample).
enum class JacobianKind { kForwardDifferences, kRenderDerivatives };

// Gauss-Newton / Levenberg-Marquardt (Ceres' trust region with bounds) on the
// per-pixel residuals of `radiographs` over `indices`, from theta; theta is
// updated in place when the loss decreases. The robust loss is Huber's (see
// residualSegments), applied per pixel inside the one residual block by
// taking the square root of the loss: r -> sign(r) sqrt(2 a |r| - a^2)
// beyond the threshold a, whose squared sum is Huber's loss and whose
// Gauss-Newton step is that of the reweighted least squares.
// The solver's variables are the parameters in units of their linearisation
// steps (linearize); the stage ends when a step would move them by less than
// `settled_steps` of those steps together, or lowers the loss by less than
// 1 / (100 N) of it for N residuals (docs/method.md, "The final
// least-squares stage").
// `quiet`: no progress bar and no log line (a re-solve inside the budget);
// `label` starts the stage's name; `prior_lambda`, when given, weighs the
// refinement's prior instead of the residuals' own scale (the budget's
// re-solves take the fit's).
// The final stage's `settled_steps`: the outline moves by under 0.0004
// pixels, below what the float image resolves (noise-free fits reach 1e-4
// mm with it; 0.02 left 3e-4 mm on a 320 px jaw).
constexpr double kSettledSteps = 0.002;
// A coarser stage's, which only has to bring the fit within the next
// level's reach: 0.004 pixels of its level.
constexpr double kCoarseSettledSteps = 0.02;
StageReport solveLeastSquares(ForwardModel& model, std::vector<double>& theta,
                              const std::vector<int>& indices, const std::vector<int>& radiographs,
                              int level, int samples, int max_iterations, bool robust,
                              JacobianKind jacobian, bool quiet = false,
                              std::string_view label = "joint",
                              std::optional<double> prior_lambda = std::nullopt,
                              double settled_steps = kSettledSteps);

}  // namespace xgauge
