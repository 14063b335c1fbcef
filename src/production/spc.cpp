#include "xgauge/production/spc.h"

#include "xgauge/core/error.h"

#include <boost/math/distributions/chi_squared.hpp>
#include <boost/math/distributions/normal.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>

namespace xgauge {

namespace {

double mean(const std::vector<double>& v) {
  return std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

}  // namespace

ControlLimits controlLimits(const std::vector<double>& baseline) {
  if (baseline.size() < 2)
    fail("SPC needs at least 2 parts in the baseline, got {}", baseline.size());
  ControlLimits l;
  l.baseline_n = baseline.size();
  l.centre = mean(baseline);
  double sum = 0.0;
  for (size_t i = 1; i < baseline.size(); ++i) sum += std::abs(baseline[i] - baseline[i - 1]);
  l.mr_bar = sum / static_cast<double>(baseline.size() - 1);
  l.sigma_within = l.mr_bar / kD2;
  l.lower = l.centre - 3.0 * l.sigma_within;
  l.upper = l.centre + 3.0 * l.sigma_within;
  l.mr_upper = kD4 * l.mr_bar;
  return l;
}

std::string ruleName(SpcRule rule) {
  if (rule == SpcRule::kMovingRange) return "mr-1";
  return "nelson-" + std::to_string(static_cast<int>(rule));
}

std::string ruleDescription(SpcRule rule) {
  switch (rule) {
    case SpcRule::kBeyond3Sigma:
      return "one point beyond 3 sigma";
    case SpcRule::kNineOneSide:
      return "nine points in a row on one side of the centre line";
    case SpcRule::kSixTrending:
      return "six points in a row steadily increasing or decreasing";
    case SpcRule::kFourteenAlternating:
      return "fourteen points in a row alternating up and down";
    case SpcRule::kTwoOfThreeBeyond2:
      return "two of three points in a row beyond 2 sigma on one side";
    case SpcRule::kFourOfFiveBeyond1:
      return "four of five points in a row beyond 1 sigma on one side";
    case SpcRule::kFifteenWithin1:
      return "fifteen points in a row within 1 sigma of the centre line";
    case SpcRule::kEightBeyond1:
      return "eight points in a row beyond 1 sigma, on either side";
    case SpcRule::kMovingRange:
      return "a moving range above the moving-range chart's upper limit";
  }
  return "";
}

std::vector<SpcRule> allRules() {
  return {SpcRule::kBeyond3Sigma,        SpcRule::kNineOneSide,       SpcRule::kSixTrending,
          SpcRule::kFourteenAlternating, SpcRule::kTwoOfThreeBeyond2, SpcRule::kFourOfFiveBeyond1,
          SpcRule::kFifteenWithin1,      SpcRule::kEightBeyond1,      SpcRule::kMovingRange};
}

namespace {

// Whether point i completes `rule`'s pattern (z: points in sigma units from
// the centre line).
bool completes(SpcRule rule, const std::vector<double>& x, const std::vector<double>& z,
               const ControlLimits& limits, size_t i) {
  const auto window = [&](size_t n) { return i + 1 >= n; };
  const auto sign = [](double v) { return (v > 0) - (v < 0); };
  switch (rule) {
    case SpcRule::kBeyond3Sigma:
      return std::abs(z[i]) > 3.0;
    case SpcRule::kNineOneSide: {
      if (!window(9) || sign(z[i]) == 0) return false;
      for (size_t j = i - 8; j < i; ++j)
        if (sign(z[j]) != sign(z[i])) return false;
      return true;
    }
    case SpcRule::kSixTrending: {
      if (!window(6)) return false;
      bool up = true, down = true;
      for (size_t j = i - 4; j <= i; ++j) {
        up &= x[j] > x[j - 1];
        down &= x[j] < x[j - 1];
      }
      return up || down;
    }
    case SpcRule::kFourteenAlternating: {
      if (!window(14)) return false;
      for (size_t j = i - 12; j <= i; ++j) {
        const int d = sign(x[j] - x[j - 1]);
        if (d == 0) return false;
        if (j > i - 12 && d == sign(x[j - 1] - x[j - 2])) return false;
      }
      return true;
    }
    case SpcRule::kTwoOfThreeBeyond2:
    case SpcRule::kFourOfFiveBeyond1: {
      const bool two = rule == SpcRule::kTwoOfThreeBeyond2;
      const size_t n = two ? 3 : 5, need = two ? 2 : 4;
      const double level = two ? 2.0 : 1.0;
      if (!window(n) || std::abs(z[i]) <= level) return false;
      size_t count = 0;
      for (size_t j = i + 1 - n; j <= i; ++j) count += (z[i] > 0 ? z[j] > level : z[j] < -level);
      return count >= need;
    }
    case SpcRule::kFifteenWithin1: {
      if (!window(15)) return false;
      for (size_t j = i - 14; j <= i; ++j)
        if (std::abs(z[j]) >= 1.0) return false;
      return true;
    }
    case SpcRule::kEightBeyond1: {
      if (!window(8)) return false;
      for (size_t j = i - 7; j <= i; ++j)
        if (std::abs(z[j]) <= 1.0) return false;
      return true;
    }
    case SpcRule::kMovingRange:
      return i >= 1 && std::abs(x[i] - x[i - 1]) > limits.mr_upper;
  }
  return false;
}

}  // namespace

std::vector<RuleHit> applyRules(const std::vector<double>& values, const ControlLimits& limits,
                                const std::vector<SpcRule>& rules, bool first_of_run) {
  XG_CHECK(limits.sigma_within >= 0.0);
  std::vector<double> z(values.size());
  for (size_t i = 0; i < values.size(); ++i)
    z[i] = limits.sigma_within > 0
               ? (values[i] - limits.centre) / limits.sigma_within
               : (values[i] == limits.centre ? 0.0 : HUGE_VAL * (values[i] - limits.centre));
  std::vector<RuleHit> hits;
  for (size_t i = 0; i < values.size(); ++i)
    for (SpcRule rule : rules)
      if (completes(rule, values, z, limits, i) &&
          !(first_of_run && i > 0 && completes(rule, values, z, limits, i - 1)))
        hits.push_back({rule, i});
  return hits;
}

Capability capability(const std::vector<double>& baseline, double lsl, double usl,
                      double confidence) {
  if (baseline.size() < 2) fail("capability needs at least 2 parts, got {}", baseline.size());
  if (!(lsl < usl)) fail("capability needs a lower limit below the upper one");
  Capability c;
  c.n = baseline.size();
  c.confidence = confidence;
  c.mean = mean(baseline);
  double ss = 0.0;
  for (double v : baseline) ss += (v - c.mean) * (v - c.mean);
  const double nu = static_cast<double>(c.n - 1);
  c.s = std::sqrt(ss / nu);
  const double alpha = 1.0 - confidence;
  c.cp.value = (usl - lsl) / (6.0 * c.s);
  c.cp.low = c.cp.value * std::sqrt(chiSquareQuantile(alpha / 2, nu) / nu);
  c.cp.high = c.cp.value * std::sqrt(chiSquareQuantile(1 - alpha / 2, nu) / nu);
  c.cpk.value = std::min(usl - c.mean, c.mean - lsl) / (3.0 * c.s);
  const double n = static_cast<double>(c.n);
  const double half = normalQuantile(1 - alpha / 2) *
                      std::sqrt(1.0 / (9.0 * n) + c.cpk.value * c.cpk.value / (2.0 * nu));
  c.cpk.low = c.cpk.value - half;
  c.cpk.high = c.cpk.value + half;
  return c;
}

double quantile(std::vector<double> values, double q) {
  XG_CHECK(!values.empty() && q >= 0.0 && q <= 1.0, "n = {}, q = {}", values.size(), q);
  std::sort(values.begin(), values.end());
  const double at = q * static_cast<double>(values.size() - 1);
  const size_t below = static_cast<size_t>(std::floor(at));
  if (below + 1 >= values.size()) return values.back();
  return values[below] + (at - static_cast<double>(below)) * (values[below + 1] - values[below]);
}

HistogramBins histogramBins(const std::vector<double>& values) {
  XG_CHECK(!values.empty());
  const auto [lo_it, hi_it] = std::minmax_element(values.begin(), values.end());
  const double lo = *lo_it, hi = *hi_it, range = hi - lo;
  const double n = static_cast<double>(values.size());
  HistogramBins h;
  const double iqr = quantile(values, 0.75) - quantile(values, 0.25);
  double s = 0.0;
  if (values.size() > 1) {
    const double m = mean(values);
    for (double v : values) s += (v - m) * (v - m);
    s = std::sqrt(s / (n - 1.0));
  }
  if (range > 0.0 && iqr > 0.0) {
    h.rule = "freedman-diaconis";
    h.width = 2.0 * iqr / std::cbrt(n);
  } else if (range > 0.0 && s > 0.0) {
    h.rule = "scott";
    h.width = 3.49 * s / std::cbrt(n);
  } else {
    // Every value the same: one bin around it, as wide as a part in a
    // million of the value (or 1e-6 at zero), so that the bar has a width.
    h.rule = "single";
    h.width = std::max(1e-6, 1e-6 * std::abs(lo));
    h.count = 1;
    h.start = lo - h.width / 2;
    h.counts = {values.size()};
    return h;
  }
  const double bins = std::max(1.0, std::ceil(range / h.width));
  if (bins > static_cast<double>(kMaxHistogramBins)) {
    h.count = kMaxHistogramBins;
    h.width = range / static_cast<double>(kMaxHistogramBins);
  } else {
    h.count = static_cast<size_t>(bins);
  }
  h.start = lo - (static_cast<double>(h.count) * h.width - range) / 2.0;
  h.counts.assign(h.count, 0);
  for (double v : values) {
    const double at = std::floor((v - h.start) / h.width);
    ++h.counts[static_cast<size_t>(std::clamp(at, 0.0, static_cast<double>(h.count - 1)))];
  }
  return h;
}

double normalQuantile(double p) {
  XG_CHECK(p > 0.0 && p < 1.0, "p = {}", p);
  return boost::math::quantile(boost::math::normal(), p);
}

double chiSquareCdf(double x, double nu) {
  XG_CHECK(nu > 0.0, "nu = {}", nu);
  return x <= 0.0 ? 0.0 : boost::math::cdf(boost::math::chi_squared(nu), x);
}

double chiSquareQuantile(double p, double nu) {
  XG_CHECK(p > 0.0 && p < 1.0 && nu > 0.0, "p = {}, nu = {}", p, nu);
  return boost::math::quantile(boost::math::chi_squared(nu), p);
}

}  // namespace xgauge
