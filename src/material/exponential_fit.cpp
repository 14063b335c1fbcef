#include "xgauge/material/exponential_fit.h"

#include "xgauge/core/error.h"

#include <Eigen/Dense>
#include <nlopt.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace xgauge {

namespace {

constexpr int kMaxTerms = 8;
constexpr double kMaxTransmission = 1.0 + 1e-9;

void checkCurve(std::span<const double> path_mm, std::span<const double> transmission,
                size_t min_points, double max_transmission = kMaxTransmission) {
  if (path_mm.size() != transmission.size())
    fail("path_mm has {} values but transmission has {}", path_mm.size(), transmission.size());
  if (path_mm.size() < min_points)
    fail("the transmission curve has {} points, at least {} are needed", path_mm.size(),
         min_points);
  for (size_t i = 0; i < path_mm.size(); ++i) {
    const double x = path_mm[i], t = transmission[i];
    if (!std::isfinite(x) || x < 0.0) fail("path_mm[{}] = {} is not a finite path >= 0", i, x);
    if (i > 0 && !(x > path_mm[i - 1]))
      fail("path_mm must be strictly increasing: path_mm[{}] = {} follows path_mm[{}] = {}", i, x,
           i - 1, path_mm[i - 1]);
    if (!std::isfinite(t) || !(t > 0.0) || t > max_transmission)
      fail("transmission[{}] = {} (at {} mm) is not in (0, {}]", i, t, x,
           max_transmission == kMaxTransmission ? 1.0 : max_transmission);
  }
}

// The variable-projection subproblem: for fixed decay rates mu, the weights a
// minimising || W (B(mu) a - T) ||^2 subject to a >= 0 (and sum a = 1 unless
// the amplitude is free), with B_ik = exp(-mu_k x_i).
class ProjectedProblem {
 public:
  ProjectedProblem(std::span<const double> path_mm, std::span<const double> transmission,
                   ExponentialFitOptions::Weighting weighting, bool sum_to_one)
      : x_(Eigen::Map<const Eigen::VectorXd>(path_mm.data(),
                                             static_cast<Eigen::Index>(path_mm.size()))),
        w_(x_.size()),
        y_(x_.size()),
        sum_to_one_(sum_to_one) {
    for (Eigen::Index i = 0; i < x_.size(); ++i) {
      const double t = transmission[static_cast<size_t>(i)];
      w_[i] = weighting == ExponentialFitOptions::Weighting::kRelative ? 1.0 / t : 1.0;
      y_[i] = w_[i] * t;
    }
  }

  // The weighted sum of squared residuals at the optimal weights, which go to
  // `weights` (zero for terms outside the optimal support).
  double solve(const std::vector<double>& mu, Eigen::VectorXd& weights) const {
    const int m = static_cast<int>(mu.size());
    Eigen::MatrixXd basis(x_.size(), m);
    for (int k = 0; k < m; ++k)
      basis.col(k) = w_.cwiseProduct((-mu[static_cast<size_t>(k)] * x_).array().exp().matrix());

    // The unconstrained optimum on the full set is the answer when feasible.
    const unsigned full = (1u << m) - 1u;
    double best = solveOnSupport(basis, full, weights);
    if (best < std::numeric_limits<double>::infinity()) return best;

    // Otherwise the optimum lies on a face: the best feasible support set.
    // Singletons are always feasible, so one is found.
    Eigen::VectorXd candidate;
    for (unsigned support = 1; support < full; ++support) {
      const double value = solveOnSupport(basis, support, candidate);
      if (value < best) {
        best = value;
        weights = candidate;
      }
    }
    return best;
  }

 private:
  // Least squares over the terms in `support` (a bit mask), others held at 0,
  // by a rank-revealing QR. With the sum fixed to 1 the last term's weight is
  // eliminated as 1 - the sum of the others. Returns infinity when a weight
  // comes out negative.
  double solveOnSupport(const Eigen::MatrixXd& basis, unsigned support,
                        Eigen::VectorXd& weights) const {
    const int m = static_cast<int>(basis.cols());
    std::array<int, kMaxTerms> terms{};
    int count = 0;
    for (int k = 0; k < m; ++k)
      if (support & (1u << k)) terms[static_cast<size_t>(count++)] = k;
    XG_CHECK(count > 0, "empty support");
    if (!sum_to_one_) {
      Eigen::MatrixXd reduced(basis.rows(), count);
      for (int j = 0; j < count; ++j) reduced.col(j) = basis.col(terms[static_cast<size_t>(j)]);
      const Eigen::VectorXd z = reduced.completeOrthogonalDecomposition().solve(y_);
      weights = Eigen::VectorXd::Zero(m);
      for (int j = 0; j < count; ++j) {
        if (!(z[j] >= 0.0)) return std::numeric_limits<double>::infinity();
        weights[terms[static_cast<size_t>(j)]] = z[j];
      }
      return (basis * weights - y_).squaredNorm();
    }
    const int last = terms[static_cast<size_t>(count - 1)];
    weights = Eigen::VectorXd::Zero(m);
    weights[last] = 1.0;
    if (count > 1) {
      const int free = count - 1;
      Eigen::MatrixXd reduced(basis.rows(), free);
      for (int j = 0; j < free; ++j)
        reduced.col(j) = basis.col(terms[static_cast<size_t>(j)]) - basis.col(last);
      const Eigen::VectorXd z =
          reduced.completeOrthogonalDecomposition().solve(y_ - basis.col(last));
      for (int j = 0; j < free; ++j) {
        if (!(z[j] >= 0.0)) return std::numeric_limits<double>::infinity();
        weights[terms[static_cast<size_t>(j)]] = z[j];
      }
      weights[last] = 1.0 - z.sum();
      if (!(weights[last] >= 0.0)) return std::numeric_limits<double>::infinity();
    }
    return (basis * weights - y_).squaredNorm();
  }

  Eigen::VectorXd x_;
  Eigen::VectorXd w_;  // per-point weight w_i
  Eigen::VectorXd y_;  // w_i T_i
  bool sum_to_one_;
};

// Decay rate -d ln T / dx estimated by chords over the first and last tenth
// of the curve: where a polychromatic curve decays fastest and slowest.
std::pair<double, double> observedDecayRates(std::span<const double> x, std::span<const double> t) {
  const size_t n = x.size();
  const double span = x[n - 1] - x[0];
  size_t head = 1;
  while (head + 1 < n && x[head] - x[0] < 0.1 * span) ++head;
  size_t tail = n - 2;
  while (tail > 0 && x[n - 1] - x[tail] < 0.1 * span) --tail;
  const double rate_head = (std::log(t[0]) - std::log(t[head])) / (x[head] - x[0]);
  const double rate_tail = (std::log(t[tail]) - std::log(t[n - 1])) / (x[n - 1] - x[tail]);
  return {std::min(rate_head, rate_tail), std::max(rate_head, rate_tail)};
}

double evaluate(const std::vector<ExponentialTerm>& terms, double x) {
  double sum = 0.0;
  for (const ExponentialTerm& term : terms) sum += term.weight * std::exp(-term.mu_per_mm * x);
  return sum;
}

// The model's residuals against the curve (no input checks).
ExponentialFitReport residualsOf(const std::vector<ExponentialTerm>& model,
                                 std::span<const double> x, std::span<const double> t) {
  ExponentialFitReport report;
  double sum_squares = 0.0;
  for (size_t i = 0; i < x.size(); ++i) {
    const double r = evaluate(model, x[i]) - t[i];
    sum_squares += r * r;
    report.max_abs_residual = std::max(report.max_abs_residual, std::abs(r));
    report.max_relative_residual = std::max(report.max_relative_residual, std::abs(r) / t[i]);
  }
  report.rms_residual = std::sqrt(sum_squares / static_cast<double>(x.size()));
  report.terms_used = static_cast<int>(model.size());
  return report;
}

}  // namespace

void ExponentialFitOptions::validate() const {
  if (weighting != Weighting::kUniform && weighting != Weighting::kRelative)
    fail("unknown exponential-fit weighting {}", static_cast<int>(weighting));
  if (!(max_transmission >= 1.0 && max_transmission <= 10.0))
    fail("max_transmission must be in [1, 10], got {}", max_transmission);
  if (!(min_mu_per_mm >= 0.0 && std::isfinite(min_mu_per_mm)))
    fail("min_mu_per_mm must be finite and >= 0, got {}", min_mu_per_mm);
  if (max_evaluations_per_start < 100)
    fail("max_evaluations_per_start must be >= 100, got {}", max_evaluations_per_start);
}

std::vector<ExponentialTerm> fitExponentialTerms(std::span<const double> path_mm,
                                                 std::span<const double> transmission, int terms,
                                                 const ExponentialFitOptions& options,
                                                 ExponentialFitReport* report) {
  options.validate();
  if (terms < 1 || terms > kMaxTerms)
    fail("an exponential-sum fit needs 1 to {} terms, got {}", kMaxTerms, terms);
  // Free parameters: terms rates and terms weights, less one when they sum to 1.
  const bool sum_to_one = !options.free_amplitude;
  checkCurve(path_mm, transmission,
             static_cast<size_t>(std::max(2, 2 * terms - (sum_to_one ? 1 : 0))),
             options.max_transmission);

  const ProjectedProblem problem(path_mm, transmission, options.weighting, sum_to_one);
  const size_t m = static_cast<size_t>(terms);
  const size_t n = path_mm.size();

  // Search over log(mu) in bounds: below the lower one a term is constant to
  // 1e-9 over the data, above the upper one it has decayed by e^-50 within
  // the closest pair of points.
  double min_spacing = std::numeric_limits<double>::infinity();
  for (size_t i = 1; i < n; ++i) min_spacing = std::min(min_spacing, path_mm[i] - path_mm[i - 1]);
  const double max_path = path_mm[n - 1];
  const bool floored = options.min_mu_per_mm > 0.0;
  const double log_mu_min = floored ? std::log(options.min_mu_per_mm) : std::log(1e-9 / max_path);
  const double log_mu_max = std::max(std::log(50.0 / min_spacing), log_mu_min + 1.0);

  // Track the best point over every evaluation of every search.
  std::vector<double> best_log_mu;
  double best_value = std::numeric_limits<double>::infinity();
  int evaluations = 0;
  std::vector<double> mu(m);
  Eigen::VectorXd weights;
  auto objective = [&](const std::vector<double>& log_mu) {
    for (size_t k = 0; k < m; ++k) mu[k] = std::exp(log_mu[k]);
    const double value = problem.solve(mu, weights);
    ++evaluations;
    if (value < best_value) {
      best_value = value;
      best_log_mu = log_mu;
    }
    return value;
  };
  using Objective = decltype(objective);
  auto trampoline = [](const std::vector<double>& p, std::vector<double>& /*grad*/, void* data) {
    return (*static_cast<Objective*>(data))(p);
  };

  int starts = 0;
  auto localSearch = [&](std::vector<double> start, double step) {
    for (double& p : start) p = std::clamp(p, log_mu_min, log_mu_max);
    nlopt::opt opt(nlopt::LN_BOBYQA, static_cast<unsigned>(m));
    opt.set_lower_bounds(std::vector<double>(m, log_mu_min));
    opt.set_upper_bounds(std::vector<double>(m, log_mu_max));
    opt.set_min_objective(+trampoline, &objective);
    opt.set_initial_step(step);
    opt.set_xtol_abs(1e-12);
    opt.set_ftol_rel(1e-15);
    opt.set_maxeval(options.max_evaluations_per_start);
    ++starts;
    double value = 0.0;
    try {
      opt.optimize(start, value);
    } catch (const nlopt::roundoff_limited&) {
      // Converged as far as rounding allows; the best point is tracked.
    } catch (const std::runtime_error&) {
      // NLopt's generic failure: keep the best point seen so far.
    }
  };

  // Starting points: rates spread geometrically over the observed range of
  // decay rates, widened by a factor `spread` each way and shifted by
  // `shift`; a single rate starts at the low end, the high end and between.
  auto [rate_low, rate_high] = observedDecayRates(path_mm, transmission);
  const double span = path_mm[n - 1] - path_mm[0];
  const double rate_floor = 1e-4 / span;
  if (!(rate_high > rate_floor)) rate_high = 1.0 / span;
  rate_low = std::clamp(rate_low, rate_floor, rate_high);
  if (floored) {  // start above the floor, not piled on it
    rate_low = std::max(rate_low, options.min_mu_per_mm);
    rate_high = std::max(rate_high, 3.0 * rate_low);
  }
  struct Start {
    double spread, shift;
  };
  const std::vector<Start> starts_list =
      m == 1 ? std::vector<Start>{{1.0, 1.0}}
             : std::vector<Start>{{1.0, 1.0},  {3.0, 1.0},       {10.0, 1.0},
                                  {30.0, 1.0}, {3.0, 1.0 / 3.0}, {3.0, 3.0}};
  for (const Start& s : starts_list) {
    const double lo = std::log(rate_low / s.spread * s.shift);
    const double hi = std::log(rate_high * s.spread * s.shift);
    if (m == 1) {
      for (double p : {lo, 0.5 * (lo + hi), hi}) localSearch({p}, 0.5);
      continue;
    }
    std::vector<double> start(m);
    for (size_t k = 0; k < m; ++k)
      start[k] = lo + (hi - lo) * static_cast<double>(k) / static_cast<double>(m - 1);
    localSearch(start, 0.5);
  }
  // Polish: restart from the best point with a small trust region.
  localSearch(best_log_mu, 0.05);

  // Without a floor, rates at the lower bound are constant over the data:
  // make them exactly 0. With one, rates at it are the floor itself. Refit
  // the weights for the rates returned.
  std::vector<double> final_mu(m);
  for (size_t k = 0; k < m; ++k)
    final_mu[k] = best_log_mu[k] <= log_mu_min ? (floored ? options.min_mu_per_mm : 0.0)
                                               : std::exp(best_log_mu[k]);
  problem.solve(final_mu, weights);

  // Drop terms with zero weight, merge equal rates, sort by rate.
  std::vector<ExponentialTerm> result;
  for (size_t k = 0; k < m; ++k)
    if (weights[static_cast<Eigen::Index>(k)] > 0.0)
      result.push_back({weights[static_cast<Eigen::Index>(k)], final_mu[k]});
  std::sort(result.begin(), result.end(), [](const ExponentialTerm& a, const ExponentialTerm& b) {
    return a.mu_per_mm < b.mu_per_mm;
  });
  std::vector<ExponentialTerm> merged;
  for (const ExponentialTerm& term : result) {
    if (!merged.empty() && merged.back().mu_per_mm == term.mu_per_mm)
      merged.back().weight += term.weight;
    else
      merged.push_back(term);
  }
  XG_CHECK(!merged.empty(), "the exponential fit kept no term");
  if (report) {
    *report = residualsOf(merged, path_mm, transmission);
    report->evaluations = evaluations;
    report->starts = starts;
  }
  return merged;
}

ExponentialSum fitExponentialSum(std::span<const double> path_mm,
                                 std::span<const double> transmission, int terms,
                                 const ExponentialFitOptions& options,
                                 ExponentialFitReport* report) {
  if (options.free_amplitude)
    fail(
        "fitExponentialSum fits weights that sum to 1; use fitExponentialTerms for a free "
        "amplitude");
  return ExponentialSum(
      fitExponentialTerms(path_mm, transmission, terms, options, report),
      fmt::format("{}-term exponential-sum fit to {} points", terms, path_mm.size()));
}

ExponentialSum shiftAndScale(const std::vector<ExponentialTerm>& fitted, double x_max_mm,
                             double* x0_out) {
  if (!(std::isfinite(x_max_mm) && x_max_mm > 0.0))
    fail("eq. 3.7 needs x_max > 0 mm, got {}", x_max_mm);
  if (fitted.empty()) fail("eq. 3.7 needs at least one exponential term");
  double max_mu = 0.0;
  for (size_t k = 0; k < fitted.size(); ++k) {
    const ExponentialTerm& t = fitted[k];
    if (!(std::isfinite(t.weight) && t.weight > 0.0 && std::isfinite(t.mu_per_mm) &&
          t.mu_per_mm >= 0.0))
      fail("eq. 3.7: term {} (weight {}, mu {} /mm) is not a positive weight with mu >= 0", k,
           t.weight, t.mu_per_mm);
    max_mu = std::max(max_mu, t.mu_per_mm);
  }
  if (!(evaluate(fitted, x_max_mm) < 1.0) || max_mu == 0.0)
    fail("eq. 3.7: the fitted curve does not fall below 1 before x_max = {} mm (I(x_max) = {})",
         x_max_mm, evaluate(fitted, x_max_mm));
  // I is convex and strictly decreasing (some mu > 0), and I(x_max) < 1, so
  // I(x) = 1 has exactly one root x0 < x_max. Bracket it, then Newton with
  // bisection safeguarding to full precision.
  double hi = x_max_mm;  // I(hi) < 1
  double lo = std::min(0.0, x_max_mm);
  double step = 1.0 / max_mu;
  while (!(evaluate(fitted, lo) >= 1.0)) {
    lo -= step, step *= 2.0;
    if (!std::isfinite(lo)) fail("eq. 3.7: no x0 with I(x0) = 1 found");
  }
  double x0 = 0.5 * (lo + hi);
  for (int iteration = 0; iteration < 200; ++iteration) {
    double value = -1.0, slope = 0.0;
    for (const ExponentialTerm& t : fitted) {
      const double e = t.weight * std::exp(-t.mu_per_mm * x0);
      value += e, slope -= t.mu_per_mm * e;
    }
    if (value >= 0.0)
      lo = x0;
    else
      hi = x0;
    double next = slope < 0.0 ? x0 - value / slope : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (next == x0 || hi - lo <= 4 * std::numeric_limits<double>::epsilon() * std::abs(x0)) {
      x0 = next;
      break;
    }
    x0 = next;
  }
  const double scale = (x_max_mm - x0) / x_max_mm;
  std::vector<ExponentialTerm> shifted;
  double sum = 0.0;
  for (const ExponentialTerm& t : fitted) {
    shifted.push_back({t.weight * std::exp(-t.mu_per_mm * x0), t.mu_per_mm * scale});
    sum += shifted.back().weight;
  }
  for (ExponentialTerm& t : shifted) t.weight /= sum;
  if (x0_out) *x0_out = x0;
  return ExponentialSum(std::move(shifted),
                        fmt::format("shifted and scaled by thesis eq. 3.7 (x0 = {:.6g} mm, "
                                    "x_max = {:.6g} mm)",
                                    x0, x_max_mm));
}

ExponentialFitReport exponentialFitResiduals(const ExponentialSum& model,
                                             std::span<const double> path_mm,
                                             std::span<const double> transmission) {
  checkCurve(path_mm, transmission, 1);
  return residualsOf(model.terms(), path_mm, transmission);
}

}  // namespace xgauge
