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

// A STEP solid's curved faces are facets within half the chord tolerance of
// the CAD surfaces (OpenCASCADE divides curved edges within t / 2), in the
// model and in no real part: each length dimension the model measures is
// uncertain by that much, rectangular over +-t / 2 (docs/method.md,
// "Uncertainty"). Zero for a part without curved STEP faces.
struct Facets {
  double u = 0.0;  // mm
  std::string quantity;
};
Facets facetsOf(const PartModel& part) {
  const PartModel::StepFaces step = part.stepFaces();
  if (!step.solid) return {};
  const bool curved = std::any_of(step.solid->faces.begin(), step.solid->faces.end(),
                                  [](const StepFace& f) { return f.surface.kind != SurfaceKind::kPlane; });
  if (!curved) return {};
  const double half = 0.5 * step.solid->chord_tolerance_mm;
  return {half / std::sqrt(3.0),
          fmt::format("the model's facets of the STEP solid's curved faces: within {} mm of them "
                      "(half its chord tolerance), rectangular",
                      half)};
}

// Each free dimension's budget (its components, u_c and U), appended to
// budget.dimensions; `m`: the residuals the statistical part is from.
void addDimensions(const ForwardModel& model, const std::vector<Eigen::Index>& column,
                   const Covariance& covariance, const std::vector<Influence>& influences,
                   const Facets& facets, const Eigen::MatrixXd& total, Eigen::Index m,
                   UncertaintyBudget& budget) {
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
    if (facets.u > 0.0 && unit == "mm")
      du.components.push_back({"facets", facets.quantity, facets.u, "mm", 1.0, facets.u});
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
  const std::vector<Influence> influences =
      bi::propagateInfluences(at, moves, budget.notes, budget.unpropagated);

  // The total covariance (with the facets' share of each length dimension,
  // independent from one dimension to another) and each free dimension's
  // budget.
  Eigen::MatrixXd total = totalCovariance(covariance.statistical, influences);
  const std::vector<Eigen::Index> column = freeColumns(model, fit);
  const Facets facets = facetsOf(model.part());
  const auto& free = model.freeDimensionIndices();
  for (size_t j = 0; j < free.size(); ++j)
    if (model.part().dimensions()[static_cast<size_t>(free[j])].unit == "mm")
      total(column[j], column[j]) += facets.u * facets.u;
  addDimensions(model, column, covariance, influences, facets, total, fit.residuals.size(),
                budget);
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
