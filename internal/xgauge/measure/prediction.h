// What a measurement would state before it is made (xgauge plan,
// docs/method.md, "Planning the views"): the budget the measurement's own
// code gives where its fit ends, and one radiograph's share of that
// budget's linearisation, which the views of a set add up.
#pragma once

#include "xgauge/measure/model.h"
#include "xgauge/measure/uncertainty.h"

#include <Eigen/Dense>

#include <optional>
#include <span>
#include <string>
#include <vector>

namespace xgauge {

// The budget of a measurement whose fit ended at theta, built as measure()
// builds it there: the Jacobian on the least-squares stage's level with its
// edge samples, then every component (uncertainty.h). The model's
// radiographs stand for the shots: theta's render with a shot's noise.
// nullopt where theta cannot be simulated.
std::optional<UncertaintyBudget> budgetAt(ForwardModel& model, std::span<const double> theta);

// Radiograph `radiograph` at theta, full size, rendered as the fit's last
// stage renders it (its point samples and edge samples): a shot without
// noise. Requires a feasible theta.
Image simulatedShot(ForwardModel& model, std::span<const double> theta, int radiograph);

// One radiograph's share of that linearisation (a model of one radiograph
// with a free pose), in the model's least-squares parameters:
//   a = J^T W J, b = the block scores' outer products (the sandwich's B),
//   g = J^T W dr per influence, dr the residuals' change with the influence
//       moved by its standard uncertainty (each linearised, one render).
// The views of a set add up their a, b and g once mapped onto the set's
// parameters (the chain rule through each view's pose).
struct ViewInformation {
  std::vector<std::string> names;  // the parameters of the columns (layout names)
  Eigen::MatrixXd a, b;
  Eigen::Index pixels = 0;
  std::vector<std::string> influences;  // names, as the budget's components
  // Per influence: whether the budget does not take it linearised (the
  // geometry's, which the poses absorb along weakly determined directions
  // that one linearised step overshoots: budget_propagation.cpp).
  std::vector<bool> iterated;
  Eigen::MatrixXd g;                    // one column per influence
  double prior_lambda = 0.0;            // the refinement's prior (0: none)
  // M^T M of the posed part's vertex velocities over the columns: a set's
  // directions that move no vertex in any view are its null space (the
  // budget's geometric null space).
  Eigen::MatrixXd vertex_normal;
};
std::optional<ViewInformation> viewInformationAt(ForwardModel& model,
                                                 std::span<const double> theta);

}  // namespace xgauge

namespace xgauge {

// The budget's pseudo-inverse of a normal matrix (scaled to a unit diagonal,
// eigenvalues below 1e-9 of the largest dropped): `null` gets the dropped
// directions, which make a dimension with a share of 1e-3 or more in one of
// them not identifiable.
Eigen::MatrixXd budgetPseudoInverse(const Eigen::MatrixXd& a, std::vector<Eigen::VectorXd>& null);

// The budget's directions that move no vertex, from a vertex-velocity normal
// matrix (ViewInformation::vertex_normal added up): orthonormal columns;
// empty for none. The budget projects them out of A, B and every shift.
Eigen::MatrixXd budgetGeometricNullSpace(const Eigen::MatrixXd& vertex_normal);

}  // namespace xgauge
