// The uncertainty budget's steps (private to the budget's files; the
// pipeline that runs them is estimateUncertainty, budget.cpp; the method is
// docs/method.md, "Uncertainty"): the statistical covariance
// (budget_covariance.cpp), the influence quantities (budget_influences.cpp),
// how each influence's shift reaches the result (budget_propagation.cpp) and
// the measurable combinations of dimensions (budget_combinations.cpp). Each
// step takes what it reads as arguments and returns what it finds; nothing
// else passes between them.
#pragma once

#include "least_squares.h"
#include "xgauge/measure/uncertainty.h"

#include <Eigen/Dense>

#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace xgauge::budget_internal {

// The covariance (budget_covariance.cpp) -------------------------------------

// The fit's linearisation at the solution, inverted: the statistical part,
// and what every influence's shift is propagated with.
struct Covariance {
  Eigen::VectorXd w;                  // the fit's weights (LinearizedFit::weights)
  Eigen::MatrixXd project;            // onto the directions some radiograph sees
  Eigen::MatrixXd a_inverse;          // pseudo-inverse of the projected A = J^T W J
  std::vector<Eigen::VectorXd> null;  // the directions it drops (in unscaled parameters)
  Eigen::MatrixXd statistical;        // the sandwich A^-1 B A^-1, small-sample corrected
};

// The radiographs of the fit's residual segments, in their order.
std::vector<int> fitRadiographs(const LinearizedFit& fit);

// The pseudo-inverse of the symmetric positive semi-definite A, scaled to a
// unit diagonal first so that millimetres and degrees compare; `null` gets
// the directions (in unscaled parameters) it drops.
Eigen::MatrixXd pseudoInverse(const Eigen::MatrixXd& a, std::vector<Eigen::VectorXd>& null);

// M^T M of the posed part's vertex velocities d(world vertices)/d theta
// [indices], stacked over `radiographs` (exact, from the part model and the
// poses; zero rows for parameters that move no vertex); false where they
// cannot be evaluated.
bool vertexNormalMatrix(ForwardModel& model, std::span<const double> theta,
                        std::span<const int> indices, std::span<const int> radiographs,
                        Eigen::MatrixXd& normal);

// The directions along which no vertex moves: eigenvectors of the
// vertex-velocity normal matrix (scaled to a unit diagonal over the
// parameters that move something) below 1e-10 of its largest eigenvalue,
// as orthonormal columns in the parameters' own units; empty for none.
Eigen::MatrixXd nullSpaceOfVertexNormal(const Eigen::MatrixXd& normal);

// A = J^T W J of the fit, with the refinement's prior; `w` its weights.
Eigen::MatrixXd normalMatrix(const LinearizedFit& fit, const Eigen::VectorXd& w);

// B: the fit's scores J_i w_i r_i summed per block of 16 x 16 pixels, then
// their outer products (the blocks taken as independent, the pixels within
// a block not).
Eigen::MatrixXd scoreMatrix(const LinearizedFit& fit, const Eigen::VectorXd& w);

// A, the directions no radiograph sees taken out of it, its pseudo-inverse,
// B and the sandwich, from the fit at theta over `radiographs`.
Covariance statisticalCovariance(ForwardModel& model, std::span<const double> theta,
                                 const LinearizedFit& fit, std::span<const int> radiographs);

// The influence quantities (budget_influences.cpp) ---------------------------

// How an influence's shift of the parameters is found (budget_propagation.cpp).
enum class Propagation { kLinearised, kIterated, kReSolved };

// A re-simulation with one influence moved by its standard uncertainty.
struct Influence {
  std::string name, quantity, unit;
  double u = 0.0;               // standard uncertainty, in unit
  Eigen::VectorXd delta_theta;  // the parameters' shift for q + u
  // When the influence scales the rates of the file's curve (the material's
  // rest): by how much, relative.
  double curve_scale = 0.0;
};

// One entry of the budget's list of influences: the influence (its
// delta_theta still empty), the model moved by its u and how its shift is
// found; or, where `left_out` is not empty, why it is not propagated (a
// note of the budget).
struct InfluenceMove {
  Influence influence;
  Propagation how = Propagation::kLinearised;
  // change(inputs, amount) moves the influence by amount * u; empty where
  // the moved model takes the model's inputs as they are.
  std::function<void(MeasurementInputs&, double)> change;
  // The moved model's material curve; nullopt: the model's.
  std::optional<ExponentialSum> curve;
  // The moved model moves the influence by u / scale, so its shift is
  // multiplied by scale (a halo kernel's end that lies elsewhere than u
  // from the kernel: linearised moves only).
  double scale = 1.0;
  std::string left_out;
};

// The model's influences in the order of the table of influence quantities
// (budget_influences.cpp). `level`: the re-solves' (resolveLevel).
std::vector<InfluenceMove> listInfluences(const ForwardModel& model, int fit_level, int level);

// How a shift reaches the result (budget_propagation.cpp) --------------------

// The pyramid level of the re-solves: about kResolveWidthPx wide, at least
// the fit's.
int resolveLevel(const ForwardModel& model, const LinearizedFit& fit);

// Where the re-solves take their Jacobian from.
JacobianKind reSolveJacobian(const ForwardModel& model);

// What every propagation reads, held fixed: the unmoved model, the fit at
// theta and its covariance.
struct FitAtSolution {
  ForwardModel& model;
  std::span<const double> theta;
  const LinearizedFit& fit;
  const Covariance& covariance;
  const std::vector<int>& radiographs;  // fitRadiographs
  int level = 0;                        // of the re-solves (resolveLevel)
  bool robust = false;                  // the job's loss is robust
  JacobianKind jacobian_kind = JacobianKind::kForwardDifferences;  // of the re-solves
};

// Each influence of `moves` with its shift, in their order; a note in
// `notes` for each one left out (a `left_out` entry, or a propagation that
// failed).
// `failed` gets the names of the influences whose propagation failed.
std::vector<Influence> propagateInfluences(const FitAtSolution& at,
                                           const std::vector<InfluenceMove>& moves,
                                           std::vector<std::string>& notes,
                                           std::vector<std::string>& failed);

// The combinations (budget_combinations.cpp) ---------------------------------

// What the combinations are read from: the total covariance of the fit's
// parameters and where the free dimensions are in it.
struct CombinationInputs {
  const ForwardModel& model;
  std::span<const double> theta;
  const std::vector<int>& free;              // ForwardModel::freeDimensionIndices
  const std::vector<Eigen::Index>& column;   // of each free dimension in fit.indices
  const Eigen::MatrixXd& total;              // every component's covariance
  const std::vector<Eigen::VectorXd>& null;  // Covariance::null
};

// The drawing's combinations and the strongly correlated pairs of
// dimensions, appended to budget.combinations (budget.dimensions filled).
void addCombinations(const CombinationInputs& in, UncertaintyBudget& budget);

// Linearised shifts (budget_misfit.cpp) -------------------------------------

// The linear least-squares shift -(J^T W' J)^+ J^T W' dr of the fit's
// parameters for a change dr of its residuals, W' the fit's weights `w`
// with the rows where keep[i] is 0 left out (all kept when `keep` is
// empty), the prior's row included; scaled to the unit diagonal of the full
// normal matrix so that millimetres and degrees compare, directions below
// 1e-9 of the largest dropped.
Eigen::VectorXd linearShift(const LinearizedFit& fit, const Eigen::VectorXd& w,
                            const Eigen::VectorXd& dr, const std::vector<char>& keep = {});

// What a shift component is the shift of: an influence of
// `standard_uncertainty` in `unit` (the component's sensitivity is then the
// dimension's signed shift over it), or, where absent, the shift itself in
// the dimension's unit (sensitivity 1).
struct ShiftSource {
  double standard_uncertainty = 0.0;
  std::string unit;
};

// Adds to every identifiable dimension of `budget` that is among the fit's
// columns the component `name` of contribution |shift of its column| *
// `factor` (1 for a bound taken as a standard uncertainty, 1/sqrt(3) for a
// rectangular half-width), and grows u_c and U by it.
void addShiftComponent(const ForwardModel& model, const LinearizedFit& fit,
                       const Eigen::VectorXd& shift, double factor, const std::string& name,
                       const std::string& quantity, const std::optional<ShiftSource>& source,
                       UncertaintyBudget& budget);

}  // namespace xgauge::budget_internal
