#include "xgauge/calibrate/halo.h"

#include "xgauge/core/error.h"
#include "xgauge/image/blur.h"
#include "xgauge/image/pyramid.h"
#include "xgauge/image/stats.h"

#include <spdlog/spdlog.h>
#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

namespace xgauge {

namespace {

double at(const Image& image, int x, int y) { return static_cast<double>(image(x, y)); }

// The model's coefficients: n = a P + b G(P) + c A.
struct Coefficients {
  double a = 1.0, b = 0.0, c = 0.0;
};

// Each column's mean attenuation 1 - n (the column darkening's regressor).
std::vector<double> columnAttenuation(const Image& n) {
  std::vector<double> out(static_cast<size_t>(n.width()), 0.0);
  for (int y = 0; y < n.height(); ++y)
    for (int x = 0; x < n.width(); ++x) out[static_cast<size_t>(x)] += 1.0 - at(n, x, y);
  for (double& value : out) value /= n.height();
  return out;
}

// The open beam's field where an image's halo is taken (decision 0041): the
// field, the image's pixel pitch and full-size pixels per pixel.
struct InField {
  const OpenBeamField* field = nullptr;
  double pitch_mm = 1.0;
  double scale = 1.0;
};

// The halo of one width in the field at an image's pixels (uniform: empty).
struct WidthField {
  ScatterModel kernel;  // the Gaussian of that width and border
  double pitch_mm = 1.0;
  HaloField halo;
  Image excess;  // K * O / O - 1: the flat frame's own halo beyond O's
};

WidthField widthField(const InField& in, const Image& like, double sigma_px, HaloBorder border) {
  WidthField out;
  // Only the kernel's shape matters here (the weight is the fit's).
  out.kernel.weight = 0.5, out.kernel.sigma_mm = sigma_px * in.pitch_mm, out.kernel.border = border;
  out.pitch_mm = in.pitch_mm;
  if (!in.field || in.field->uniform()) return out;
  out.halo = out.kernel.haloField(*in.field, like.width(), like.height(), in.pitch_mm, in.scale);
  out.excess = out.halo.open;
  for (size_t i = 0; i < out.excess.size(); ++i)
    out.excess.pixels()[i] = out.halo.open_halo.pixels()[i] / out.halo.open.pixels()[i] - 1.0f;
  return out;
}

// K * P for the halo's width and border: mirrored at the panel's edges, or
// with open beam (a primary of 1) beyond them. In a non-uniform field
// K * (P O) / O less the flat's own excess (`wf.excess`): 1 in the open
// beam, as the uniform field's.
Image haloBlur(const Image& primary, double sigma_px, HaloBorder border, const WidthField& wf) {
  if (!wf.halo.uniform()) {
    Image out = wf.kernel.spreadIn(primary, wf.pitch_mm, 1.0f, wf.halo);
    for (size_t i = 0; i < out.size(); ++i) out.pixels()[i] -= wf.excess.pixels()[i];
    return out;
  }
  if (border == HaloBorder::kMirror) return gaussianBlur(primary, sigma_px);
  Image shifted = primary;
  for (float& v : shifted.pixels()) v -= 1.0f;
  Image blurred = gaussianBlur(std::move(shifted), sigma_px, BlurBorder::kZero);
  for (float& v : blurred.pixels()) v += 1.0f;
  return blurred;
}

// P = (n - b G(P) - c A) / a: one step of the fixed point, which contracts by
// about b / a = w / (1 - w) per step. In a non-uniform field the flat
// divided by its own halo, mix(1, 1 + e): P = ((n - c A) (1 + w e) - b (G + e)) / a.
void primaryStep(const Image& n, const std::vector<double>& attenuation, const Coefficients& k,
                 const Image& blurred, const WidthField& wf, Image& primary) {
  if (wf.halo.uniform()) {
    for (int y = 0; y < n.height(); ++y)
      for (int x = 0; x < n.width(); ++x)
        primary(x, y) = static_cast<float>(
            (at(n, x, y) - k.b * at(blurred, x, y) - k.c * attenuation[static_cast<size_t>(x)]) /
            k.a);
    return;
  }
  const double w = k.b / (k.a + k.b);
  for (int y = 0; y < n.height(); ++y)
    for (int x = 0; x < n.width(); ++x) {
      const double e = at(wf.excess, x, y);
      primary(x, y) = static_cast<float>(
          ((at(n, x, y) - k.c * attenuation[static_cast<size_t>(x)]) * (1.0 + w * e) -
           k.b * (at(blurred, x, y) + e)) /
          k.a);
    }
}

// Enough steps to leave about 1e-5 of the scatter for w up to 0.25.
constexpr int kFixedPointSteps = 9;

Image solvePrimary(const Image& n, const std::vector<double>& attenuation, const Coefficients& k,
                   double sigma_px, HaloBorder border, const InField& in) {
  Image primary = n;
  const WidthField wf = widthField(in, n, sigma_px, border);
  for (int step = 0; step < kFixedPointSteps; ++step)
    primaryStep(n, attenuation, k, haloBlur(primary, sigma_px, border, wf), wf, primary);
  return primary;
}

// The part's shadow: the bounding box of the image's sharp edges (forward
// differences above a quarter of their 99.9th percentile and ten times their
// median, the noise's), its outermost 0.2 % on each side dropped as strays,
// widened by 2 % of the longer side.
PixelRect shadowBox(const Image& n, const std::string& name) {
  Image gradient(n.width(), n.height(), 0.0f);
  for (int y = 0; y + 1 < n.height(); ++y)
    for (int x = 0; x + 1 < n.width(); ++x)
      gradient(x, y) = std::max(std::abs(n(x + 1, y) - n(x, y)), std::abs(n(x, y + 1) - n(x, y)));
  const double top = percentileOf(gradient, 99.9), noise = percentileOf(gradient, 50.0);
  if (!(top > 20.0 * noise && top > 0.005))
    fail(
        "{}: the scatter's halo needs a part with a sharp outline, and this radiograph has "
        "none (its steepest steps, {:.4f} per pixel, are not above its noise, {:.4f}): give the "
        "job's \"scatter\"",
        name, top, noise);
  const float threshold = static_cast<float>(std::max(0.25 * top, 10.0 * noise));
  std::vector<int> xs, ys;
  for (int y = 0; y < n.height(); ++y)
    for (int x = 0; x < n.width(); ++x)
      if (gradient(x, y) > threshold) xs.push_back(x), ys.push_back(y);
  auto quantile = [](std::vector<int>& v, double q) {
    const auto at = v.begin() + static_cast<std::ptrdiff_t>(q * static_cast<double>(v.size() - 1));
    std::nth_element(v.begin(), at, v.end());
    return *at;
  };
  const int margin =
      std::max(2, static_cast<int>(std::lround(0.02 * std::max(n.width(), n.height()))));
  const int x0 = quantile(xs, 0.002) - margin, x1 = quantile(xs, 0.998) + 1 + margin;
  const int y0 = quantile(ys, 0.002) - margin, y1 = quantile(ys, 0.998) + 1 + margin;
  return PixelRect{x0, y0, x1 - x0, y1 - y0}.intersect(n.rect());
}

// The fit at one width: (a, b, c) by least squares over the open beam,
// alternated with the fixed point for P.
struct WidthFit {
  double sigma_px = 0.0;  // binned pixels
  HaloBorder border = HaloBorder::kMirror;
  Coefficients k;
  double rms = 0.0;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  // How much the residual's correlation inflates a sum of squares'
  // fluctuation over white noise's (at least 1): see fitAtWidth.
  double correlation = 1.0;
};

// The residual's blocks: kCorrelationBlock binned pixels a side.
constexpr int kCorrelationBlock = 16;

WidthFit fitAtWidth(const Image& n, const std::vector<double>& attenuation,
                    const std::vector<int>& open, double sigma_px, HaloBorder border,
                    const InField& in) {
  WidthFit out;
  const WidthField wf = widthField(in, n, sigma_px, border);
  out.sigma_px = sigma_px;
  out.border = border;
  Image primary = n;
  const auto values = n.pixels();
  Eigen::Matrix3d normal;
  for (int step = 0; step < kFixedPointSteps; ++step) {
    const Image blurred = haloBlur(primary, sigma_px, border, wf);
    const auto g = blurred.pixels();
    normal.setZero();
    Eigen::Vector3d right = Eigen::Vector3d::Zero();
    for (const int i : open) {
      const Eigen::Vector3d row(1.0, static_cast<double>(g[static_cast<size_t>(i)]),
                                attenuation[static_cast<size_t>(i % n.width())]);
      normal += row * row.transpose();
      right += row * static_cast<double>(values[static_cast<size_t>(i)]);
    }
    const Eigen::Vector3d k = normal.completeOrthogonalDecomposition().solve(right);
    out.k = {k(0), k(1), k(2)};
    if (!(out.k.a > 0.05)) break;  // no primary left to solve for: the width is far off
    if (step + 1 == kFixedPointSteps) {
      // The residual, and its sums over blocks: the open beam's residual
      // also holds what no halo explains (the panel's gain pattern, the
      // heel, the previous shot's ghost), smooth over many pixels, so that
      // the residual's sum of squares fluctuates between widths by far more
      // than white noise's would. The ratio of the blocks' squared sums to
      // the pixels' (1 for white noise, up to a block's pixel count for a
      // residual smooth over it) says by how much.
      const int blocks_x = (n.width() + kCorrelationBlock - 1) / kCorrelationBlock;
      const int blocks_y = (n.height() + kCorrelationBlock - 1) / kCorrelationBlock;
      std::vector<double> block(static_cast<size_t>(blocks_x) * static_cast<size_t>(blocks_y), 0.0);
      double sum = 0.0;
      for (const int i : open) {
        const double r = static_cast<double>(values[static_cast<size_t>(i)]) - k(0) -
                         k(1) * static_cast<double>(g[static_cast<size_t>(i)]) -
                         k(2) * attenuation[static_cast<size_t>(i % n.width())];
        sum += r * r;
        block[static_cast<size_t>((i / n.width()) / kCorrelationBlock * blocks_x +
                                  (i % n.width()) / kCorrelationBlock)] += r;
      }
      double blocked = 0.0;
      for (const double b : block) blocked += b * b;
      out.correlation = sum > 0.0 ? std::max(1.0, blocked / sum) : 1.0;
      out.rms = std::sqrt(sum / static_cast<double>(open.size()));
      out.covariance = out.rms * out.rms * normal.completeOrthogonalDecomposition().pseudoInverse();
      return out;
    }
    primaryStep(n, attenuation, out.k, blurred, wf, primary);
  }
  out.rms = std::numeric_limits<double>::infinity();
  return out;
}

double weightOf(const Coefficients& k) { return k.b / (k.a + k.b); }

// Refuses an open beam too small, or not open (a part that fills the
// radiograph leaves pieces of itself outside the box of its sharp edges).
void checkOpenBeam(const Image& n, const std::vector<int>& open, const std::string& name,
                   const HaloOptions& options, HaloFit& out) {
  out.open_pixels = static_cast<int>(open.size());
  const double open_fraction = static_cast<double>(open.size()) / static_cast<double>(n.size());
  if (open_fraction < options.min_open_fraction)
    fail(
        "{}: the scatter's halo needs open beam around the part, and only {:.1f} % of the "
        "radiograph lies outside the part's shadow {} (at least {:.0f} %): give the job's "
        "\"scatter\"",
        name, 100.0 * open_fraction, toString(out.shadow), 100.0 * options.min_open_fraction);
  {
    std::vector<float> levels;
    for (const int i : open) levels.push_back(n.pixels()[static_cast<size_t>(i)]);
    const auto middle = levels.begin() + static_cast<std::ptrdiff_t>(levels.size() / 2);
    std::nth_element(levels.begin(), middle, levels.end());
    if (!(static_cast<double>(*middle) >= options.min_open_level))
      fail(
          "{}: the scatter's halo needs open beam around the part, and the radiograph outside "
          "the part's shadow {} is not open (its median {:.3f}, below {}): the part seems to "
          "fill the radiograph; give the job's \"scatter\"",
          name, toString(out.shadow), static_cast<double>(*middle), options.min_open_level);
  }
}

// A primary below -kNegativePrimary on more than kMaxNegativeFraction of
// the radiograph: the scatter removed is not the shot's (noise alone leaves
// a few pixels of the darkest paths below zero).
constexpr float kNegativePrimary = 0.01f;
constexpr double kMaxNegativeFraction = 0.001;

// The halo's width profile (searchWidth): kProfileSigmas standard
// deviations in one parameter, a rise of the open beam's residual sum of
// squares by its square times rms^2 (a claim that there is no scatter, or
// of a weight's spread, should not rest on a 2-sigma wobble of the
// profile). A scatter the open beam cannot bound below kMaxUnseenEffect
// (its largest change of the radiograph inside the part's shadow, in
// transmission) is not "none" but undecided.
constexpr double kProfileSigmas = 3.0;
constexpr double kMaxUnseenEffect = 0.005;

// How much a halo of width sigma_px changes the radiograph inside the
// part's shadow per unit weight: the median of |m - G(m)| over the pixels
// not in `open` (sorted), `smooth` the binned radiograph smoothed by one
// pixel (its noise is not a change). A narrow halo barely changes a smooth
// shadow whatever its weight (only its edges, which the median leaves out);
// one as wide as the detector adds a level that differs from the shadow by
// its contrast.
double shadowChange(const Image& smooth, const std::vector<int>& open, double sigma_px) {
  const Image blurred = gaussianBlur(smooth, sigma_px);
  std::vector<float> change;
  auto next = open.begin();
  for (size_t i = 0; i < smooth.pixels().size(); ++i) {
    if (next != open.end() && static_cast<size_t>(*next) == i) {
      ++next;
      continue;
    }
    change.push_back(std::abs(smooth.pixels()[i] - blurred.pixels()[i]));
  }
  if (change.empty()) return 0.0;
  const auto middle = change.begin() + static_cast<std::ptrdiff_t>(change.size() / 2);
  std::nth_element(change.begin(), middle, change.end());
  return static_cast<double>(*middle);
}

// The width's profile over the logarithmic grid of searchWidth, for one
// border: `fitAt(sigma_px, border)`.
template <typename FitAt>
std::vector<WidthFit> widthGrid(const FitAt& fitAt, HaloBorder border, double low, double high,
                                int points, double binned_pitch, const std::string& name) {
  std::vector<WidthFit> grid;
  for (int i = 0; i < points; ++i) {
    const double sigma = low * std::pow(high / low, i / (points - 1.0));
    grid.push_back(fitAt(sigma, border));
    spdlog::debug(
        "{}: halo ({} border) at sigma {:.3g} mm: rms {:.6g}, weight {:.4f}, correlation {:.1f}",
        name, toString(border), sigma * binned_pitch, grid.back().rms, weightOf(grid.back().k),
        grid.back().correlation);
  }
  return grid;
}

int bestOf(const std::vector<WidthFit>& grid) {
  return static_cast<int>(
      std::min_element(grid.begin(), grid.end(),
                       [](const WidthFit& p, const WidthFit& q) { return p.rms < q.rms; }) -
      grid.begin());
}

// The interval of ln(sigma) around the best width `t0` over which the open
// beam's residual sum of squares S stays within `limit`: the profile of the
// loss, which a flat or lopsided minimum widens where the curvature at the
// optimum would not. Each side is bracketed by the grid (`grid`, ascending
// widths) and bisected; a side that reaches the grid's end stays there.
template <typename SumAt>
std::pair<double, double> profileInterval(const SumAt& sumAt, const std::vector<WidthFit>& grid,
                                          double t0, double limit) {
  auto side = [&](int direction) {
    double inside = t0, outside = NAN;
    const int n = static_cast<int>(grid.size());
    for (int i = direction > 0 ? 0 : n - 1; i >= 0 && i < n; i += direction) {
      const double t = std::log(grid[static_cast<size_t>(i)].sigma_px);
      if ((t - t0) * direction <= 0.0) continue;
      if (!(sumAt(t) <= limit)) {
        outside = t;
        break;
      }
      inside = t;
    }
    if (std::isnan(outside)) return inside;
    for (int k = 0; k < 8; ++k) {
      const double mid = 0.5 * (inside + outside);
      (sumAt(mid) <= limit ? inside : outside) = mid;
    }
    return inside;
  };
  return {side(-1), side(+1)};
}

// The weight's standard uncertainty at one width, from the least squares'
// covariance of (a, b).
double weightUncertaintyOf(const WidthFit& fit) {
  const double s = fit.k.a + fit.k.b;
  const Eigen::Vector2d gradient(-fit.k.b / (s * s), fit.k.a / (s * s));
  return std::sqrt(std::max(0.0, gradient.dot(fit.covariance.topLeftCorner<2, 2>() * gradient)));
}

// A width of the grid and the weights the open beam allows there.
struct AllowedWeights {
  double sigma_px, low, high;
};

// The width between the grid's neighbours of its best point `best_at`, by
// golden sections on ln sigma (14 steps); `best` if none fits better.
template <typename FitAt>
WidthFit refineWidth(const FitAt& fitAt, const std::vector<WidthFit>& grid, int best_at,
                     const WidthFit& best) {
  double lo = std::log(grid[static_cast<size_t>(best_at - 1)].sigma_px);
  double hi = std::log(grid[static_cast<size_t>(best_at + 1)].sigma_px);
  const double ratio = 0.5 * (std::sqrt(5.0) - 1.0);
  auto at = [&](double t) { return fitAt(std::exp(t)); };
  double t1 = hi - ratio * (hi - lo), t2 = lo + ratio * (hi - lo);
  WidthFit f1 = at(t1), f2 = at(t2);
  for (int i = 0; i < 14; ++i) {
    if (f1.rms < f2.rms)
      hi = t2, t2 = t1, f2 = f1, t1 = hi - ratio * (hi - lo), f1 = at(t1);
    else
      lo = t1, t1 = t2, f1 = f2, t2 = lo + ratio * (hi - lo), f2 = at(t2);
  }
  if (f1.rms < best.rms || f2.rms < best.rms) return f1.rms < f2.rms ? f1 : f2;
  return best;
}

// No halo worth the name (searchWidth): a detector without scatter (or too
// little to see), or a blur no wider than the narrowest width searched.
// Fails when a width that explains the open beam as well allows a halo that
// would change the shadow by more than kMaxUnseenEffect; otherwise `out`
// gets no scatter and a third of that change as unseen_change.
void noMeasurableHalo(const WidthFit& best, const std::vector<AllowedWeights>& allowed_weights,
                      const Image& n, const std::vector<int>& open, const Image& normalized,
                      double binned_pitch, const std::string& name, const HaloOptions& options,
                      HaloFit& out) {
  const Image smooth = gaussianBlur(n, 1.0);
  double effect = 0.0, weight_at_effect = 0.0, sigma_mm = 0.0;
  for (const AllowedWeights& allowed : allowed_weights) {
    const double bound =
        std::min(std::max(std::abs(allowed.low), std::abs(allowed.high)), options.max_weight);
    const double change = bound * shadowChange(smooth, open, allowed.sigma_px);
    if (change > effect)
      effect = change, weight_at_effect = bound, sigma_mm = allowed.sigma_px * binned_pitch;
  }
  if (!(effect <= kMaxUnseenEffect))
    fail(
        "{}: the scatter's halo does not decide the scatter: no halo fits the open beam around "
        "the part, and so does one of weight {:.3f} at sigma {:.3g} mm, which would change "
        "the part's shadow by up to {:.3f} (the open beam is too small or too far from the "
        "part to tell a halo that wide from the open level): give the job's \"scatter\"",
        name, weight_at_effect, sigma_mm, effect);
  spdlog::warn(
      "{}: no measurable scatter halo (weight {:.4f} +- {:.4f} at sigma {:.3g} mm; of the "
      "widths that fit as well, a weight of {:.4f} at {:.3g} mm would change the shadow most, "
      "by {:.4f}): scatter left out, a third of that change counted in the curve's "
      "uncertainty",
      name, weightOf(best.k), weightUncertaintyOf(best), best.sigma_px * binned_pitch,
      weight_at_effect, sigma_mm, effect);
  out.column_darkening = -best.k.c / (best.k.a + best.k.b);
  out.open_level = 1.0 / (best.k.a + best.k.b);
  out.rms = best.rms;
  out.unseen_change = effect / kProfileSigmas;
  // Without a halo G(P) is 1 in the open beam: a + b is its level.
  out.primary =
      solvePrimary(normalized, columnAttenuation(normalized), {best.k.a + best.k.b, 0.0, best.k.c},
                   1.0, HaloBorder::kMirror, InField{});
}

// A scatter removed that was not there leaves the darkest paths below
// zero: the open beam's halo was something else (Error).
void checkPrimaryNotNegative(const Image& primary, double weight, double sigma_mm,
                             const std::string& name) {
  int64_t negative = 0;
  for (const float p : primary.pixels()) negative += p < -kNegativePrimary;
  const double fraction = static_cast<double>(negative) / static_cast<double>(primary.size());
  if (fraction > kMaxNegativeFraction)
    fail(
        "{}: the scatter fitted to the open beam (weight {:.4f}, sigma {:.3g} mm) leaves {:.2f} % "
        "of the radiograph below zero once removed: it is not the scatter of this shot; give the "
        "job's \"scatter\"",
        name, weight, sigma_mm, 100.0 * fraction);
}

// The other borders: one whose best width fits the open beam as well
// (its S within kProfileSigmas^2 c rms^2 of the chosen one's) is not ruled
// out by the shot, and the halo's uncertainty covers both (half their
// difference, as a standard uncertainty).
void widenForOtherBorders(const std::vector<std::vector<WidthFit>>& grids, size_t chosen,
                          const WidthFit& best, size_t count,
                          const std::vector<HaloBorder>& borders, double binned_pitch,
                          const std::string& name, double& u_weight, double& u_log_sigma) {
  auto sum = [&](const WidthFit& fit) { return fit.rms * fit.rms * static_cast<double>(count); };
  const double correlation = best.correlation, weight = weightOf(best.k);
  const double t = std::log(best.sigma_px);
  const HaloBorder border = borders[chosen];
  for (size_t b = 0; b < grids.size(); ++b) {
    if (b == chosen) continue;
    const WidthFit& other = grids[b][static_cast<size_t>(bestOf(grids[b]))];
    const double excess = (sum(other) - sum(best)) / (correlation * best.rms * best.rms);
    spdlog::info(
        "{}: the halo with a {} border: weight {:.4f}, sigma {:.3g} mm, its open beam's residual "
        "sum of squares {:.1f} (correlated) variances above the {} border's",
        name, toString(borders[b]), weightOf(other.k), other.sigma_px * binned_pitch, excess,
        toString(border));
    if (!(excess <= kProfileSigmas * kProfileSigmas)) continue;
    u_weight = std::hypot(u_weight, 0.5 * std::abs(weightOf(other.k) - weight));
    u_log_sigma = std::hypot(u_log_sigma, 0.5 * std::abs(std::log(other.sigma_px) - t));
  }
}

// The width's search and what follows from its best fit, shared by both
// estimates: `fitAt(sigma_px, border)` fits (a, b, c) at one width (binned
// pixels) over the pixels `open` (sorted) of `n`, the radiograph binned;
// `out` has its binning and shadow set.
template <typename FitAtBorder>
void searchWidth(const FitAtBorder& fitAtBorder, const Image& n, const std::vector<int>& open,
                 const Image& normalized, double pitch_mm, const std::string& name,
                 const HaloOptions& options, HaloFit& out) {
  const size_t count = open.size();
  // The width: a logarithmic grid per border, the border whose grid fits the
  // open beam best, then golden sections around its best point.
  const int width = std::max(normalized.width(), normalized.height()) / out.binning;
  const double binned_pitch = pitch_mm * out.binning;
  const double low = std::max(options.min_sigma_px, options.min_sigma_mm / pitch_mm) / out.binning;
  const double high = options.max_sigma_fraction * width;
  constexpr int kGrid = 24;
  XG_CHECK(!options.borders.empty(), "a halo search needs a border to try");
  std::vector<std::vector<WidthFit>> grids;
  for (const HaloBorder border : options.borders)
    grids.push_back(widthGrid(fitAtBorder, border, low, high, kGrid, binned_pitch, name));
  size_t chosen = 0;
  for (size_t b = 1; b < grids.size(); ++b)
    if (grids[b][static_cast<size_t>(bestOf(grids[b]))].rms <
        grids[chosen][static_cast<size_t>(bestOf(grids[chosen]))].rms)
      chosen = b;
  const HaloBorder border = options.borders[chosen];
  const std::vector<WidthFit>& grid = grids[chosen];
  const auto fitAt = [&](double sigma) { return fitAtBorder(sigma, border); };
  for (const WidthFit& fit : grid)
    out.sigma_mm.push_back(fit.sigma_px * binned_pitch), out.residual_rms.push_back(fit.rms);
  const int best_at = bestOf(grid);
  WidthFit best = grid[static_cast<size_t>(best_at)];
  // What no detector does: the fit has explained something else.
  // At the narrowest width the blur is about 1 all over the open beam, which
  // leaves the split between a and b (the weight) undecided.
  auto checkPlausible = [&](const WidthFit& fit, bool weight_decided) {
    const double darkening = -fit.k.c / (fit.k.a + fit.k.b);
    if (!std::isfinite(fit.rms) || (weight_decided && !(weightOf(fit.k) <= options.max_weight)) ||
        !(std::abs(darkening) <= options.max_column_darkening))
      fail(
          "{}: the scatter's halo does not fit the open beam around the part as a scatter: "
          "weight {:.3f} (at most {}), column darkening {:.3f} (at most {}), sigma {:.3g} mm: "
          "what lies outside the part's shadow {} is probably not open beam; give the job's "
          "\"scatter\"",
          name, weightOf(fit.k), options.max_weight, darkening, options.max_column_darkening,
          fit.sigma_px * binned_pitch, toString(out.shadow));
  };
  checkPlausible(best, best_at != 0);
  auto sum = [&](const WidthFit& fit) { return fit.rms * fit.rms * static_cast<double>(count); };
  // The weights the open beam allows: at every width of the grid whose
  // residual sum of squares is within kProfileSigmas^2 rms^2 of the best,
  // times the residual's correlation (as well explained), the weight give or
  // take kProfileSigmas of its standard uncertainties. A halo much wider
  // than the open beam is a near-uniform level over it, which trades with
  // the open level: a wide halo of any weight may then fit as well as none,
  // and the range says so.
  auto allowedWeights = [&](const WidthFit& best_fit) {
    std::vector<AllowedWeights> allowed;
    const double limit = sum(best_fit) + kProfileSigmas * kProfileSigmas * best_fit.correlation *
                                             best_fit.rms * best_fit.rms;
    for (const WidthFit& fit : grid) {
      if (!(sum(fit) <= limit)) continue;
      const double w = weightOf(fit.k), u = weightUncertaintyOf(fit) * std::sqrt(fit.correlation);
      allowed.push_back({fit.sigma_px, w - kProfileSigmas * u, w + kProfileSigmas * u});
    }
    return allowed;
  };
  // No halo worth the name: a detector without scatter (or too little to
  // see), whose width is then arbitrary and does not matter; or a blur no
  // wider than the narrowest width searched, which is the detector's
  // unsharpness rather than a halo. Said only when no width that explains
  // the open beam as well allows a halo that would change the shadow by
  // more than kMaxUnseenEffect (its weight's bound, at most max_weight: no
  // scintillator scatters more, times shadowChange at its width); a third of
  // the largest change counts in the curve's uncertainty.
  if (best_at == 0 || weightOf(best.k) < std::max(0.003, 3.0 * weightUncertaintyOf(best))) {
    noMeasurableHalo(best, allowedWeights(best), n, open, normalized, binned_pitch, name, options,
                     out);
    return;
  }
  if (best_at == kGrid - 1)
    fail(
        "{}: the scatter's halo does not decide its width: the open beam's residual is smallest "
        "at the end of the search, sigma = {:.3g} mm ({:.0f} px): give the job's \"scatter\"",
        name, best.sigma_px * binned_pitch, best.sigma_px * out.binning);
  best = refineWidth(fitAt, grid, best_at, best);
  checkPlausible(best, true);
  auto at = [&](double t) { return fitAt(std::exp(t)); };

  // Uncertainties: the width's from the curvature of the residual sum of
  // squares S(ln sigma) (a change of S by 2 c rms^2 is one standard
  // deviation), the weight's from the least squares at that width combined
  // with its change across the width's uncertainty. Both are widened by the
  // residual's correlation c (fitAtWidth): what no halo explains (the
  // panel's fixed pattern, the heel, the previous shot's ghost, a glare the
  // Gaussian does not describe) is smooth over many pixels, and makes S and
  // the least squares fluctuate c times more than white noise would.
  const double correlation = best.correlation;
  const double t = std::log(best.sigma_px), h = 0.05;
  const WidthFit minus = at(t - h), plus = at(t + h);
  const double curvature = (sum(plus) - 2.0 * sum(best) + sum(minus)) / (h * h);
  double u_log_sigma =
      curvature > 0.0 ? std::sqrt(2.0 * correlation * best.rms * best.rms / curvature) : HUGE_VAL;
  const WidthFit wider = at(t + std::min(u_log_sigma, 0.5)),
                 narrower = at(t - std::min(u_log_sigma, 0.5));
  const double weight = weightOf(best.k);
  // Never less than the spread of the weights the grid's widths allow (a
  // flat profile the curvature at the optimum does not see).
  double lowest = HUGE_VAL, highest = -HUGE_VAL;
  for (const AllowedWeights& allowed : allowedWeights(best))
    lowest = std::min(lowest, allowed.low), highest = std::max(highest, allowed.high);
  double u_weight = std::max(std::hypot(weightUncertaintyOf(best) * std::sqrt(correlation),
                                        0.5 * std::abs(weightOf(wider.k) - weightOf(narrower.k))),
                             (highest - lowest) / (2.0 * kProfileSigmas));
  const double sigma_mm = best.sigma_px * binned_pitch;
  // The profile of the loss over the width (one standard deviation: S within
  // c rms^2 of its least), rather than only its curvature at the optimum:
  // the widths and weights that fit the open beam within its noise.
  {
    const auto [t_low, t_high] = profileInterval(
        [&](double ln_sigma) { return sum(at(ln_sigma)); }, grid, t,
        sum(best) + correlation * best.rms * best.rms);
    const double w_low = weightOf(at(t_low).k), w_high = weightOf(at(t_high).k);
    spdlog::debug("{}: the halo's width profile: sigma {:.3g} .. {:.3g} mm, weight {:.4f} .. {:.4f}",
                  name, std::exp(t_low) * binned_pitch, std::exp(t_high) * binned_pitch, w_low,
                  w_high);
    u_log_sigma = std::max(u_log_sigma, std::max(t - t_low, t_high - t));
    u_weight = std::max(u_weight, std::max(std::abs(w_low - weight), std::abs(w_high - weight)));
  }
  widenForOtherBorders(grids, chosen, best, count, options.borders, binned_pitch, name, u_weight,
                       u_log_sigma);
  if (!(u_log_sigma < 0.5) || !(u_weight < 0.5 * weight) || !(weight < 0.9))
    fail(
        "{}: the scatter's halo does not decide the scatter: weight {:.4f} +- {:.4f}, sigma "
        "{:.3g} mm +- {:.0f} % (the open beam around the part is too small or too far from it): "
        "give the job's \"scatter\"",
        name, weight, u_weight, sigma_mm, 100.0 * (std::exp(std::min(u_log_sigma, 5.0)) - 1.0));

  out.scatter.weight = weight;
  out.scatter.sigma_mm = sigma_mm;
  out.scatter.border = border;
  out.scatter.weight_uncertainty = u_weight;
  out.scatter.sigma_uncertainty_mm = sigma_mm * u_log_sigma;
  out.correlation = correlation;
  out.column_darkening = -best.k.c / (best.k.a + best.k.b);
  out.open_level = 1.0 / (best.k.a + best.k.b);
  out.rms = best.rms;
  out.primary = solvePrimary(normalized, columnAttenuation(normalized), best.k, sigma_mm / pitch_mm,
                             border, InField{&options.field, pitch_mm, 1.0});
  checkPrimaryNotNegative(out.primary, weight, sigma_mm, name);
}

// The fit over the open beam `open` (pixels of `n`, the radiograph binned
// by out.binning): its checks, then the width's search.
void fitOpenBeam(const Image& n, const std::vector<int>& open, const Image& normalized,
                 double pitch_mm, const std::string& name, const HaloOptions& options,
                 HaloFit& out) {
  checkOpenBeam(n, open, name, options, out);
  const std::vector<double> attenuation = columnAttenuation(n);
  searchWidth(
      [&](double sigma, HaloBorder border) {
        return fitAtWidth(
            n, attenuation, open, sigma, border,
            InField{&options.field, pitch_mm * out.binning, static_cast<double>(out.binning)});
      },
      n, open, normalized, pitch_mm, name, options, out);
}

}  // namespace

Image HaloFit::primaryWith(const Image& normalized, double pitch_mm, double weight,
                           double sigma) const {
  const double c = -column_darkening / open_level;
  return solvePrimary(normalized, columnAttenuation(normalized),
                      {(1.0 - weight) / open_level, weight / open_level, c}, sigma / pitch_mm,
                      scatter.border, InField{&field, pitch_mm, 1.0});
}

HaloFit fitScatterHalo(const Image& normalized, double pitch_mm, const std::string& name,
                       const HaloOptions& options) {
  if (!(pitch_mm > 0.0)) fail("{}: the pixel pitch must be positive, got {}", name, pitch_mm);
  HaloFit out;
  out.field = options.field;
  Image n = normalized;
  while (std::max(n.width(), n.height()) > options.max_side) n = downsample2x(n), out.binning *= 2;

  // The open beam: outside the shadow's box, gross outliers (a fixture, a
  // collimator's edge) left out.
  const PixelRect box = shadowBox(n, name);
  spdlog::debug("{}: shadow box {} of {}x{} binned by {}", name, toString(box), n.width(),
                n.height(), out.binning);
  out.shadow = {box.x * out.binning, box.y * out.binning, box.width * out.binning,
                box.height * out.binning};
  std::vector<int> open;
  for (int y = 0; y < n.height(); ++y)
    for (int x = 0; x < n.width(); ++x) {
      const bool inside = x >= box.x && x < box.right() && y >= box.y && y < box.bottom();
      if (!inside && n(x, y) > 0.5f && n(x, y) < 1.5f) open.push_back(y * n.width() + x);
    }
  fitOpenBeam(n, open, normalized, pitch_mm, name, options, out);
  return out;
}

HaloFit fitScatterWithPaths(const Image& normalized, const Image& path_mm, double pitch_mm,
                            const std::string& name, const HaloOptions& options) {
  if (!(pitch_mm > 0.0)) fail("{}: the pixel pitch must be positive, got {}", name, pitch_mm);
  HaloFit out;
  out.field = options.field;
  Image n = normalized;
  while (n.width() > path_mm.width() && n.width() > 1) n = downsample2x(n), out.binning *= 2;
  if (n.width() != path_mm.width() || n.height() != path_mm.height())
    fail(
        "{}: the path map is {}x{}, and no binning of the {}x{} radiograph by a power of 2 has "
        "that size",
        name, path_mm.width(), path_mm.height(), normalized.width(), normalized.height());
  // The open beam: no path at the pixel or its 8 neighbours (a pixel the
  // outline crosses may have none at its centre); its box, the shadow.
  std::vector<int> open;
  int x0 = n.width(), y0 = n.height(), x1 = 0, y1 = 0;
  for (int y = 0; y < n.height(); ++y)
    for (int x = 0; x < n.width(); ++x) {
      bool clear = true;
      for (int v = std::max(0, y - 1); v <= std::min(n.height() - 1, y + 1); ++v)
        for (int u = std::max(0, x - 1); u <= std::min(n.width() - 1, x + 1); ++u)
          clear &= !(path_mm(u, v) > 0.0f);
      if (path_mm(x, y) > 0.0f)
        x0 = std::min(x0, x), y0 = std::min(y0, y), x1 = std::max(x1, x + 1),
        y1 = std::max(y1, y + 1);
      if (clear && n(x, y) > 0.5f && n(x, y) < 1.5f) open.push_back(y * n.width() + x);
    }
  if (x1 <= x0) fail("{}: the part's model casts no shadow in the radiograph", name);
  out.shadow = {x0 * out.binning, y0 * out.binning, (x1 - x0) * out.binning,
                (y1 - y0) * out.binning};
  fitOpenBeam(n, open, normalized, pitch_mm, name, options, out);
  return out;
}

}  // namespace xgauge
