// The halo from an edge shot (characterize.h, fitEdgeHalo): variable
// projection. For fixed kernel widths the model
//   data = alpha T + sum_j beta_j X(K_j * T)
// is linear (alpha = a (1 - w), beta_j = a w f_j, X the column crosstalk), so
// only the widths are searched; the weight and the fractions follow from the
// linear coefficients.
#include "xgauge/characterize/characterize.h"

#include "xgauge/core/error.h"
#include "xgauge/optimize/minimize.h"

#include <spdlog/spdlog.h>
#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace xgauge {

namespace {

// The binned shot: the data, the open mask T (area fraction) and the weight
// 1 / variance per bin (0: left out).
struct EdgeBins {
  Image data, open, weight;
  double pitch_mm = 0.0;
  int binning = 1;
  int count = 0;  // bins with weight > 0
};

// Noise variance of single pixels where the mask is `level` on both sides of
// a horizontal pair: half the median squared difference / median of chi2_1.
double pixelVariance(const Image& c, const ImageT<uint8_t>& mask, uint8_t level) {
  std::vector<double> squares;
  for (int y = 0; y < c.height(); y += 2)
    for (int x = 0; x + 1 < c.width(); x += 2)
      if (mask(x, y) == level && mask(x + 1, y) == level) {
        const double d = static_cast<double>(c(x + 1, y)) - static_cast<double>(c(x, y));
        squares.push_back(d * d);
      }
  if (squares.size() < 100) return std::numeric_limits<double>::quiet_NaN();
  auto mid = squares.begin() + static_cast<ptrdiff_t>(squares.size() / 2);
  std::nth_element(squares.begin(), mid, squares.end());
  return 0.5 * *mid / 0.4549364;
}

EdgeBins binEdgeShot(const Image& c, double pitch_mm) {
  // Open where above half the open level: behind the plate only the halo
  // (w <= 0.9 of a level far below 1 away from the edge) remains.
  ImageT<uint8_t> mask(c.width(), c.height());
  int64_t plate = 0;
  for (int y = 0; y < c.height(); ++y)
    for (int x = 0; x < c.width(); ++x) {
      mask(x, y) = c(x, y) > 0.5f ? 1 : 0;
      plate += mask(x, y) == 0;
    }
  const double area = static_cast<double>(c.width()) * c.height();
  if (plate < 0.02 * area || plate > 0.9 * area)
    fail(
        "characterize, edge: the plate's shadow covers {:.1f} % of the panel; an edge shot needs "
        "an opaque plate over 2 to 90 % of it with open beam around",
        100.0 * static_cast<double>(plate) / area);
  const double var_open = pixelVariance(c, mask, 1), var_plate = pixelVariance(c, mask, 0);
  EdgeBins out;
  int b = 1;
  while (std::max(c.width(), c.height()) / b > 320) b *= 2;
  out.binning = b;
  out.pitch_mm = pitch_mm * b;
  const int nx = c.width() / b, ny = c.height() / b;
  out.data = Image(nx, ny), out.open = Image(nx, ny), out.weight = Image(nx, ny, 0.0f);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      double sum = 0.0, open = 0.0;
      for (int y = j * b; y < (j + 1) * b; ++y)
        for (int x = i * b; x < (i + 1) * b; ++x)
          sum += static_cast<double>(c(x, y)), open += mask(x, y);
      out.data(i, j) = static_cast<float>(sum / (b * b));
      out.open(i, j) = static_cast<float>(open / (b * b));
    }
  // Bins on the plate's edge and next to it are left out: their pixels are
  // partly covered, which the binary mask does not describe.
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      bool mixed = false;
      for (int dj = -1; dj <= 1; ++dj)
        for (int di = -1; di <= 1; ++di) {
          const int u = std::clamp(i + di, 0, nx - 1), v = std::clamp(j + dj, 0, ny - 1);
          mixed |=
              out.open(u, v) != out.open(i, j) || (out.open(u, v) > 0.0f && out.open(u, v) < 1.0f);
        }
      if (mixed) continue;
      const double var = (out.open(i, j) > 0.5f ? var_open : var_plate) / (b * b);
      if (std::isfinite(var) && var > 0.0)
        out.weight(i, j) = static_cast<float>(1.0 / var), ++out.count;
    }
  if (out.count < 100)
    fail("characterize, edge: only {} bins away from the plate's edge", out.count);
  return out;
}

// X(P) = P + c mean over rows of P, per column (the flat's (1 + c) is in a).
Image withCrosstalk(Image p, double c) {
  if (c == 0.0) return p;
  for (int x = 0; x < p.width(); ++x) {
    double mean = 0.0;
    for (int y = 0; y < p.height(); ++y) mean += static_cast<double>(p(x, y));
    mean /= p.height();
    for (int y = 0; y < p.height(); ++y) p(x, y) += static_cast<float>(c * mean);
  }
  return p;
}

// A candidate's kernel components as one-component models: the Gaussians of
// the widths, or the exponential tail (its fixed mixture).
struct Shape {
  HaloShape shape;
  HaloBorder border;
  int widths;  // nonlinear parameters
};

std::vector<ScatterModel> componentKernels(const Shape& s, std::span<const double> widths) {
  auto gaussian = [&](double sigma) {
    ScatterModel m;
    m.weight = 0.5, m.sigma_mm = sigma, m.border = s.border;
    return m;
  };
  std::vector<ScatterModel> out{gaussian(widths[0])};
  if (s.shape == HaloShape::kTwoGauss) out.push_back(gaussian(widths[1]));
  if (s.shape == HaloShape::kGaussExp) {
    ScatterModel tail = gaussian(widths[0]);
    tail.shape = HaloShape::kGaussExp, tail.tail_fraction = 1.0, tail.tail_length_mm = widths[1];
    out.push_back(tail);
  }
  return out;
}

// Weighted least squares of the bins on the basis, optionally under one
// linear constraint g . c = 0, and with the kernels' coefficients >= 0
// (else the best fit without the offending one).
struct LinearFit {
  Eigen::VectorXd c;
  double chi2 = std::numeric_limits<double>::infinity();
};

LinearFit solveLinear(const std::vector<Image>& basis, const EdgeBins& bins,
                      const std::vector<double>* constraint) {
  const int k = static_cast<int>(basis.size());
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(k, k);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(k);
  double dd = 0.0;
  const auto w = bins.weight.pixels(), d = bins.data.pixels();
  for (size_t i = 0; i < w.size(); ++i) {
    if (w[i] <= 0.0f) continue;
    const double wi = static_cast<double>(w[i]), di = static_cast<double>(d[i]);
    dd += wi * di * di;
    for (int a = 0; a < k; ++a) {
      const double ba = static_cast<double>(basis[static_cast<size_t>(a)].pixels()[i]);
      rhs(a) += wi * ba * di;
      for (int b = 0; b <= a; ++b)
        gram(a, b) += wi * ba * static_cast<double>(basis[static_cast<size_t>(b)].pixels()[i]);
    }
  }
  gram = gram.selfadjointView<Eigen::Lower>();
  auto chi2Of = [&](const Eigen::VectorXd& c) { return dd - 2.0 * c.dot(rhs) + c.dot(gram * c); };
  LinearFit best;
  if (constraint) {
    // c = N y with N spanning the constraint's null space.
    const Eigen::Map<const Eigen::VectorXd> g(constraint->data(),
                                              static_cast<int>(constraint->size()));
    Eigen::FullPivLU<Eigen::MatrixXd> lu(g.transpose());
    const Eigen::MatrixXd n = lu.kernel();
    const Eigen::VectorXd y = (n.transpose() * gram * n).ldlt().solve(n.transpose() * rhs);
    best.c = n * y, best.chi2 = chi2Of(best.c);
    return best;
  }
  // Active sets: the open term always, each kernel in or out.
  for (int set = 0; set < (1 << (k - 1)); ++set) {
    std::vector<int> in{0};
    for (int j = 1; j < k; ++j)
      if (set & (1 << (j - 1))) in.push_back(j);
    Eigen::MatrixXd g(in.size(), in.size());
    Eigen::VectorXd r(in.size());
    for (size_t a = 0; a < in.size(); ++a) {
      r(static_cast<int>(a)) = rhs(in[a]);
      for (size_t b = 0; b < in.size(); ++b)
        g(static_cast<int>(a), static_cast<int>(b)) = gram(in[a], in[b]);
    }
    const Eigen::VectorXd y = g.ldlt().solve(r);
    Eigen::VectorXd c = Eigen::VectorXd::Zero(k);
    bool feasible = true;
    for (size_t a = 0; a < in.size(); ++a) {
      c(in[a]) = y(static_cast<int>(a));
      if (a > 0 && c(in[a]) < 0.0) feasible = false;
    }
    const double chi2 = chi2Of(c);
    if (feasible && chi2 < best.chi2) best.c = c, best.chi2 = chi2;
  }
  return best;
}

// The fitted state of a shape: widths (mm) and linear coefficients.
struct State {
  std::vector<double> widths;
  LinearFit linear;
};

class EdgeModel {
 public:
  EdgeModel(const EdgeBins& bins, double crosstalk, const OpenBeamField& field)
      : bins_(bins), crosstalk_(crosstalk), field_(field) {}

  // The halo in the open beam's field, K * (O T) / O (ScatterModel::spreadIn,
  // the calibration's and the measurement's: decision 0041), the open
  // border's O continued beyond the panel, the mirror's T O mirrored.
  std::vector<Image> basis(const Shape& s, std::span<const double> widths) const {
    std::vector<Image> out{withCrosstalk(bins_.open, crosstalk_)};
    const int nx = bins_.open.width(), ny = bins_.open.height();
    for (const ScatterModel& k : componentKernels(s, widths)) {
      const HaloField field = k.haloField(field_, nx, ny, bins_.pitch_mm, bins_.binning);
      out.push_back(withCrosstalk(k.spreadIn(bins_.open, bins_.pitch_mm, 1.0f, field), crosstalk_));
    }
    return out;
  }
  // Normalised residuals' correlation: the mean squared sum over 8 x 8
  // blocks of bins, per bin, over the mean square (1 for white noise; the
  // area over which a misfit is shared otherwise).
  double residualCorrelation(const Shape& s, const State& st) const;
  LinearFit fit(const Shape& s, std::span<const double> widths,
                const std::vector<double>* constraint = nullptr) const {
    return solveLinear(basis(s, widths), bins_, constraint);
  }
  const EdgeBins& bins() const { return bins_; }

 private:
  const EdgeBins& bins_;
  double crosstalk_;
  const OpenBeamField& field_;
};

double EdgeModel::residualCorrelation(const Shape& s, const State& st) const {
  const std::vector<Image> b = basis(s, st.widths);
  const int nx = bins_.data.width(), ny = bins_.data.height();
  Image r(nx, ny, 0.0f);
  double sum2 = 0.0;
  int64_t count = 0;
  for (size_t i = 0; i < r.size(); ++i) {
    if (bins_.weight.pixels()[i] <= 0.0f) continue;
    double model = 0.0;
    for (size_t j = 0; j < b.size(); ++j)
      model += st.linear.c(static_cast<int>(j)) * static_cast<double>(b[j].pixels()[i]);
    const double v = (static_cast<double>(bins_.data.pixels()[i]) - model) *
                     std::sqrt(static_cast<double>(bins_.weight.pixels()[i]));
    r.pixels()[i] = static_cast<float>(v), sum2 += v * v, ++count;
  }
  constexpr int kBlock = 8;
  double blocks = 0.0, block_sum2 = 0.0;
  for (int j0 = 0; j0 + kBlock <= ny; j0 += kBlock)
    for (int i0 = 0; i0 + kBlock <= nx; i0 += kBlock) {
      double sum = 0.0;
      int n = 0;
      for (int y = j0; y < j0 + kBlock; ++y)
        for (int x = i0; x < i0 + kBlock; ++x)
          if (bins_.weight(x, y) > 0.0f) sum += static_cast<double>(r(x, y)), ++n;
      if (n < kBlock * kBlock / 2) continue;
      block_sum2 += sum * sum / n, blocks += 1.0;
    }
  if (blocks < 4.0 || count == 0 || sum2 <= 0.0) return 1.0;
  return std::max(1.0, (block_sum2 / blocks) / (sum2 / static_cast<double>(count)));
}

ScatterModel toScatter(const Shape& s, const State& st) {
  ScatterModel m;
  m.shape = s.shape, m.border = s.border, m.sigma_mm = st.widths[0];
  const Eigen::VectorXd& c = st.linear.c;
  const double kernels = c.tail(c.size() - 1).sum(), a = c(0) + kernels;
  m.weight = a > 0.0 ? kernels / a : 0.0;
  const double second = c.size() > 2 && kernels > 0.0 ? c(2) / kernels : 0.0;
  if (s.shape == HaloShape::kTwoGauss) {
    m.sigma2_mm = st.widths[1], m.fraction2 = second;
    // The narrower one first, whichever way the search found them.
    if (m.sigma2_mm < m.sigma_mm) std::swap(m.sigma_mm, m.sigma2_mm), m.fraction2 = 1.0 - second;
  }
  if (s.shape == HaloShape::kGaussExp) m.tail_length_mm = st.widths[1], m.tail_fraction = second;
  return m;
}

// Minimises chi2 over the widths not fixed (log coordinates), each linear
// fit under `constraint` if given; `fixed` >= 0 holds that width at its
// value in `start`.
State minimizeWidths(const EdgeModel& model, const Shape& s, std::vector<double> start,
                     double low_mm, double high_mm, int fixed = -1,
                     const std::vector<double>* constraint = nullptr, int evaluations = 120) {
  std::vector<int> free;
  for (int j = 0; j < s.widths; ++j)
    if (j != fixed) free.push_back(j);
  State best{start, model.fit(s, start, constraint)};
  if (free.empty()) return best;
  Objective objective;
  for (const int j : free) {
    objective.lower.push_back(std::log(low_mm));
    objective.upper.push_back(std::log(high_mm));
    objective.start.push_back(
        std::clamp(std::log(start[static_cast<size_t>(j)]), std::log(low_mm), std::log(high_mm)));
    objective.initial_step.push_back(0.2);
  }
  objective.f = [&](std::span<const double> x) {
    std::vector<double> widths = start;
    for (size_t i = 0; i < free.size(); ++i) widths[static_cast<size_t>(free[i])] = std::exp(x[i]);
    const LinearFit f = model.fit(s, widths, constraint);
    if (f.chi2 < best.linear.chi2) best = {widths, f};
    return std::isfinite(f.chi2) ? f.chi2 : std::numeric_limits<double>::infinity();
  };
  OptimizeOptions options;
  options.method = Method::kBobyqa;
  options.max_evaluations = evaluations;
  options.x_tolerance = 1e-5;
  options.max_restarts = 1;
  minimize(objective, options);
  return best;
}

// The best state of a shape: a grid over the widths, then a local search
// from each of the three best grid points (with two widths the loss has
// more than one valley: a core at the widest bound with a short tail fits
// some shots' halo a little, and the grid's best point can lie there).
State fitShape(const EdgeModel& model, const Shape& s, double low_mm, double high_mm) {
  constexpr int kGrid = 10;
  auto at = [&](int i) { return low_mm * std::pow(high_mm / low_mm, (i + 0.5) / kGrid); };
  std::vector<State> grid;
  for (int i = 0; i < kGrid; ++i) {
    for (int j = 0; j < (s.widths > 1 ? kGrid : 1); ++j) {
      std::vector<double> widths{at(i)};
      if (s.widths > 1) widths.push_back(at(j));
      // Two Gaussians in order: the second the wider.
      if (s.shape == HaloShape::kTwoGauss && widths[1] <= widths[0]) continue;
      grid.push_back({widths, model.fit(s, widths)});
    }
  }
  std::sort(grid.begin(), grid.end(),
            [](const State& a, const State& b) { return a.linear.chi2 < b.linear.chi2; });
  State best;
  best.linear.chi2 = std::numeric_limits<double>::infinity();
  const size_t starts = s.widths > 1 ? 3 : 1;
  for (size_t k = 0; k < std::min(starts, grid.size()); ++k) {
    State st = minimizeWidths(model, s, grid[k].widths, low_mm, high_mm, -1, nullptr, 200);
    if (st.linear.chi2 < best.linear.chi2) best = std::move(st);
  }
  return best;
}

// The two two-width kernels describe much the same halos: a core and a
// wider part, which a Gaussian of sigma s2 or an exponential tail of length
// L with the same second moment (2 s2^2 = 6 L^2) gives. Each one's search
// also starts from the other's widths so mapped, and keeps the better fit:
// on a grid of log-spaced widths from a bin to twice the panel, the tail's
// search alone fell into a valley of a core wider than the panel and a
// short tail on two of the second lab's machines (misfit 5 and 12 times
// the noise, where the two Gaussians fitted within it).
void crossSeed(const EdgeModel& model, const Shape& gauss_exp, const Shape& two_gauss,
               double low_mm, double high_mm, State& tail, State& pair) {
  const double root3 = std::sqrt(3.0);
  auto clamp = [&](double w) { return std::clamp(w, low_mm, high_mm); };
  std::vector<double> as_tail{clamp(pair.widths[0]), clamp(pair.widths[1] / root3)};
  std::vector<double> as_pair{clamp(std::min(tail.widths[0], root3 * tail.widths[1])),
                              clamp(std::max(tail.widths[0], root3 * tail.widths[1]))};
  State from_pair = minimizeWidths(model, gauss_exp, as_tail, low_mm, high_mm, -1, nullptr, 200);
  State from_tail = minimizeWidths(model, two_gauss, as_pair, low_mm, high_mm, -1, nullptr, 200);
  if (from_pair.linear.chi2 < tail.linear.chi2) tail = std::move(from_pair);
  if (from_tail.linear.chi2 < pair.linear.chi2) pair = std::move(from_tail);
}

// The profile of one parameter: the chi2 minimised over the others with it
// held at a value. Parameters: 0 weight, 1 first width, 2 second width, 3
// second component's fraction.
class Profile {
 public:
  Profile(const EdgeModel& model, const Shape& s, State best, double low, double high)
      : model_(model), shape_(s), best_(std::move(best)), low_(low), high_(high) {}

  State at(int parameter, double value) const {
    if (parameter == 1 || parameter == 2) {
      std::vector<double> start = best_.widths;
      start[static_cast<size_t>(parameter - 1)] = value;
      // The other width stays on its side of the held one (the core the
      // narrower: sigma1 < sigma2, or sigma < sqrt(3) lambda, the tail's
      // Gaussian of the same second moment). Across it the two components
      // swap roles and fit as well: a profile that crossed would measure
      // the labels' swap (lab2's m08: a tail's core sigma 20 mm "+- 262").
      const double ratio = shape_.shape == HaloShape::kGaussExp ? std::sqrt(3.0) : 1.0;
      double low = low_, high = high_;
      if (parameter == 1)
        low = std::max(low_, value / ratio);
      else
        high = std::min(high_, value * ratio);
      if (shape_.widths < 2 || low > high) low = low_, high = high_;
      return minimizeWidths(model_, shape_, start, low, high, parameter - 1, nullptr, 60);
    }
    const auto k = static_cast<ptrdiff_t>(shape_.widths) + 1;
    std::array<double, 3> g{};
    if (parameter == 0) {  // sum beta = w (alpha + sum beta)
      g = {-value, 1.0 - value, 1.0 - value};
    } else {  // beta_2 = f (beta_1 + beta_2)
      g = {0.0, -value, 1.0 - value};
    }
    const std::vector<double> constraint(g.begin(), g.begin() + k);
    return minimizeWidths(model_, shape_, best_.widths, low_, high_, -1, &constraint, 60);
  }

 private:
  const EdgeModel& model_;
  Shape shape_;
  State best_;
  double low_, high_;
};

double parameterOf(const ScatterModel& m, int parameter) {
  switch (parameter) {
    case 0:
      return m.weight;
    case 1:
      return m.sigma_mm;
    case 2:
      return m.shape == HaloShape::kTwoGauss ? m.sigma2_mm : m.tail_length_mm;
    default:
      return m.shape == HaloShape::kTwoGauss ? m.fraction2 : m.tail_fraction;
  }
}

// Where the profile rises by s^2 on each side: steps doubled until it does,
// then bisected. Returns half the interval's width; also widens
// `sigma_eq_spread` by the equivalent sigma's largest move at the ends.
double profileUncertainty(const Profile& profile, const Shape& s, int parameter, double best_value,
                          double chi2_min, double scale2, double limit_low, double limit_high,
                          double sigma_eq, double& sigma_eq_spread) {
  double half_widths = 0.0;
  for (const int side : {-1, 1}) {
    auto rise = [&](double v) {
      const State st = profile.at(parameter, v);
      return std::pair{(st.linear.chi2 - chi2_min) / scale2, toScatter(s, st).equivalentSigmaMm()};
    };
    const double limit = side < 0 ? limit_low : limit_high;
    double inside = 0.0, step = 0.01 * std::max(std::abs(best_value), 1e-3), outside = 0.0;
    double eq_out = sigma_eq;
    for (int i = 0; i < 20; ++i) {
      const double v = best_value + side * step;
      if ((side < 0 && v <= limit) || (side > 0 && v >= limit)) {
        outside = std::abs(limit - best_value);
        break;
      }
      const auto [r, eq] = rise(v);
      eq_out = eq;
      if (r >= 1.0) {
        outside = step;
        break;
      }
      inside = step, step *= 2.0;
    }
    if (outside == 0.0) outside = step;
    for (int i = 0; i < 6 && outside > inside * 1.05; ++i) {
      const double mid = 0.5 * (inside + outside);
      const auto [r, eq] = rise(best_value + side * mid);
      (r >= 1.0 ? outside : inside) = mid;
      if (r >= 1.0) eq_out = eq;
    }
    sigma_eq_spread = std::max(sigma_eq_spread, std::abs(eq_out - sigma_eq));
    half_widths += 0.5 * (inside + outside);
  }
  return 0.5 * half_widths;
}

double uncertaintyOf(const ScatterModel& m, int parameter) {
  switch (parameter) {
    case 0:
      return m.weight_uncertainty;
    case 1:
      return m.sigma_uncertainty_mm;
    case 2:
      return m.shape == HaloShape::kTwoGauss ? m.sigma2_uncertainty_mm
                                             : m.tail_length_uncertainty_mm;
    default:
      return m.shape == HaloShape::kTwoGauss ? m.fraction2_uncertainty
                                             : m.tail_fraction_uncertainty;
  }
}

void setUncertainty(ScatterModel& m, int parameter, double u) {
  switch (parameter) {
    case 0:
      m.weight_uncertainty = u;
      break;
    case 1:
      m.sigma_uncertainty_mm = u;
      break;
    case 2:
      (m.shape == HaloShape::kTwoGauss ? m.sigma2_uncertainty_mm : m.tail_length_uncertainty_mm) =
          u;
      break;
    default:
      (m.shape == HaloShape::kTwoGauss ? m.fraction2_uncertainty : m.tail_fraction_uncertainty) = u;
      break;
  }
}

// The chosen shape fitted again to changed data (a half of the shot, a
// moved field) from the full fit's widths: the change of the estimate the
// change of the data makes, in the valley the full fit found (a search from
// the grid may land in another, where the two components swap roles).
State refit(const EdgeModel& model, const Shape& s, const State& best, double low, double high) {
  return minimizeWidths(model, s, best.widths, low, high, -1, nullptr, 200);
}

// What the noise does not explain: the shot's four halves (upper, lower,
// left, right), each fitted on its own, the model still the whole shot's
// (plate, edge and open beam) with the other half's bins left out; the
// root mean square of their estimates' deviations from the full fit
// (splitHalvesTerm) is added in quadrature to each profile uncertainty.
// Half the difference of the upper and lower halves alone (the term
// before) is the spread from whatever varies across the panel (the open
// field's shape, the gain), but it cannot see an estimate that both
// halves place elsewhere than the full shot does: on lab2's m02 (a tail
// beyond the panel fitted by two Gaussians) they gave 59.5 and 55.8 mm
// where the full shot gave 51.7, their half difference 1.8 mm. The left
// and right halves see the halo from different sides of the edge (behind
// the plate, beside it in the open beam), so a kernel of the wrong shape
// fits them differently: 50.3 and 66.0 mm on m02 (truth 74.0). They are
// not alike (a half may hold little of the plate), so a half's deviation
// holds its own noise too: the right half of m06 moved the weight by 0.003.
void addSplitHalves(const EdgeBins& bins, const EdgeHaloOptions& options, const Shape& s,
                    const State& best, double low, double high, EdgeHaloFit& out) {
  const int nx = bins.weight.width(), ny = bins.weight.height();
  std::vector<ScatterModel> halves;
  for (const int half : {0, 1, 2, 3}) {
    EdgeBins part = bins;
    for (int y = 0; y < ny; ++y)
      for (int x = 0; x < nx; ++x) {
        const bool first = half < 2 ? y < ny / 2 : x < nx / 2;
        if (first != (half % 2 == 0)) part.weight(x, y) = 0.0f;
      }
    const EdgeModel model(part, options.crosstalk, options.field);
    halves.push_back(toScatter(s, refit(model, s, best, low, high)));
  }
  auto term = [&](auto value) {
    std::array<double, 4> of{};
    for (size_t i = 0; i < 4; ++i) of[i] = value(halves[i]);
    return splitHalvesTerm(value(out.scatter), of);
  };
  const int parameters = s.widths == 1 ? 2 : 4;
  for (int p = 0; p < parameters; ++p) {
    const double t = term([p](const ScatterModel& m) { return parameterOf(m, p); });
    setUncertainty(out.scatter, p, std::hypot(uncertaintyOf(out.scatter, p), t));
  }
  for (size_t i = 0; i < 4; ++i)
    out.split_halves_weight[i] = halves[i].weight,
    out.split_halves_equivalent_sigma_mm[i] = halves[i].equivalentSigmaMm();
  out.split_halves_weight_term = term([](const ScatterModel& m) { return m.weight; });
  out.split_halves_equivalent_sigma_term_mm =
      term([](const ScatterModel& m) { return m.equivalentSigmaMm(); });
  out.equivalent_sigma_uncertainty_mm =
      std::hypot(out.equivalent_sigma_uncertainty_mm, out.split_halves_equivalent_sigma_term_mm);
}

// The flat cannot tell the tube's heel from a slope of the panel's gain
// (image/open_beam.h): the chosen shape fitted again with the heel's share
// moved by its standard uncertainty; each parameter's change is added in
// quadrature to its uncertainty.
void addHeelShare(const EdgeBins& bins, const EdgeHaloOptions& options, const Shape& s,
                  const State& best, double low, double high, EdgeHaloFit& out) {
  if (!options.field.sloped()) return;
  const OpenBeamField moved_field =
      options.field.withHeelShare(OpenBeamField::kHeelShare + OpenBeamField::kHeelShareUncertainty);
  const EdgeModel model(bins, options.crosstalk, moved_field);
  const ScatterModel moved = toScatter(s, refit(model, s, best, low, high));
  const int parameters = s.widths == 1 ? 2 : 4;
  for (int p = 0; p < parameters; ++p) {
    const double change = parameterOf(moved, p) - parameterOf(out.scatter, p);
    setUncertainty(out.scatter, p, std::hypot(uncertaintyOf(out.scatter, p), change));
  }
  out.heel_share_weight_change = moved.weight - out.scatter.weight;
  out.heel_share_equivalent_sigma_change_mm = moved.equivalentSigmaMm() - out.equivalent_sigma_mm;
  out.equivalent_sigma_uncertainty_mm =
      std::hypot(out.equivalent_sigma_uncertainty_mm, out.heel_share_equivalent_sigma_change_mm);
}

// A kernel's parameters as an alternative standing for u.
HaloKernelEnd kernelOf(const ScatterModel& m, double u) {
  HaloKernelEnd k;
  k.shape = m.shape, k.weight = m.weight, k.sigma_mm = m.sigma_mm;
  k.tail_fraction = m.tail_fraction, k.tail_length_mm = m.tail_length_mm;
  k.sigma2_mm = m.sigma2_mm, k.fraction2 = m.fraction2;
  k.equivalent_sigma_uncertainty_mm = u;
  return k;
}

// Kernels whose misfit ratio lies within this share of the chosen one's fit
// the shot about as well: which of them the panel's halo is, the edge shot
// does not say, and their Gaussian-equivalent widths differ by what lies
// beyond the panel (an exponential tail's second moment against a wide
// Gaussian's).
constexpr double kKernelChoiceMisfit = 0.10;

// The width's uncertainty from the choice of kernel: the largest difference
// of the Gaussian-equivalent width between the chosen kernel and another of
// its border fitting about as well (and that kernel's weight's difference,
// the weight's), taken as a standard uncertainty whole
// (not as the half-width of a rectangle): on the second lab's gauss_exp
// panels the true width lay beyond both kernels' widths (decision 0044).
void addKernelChoice(size_t chosen, EdgeHaloFit& out) {
  const EdgeHaloCandidate& pick = out.candidates[chosen];
  const ScatterModel* other = nullptr;
  for (size_t i = 0; i < out.candidates.size(); ++i) {
    const EdgeHaloCandidate& c = out.candidates[i];
    if (i == chosen || c.scatter.border != pick.scatter.border ||
        c.misfit_ratio > (1.0 + kKernelChoiceMisfit) * pick.misfit_ratio)
      continue;
    const double change = c.scatter.equivalentSigmaMm() - out.equivalent_sigma_mm;
    if (std::abs(change) > std::abs(out.kernel_choice_equivalent_sigma_change_mm))
      out.kernel_choice_equivalent_sigma_change_mm = change,
      out.kernel_choice_weight_change = c.scatter.weight - out.scatter.weight,
      out.kernel_choice_shape = toString(c.scatter.shape), other = &c.scatter;
  }
  // The other two-width kernel itself, for the budget (a Gaussian has one
  // width: its difference is the core width's, which the budget moves).
  if (other && other->shape != HaloShape::kGaussian && pick.scatter.shape != HaloShape::kGaussian)
    out.scatter.kernel_choice =
        kernelOf(*other, std::abs(out.kernel_choice_equivalent_sigma_change_mm));
  out.equivalent_sigma_uncertainty_mm =
      std::hypot(out.equivalent_sigma_uncertainty_mm, out.kernel_choice_equivalent_sigma_change_mm);
  out.scatter.weight_uncertainty =
      std::hypot(out.scatter.weight_uncertainty, out.kernel_choice_weight_change);
}

// The kernel at the Gaussian-equivalent width's end, sigma_eq + u, u with
// the terms of this kernel's fit (its profile, the halves, the heel: what
// the profile's own u cannot see), the other kernel's apart (the budget
// moves the halo to that kernel itself: kernel_choice). The profile along
// the second width (the tail's length, the wide Gaussian's sigma: most of
// the second moment), the others refitted, is stepped outwards in log
// width until its equivalent width reaches sigma_eq + u, then bisected. It
// fits the shot as well as any kernel that wide can, so a measurement's
// budget moves the halo to it, with its move scaled to u where the profile
// ends short of it (at the width's bound). Why not one parameter moved
// alone: a wide part moved by itself leaves the kernel off the shot it was
// fitted to (on lab2's m06 it took the mean U 2.5 times, decision 0049).
void addEquivalentEnd(const Profile& profile, const Shape& s, const State& best, double low,
                      double high, EdgeHaloFit& out) {
  const double choice = out.kernel_choice_equivalent_sigma_change_mm;
  const double u = std::sqrt(std::max(
      0.0,
      out.equivalent_sigma_uncertainty_mm * out.equivalent_sigma_uncertainty_mm - choice * choice));
  if (s.widths < 2 || !(u > 0.0)) return;
  const double start = std::log(best.widths[1]);
  auto at = [&](double log_width) {
    return toScatter(s, profile.at(2, std::clamp(std::exp(log_width), low, high)));
  };
  auto reach = [&](const ScatterModel& m) {
    return m.equivalentSigmaMm() - out.equivalent_sigma_mm;
  };
  // Which way the second width widens the kernel: the refitted shares can
  // turn it (a tail longer, its share much smaller).
  constexpr double kFirstStep = 0.05;
  ScatterModel outside = at(start + kFirstStep);
  const double side = reach(outside) >= 0.0 ? 1.0 : -1.0;
  if (side < 0.0) outside = at(start - kFirstStep);
  double inside_step = 0.0, outside_step = kFirstStep;
  for (int i = 0; i < 8 && reach(outside) < u; ++i) {
    const double next = 2.0 * outside_step;
    const double w = std::exp(start + side * next);
    if (w <= low || w >= high) break;
    inside_step = outside_step, outside_step = next, outside = at(start + side * next);
  }
  if (reach(outside) >= u)
    for (int i = 0; i < 8; ++i) {
      const double mid = 0.5 * (inside_step + outside_step);
      const ScatterModel m = at(start + side * mid);
      if (reach(m) >= u)
        outside_step = mid, outside = m;
      else
        inside_step = mid;
    }
  if (!(reach(outside) > 1e-3 * u)) return;
  out.scatter.equivalent_end = kernelOf(outside, u);
}

}  // namespace

double splitHalvesTerm(double full, std::span<const double> halves) {
  if (halves.empty()) return 0.0;
  double sum2 = 0.0;
  for (const double h : halves) sum2 += (h - full) * (h - full);
  return std::sqrt(sum2 / static_cast<double>(halves.size()));
}

EdgeHaloFit fitEdgeHalo(const Image& corrected, double pitch_mm, const EdgeHaloOptions& options) {
  const EdgeBins bins = binEdgeShot(corrected, pitch_mm);
  const EdgeModel model(bins, options.crosstalk, options.field);
  const double shorter_mm = std::min(corrected.width(), corrected.height()) * pitch_mm;
  // Widths from a bin to twice the panel: the search may find the halo too
  // wide, which is then refused with its figures rather than clipped.
  const double low = bins.pitch_mm, high = 2.0 * shorter_mm;
  EdgeHaloFit out;
  out.binning = bins.binning, out.bins = bins.count;
  std::vector<State> states;
  std::vector<Shape> shapes;
  for (const HaloBorder border : {HaloBorder::kOpen, HaloBorder::kMirror}) {
    const Shape gauss_exp{HaloShape::kGaussExp, border, 2},
        two_gauss{HaloShape::kTwoGauss, border, 2};
    const State gaussian = fitShape(model, {HaloShape::kGaussian, border, 1}, low, high);
    State tail = fitShape(model, gauss_exp, low, high);
    State pair = fitShape(model, two_gauss, low, high);
    crossSeed(model, gauss_exp, two_gauss, low, high, tail, pair);
    using Fitted = std::pair<Shape, const State*>;
    for (const auto& [s, st] : {Fitted{Shape{HaloShape::kGaussian, border, 1}, &gaussian},
                                Fitted{gauss_exp, &tail}, Fitted{two_gauss, &pair}}) {
      EdgeHaloCandidate c;
      c.scatter = toScatter(s, *st);
      c.chi2 = st->linear.chi2;
      c.parameters = 2 + 2 * s.widths;  // a, w, widths, fraction
      if (s.widths == 1) c.parameters = 3;
      c.misfit_ratio = std::sqrt(c.chi2 / std::max(1, bins.count - c.parameters));
      c.residual_correlation = model.residualCorrelation(s, *st);
      out.candidates.push_back(c), states.push_back(*st), shapes.push_back(s);
    }
  }
  // The noise scale: the best candidate's misfit, times its residuals'
  // correlation area (a misfit shared by neighbouring bins counts once per
  // area, not per bin), >= 1: the BIC's chi2 in units of what the data
  // scatter by around any model, over the independent bins' number.
  size_t best = 0;
  for (size_t i = 0; i < out.candidates.size(); ++i)
    if (out.candidates[i].chi2 < out.candidates[best].chi2) best = i;
  const double best_ratio = out.candidates[best].misfit_ratio;
  const double correlation = out.candidates[best].residual_correlation;
  const double scale2 = std::max(1.0, best_ratio * best_ratio * correlation);
  const double independent = std::max(2.0, bins.count / correlation);
  size_t chosen = 0;
  for (size_t i = 0; i < out.candidates.size(); ++i) {
    EdgeHaloCandidate& c = out.candidates[i];
    c.bic = c.chi2 / scale2 + c.parameters * std::log(independent);
    if (c.bic < out.candidates[chosen].bic) chosen = i;
  }
  const EdgeHaloCandidate& pick = out.candidates[chosen];
  out.scatter = pick.scatter;
  out.equivalent_sigma_mm = pick.scatter.equivalentSigmaMm();
  out.choice = fmt::format(
      "{} with a {} border: the lowest BIC (chi2 over the best misfit ratio {:.3g} squared times "
      "its residuals' correlation area {:.3g} bins, plus parameters x ln {:.0f} independent "
      "bins); {}",
      toString(pick.scatter.shape), toString(pick.scatter.border), best_ratio, correlation,
      independent, [&] {
        std::string others;
        for (const EdgeHaloCandidate& c : out.candidates)
          others +=
              fmt::format("{}{}/{} BIC {:+.1f}", others.empty() ? "" : ", ",
                          toString(c.scatter.shape), toString(c.scatter.border), c.bic - pick.bic);
        return others;
      }());
  if (out.equivalent_sigma_mm > options.max_sigma_fraction * shorter_mm)
    fail(
        "characterize, edge: the halo's width (Gaussian-equivalent sigma {:.1f} mm, {} kernel, "
        "weight {:.3f}) is wider than {:.0f} % of the panel's shorter side ({:.1f} mm): a halo "
        "that "
        "wide looks like a level on this panel and the edge shot cannot measure it",
        out.equivalent_sigma_mm, toString(pick.scatter.shape), pick.scatter.weight,
        100.0 * options.max_sigma_fraction, shorter_mm);
  out.noise_scale =
      std::sqrt(std::max(1.0, pick.misfit_ratio * pick.misfit_ratio * pick.residual_correlation));
  if (!options.profiles) return out;
  const Shape& s = shapes[chosen];
  const Profile profile(model, s, states[chosen], low, high);
  const int parameters = s.widths == 1 ? 2 : 4;
  double eq_spread = 0.0;
  for (int p = 0; p < parameters; ++p) {
    const bool fraction = p == 0 || p == 3;
    const double value = parameterOf(out.scatter, p);
    const double u = profileUncertainty(profile, s, p, value, pick.chi2,
                                        out.noise_scale * out.noise_scale, fraction ? 0.0 : low,
                                        fraction ? 1.0 : high, out.equivalent_sigma_mm, eq_spread);
    setUncertainty(out.scatter, p, u);
  }
  out.equivalent_sigma_uncertainty_mm =
      s.widths == 1 ? out.scatter.sigma_uncertainty_mm : eq_spread;
  addSplitHalves(bins, options, s, states[chosen], low, high, out);
  addHeelShare(bins, options, s, states[chosen], low, high, out);
  addKernelChoice(chosen, out);
  addEquivalentEnd(profile, s, states[chosen], low, high, out);
  return out;
}

}  // namespace xgauge
