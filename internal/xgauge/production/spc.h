// Statistical process control of one dimension over a lot: an individuals
// (X) chart and a moving-range (MR) chart with limits from a phase-I
// baseline, the Western Electric / Nelson run rules, and the process
// capability with confidence intervals. Plain computation over a series of
// values in production order; production/spc_page.h draws the page.
//
// Formulas (Montgomery, "Introduction to Statistical Quality Control", 6th
// ed., ch. 6.4 and 8):
//   moving range MR_i = |x_i - x_{i-1}|; MR-bar its mean over the baseline;
//   sigma_within = MR-bar / d2, d2 = 1.128 (n = 2);
//   X chart: centre x-bar (baseline mean), limits x-bar +- 3 sigma_within;
//   MR chart: centre MR-bar, upper limit D4 MR-bar, D4 = 3.267.
// Capability from the baseline's sample standard deviation s (so that the
// intervals below hold exactly for normal data):
//   Cp = (USL - LSL) / 6 s, Cpk = min(USL - x-bar, x-bar - LSL) / 3 s;
//   Cp's interval Cp sqrt(chi2_{a/2, n-1} / (n-1)) .. Cp sqrt(chi2_{1-a/2, n-1} / (n-1));
//   Cpk's, Bissell (1990): Cpk -+ z_{1-a/2} sqrt(1 / 9n + Cpk^2 / 2(n-1)).
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace xgauge {

struct ControlLimits {
  size_t baseline_n = 0;
  double centre = 0.0;              // x-bar
  double sigma_within = 0.0;        // MR-bar / d2
  double lower = 0.0, upper = 0.0;  // x-bar -+ 3 sigma_within
  double mr_bar = 0.0, mr_upper = 0.0;
};
inline constexpr double kD2 = 1.128;
inline constexpr double kD4 = 3.267;

// Limits from `baseline` (at least 2 values; Error otherwise).
ControlLimits controlLimits(const std::vector<double>& baseline);

// The run rules, as Nelson (1984) numbers them; Western Electric's four
// are Nelson's 1, 5, 6 and (with 8 points) 2.
enum class SpcRule {
  kBeyond3Sigma = 1,         // one point beyond 3 sigma
  kNineOneSide = 2,          // nine in a row on one side of the centre line
  kSixTrending = 3,          // six in a row steadily increasing or decreasing
  kFourteenAlternating = 4,  // fourteen in a row alternating up and down
  kTwoOfThreeBeyond2 = 5,    // two of three beyond 2 sigma on one side
  kFourOfFiveBeyond1 = 6,    // four of five beyond 1 sigma on one side
  kFifteenWithin1 = 7,       // fifteen in a row within 1 sigma (stratification)
  kEightBeyond1 = 8,         // eight in a row beyond 1 sigma, either side
  kMovingRange = 9,          // a moving range above the MR chart's upper limit
};
std::string ruleName(SpcRule rule);         // "nelson-1" ... "nelson-8", "mr-1"
std::string ruleDescription(SpcRule rule);  // the sentences above

struct RuleHit {
  SpcRule rule;
  size_t index = 0;  // 0-based: the point that completes the pattern
};

// Every point that completes a rule's pattern, by index then rule; with
// `first_of_run`, only the first of consecutive points that complete the
// same rule (the part that triggered the alarm, not every part after it).
std::vector<RuleHit> applyRules(const std::vector<double>& values, const ControlLimits& limits,
                                const std::vector<SpcRule>& rules, bool first_of_run = true);
std::vector<SpcRule> allRules();

struct Interval {
  double value = 0.0, low = 0.0, high = 0.0;
};
struct Capability {
  size_t n = 0;
  double mean = 0.0, s = 0.0;
  Interval cp, cpk;
  double confidence = 0.95;
};

// Capability of `baseline` against [lsl, usl] (lsl < usl, n >= 2).
Capability capability(const std::vector<double>& baseline, double lsl, double usl,
                      double confidence = 0.95);

// A histogram's bins over a series, by a rule on the data alone (the
// tolerance does not set them; the page draws its limits as lines):
//   Freedman-Diaconis, width 2 IQR n^(-1/3) (IQR by linear interpolation
//   between order statistics, numpy's default); when the IQR is zero (more
//   than half the values equal), Scott's 3.49 s n^(-1/3) with s the sample
//   standard deviation; when every value is the same, one bin.
// The bins cover [min, max] (count = ceil((max - min) / width), at least 1
// and at most kMaxHistogramBins, widened to cover the range when capped),
// centred on the data's range; a value on an inner edge falls in the bin
// above it, the maximum in the last.
inline constexpr size_t kMaxHistogramBins = 100;
struct HistogramBins {
  std::string rule;  // "freedman-diaconis", "scott" or "single"
  double start = 0.0, width = 0.0;
  size_t count = 1;
  std::vector<size_t> counts;  // per bin
  double centre(size_t bin) const { return start + (static_cast<double>(bin) + 0.5) * width; }
};
HistogramBins histogramBins(const std::vector<double>& values);  // at least one value
// The q-quantile (0 <= q <= 1) by linear interpolation between order statistics.
double quantile(std::vector<double> values, double q);

// Quantiles of the standard normal and of the chi-square with nu degrees of
// freedom, and the chi-square's distribution function (Boost.Math).
double normalQuantile(double p);
double chiSquareQuantile(double p, double nu);
double chiSquareCdf(double x, double nu);

}  // namespace xgauge
