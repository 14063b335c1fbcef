// The envelope of the exponential sums a calibration's table admits beyond
// its longest path (material/extrapolation.h; docs/method.md, "The curve
// beyond its calibrated range").
#include "xgauge/material/extrapolation.h"

#include "xgauge/core/error.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

namespace xgauge {

namespace {

// The multiplier's bisection stops when its bracket is this narrow
// (relative): the value it bounds then moves by far less than the noise.
constexpr double kBracket = 1.001;
constexpr int kMaxBisections = 80;
// The multiplier's search upwards stops here (a value the bound never
// stops: a direction the table does not see at all).
constexpr double kLargestMultiplier = 1e30;

// min ||B a - y||^2 - lambda c.a over a >= 0: Lawson and Hanson's active set
// (NNLS) with the linear term, each passive set's problem solved by QR of its
// columns, (B_P^T B_P) s = B_P^T y + lambda c_P / 2.
// Written here because no packaged library does it: Eigen 3.4 (Debian 12)
// has no NNLS (its unsupported NNLS module came later), and Ceres or NLopt
// would solve these 64-unknown bound-constrained quadratics iteratively, to a
// tolerance, where the active set ends exactly in a few dozen QR solves.
class ActiveSet {
 public:
  ActiveSet(const Eigen::MatrixXd& b, const Eigen::VectorXd& y)
      : b_(b), y_(y), bty_(b.transpose() * y) {}

  Eigen::VectorXd solve(const Eigen::VectorXd& linear) const {
    const Eigen::Index n = b_.cols();
    Eigen::VectorXd a = Eigen::VectorXd::Zero(n);
    std::vector<char> passive(static_cast<size_t>(n), 0);
    const double tolerance =
        1e-10 * (bty_.cwiseAbs().maxCoeff() + linear.cwiseAbs().maxCoeff() + 1.0);
    for (Eigen::Index outer = 0; outer < 3 * n; ++outer) {
      const Eigen::VectorXd w = bty_ - b_.transpose() * (b_ * a) + linear;
      Eigen::Index best = -1;
      for (Eigen::Index j = 0; j < n; ++j)
        if (!passive[static_cast<size_t>(j)] && w(j) > tolerance && (best < 0 || w(j) > w(best)))
          best = j;
      if (best < 0) break;
      passive[static_cast<size_t>(best)] = 1;
      for (Eigen::Index inner = 0; inner < n; ++inner) {
        const Eigen::VectorXd s = passiveSolution(passive, linear);
        bool positive = true;
        for (Eigen::Index j = 0; j < n; ++j)
          if (passive[static_cast<size_t>(j)] && !(s(j) > 0.0)) positive = false;
        if (positive) {
          a = s;
          break;
        }
        double alpha = 1.0;
        for (Eigen::Index j = 0; j < n; ++j)
          if (passive[static_cast<size_t>(j)] && !(s(j) > 0.0))
            alpha = std::min(alpha, a(j) / (a(j) - s(j)));
        a += alpha * (s - a);
        for (Eigen::Index j = 0; j < n; ++j)
          if (passive[static_cast<size_t>(j)] && !(a(j) > 1e-15))
            passive[static_cast<size_t>(j)] = 0, a(j) = 0.0;
      }
    }
    return a;
  }

  double chi2(const Eigen::VectorXd& a) const { return (b_ * a - y_).squaredNorm(); }

 private:
  Eigen::VectorXd passiveSolution(const std::vector<char>& passive,
                                  const Eigen::VectorXd& linear) const {
    std::vector<Eigen::Index> index;
    for (size_t j = 0; j < passive.size(); ++j)
      if (passive[j]) index.push_back(static_cast<Eigen::Index>(j));
    const auto k = static_cast<Eigen::Index>(index.size());
    Eigen::MatrixXd columns(b_.rows(), k);
    Eigen::VectorXd g(k);
    for (Eigen::Index i = 0; i < k; ++i)
      columns.col(i) = b_.col(index[static_cast<size_t>(i)]),
      g(i) = linear(index[static_cast<size_t>(i)]);
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(columns);
    const Eigen::MatrixXd r = qr.matrixQR().topLeftCorner(k, k).triangularView<Eigen::Upper>();
    const Eigen::VectorXd qty = (qr.householderQ().transpose() * y_).head(k);
    const Eigen::VectorXd t = r.transpose().triangularView<Eigen::Lower>().solve(g);
    const Eigen::VectorXd s = r.triangularView<Eigen::Upper>().solve(qty + t);
    Eigen::VectorXd out = Eigen::VectorXd::Zero(b_.cols());
    for (Eigen::Index i = 0; i < k; ++i) out(index[static_cast<size_t>(i)]) = s(i);
    return out;
  }

  const Eigen::MatrixXd& b_;
  const Eigen::VectorXd& y_;
  Eigen::VectorXd bty_;
};

}  // namespace

ExtrapolationEnvelope extrapolationEnvelope(std::span<const double> path_mm,
                                            std::span<const double> transmission, double noise,
                                            double rate_floor_per_mm, const ExponentialSum& curve,
                                            const ExtrapolationOptions& options) {
  const size_t n = path_mm.size();
  if (n < 4 || transmission.size() != n)
    fail(
        "the curve's extrapolation needs a table of at least 4 paths and as many values, got {} "
        "and {}",
        n, transmission.size());
  if (!(noise > 0.0)) fail("the curve's extrapolation needs the table's noise, got {}", noise);
  if (options.factors.empty() || options.factors.front() != 1.0 || options.rates < 4)
    fail(
        "the curve's extrapolation: the factors must start at 1 and the grid have 4 rates or more");
  const double longest = path_mm[n - 1];
  const double first = std::max(path_mm[0], 1e-3 * longest);
  // The rates: from the floor (or a constant term and 0.1 / L without one)
  // up to 10 / x_1, beyond which a term is gone before the first path.
  std::vector<double> rates;
  const int r = options.rates;
  const double low = rate_floor_per_mm > 0.0 ? rate_floor_per_mm : 0.1 / longest;
  const double high = std::max(10.0 / first, 4.0 * low);
  if (!(rate_floor_per_mm > 0.0)) rates.push_back(0.0);
  const int spread = r - static_cast<int>(rates.size());
  for (int j = 0; j < spread; ++j)
    rates.push_back(low * std::pow(high / low, static_cast<double>(j) / (spread - 1)));
  const auto m = static_cast<Eigen::Index>(rates.size());
  Eigen::MatrixXd b(static_cast<Eigen::Index>(n), m);
  Eigen::VectorXd y(static_cast<Eigen::Index>(n));
  for (size_t i = 0; i < n; ++i) {
    y(static_cast<Eigen::Index>(i)) = transmission[i] / noise;
    for (Eigen::Index j = 0; j < m; ++j)
      b(static_cast<Eigen::Index>(i), j) =
          std::exp(-rates[static_cast<size_t>(j)] * path_mm[i]) / noise;
  }
  const ActiveSet solver(b, y);
  ExtrapolationEnvelope out;
  const Eigen::VectorXd a0 = solver.solve(Eigen::VectorXd::Zero(m));
  out.chi2_min = solver.chi2(a0);
  out.support = static_cast<int>((a0.array() > 0.0).count());
  const double dof = static_cast<double>(n) - 2.0 * out.support;
  out.birge = dof > 0.0 ? std::max(1.0, out.chi2_min / dof) : 1.0;
  const double limit = out.chi2_min + options.delta * options.delta * out.birge;

  // c.a at the largest sign * c.a the bound admits: bisection on the
  // multiplier, whose chi2 grows with it.
  auto extreme = [&](const Eigen::VectorXd& c, double sign) {
    const Eigen::VectorXd half = 0.5 * sign * c;
    auto admitted = [&](double lambda, Eigen::VectorXd& a) {
      a = solver.solve(lambda * half);
      return solver.chi2(a) <= limit;
    };
    Eigen::VectorXd best = a0, a;
    double lo = 0.0, hi = 1.0;
    while (hi < kLargestMultiplier && admitted(hi, a)) lo = hi, best = a, hi *= 10.0;
    for (int it = 0; it < kMaxBisections && !(lo > 0.0 && hi / lo < kBracket); ++it) {
      const double mid = lo > 0.0 ? std::sqrt(lo * hi) : 0.1 * hi;
      if (admitted(mid, a))
        lo = mid, best = a;
      else
        hi = mid;
    }
    return c.dot(best);
  };
  std::vector<double> distance;
  for (double factor : options.factors) {
    const double x = factor * longest;
    Eigen::VectorXd c(m);
    for (Eigen::Index j = 0; j < m; ++j) c(j) = std::exp(-rates[static_cast<size_t>(j)] * x);
    const double upper = extreme(c, 1.0), lower = extreme(c, -1.0);
    const double at = curve.transmission(x);
    out.upper.push_back(upper);
    out.lower.push_back(lower);
    distance.push_back(std::max(upper - at, at - lower));
  }
  for (size_t k = 0; k < distance.size(); ++k)
    out.points.push_back(
        {options.factors[k] * longest, std::max(0.0, distance[k] - distance.front())});
  return out;
}

}  // namespace xgauge
