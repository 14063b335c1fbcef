// The budget's measurable combinations of dimensions: the drawing's, and
// pairs whose errors correlate so strongly that their sum or difference is
// known much better than either (docs/method.md, "Uncertainty").
#include "budget_internal.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>

namespace xgauge::budget_internal {

namespace {

// A pair of dimensions is reported as a measurable sum or difference when
// their errors correlate beyond kCombinationCorrelation and the combination's
// U is below kCombinationGain times the smaller of theirs. On the replica
// prism pairs, 0.95 and 0.5 also let through pairs whose common bias (the
// detector's ghost, which the budget has no component for) the combination
// does not cancel (groove_left - groove_right: U 0.010 mm, error 0.078 mm).
constexpr double kCombinationCorrelation = 0.99;
constexpr double kCombinationGain = 0.2;

// A combination's terms: (index among the free dimensions, coefficient).
using TermsAt = std::vector<std::pair<size_t, double>>;

// The drawing's combinations (the part model's "combinations") whose
// dimensions are all free: their value and U from the total covariance,
// whether or not the single dimensions are identifiable. Returns the terms
// of those with two.
std::vector<TermsAt> declaredCombinations(const CombinationInputs& in, UncertaintyBudget& budget) {
  const auto& dims = in.model.part().dimensions();
  const std::vector<int>& free = in.free;
  const auto freeColumn = [&](const std::string& name) -> std::optional<size_t> {
    for (size_t j = 0; j < free.size(); ++j)
      if (dims[static_cast<size_t>(free[j])].name == name) return j;
    return std::nullopt;
  };
  std::vector<TermsAt> declared_pairs;
  for (const DeclaredCombination& declared : in.model.part().combinations()) {
    TermsAt at;
    for (const auto& [name, coefficient] : declared.terms)
      if (const auto j = freeColumn(name)) at.emplace_back(*j, coefficient);
    if (at.size() != declared.terms.size()) continue;
    Eigen::VectorXd t = Eigen::VectorXd::Zero(in.total.rows());
    MeasurableCombination combination;
    combination.name = declared.name;
    std::string expression;
    for (size_t k = 0; k < at.size(); ++k) {
      const auto [j, coefficient] = at[k];
      t(in.column[j]) = coefficient;
      combination.terms.emplace_back(budget.dimensions[j].name, coefficient);
      combination.value += coefficient * in.theta[static_cast<size_t>(free[j])];
      const std::string factor =
          std::abs(coefficient) == 1.0 ? "" : fmt::format("{:g} ", std::abs(coefficient));
      expression += k == 0 ? fmt::format("{}{}{}", coefficient < 0 ? "-" : "", factor,
                                         budget.dimensions[j].name)
                           : fmt::format(" {} {}{}", coefficient < 0 ? "-" : "+", factor,
                                         budget.dimensions[j].name);
    }
    combination.expression = expression;
    bool identifiable = true;
    for (const Eigen::VectorXd& v : in.null)
      identifiable &= std::abs(t.dot(v)) < 1e-3 * t.norm() * v.norm();  // as a dimension's test
    combination.expanded =
        identifiable ? budget.coverage_factor * std::sqrt(std::max(0.0, t.dot(in.total * t))) : 0.0;
    if (at.size() == 2) declared_pairs.push_back(at);
    budget.combinations.push_back(std::move(combination));
  }
  return declared_pairs;
}

// Measurable combinations: two dimensions whose errors are (anti)correlated
// so strongly that their sum (difference) is known much better than either,
// unless the drawing declares it (`declared_pairs`).
void correlatedPairs(const CombinationInputs& in, const std::vector<TermsAt>& declared_pairs,
                     UncertaintyBudget& budget) {
  const std::vector<int>& free = in.free;
  const Eigen::MatrixXd& total = in.total;
  for (size_t i = 0; i < free.size(); ++i)
    for (size_t j = i + 1; j < free.size(); ++j) {
      const Eigen::Index ci = in.column[i], cj = in.column[j];
      const double vi = total(ci, ci), vj = total(cj, cj), cov = total(ci, cj);
      const bool either_lost =
          !budget.dimensions[i].identifiable || !budget.dimensions[j].identifiable;
      if (!(vi > 0.0 && vj > 0.0) && !either_lost) continue;
      const double rho = vi > 0.0 && vj > 0.0 ? cov / std::sqrt(vi * vj) : 0.0;
      const double sign = either_lost ? 0.0 : (rho < 0.0 ? 1.0 : -1.0);
      double coefficient = sign;
      if (either_lost) {
        // The combination orthogonal to every null direction, if a sum or
        // difference is.
        for (double s : {1.0, -1.0}) {
          bool orthogonal = true;
          for (const Eigen::VectorXd& v : in.null)
            orthogonal &= std::abs(v(ci) + s * v(cj)) < 1e-3 * (std::abs(v(ci)) + std::abs(v(cj)));
          if (orthogonal) coefficient = s;
        }
        if (coefficient == 0.0) continue;
      } else if (std::abs(rho) < kCombinationCorrelation) {
        continue;
      }
      const double var = vi + vj + 2.0 * coefficient * cov;
      const double u = std::sqrt(std::max(0.0, var));
      if (!either_lost && !(u < kCombinationGain * std::sqrt(std::min(vi, vj)))) continue;
      const bool already =
          std::any_of(declared_pairs.begin(), declared_pairs.end(), [&](const auto& at) {
            return at[0].first == i && at[1].first == j &&
                   at[1].second / at[0].second == coefficient;
          });
      if (already) continue;
      MeasurableCombination combination;
      combination.terms = {{budget.dimensions[i].name, 1.0},
                           {budget.dimensions[j].name, coefficient}};
      combination.expression = fmt::format("{} {} {}", budget.dimensions[i].name,
                                           coefficient > 0 ? "+" : "-", budget.dimensions[j].name);
      combination.value = in.theta[static_cast<size_t>(free[i])] +
                          coefficient * in.theta[static_cast<size_t>(free[j])];
      combination.expanded = budget.coverage_factor * u;
      budget.combinations.push_back(std::move(combination));
    }
}

}  // namespace

void addCombinations(const CombinationInputs& in, UncertaintyBudget& budget) {
  correlatedPairs(in, declaredCombinations(in, budget), budget);
}

}  // namespace xgauge::budget_internal
