#include "xgauge/production/spc.h"

#include "xgauge/core/error.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>

namespace xgauge {

namespace {

double mean(const std::vector<double>& v) {
  return std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

// Regularized lower incomplete gamma P(a, x): its series below a + 1, the
// continued fraction of Q = 1 - P above (Numerical Recipes, 6.2).
double lowerGammaRegularized(double a, double x) {
  if (x <= 0) return 0.0;
  const double log_prefix = a * std::log(x) - x - std::lgamma(a);
  if (x < a + 1.0) {
    double term = 1.0 / a, sum = term;
    for (int n = 1; n < 10000 && std::abs(term) > 1e-17 * std::abs(sum); ++n) {
      term *= x / (a + n);
      sum += term;
    }
    return sum * std::exp(log_prefix);
  }
  constexpr double tiny = 1e-300;
  double b = x + 1.0 - a, c = 1.0 / tiny, d = 1.0 / b, h = d;
  for (int i = 1; i < 10000; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::abs(d) < tiny) d = tiny;
    c = b + an / c;
    if (std::abs(c) < tiny) c = tiny;
    d = 1.0 / d;
    const double step = d * c;
    h *= step;
    if (std::abs(step - 1.0) < 1e-16) break;
  }
  return 1.0 - std::exp(log_prefix) * h;
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

double normalQuantile(double p) {
  XG_CHECK(p > 0.0 && p < 1.0, "p = {}", p);
  // P. J. Acklam's coefficients.
  static const double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,  -2.759285104469687e+02,
                             1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  static const double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                             6.680131188771972e+01, -1.328068155288572e+01};
  static const double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                             -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  static const double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                             3.754408661907416e+00};
  constexpr double low = 0.02425;
  double x;
  if (p < low) {
    const double q = std::sqrt(-2 * std::log(p));
    x = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
        ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
  } else if (p <= 1 - low) {
    const double q = p - 0.5, r = q * q;
    x = (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
        (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
  } else {
    const double q = std::sqrt(-2 * std::log(1 - p));
    x = -(((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
        ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
  }
  // One Halley step on the exact distribution function.
  const double e = 0.5 * std::erfc(-x / std::sqrt(2.0)) - p;
  const double u = e * std::sqrt(2 * std::numbers::pi) * std::exp(x * x / 2);
  return x - u / (1 + x * u / 2);
}

double chiSquareCdf(double x, double nu) { return lowerGammaRegularized(nu / 2, x / 2); }

double chiSquareQuantile(double p, double nu) {
  XG_CHECK(p > 0.0 && p < 1.0 && nu > 0.0, "p = {}, nu = {}", p, nu);
  const double z = normalQuantile(p);
  const double h = 2.0 / (9.0 * nu);
  double x = std::max(1e-8, nu * std::pow(std::max(1.0 - h + z * std::sqrt(h), 1e-3), 3));
  for (int i = 0; i < 100; ++i) {
    const double f = chiSquareCdf(x, nu) - p;
    const double log_pdf =
        (nu / 2 - 1) * std::log(x) - x / 2 - (nu / 2) * std::log(2.0) - std::lgamma(nu / 2);
    const double step = f / std::exp(log_pdf);
    double next = x - step;
    if (next <= 0) next = x / 2;
    if (std::abs(next - x) <= 1e-13 * x) return next;
    x = next;
  }
  return x;
}

}  // namespace xgauge
