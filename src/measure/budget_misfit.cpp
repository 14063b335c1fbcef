// The budget's misfit term (docs/method.md, "The misfit term"): how far the
// dimensions move when the residual regions' pixels are left out of the fit.
#include "budget.h"
#include "budget_internal.h"

#include <fmt/format.h>

#include <Eigen/QR>

#include <algorithm>
#include <cmath>

namespace xgauge {

namespace budget_internal {

namespace {

// A relative eigenvalue of the scaled normal matrix below which a direction
// counts as undetermined (as the statistical part's kNullRatio).
constexpr double kUndetermined = 1e-9;

}  // namespace

Eigen::VectorXd linearShift(const LinearizedFit& fit, const Eigen::VectorXd& w,
                            const Eigen::VectorXd& dr, const std::vector<char>& keep) {
  const Eigen::Index n = fit.jacobian.cols(), m = dr.size();
  XG_CHECK(m == fit.jacobian.rows() && w.size() == m, "one change and one weight per residual");
  XG_CHECK(keep.empty() || keep.size() == static_cast<size_t>(m), "one keep flag per residual");
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd g = Eigen::VectorXd::Zero(n), scale(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const double d = (fit.jacobian.col(k).array().square() * w.array()).sum();
    scale(k) = d > 0.0 ? 1.0 / std::sqrt(d) : 0.0;
  }
  for (Eigen::Index i = 0; i < m; ++i) {
    if (!keep.empty() && !keep[static_cast<size_t>(i)]) continue;
    const auto row = fit.jacobian.row(i);
    a.noalias() += w(i) * row.transpose() * row;
    g.noalias() += w(i) * dr(i) * row.transpose();
  }
  if (fit.prior) a(fit.prior->column, fit.prior->column) += fit.prior->lambda * fit.prior->lambda;
  const Eigen::MatrixXd scaled = scale.asDiagonal() * a * scale.asDiagonal();
  Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> solver(scaled);
  solver.setThreshold(kUndetermined);
  return -(scale.asDiagonal() * solver.solve(scale.asDiagonal() * g)).eval();
}

void addShiftComponent(const ForwardModel& model, const LinearizedFit& fit,
                       const Eigen::VectorXd& shift, double factor, const std::string& name,
                       const std::string& quantity, const std::optional<ShiftSource>& source,
                       UncertaintyBudget& budget) {
  const auto& dims = model.part().dimensions();
  for (DimensionUncertainty& du : budget.dimensions) {
    if (!du.identifiable) continue;
    const auto it = std::find(fit.indices.begin(), fit.indices.end(),
                              model.parameters().index("dim/" + du.name));
    if (it == fit.indices.end()) continue;
    const double d = shift(it - fit.indices.begin()) * factor;
    std::string unit = "mm";
    for (const auto& dim : dims)
      if (dim.name == du.name) unit = dim.unit;
    const double u = std::abs(d);
    if (source)
      du.components.push_back({name, quantity, source->standard_uncertainty, source->unit,
                               source->standard_uncertainty > 0.0 ? d / source->standard_uncertainty
                                                                  : 0.0,
                               u});
    else
      du.components.push_back({name, quantity, u, unit, 1.0, u});
    du.combined = std::sqrt(du.combined * du.combined + u * u);
    du.expanded = budget.coverage_factor * du.combined;
  }
}

}  // namespace budget_internal

void addMisfitTerm(const ForwardModel& model, const LinearizedFit& fit,
                   const std::vector<char>& region_pixels, UncertaintyBudget& budget) {
  XG_CHECK(region_pixels.size() == static_cast<size_t>(fit.residuals.size()),
           "one region flag per residual");
  const auto left_out = std::count(region_pixels.begin(), region_pixels.end(), char{1});
  if (left_out == 0) return;
  std::vector<char> keep(region_pixels.size());
  for (size_t i = 0; i < keep.size(); ++i) keep[i] = !region_pixels[i];
  const Eigen::VectorXd w = fit.weights();
  // The shift from the solution when the regions are left out, less the
  // full fit's own remaining step (about 0 at its minimum).
  const Eigen::VectorXd shift = budget_internal::linearShift(fit, w, fit.residuals, keep) -
                                budget_internal::linearShift(fit, w, fit.residuals);
  const std::string quantity = fmt::format(
      "the shift when the residual regions' {} pixels ({:.1f} % of {}) are left out", left_out,
      100.0 * static_cast<double>(left_out) / static_cast<double>(keep.size()), keep.size());
  budget_internal::addShiftComponent(model, fit, shift, 1.0, "misfit", quantity, std::nullopt,
                                     budget);
  budget.notes.push_back(
      fmt::format("the misfit term: {}; each dimension's shift is a component of its U", quantity));
}

}  // namespace xgauge
