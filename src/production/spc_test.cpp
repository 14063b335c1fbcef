// SPC: limits, each run rule on a series built to trigger it at a known
// point (and not before), capability and its intervals against closed forms.
#include "xgauge/production/spc.h"

#include "xgauge/core/error.h"
#include "xgauge/production/spc_report.h"
#include "xgauge/production/store.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <random>

namespace xgauge {
namespace {

// Limits with centre 0 and sigma 1, so that values are in sigma units.
ControlLimits unitLimits() {
  ControlLimits l;
  l.baseline_n = 20;
  l.centre = 0.0;
  l.sigma_within = 1.0;
  l.lower = -3.0;
  l.upper = 3.0;
  l.mr_bar = kD2;
  l.mr_upper = kD4 * kD2;
  return l;
}

// Hits of one rule.
std::vector<size_t> hitsOf(SpcRule rule, const std::vector<double>& x) {
  std::vector<size_t> out;
  for (const auto& h : applyRules(x, unitLimits(), {rule})) out.push_back(h.index);
  return out;
}

// A quiet series: alternating small values (no rule but 4 and 7 can fire
// on it, so those tests build their own).
std::vector<double> quiet(size_t n) {
  std::vector<double> x(n);
  for (size_t i = 0; i < n; ++i) x[i] = (i % 3 == 0) ? 0.5 : (i % 3 == 1 ? -0.5 : 1.5);
  return x;
}

TEST(Spc, LimitsFromTheMovingRange) {
  // Moving ranges 1, 2, 3: MR-bar 2, sigma 2 / 1.128; mean 1.5.
  const ControlLimits l = controlLimits({0.0, 1.0, 3.0, 0.0});
  EXPECT_DOUBLE_EQ(l.centre, 1.0);
  EXPECT_DOUBLE_EQ(l.mr_bar, 2.0);
  EXPECT_DOUBLE_EQ(l.sigma_within, 2.0 / kD2);
  EXPECT_DOUBLE_EQ(l.upper, 1.0 + 3.0 * 2.0 / kD2);
  EXPECT_DOUBLE_EQ(l.mr_upper, kD4 * 2.0);
  EXPECT_THROW(controlLimits({1.0}), Error);
}

TEST(Spc, Rule1OnePointBeyondThreeSigma) {
  auto x = quiet(30);
  x[17] = 3.2;
  EXPECT_EQ(hitsOf(SpcRule::kBeyond3Sigma, x), std::vector<size_t>{17});
  x[17] = 2.9;
  EXPECT_TRUE(hitsOf(SpcRule::kBeyond3Sigma, x).empty());
}

TEST(Spc, Rule2NineOnOneSideFlaggedAtTheNinth) {
  std::vector<double> x(40);
  for (size_t i = 0; i < x.size(); ++i) x[i] = (i % 2 ? 0.4 : -0.4);
  for (size_t i = 10; i < 25; ++i) x[i] = 0.3;  // 15 above: one alarm, at the 9th
  x[9] = x[25] = -0.4;
  EXPECT_EQ(hitsOf(SpcRule::kNineOneSide, x), std::vector<size_t>{18});
  // Every completing point when asked for all of them.
  EXPECT_EQ(applyRules(x, unitLimits(), {SpcRule::kNineOneSide}, false).size(), 7u);
  x[14] = -0.3;  // broken into 4 + 10: the run of 10 completes at 23
  EXPECT_EQ(hitsOf(SpcRule::kNineOneSide, x), std::vector<size_t>{23});
}

TEST(Spc, Rule3SixTrending) {
  auto x = quiet(30);
  for (size_t i = 0; i < 6; ++i) x[20 + i] = -1.0 + 0.3 * static_cast<double>(i);
  EXPECT_EQ(hitsOf(SpcRule::kSixTrending, x), std::vector<size_t>{25});
  x[23] = x[22];  // a tie breaks the trend
  EXPECT_TRUE(hitsOf(SpcRule::kSixTrending, x).empty());
}

TEST(Spc, Rule4FourteenAlternating) {
  std::vector<double> x(30, 0.0);
  for (size_t i = 0; i < 30; ++i) x[i] = 0.01 * static_cast<double>(i);  // rising: no alternation
  for (size_t i = 10; i < 24; ++i) x[i] = (i % 2 ? 0.5 : -0.5);          // points 10..23
  x[9] = x[8];  // a tie: the alternation starts at 9 (down to 10, up to 11, ...)
  EXPECT_EQ(hitsOf(SpcRule::kFourteenAlternating, x), std::vector<size_t>{22});
}

TEST(Spc, Rule5TwoOfThreeBeyondTwoSigma) {
  auto x = quiet(30);
  x[12] = 2.5;
  x[14] = 2.2;
  EXPECT_EQ(hitsOf(SpcRule::kTwoOfThreeBeyond2, x), std::vector<size_t>{14});
  x[14] = -2.2;  // opposite sides do not count
  EXPECT_TRUE(hitsOf(SpcRule::kTwoOfThreeBeyond2, x).empty());
}

TEST(Spc, Rule6FourOfFiveBeyondOneSigma) {
  auto x = quiet(30);
  for (size_t i : {20, 21, 23, 24}) x[i] = -1.4;
  x[22] = 0.0;
  EXPECT_EQ(hitsOf(SpcRule::kFourOfFiveBeyond1, x), std::vector<size_t>{24});
}

TEST(Spc, Rule7FifteenWithinOneSigma) {
  std::vector<double> x(40, 1.5);
  for (size_t i = 0; i < 40; ++i) x[i] = (i % 2 ? 1.5 : -1.5);
  for (size_t i = 5; i < 20; ++i) x[i] = (i % 2 ? 0.5 : -0.5);  // 15 within
  EXPECT_EQ(hitsOf(SpcRule::kFifteenWithin1, x), std::vector<size_t>{19});
}

TEST(Spc, Rule8EightBeyondOneSigmaEitherSide) {
  auto x = quiet(30);
  for (size_t i = 0; i < 30; ++i) x[i] = 0.2;
  for (size_t i = 10; i < 18; ++i) x[i] = (i % 2 ? 1.2 : -1.3);
  EXPECT_EQ(hitsOf(SpcRule::kEightBeyond1, x), std::vector<size_t>{17});
}

TEST(Spc, MovingRangeAboveItsLimit) {
  auto x = quiet(30);
  x[8] = x[7] + 3.8;  // MR upper limit 3.267 * 1.128 = 3.685
  const auto hits = hitsOf(SpcRule::kMovingRange, x);
  ASSERT_FALSE(hits.empty());
  EXPECT_EQ(hits.front(), 8u);
}

TEST(Spc, ANormalProcessRaisesFewFalseAlarmsAndADriftIsCaught) {
  std::mt19937_64 rng(47);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<double> x(200);
  for (size_t i = 0; i < x.size(); ++i)
    x[i] = noise(rng) + (i >= 119 ? 0.6667 * static_cast<double>(i - 118) : 0.0);
  const ControlLimits l = controlLimits(std::vector<double>(x.begin(), x.begin() + 100));
  const auto hits = applyRules(x, l, allRules());
  size_t before = 0, first_after = x.size();
  for (const auto& h : hits) {
    if (h.index < 119)
      ++before;
    else
      first_after = std::min(first_after, h.index);
  }
  // About 3.6 expected from the nine rules' false-alarm rates over 119 points.
  EXPECT_LE(before, 8u);
  // A drift of 2/3 sigma per part is flagged within a few parts.
  EXPECT_LT(first_after, 119u + 8u);
}

// The count of false alarms a stable process raises over the 119 parts
// before a drift, with limits from its first 100 (the acceptance lot's
// set-up), over 2000 series: the figure an inspected lot's count is judged
// against (this seed: mean 2.68, median 2, 95th percentile 6).
TEST(Spc, FalseAlarmsOfAStableProcessOver119Parts) {
  std::mt19937_64 rng(4747);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<size_t> counts;
  for (int series = 0; series < 2000; ++series) {
    std::vector<double> x(119);
    for (double& v : x) v = noise(rng);
    const ControlLimits l = controlLimits(std::vector<double>(x.begin(), x.begin() + 100));
    counts.push_back(applyRules(x, l, allRules()).size());
  }
  std::sort(counts.begin(), counts.end());
  double mean = 0.0;
  for (size_t c : counts) mean += static_cast<double>(c) / static_cast<double>(counts.size());
  const size_t p95 = counts[counts.size() * 95 / 100];
  std::printf("false alarms over 119 parts: mean %.2f, median %zu, 95th percentile %zu\n", mean,
              counts[counts.size() / 2], p95);
  EXPECT_GT(mean, 2.0);
  EXPECT_LT(mean, 6.0);
  EXPECT_GE(p95, 5u);
  EXPECT_LE(p95, 12u);
}

TEST(Spc, QuantilesMatchTables) {
  EXPECT_NEAR(normalQuantile(0.975), 1.959963984540054, 1e-12);
  EXPECT_NEAR(normalQuantile(0.001), -3.090232306167813, 1e-11);
  // chi2 tables (Abramowitz and Stegun 26.4).
  EXPECT_NEAR(chiSquareQuantile(0.025, 10), 3.246972780236841, 1e-9);
  EXPECT_NEAR(chiSquareQuantile(0.975, 10), 20.48317735080739, 1e-9);
  EXPECT_NEAR(chiSquareQuantile(0.975, 1), 5.023886187314888, 1e-9);
  EXPECT_NEAR(chiSquareCdf(chiSquareQuantile(0.3, 4.5), 4.5), 0.3, 1e-12);
}

TEST(Spc, CapabilityAndItsIntervals) {
  // Mean 10, s = 1 exactly (values -+ sqrt((n - 1) / n) around the mean).
  const size_t n = 50;
  std::vector<double> x;
  const double a = std::sqrt(static_cast<double>(n - 1) / static_cast<double>(n));
  for (size_t i = 0; i < n; ++i) x.push_back(10.0 + (i % 2 ? a : -a));
  const Capability c = capability(x, 4.0, 19.0);
  EXPECT_NEAR(c.s, 1.0, 1e-12);
  EXPECT_NEAR(c.cp.value, 15.0 / 6.0, 1e-12);
  EXPECT_NEAR(c.cpk.value, 2.0, 1e-12);
  const double nu = n - 1;
  EXPECT_NEAR(c.cp.low, 2.5 * std::sqrt(chiSquareQuantile(0.025, nu) / nu), 1e-12);
  EXPECT_NEAR(c.cp.high, 2.5 * std::sqrt(chiSquareQuantile(0.975, nu) / nu), 1e-12);
  const double half = 1.959963984540054 * std::sqrt(1.0 / (9.0 * n) + 4.0 / (2.0 * nu));
  EXPECT_NEAR(c.cpk.low, 2.0 - half, 1e-9);
  EXPECT_NEAR(c.cpk.high, 2.0 + half, 1e-9);
  EXPECT_THROW(capability(x, 5.0, 4.0), Error);
}

TEST(Spc, CapabilityIntervalsCoverTheTrueValue) {
  // 400 normal samples of 60: the 95 % intervals cover the true Cp and Cpk
  // about 95 % of the time.
  std::mt19937_64 rng(4747);
  std::normal_distribution<double> noise(0.0, 1.0);
  const double lsl = -3.0, usl = 4.5, cp = 7.5 / 6.0, cpk = 3.0 / 3.0;
  int cover_cp = 0, cover_cpk = 0;
  const int trials = 400;
  for (int t = 0; t < trials; ++t) {
    std::vector<double> x(60);
    for (auto& v : x) v = noise(rng);
    const Capability c = capability(x, lsl, usl);
    cover_cp += c.cp.low <= cp && cp <= c.cp.high;
    cover_cpk += c.cpk.low <= cpk && cpk <= c.cpk.high;
  }
  EXPECT_NEAR(cover_cp / double(trials), 0.95, 0.035);
  EXPECT_NEAR(cover_cpk / double(trials), 0.95, 0.035);
}

// Histogram bins by the rule, on data whose bins are worked out by hand.
TEST(SpcHistogram, FreedmanDiaconisOnKnownData) {
  // 0 .. 9: quartiles 2.25 and 6.75 (linear interpolation), IQR 4.5, width
  // 2 * 4.5 / 10^(1/3) = 4.1774; range 9 / 4.1774 = 2.15: 3 bins, centred on
  // the range (start -1.766, edges 2.411 and 6.588).
  std::vector<double> x;
  for (int i = 9; i >= 0; --i) x.push_back(i);  // order does not matter
  EXPECT_DOUBLE_EQ(quantile(x, 0.25), 2.25);
  EXPECT_DOUBLE_EQ(quantile(x, 0.75), 6.75);
  const HistogramBins h = histogramBins(x);
  EXPECT_EQ(h.rule, "freedman-diaconis");
  EXPECT_NEAR(h.width, 9.0 / std::cbrt(10.0), 1e-12);
  EXPECT_EQ(h.count, 3u);
  EXPECT_NEAR(h.start, -(3.0 * 9.0 / std::cbrt(10.0) - 9.0) / 2.0, 1e-12);
  EXPECT_EQ(h.counts, (std::vector<size_t>{3, 4, 3}));
}

TEST(SpcHistogram, ScottWhenTheIqrIsZeroOneBinWhenEveryValueIsTheSame) {
  // Seven 5s of nine: IQR 0. Mean 5, s = sqrt(32 / 8) = 2, width
  // 3.49 * 2 / 9^(1/3) = 3.3557; range 8 / 3.3557 = 2.38: 3 bins.
  const std::vector<double> x = {1, 5, 5, 5, 5, 5, 5, 5, 9};
  const HistogramBins h = histogramBins(x);
  EXPECT_EQ(h.rule, "scott");
  EXPECT_NEAR(h.width, 6.98 / std::cbrt(9.0), 1e-12);
  EXPECT_EQ(h.count, 3u);
  EXPECT_EQ(h.counts, (std::vector<size_t>{1, 7, 1}));
  const HistogramBins one = histogramBins({20.5, 20.5, 20.5});
  EXPECT_EQ(one.rule, "single");
  EXPECT_EQ(one.count, 1u);
  EXPECT_EQ(one.counts, std::vector<size_t>{3});
  EXPECT_NEAR(one.centre(0), 20.5, 1e-12);
}

TEST(SpcHistogram, AFarOutlierCapsTheBinsAndEveryValueIsCounted) {
  std::vector<double> x;
  for (int i = 0; i < 10; ++i) x.push_back(i);
  x.push_back(1e6);
  const HistogramBins h = histogramBins(x);
  EXPECT_EQ(h.count, kMaxHistogramBins);
  EXPECT_NEAR(h.width, 1e6 / static_cast<double>(kMaxHistogramBins), 1e-6);
  EXPECT_EQ(h.counts.front(), 10u);
  EXPECT_EQ(h.counts.back(), 1u);
}

// The lot: 24 parts, s 0.01 mm, tolerance +-0.1 mm. Bins of a fifth
// of the tolerance put 17 to 22 parts in one bar; the rule's bins, on the
// data, spread them.
TEST(SpcHistogram, TwentyFourPartsInATolerancesFifthAreSpread) {
  std::mt19937_64 rng(61);
  std::normal_distribution<double> noise(20.0, 0.01);
  std::vector<double> x(24);
  for (double& v : x) v = noise(rng);
  const HistogramBins h = histogramBins(x);
  std::vector<double> sorted = x;
  std::sort(sorted.begin(), sorted.end());
  // The quartiles at (n - 1) q = 5.75 and 17.25 between order statistics.
  const double iqr = (sorted[17] + 0.25 * (sorted[18] - sorted[17])) -
                     (sorted[5] + 0.75 * (sorted[6] - sorted[5]));
  const double width = 2.0 * iqr / std::cbrt(24.0);
  EXPECT_NEAR(h.width, width, 1e-12);
  EXPECT_EQ(h.count, static_cast<size_t>(std::ceil((sorted.back() - sorted.front()) / width)));
  EXPECT_GE(h.count, 4u);
  EXPECT_LT(*std::max_element(h.counts.begin(), h.counts.end()), 12u);
  size_t total = 0;
  for (size_t c : h.counts) total += c;
  EXPECT_EQ(total, 24u);
}

// A lot of `n` parts in a fresh SQLite store: width drifting from part 16.
class SpcLotTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           fmt::format("xgauge_spc_{}_{}", ::getpid(),
                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    store_ = ResultStore::open((dir_ / "lot.sqlite").string());
  }
  void TearDown() override {
    store_.reset();
    std::filesystem::remove_all(dir_);
  }
  void addParts(size_t n) {
    for (size_t i = 0; i < n; ++i) {
      MeasurementRecord r;
      r.lot = "L1";
      r.part = fmt::format("p{:04d}", i + 1);
      r.part_index = static_cast<int64_t>(i);
      r.acquired_at = "2026-12-04T10:00:00Z";
      r.inputs_digest = r.part;
      r.status = "measured";
      StoredDimension d;
      d.name = "width";
      d.value = 20.0 + 0.004 * ((i * 7) % 5) + (i >= 16 ? 0.01 * static_cast<double>(i - 15) : 0.0);
      d.unit = "mm";
      d.expanded_uncertainty = 0.004;
      d.nominal = 20.0, d.lower_limit = 19.9, d.upper_limit = 20.1;
      r.dimensions.push_back(d);
      const Claim c = store_->claim(r, Claimant::thisProcess("s1", 900.0));
      ASSERT_TRUE(store_->record(r, c.token));
    }
  }
  std::filesystem::path dir_;
  std::unique_ptr<ResultStore> store_;
};

TEST_F(SpcLotTest, ALotShorterThanTheBaselineIsRefusedNamingLotPartsAndBaseline) {
  addParts(24);
  SpcOptions options;  // the default baseline, 30
  try {
    analyseLot(*store_, "L1", options);
    FAIL() << "a 24-part lot was analysed against a 30-part baseline";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("lot L1 has 24 measured part(s)"), std::string::npos) << m;
    EXPECT_NE(m.find("the 30 of the phase-I baseline"), std::string::npos) << m;
    EXPECT_NE(m.find("--baseline N with N at most 24"), std::string::npos) << m;
  }
  options.baseline_parts = 25;  // given, but still more than the parts
  EXPECT_THROW(analyseLot(*store_, "L1", options), Error);
  // inspect --spc: phase I not complete yet, no analysis.
  options.skip_short_baseline = true;
  EXPECT_TRUE(analyseLot(*store_, "L1", options).empty());
}

TEST_F(SpcLotTest, AnExplicitBaselineAtMostThePartsIsTakenAndTheDriftCaught) {
  addParts(24);
  SpcOptions options;
  options.baseline_parts = 16;
  const auto analyses = analyseLot(*store_, "L1", options);
  ASSERT_EQ(analyses.size(), 1u);
  const DimensionSpc& d = analyses[0];
  EXPECT_EQ(d.limits.baseline_n, 16u);
  EXPECT_EQ(d.baseline, "first 16 parts");
  EXPECT_EQ(d.values.size(), 24u);
  // The drift beyond 3 sigma, not phase I (whose repeating pattern stays
  // within 1 sigma: nelson-7 at part 15).
  const auto beyond = std::find_if(d.hits.begin(), d.hits.end(), [](const RuleHit& h) {
    return h.rule == SpcRule::kBeyond3Sigma;
  });
  ASSERT_NE(beyond, d.hits.end());
  EXPECT_GE(beyond->index, 16u);
  EXPECT_LE(beyond->index, 20u);
  // The same lot with every part as phase I (what a short lot used to get)
  // widens the limits by the drift.
  options.baseline_parts = 24;
  EXPECT_GT(analyseLot(*store_, "L1", options)[0].limits.sigma_within, d.limits.sigma_within);
  // The histogram of spc.json: the rule's bins.
  const auto json = d.toJson().at("histogram");
  const HistogramBins h = histogramBins(d.values);
  EXPECT_EQ(json.at("rule"), h.rule);
  EXPECT_EQ(json.at("bins").get<size_t>(), h.count);
  EXPECT_EQ(json.at("counts").size(), h.count);
  EXPECT_EQ(json.at("centres").size(), h.count);
}

}  // namespace
}  // namespace xgauge
