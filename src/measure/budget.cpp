// The uncertainty budget as a pipeline of its steps (budget_internal.h):
// the statistical covariance, the influences listed and propagated, their
// total, and from it each free dimension's budget, the combinations and the
// refined material's uncertainty.
#include "budget.h"
#include "budget_internal.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace xgauge {

namespace {

using budget_internal::Covariance;
using budget_internal::Influence;

// The total covariance: the statistical part and every influence's shift.
Eigen::MatrixXd totalCovariance(const Eigen::MatrixXd& statistical,
                                const std::vector<Influence>& influences) {
  Eigen::MatrixXd total = statistical;
  for (const Influence& f : influences) total += f.delta_theta * f.delta_theta.transpose();
  return total;
}

// The column of each free dimension in fit.indices.
std::vector<Eigen::Index> freeColumns(const ForwardModel& model, const LinearizedFit& fit) {
  std::vector<Eigen::Index> column;
  for (int d : model.freeDimensionIndices()) {
    const auto it = std::find(fit.indices.begin(), fit.indices.end(), d);
    XG_CHECK(it != fit.indices.end(), "free dimension {} is not in the linearisation", d);
    column.push_back(it - fit.indices.begin());
  }
  return column;
}

// Each free dimension's budget (its components, u_c and U), appended to
// budget.dimensions; `m`: the residuals the statistical part is from.
void addDimensions(const ForwardModel& model, const std::vector<Eigen::Index>& column,
                   const Covariance& covariance, const std::vector<Influence>& influences,
                   const Eigen::MatrixXd& total, Eigen::Index m, UncertaintyBudget& budget) {
  const auto& dims = model.part().dimensions();
  const auto& free = model.freeDimensionIndices();
  for (size_t j = 0; j < free.size(); ++j) {
    const Eigen::Index c = column[j];
    DimensionUncertainty du;
    du.name = dims[static_cast<size_t>(free[j])].name;
    const std::string unit = dims[static_cast<size_t>(free[j])].unit;
    for (const Eigen::VectorXd& v : covariance.null) du.identifiable &= std::abs(v(c)) < 1e-3;
    const double u_stat = std::sqrt(std::max(0.0, covariance.statistical(c, c)));
    du.components.push_back({"statistical", fmt::format("noise and misfit over {} pixels", m),
                             u_stat, unit, 1.0, u_stat});
    for (const Influence& f : influences) {
      const double d = f.delta_theta(c);
      du.components.push_back({f.name, f.quantity, f.u, f.unit, d / f.u, std::abs(d)});
    }
    du.combined = std::sqrt(std::max(0.0, total(c, c)));
    du.expanded = du.identifiable ? budget.coverage_factor * du.combined : 0.0;
    budget.dimensions.push_back(std::move(du));
  }
}

// The material refined in situ: the rate scale e at column c of the fit and
// its uncertainty, and what it does to the curve.
MaterialRefinementResult materialRefinement(const ForwardModel& model,
                                            std::span<const double> theta, Eigen::Index c,
                                            const Eigen::MatrixXd& statistical,
                                            const std::vector<Influence>& influences) {
  MaterialRefinementResult refined;
  refined.rate_scale = theta[static_cast<size_t>(model.rateScaleIndex())];
  refined.prior_standard_uncertainty = model.rateScalePrior();
  // e corrects the file's curve: a scale s of that curve moves e by about
  // -s and the refined curve, (1 + s)(1 + e), by s + de, which is what the
  // prior holds back. So e's uncertainty as the radiographs determine it
  // (that of the refined curve's scale) is the statistical part, the
  // material's rest as s + de, and the other influences. The calibration
  // inputs' curve moves are not scales and are left out of it.
  double variance = statistical(c, c);
  for (const Influence& f : influences) {
    if (f.curve_scale != 0.0) {
      const double refined_scale = f.curve_scale + f.delta_theta(c);
      variance += refined_scale * refined_scale;
    } else if (!f.name.starts_with("material")) {
      variance += f.delta_theta(c) * f.delta_theta(c);
    }
  }
  refined.standard_uncertainty = std::sqrt(std::max(0.0, variance));
  const ExponentialSum used = model.materialOf(theta);
  const ExponentialSum& stated = model.material();
  constexpr int kPaths = 400;
  for (int k = 0; k <= kPaths; ++k) {
    const double x = model.partSizeMm() * k / kPaths;
    const double change = used.transmission(x) - stated.transmission(x);
    if (std::abs(change) > std::abs(refined.transmission_change))
      refined.transmission_change = change, refined.at_path_mm = x;
  }
  return refined;
}

}  // namespace

UncertaintyBudget estimateUncertainty(ForwardModel& model, std::span<const double> theta,
                                      const LinearizedFit& fit) {
  namespace bi = budget_internal;
  UncertaintyBudget budget;
  budget.level = fit.level;
  budget.pixels = static_cast<double>(fit.residuals.size());

  // The statistical part: the sandwich over the radiographs the fit saw.
  const std::vector<int> radiographs = bi::fitRadiographs(fit);
  const Covariance covariance = bi::statisticalCovariance(model, theta, fit, radiographs);

  // The influences: the table's moves of the model, each propagated to a
  // shift of the parameters with the fit held fixed.
  const bi::FitAtSolution at{model,
                             theta,
                             fit,
                             covariance,
                             radiographs,
                             bi::resolveLevel(model, fit),
                             model.job().loss == LossKind::kMeanAbsolute,
                             bi::reSolveJacobian(model)};
  const std::vector<bi::InfluenceMove> moves = bi::listInfluences(model, fit.level, at.level);
  const std::vector<Influence> influences = bi::propagateInfluences(at, moves, budget.notes);

  // The total covariance and each free dimension's budget.
  const Eigen::MatrixXd total = totalCovariance(covariance.statistical, influences);
  const std::vector<Eigen::Index> column = freeColumns(model, fit);
  addDimensions(model, column, covariance, influences, total, fit.residuals.size(), budget);
  bi::addCombinations({model, theta, model.freeDimensionIndices(), column, total, covariance.null},
                      budget);
  if (fit.prior)
    budget.refinement =
        materialRefinement(model, theta, fit.prior->column, covariance.statistical, influences);
  if (!covariance.null.empty())
    budget.notes.push_back(
        fmt::format("{} direction(s) of the parameters are not determined by the "
                    "radiographs",
                    covariance.null.size()));
  return budget;
}

}  // namespace xgauge
