// Tolerances and verdicts by ISO 14253-1's default rule: closed-form cases
// of every verdict and boundary, the exit status, and the job's "tolerances"
// key with the part model's defaults.
#include "xgauge/measure/tolerance.h"

#include "checks.h"

#include "geometry/test_files.h"
#include "xgauge/core/config.h"
#include "xgauge/measure/job.h"

#include <gtest/gtest.h>

#include <map>

#include <cmath>
#include <limits>
#include <ostream>

namespace xgauge {

// Failures print "conforms", not the enum's bytes (found by GoogleTest by
// argument-dependent lookup).
void PrintTo(Verdict verdict, std::ostream* out) { *out << verdictName(verdict); }

namespace {

// Every number below is a binary fraction, so limits such as H - U are
// exact and a value can sit exactly on them.

// 20 +- 0.5: specification zone [19.5, 20.5], T = 1.
const Tolerance kSymmetric{20.0, -0.5, 0.5, "job"};

Verdict verdictOf(double value, double u, const Tolerance& tolerance = kSymmetric) {
  return decide(value, u, tolerance).verdict;
}

TEST(Tolerance, ThreeVerdictsByTheGuardBandRule) {
  // U = 0.125: conformance zone [19.625, 20.375], nonconformance outside
  // [19.375, 20.625].
  const double u = 0.125;
  EXPECT_EQ(verdictOf(20.0, u), Verdict::kConforms);
  EXPECT_EQ(verdictOf(20.25, u), Verdict::kConforms);
  EXPECT_EQ(verdictOf(20.4375, u), Verdict::kInconclusive);  // in the zone, within U of H
  EXPECT_EQ(verdictOf(20.5, u), Verdict::kInconclusive);     // on H
  EXPECT_EQ(verdictOf(20.5625, u), Verdict::kInconclusive);  // beyond H, within U of it
  EXPECT_EQ(verdictOf(20.75, u), Verdict::kDoesNotConform);
  EXPECT_EQ(verdictOf(19.5625, u), Verdict::kInconclusive);
  EXPECT_EQ(verdictOf(19.25, u), Verdict::kDoesNotConform);
  EXPECT_EQ(decide(20.0, u, kSymmetric).rule, kDecisionRule);
}

TEST(Tolerance, ShrunkLimitsConformWidenedLimitsAreInconclusive) {
  const double u = 0.125;
  EXPECT_EQ(verdictOf(20.375, u), Verdict::kConforms);  // exactly H - U
  EXPECT_EQ(verdictOf(19.625, u), Verdict::kConforms);  // exactly L + U
  EXPECT_EQ(verdictOf(std::nextafter(20.375, 21.0), u), Verdict::kInconclusive);
  EXPECT_EQ(verdictOf(std::nextafter(19.625, 19.0), u), Verdict::kInconclusive);
  EXPECT_EQ(verdictOf(20.625, u), Verdict::kInconclusive);  // exactly H + U
  EXPECT_EQ(verdictOf(19.375, u), Verdict::kInconclusive);  // exactly L - U
  EXPECT_EQ(verdictOf(std::nextafter(20.625, 21.0), u), Verdict::kDoesNotConform);
  EXPECT_EQ(verdictOf(std::nextafter(19.375, 19.0), u), Verdict::kDoesNotConform);
}

TEST(Tolerance, AsymmetricZoneOnOneSideOfTheNominal) {
  // 10 +0.25/+0.75: zone [10.25, 10.75]; U = 0.125 shrinks it to
  // [10.375, 10.625] and widens it to [10.125, 10.875].
  const Tolerance above{10.0, 0.25, 0.75, "part model"};
  const double u = 0.125;
  EXPECT_EQ(verdictOf(10.0, u, above), Verdict::kDoesNotConform);  // the nominal itself
  EXPECT_EQ(verdictOf(10.1875, u, above), Verdict::kInconclusive);
  EXPECT_EQ(verdictOf(10.375, u, above), Verdict::kConforms);
  EXPECT_EQ(verdictOf(10.625, u, above), Verdict::kConforms);
  EXPECT_EQ(verdictOf(10.6875, u, above), Verdict::kInconclusive);
  EXPECT_EQ(verdictOf(10.9375, u, above), Verdict::kDoesNotConform);
  // 10 -0.25/+0.5, T = 0.75: the limits are not mirrored about the nominal.
  const Tolerance skewed{10.0, -0.25, 0.5, "job"};
  EXPECT_EQ(verdictOf(9.875, u, skewed), Verdict::kConforms);   // L + U
  EXPECT_EQ(verdictOf(10.375, u, skewed), Verdict::kConforms);  // H - U
  EXPECT_EQ(verdictOf(9.8125, u, skewed), Verdict::kInconclusive);
  EXPECT_EQ(verdictOf(10.4375, u, skewed), Verdict::kInconclusive);
  EXPECT_EQ(verdictOf(9.625, u, skewed), Verdict::kInconclusive);  // L - U
  EXPECT_EQ(verdictOf(9.5, u, skewed), Verdict::kDoesNotConform);
}

TEST(Tolerance, WithoutUncertaintyTheLimitsDecideAndNothingIsInconclusive) {
  EXPECT_EQ(verdictOf(20.5, 0.0), Verdict::kConforms);
  EXPECT_EQ(verdictOf(19.5, 0.0), Verdict::kConforms);
  EXPECT_EQ(verdictOf(std::nextafter(20.5, 21.0), 0.0), Verdict::kDoesNotConform);
  EXPECT_EQ(verdictOf(std::nextafter(19.5, 19.0), 0.0), Verdict::kDoesNotConform);
  for (double value = 19.0; value <= 21.0; value += 1.0 / 64.0)
    EXPECT_NE(verdictOf(value, 0.0), Verdict::kInconclusive) << value;
  EXPECT_FALSE(decide(20.0, 0.0, kSymmetric).cannot_decide);
}

TEST(Tolerance, AnUncertaintyOfHalfTheZoneOrMoreNeverConforms) {
  // U = T / 2: the conformance zone shrinks to the point 20; even that point
  // is not enough.
  EXPECT_EQ(verdictOf(20.0, 0.5), Verdict::kInconclusive);
  EXPECT_EQ(verdictOf(std::nextafter(20.0, 21.0), 0.5), Verdict::kInconclusive);
  EXPECT_EQ(verdictOf(21.0, 0.5), Verdict::kInconclusive);  // exactly H + U
  EXPECT_EQ(verdictOf(21.0625, 0.5), Verdict::kDoesNotConform);
  // U = 0.75 > T / 2: the widened zone [18.75, 21.25] still rejects.
  for (double value = 18.75; value <= 21.25; value += 1.0 / 16.0)
    EXPECT_EQ(verdictOf(value, 0.75), Verdict::kInconclusive) << value;
  EXPECT_EQ(verdictOf(21.5, 0.75), Verdict::kDoesNotConform);
  EXPECT_EQ(verdictOf(18.5, 0.75), Verdict::kDoesNotConform);
  // No uncertainty could be given: nothing is decided.
  const double unknown = std::numeric_limits<double>::infinity();
  EXPECT_EQ(verdictOf(20.0, unknown), Verdict::kInconclusive);
  EXPECT_EQ(verdictOf(1000.0, unknown), Verdict::kInconclusive);
}

TEST(Tolerance, CannotDecideWhenUExceedsAThirdOfTheZone) {
  // 0 +- 0.75: T = 1.5, T / 3 = 0.5 exactly.
  const Tolerance t{0.0, -0.75, 0.75, "job"};
  EXPECT_FALSE(decide(0.0, 0.25, t).cannot_decide);
  EXPECT_FALSE(decide(0.0, 0.5, t).cannot_decide);  // exactly T / 3
  EXPECT_TRUE(decide(0.0, std::nextafter(0.5, 1.0), t).cannot_decide);
  // A warning, independent of the verdict: U = 0.625 < T / 2 still lets the
  // middle conform, and a value far out still does not conform.
  const Decision middle = decide(0.0, 0.625, t);
  EXPECT_EQ(middle.verdict, Verdict::kConforms);
  EXPECT_TRUE(middle.cannot_decide);
  const Decision far = decide(2.0, 0.625, t);
  EXPECT_EQ(far.verdict, Verdict::kDoesNotConform);
  EXPECT_TRUE(far.cannot_decide);
  // The flag follows the zone's width, not the limits' magnitudes.
  const Tolerance one_sided{100.0, 0.25, 1.75, "job"};  // T = 1.5 too
  EXPECT_FALSE(decide(101.0, 0.5, one_sided).cannot_decide);
  EXPECT_TRUE(decide(101.0, 0.5625, one_sided).cannot_decide);
}

TEST(Tolerance, VerdictNames) {
  EXPECT_EQ(verdictName(Verdict::kConforms), "conforms");
  EXPECT_EQ(verdictName(Verdict::kDoesNotConform), "does not conform");
  EXPECT_EQ(verdictName(Verdict::kInconclusive), "inconclusive");
}

TEST(Tolerance, ExitCodeIsTheWorstVerdict) {
  const Decision conforms{Verdict::kConforms, false, std::string(kDecisionRule), {}};
  const Decision flagged{Verdict::kConforms, true, std::string(kDecisionRule), {}};
  const Decision inconclusive{Verdict::kInconclusive, false, std::string(kDecisionRule), {}};
  const Decision rejected{Verdict::kDoesNotConform, false, std::string(kDecisionRule), {}};
  EXPECT_EQ(kExitConforms, 0);
  EXPECT_EQ(kExitCouldNotMeasure, 1);
  EXPECT_EQ(kExitInconclusive, 2);
  EXPECT_EQ(kExitDoesNotConform, 3);
  EXPECT_EQ(exitCodeFor({}), kExitConforms);
  EXPECT_EQ(exitCodeFor({conforms, conforms}), kExitConforms);
  EXPECT_EQ(exitCodeFor({conforms, flagged}), kExitConforms);  // a warning only
  EXPECT_EQ(exitCodeFor({conforms, inconclusive, conforms}), kExitInconclusive);
  EXPECT_EQ(exitCodeFor({inconclusive, rejected}), kExitDoesNotConform);
  EXPECT_EQ(exitCodeFor({rejected, inconclusive, conforms}), kExitDoesNotConform);
  EXPECT_EQ(exitCodeFor({conforms, rejected}), kExitDoesNotConform);
}

// A box part whose size_x carries the drawing's default tolerance.
constexpr const char* kBoxPart = R"({
  "description": "box",
  "dimensions": [
    {"name": "size_x", "nominal": 20, "min": 10, "max": 30, "unit": "mm",
     "tolerance": {"lower": -0.1, "upper": 0.1}},
    {"name": "size_y", "nominal": 30, "min": 20, "max": 40, "unit": "mm"},
    {"name": "size_z", "nominal": 10, "min": 5, "max": 15, "unit": "mm",
     "tolerance": {"lower": 0, "upper": 0.2}}
  ],
  "shape": {"type": "box", "min": [0, 0, 0], "max": ["size_x", "size_y", "size_z"]}
})";

// A job for the box; `dimensions` and `tolerances` are the values of those
// keys (omitted when empty). "tolerances" starts on line 6, and each of its
// members written on a line of its own below it.
std::string boxJob(const std::string& dimensions, const std::string& tolerances) {
  std::string text = R"({
  "part": "part.json",
  "machine": "machine.json",
  "material": "material.json",
  "dimensions": )" + (dimensions.empty() ? std::string("{}") : dimensions) +
                     ",\n";
  if (!tolerances.empty()) text += "  \"tolerances\": " + tolerances + ",\n";
  text += R"(  "radiographs": [{"name": "a", "image": "a.tif", "white_region": [0, 0, 4, 4]}],
  "pose_bounds": {"rotation_deg": [[0, 0], [0, 0], [0, 0]],
                  "centre_mm": [[0, 0], [0, 0], [500, 500]]}
})";
  return text;
}

class JobTolerances : public ::testing::Test {
 protected:
  MeasurementJob read(const std::string& text) const {
    const ConfigNode root = ConfigNode::parse(text, "job.json");
    MeasurementJob job = MeasurementJob::fromConfig(root, "job.json", part_, true);
    root.finish();
    return job;
  }
  // Reading `text` fails with exactly this message at this key path and line.
  void expectError(const std::string& text, const std::string& message, const std::string& key_path,
                   int line) const {
    try {
      read(text);
      ADD_FAILURE() << "expected: " << message;
    } catch (const Error& e) {
      EXPECT_EQ(e.message(), message);
      EXPECT_EQ(e.where().file, "job.json");
      EXPECT_EQ(e.where().key_path, key_path);
      EXPECT_EQ(e.where().line, line) << e.what();
    }
  }

  PartModel part_ = testing::loadText(kBoxPart);
};

TEST_F(JobTolerances, TheJobOverridesThePartModelPerDimension) {
  const MeasurementJob job = read(boxJob("", R"({
    "size_y": {"nominal": 30.5, "lower": -0.25, "upper": 0.125},
    "size_z": {"lower": -0.5, "upper": 0.5}
  })"));
  ASSERT_EQ(job.tolerances.size(), 2u);
  EXPECT_EQ(job.tolerances.at("size_y").nominal, 30.5);
  EXPECT_EQ(job.tolerances.at("size_z").nominal, 10.0);  // the part model's nominal

  const auto tolerances = tolerancesFor(job, part_);
  ASSERT_EQ(tolerances.size(), 3u);
  const Tolerance& x = tolerances.at("size_x");  // the part model's default
  EXPECT_EQ(x.nominal, 20.0);
  EXPECT_EQ(x.lower, -0.1);
  EXPECT_EQ(x.upper, 0.1);
  EXPECT_EQ(x.source, "part model");
  const Tolerance& y = tolerances.at("size_y");  // the job's only
  EXPECT_EQ(y.nominal, 30.5);
  EXPECT_EQ(y.lower, -0.25);
  EXPECT_EQ(y.upper, 0.125);
  EXPECT_EQ(y.source, "job");
  const Tolerance& z = tolerances.at("size_z");  // the job's replaces the default
  EXPECT_EQ(z.lower, -0.5);
  EXPECT_EQ(z.upper, 0.5);
  EXPECT_EQ(z.source, "job");
}

TEST_F(JobTolerances, OnlyMeasuredDimensionsGetATolerance) {
  // size_z is fixed: its part model default does not apply.
  const MeasurementJob job = read(boxJob(R"({"fixed": {"size_z": 10}})", ""));
  EXPECT_TRUE(job.tolerances.empty());
  const auto tolerances = tolerancesFor(job, part_);
  ASSERT_EQ(tolerances.size(), 1u);
  EXPECT_EQ(tolerances.count("size_x"), 1u);
  // Without any tolerance, none.
  const MeasurementJob untoleranced = read(boxJob(R"({"free": ["size_y"]})", ""));
  EXPECT_TRUE(tolerancesFor(untoleranced, part_).empty());
}

TEST_F(JobTolerances, BadTolerancesNameTheFileKeyAndLine) {
  expectError(boxJob("", "{\n    \"size_w\": {\"lower\": -0.1, \"upper\": 0.1}}"),
              "unknown dimension 'size_w' of part 'part' (known: size_x, size_y, size_z)",
              "/tolerances/size_w", 7);
  expectError(
      boxJob(R"({"free": ["size_x"]})", "{\n    \"size_y\": {\"lower\": -0.1, \"upper\": 0.1}}"),
      "'size_y' is not a free dimension of this job: a tolerance applies to measured "
      "dimensions only",
      "/tolerances/size_y", 7);
  expectError(boxJob(R"({"fixed": {"size_y": 30}})",
                     "{\n    \"size_y\": {\"lower\": -0.1, \"upper\": 0.1}}"),
              "'size_y' is not a free dimension of this job: a tolerance applies to measured "
              "dimensions only",
              "/tolerances/size_y", 7);
  expectError(boxJob("", "{\n    \"size_x\": {\"lower\": 0.1, \"upper\": -0.1}}"),
              "lower (0.1) must be below upper (-0.1)", "/tolerances/size_x", 7);
  expectError(boxJob("", "{\n    \"size_x\": {\"lower\": 0.1, \"upper\": 0.1}}"),
              "lower (0.1) must be below upper (0.1)", "/tolerances/size_x", 7);
  expectError(boxJob("", "{\n    \"size_x\": {\"lower\": -0.1}}"), "missing key 'upper'",
              "/tolerances/size_x", 7);
  expectError(boxJob("", "{\n    \"size_x\": {\"nominl\": 20, \"lower\": -0.1, \"upper\": 0.1}}"),
              "unknown key 'nominl'; did you mean 'nominal'?", "/tolerances/size_x/nominl", 7);
  expectError(boxJob("", "{\n    \"size_x\": 0.1}"), "expected an object", "/tolerances/size_x", 7);
  expectError(boxJob("", "[0.1]"), "expected an object", "/tolerances", 6);
  // A nominal in the wrong unit (cm for mm): no value in [10, 30] could conform.
  expectError(boxJob("", "{\n    \"size_x\": {\"nominal\": 2, \"lower\": -0.1, \"upper\": 0.1}}"),
              "the tolerance zone [1.9, 2.1] mm lies outside the part model's [min, max] = [10, "
              "30]",
              "/tolerances/size_x", 7);
}

// "nominals": this part number's nominal values, a job tolerance's default
// nominal; the part model's stays the default of the rest.
TEST_F(JobTolerances, TheJobsNominalsAreItsTolerancesDefaults) {
  std::string text = boxJob("", R"({"size_y": {"lower": -0.25, "upper": 0.125},
    "size_z": {"nominal": 12.5, "lower": -0.5, "upper": 0.5}})");
  text.insert(text.find("\"tolerances\""), "\"nominals\": {\"size_y\": 31.5, \"size_z\": 11},\n  ");
  const MeasurementJob job = read(text);
  EXPECT_EQ(job.nominals, (std::map<std::string, double>{{"size_y", 31.5}, {"size_z", 11.0}}));
  EXPECT_EQ(job.tolerances.at("size_y").nominal, 31.5);  // the job's nominal
  EXPECT_EQ(job.tolerances.at("size_z").nominal, 12.5);  // the tolerance's own wins
  EXPECT_EQ(tolerancesFor(job, part_).at("size_x").nominal, 20.0);  // the part model's
}

TEST_F(JobTolerances, BadNominalsNameTheFileKeyAndLine) {
  const auto with = [](const std::string& dimensions, const std::string& nominals) {
    std::string text = boxJob(dimensions, "");
    text.insert(text.find("\"radiographs\""), "\"nominals\": " + nominals + ",\n  ");
    return text;
  };
  expectError(with("", "{\"size_w\": 20}"),
              "unknown dimension 'size_w' of part 'part' (known: size_x, size_y, size_z)",
              "/nominals/size_w", 6);
  expectError(with(R"({"fixed": {"size_y": 30}})", "{\"size_y\": 30}"),
              "'size_y' is not a free dimension of this job: a nominal applies to measured "
              "dimensions only",
              "/nominals/size_y", 6);
  expectError(with("", "{\"size_x\": 2}"), "value 2 out of range [10, 30]", "/nominals/size_x",
              6);
  expectError(with("", "[20]"), "expected {dimension: nominal value}", "/nominals", 6);
}

TEST_F(JobTolerances, ANonFiniteToleranceIsRefused) {
  // JSON text cannot hold a NaN; a document built in memory (a study's job)
  // can.
  nlohmann::json document = nlohmann::json::parse(boxJob("", R"({"size_x": {"lower": -0.1,
      "upper": 0.1}})"));
  document["tolerances"]["size_x"]["upper"] = std::nan("");
  try {
    MeasurementJob::fromConfig(ConfigNode::fromJson(document, "job.json"), "job.json", part_, true);
    ADD_FAILURE() << "a NaN tolerance was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.message(), "expected a finite number");
    EXPECT_EQ(e.where().key_path, "/tolerances/size_x/upper");
  }
}

// A dimension that cannot decide because of the model discrepancy says so
// and names the residual regions; one whose U is too large without it, or
// that has no discrepancy component, gets no reason.
TEST(CannotDecide, TheReasonNamesTheResidualRegionsWhereTheDiscrepancyMakesIt) {
  DimensionUncertainty u;
  u.name = "thickness";
  // u_c^2 = 0.003^2 + 0.004^2: U = 0.010 with the discrepancy, 0.006 without.
  u.components.push_back({"statistical", "noise", 0.003, "mm", 1.0, 0.003});
  u.components.push_back({"misfit", "the shift", 0.004, "mm", 1.0, 0.004});
  u.combined = 0.005;
  u.expanded = 0.010;
  Tolerance t{4.0, -0.012, 0.012, "job"};  // T / 3 = 0.008
  SelfCheck check;
  ResidualRegion a, b;
  a.radiograph = "t00";
  a.centre_px = {327.4, 451.0};
  a.sigmas = 64.5;
  a.sign = "darker";
  b.radiograph = "t01";
  b.centre_px = {425.0, 451.6};
  b.sigmas = 61.0;
  b.sign = "brighter";
  check.regions = {a, b};
  const std::string reason = discrepancyReason(u, 2.0, t, check);
  EXPECT_NE(reason.find("model discrepancy"), std::string::npos) << reason;
  EXPECT_NE(reason.find("0.0060 without"), std::string::npos) << reason;
  EXPECT_NE(reason.find("t00 at pixel (327, 451), 64 sigmas darker"), std::string::npos) << reason;
  EXPECT_NE(reason.find("t01 at pixel (425, 452)"), std::string::npos) << reason;
  // Too uncertain even without it: U would be 0.0060 > T / 3 = 0.005.
  Tolerance narrow{4.0, -0.0075, 0.0075, "job"};
  EXPECT_EQ(discrepancyReason(u, 2.0, narrow, check), "");
  // No regions, or no discrepancy component: no reason.
  EXPECT_EQ(discrepancyReason(u, 2.0, t, SelfCheck{}), "");
  u.components.pop_back();
  EXPECT_EQ(discrepancyReason(u, 2.0, t, check), "");
}

}  // namespace
}  // namespace xgauge
