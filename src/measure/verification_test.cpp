// The substitution of ISO 15530-3 (measure/verification.h) against a worked
// example computed by hand, the verification file's round trip, and the
// refusals outside its conditions.
#include "xgauge/measure/verification.h"
#include "xgauge/measure/verify.h"

#include "xgauge/core/error.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

#include <unistd.h>

namespace xgauge {
namespace {

// A master certified at 10.000 mm (u_cal 0.002 mm) measured four times:
// 10.012, 10.018, 10.009, 10.015 mm, with own combined standard
// uncertainties 0.004, 0.004, 0.005, 0.003 mm. By hand:
//   mean = 40.054 / 4 = 10.0135;  b = 0.0135
//   deviations -0.0015, +0.0045, -0.0045, +0.0015; squares sum 45e-6
//   u_p = sqrt(45e-6 / 3) = sqrt(15e-6) = 0.00387298
//   u_b = u_p / sqrt(4) = 0.00193649
//   own on the master: (0.004 + 0.004 + 0.005 + 0.003) / 4 = 0.004
// A workpiece measured 10.030 mm with its own u 0.005 mm:
//   y' = 10.030 - 0.0135 = 10.0165
//   u_w = sqrt(0.005^2 - 0.004^2) = 0.003
//   u^2 = 4e-6 + 15e-6 + 3.75e-6 + 9e-6 = 31.75e-6;  u = 0.00563471
//   u_p and u_b known to n - 1 = 3 degrees of freedom (Welch-Satterthwaite):
//   nu = (31.75e-6)^2 / ((15e-6 + 3.75e-6)^2 / 3) = 1008.0625 / 117.1875
//      = 8.60213
//   k = Student's t at 8.60213 degrees of freedom for p = Phi(2) = 0.97725
//     = 2.33686 (scipy.stats.t.ppf(0.9772498680518208, 8.602133333))
//   U = k u = 0.01316755
std::vector<MasterMeasurement> fourMeasurements() {
  const double y[] = {10.012, 10.018, 10.009, 10.015}, own[] = {0.004, 0.004, 0.005, 0.003};
  const double magnification[] = {2.01, 2.03, 1.99, 2.00};
  std::vector<MasterMeasurement> out;
  for (int i = 0; i < 4; ++i) {
    MasterMeasurement m;
    m.job = fmt::format("m{}.json", i);
    m.dimensions["width"] = {y[i], own[i]};
    m.dimensions["not_certified"] = {1.0, 0.1};
    m.magnifications = {magnification[i], magnification[i] + 0.005};
    out.push_back(m);
  }
  return out;
}

VerificationConditions someConditions() {
  VerificationConditions c;
  c.part_file = "part.json", c.part_sha256 = std::string(64, 'a');
  c.machine_file = "machine.json", c.machine_sha256 = std::string(64, 'b');
  c.material_file = "material.json", c.material_sha256 = std::string(64, 'c');
  return c;
}

TEST(Verification, TheSubstitutionMatchesAWorkedExampleByHand) {
  const Verification v =
      verifyOnMaster(fourMeasurements(), {{"width", {10.000, 0.002}}}, someConditions());
  ASSERT_EQ(v.dimensions.size(), 1u);  // the uncertified dimension is not verified
  const VerifiedDimension& d = v.dimensions.front();
  EXPECT_EQ(d.measurements, 4);
  EXPECT_NEAR(d.mean, 10.0135, 1e-12);
  EXPECT_NEAR(d.bias, 0.0135, 1e-12);
  EXPECT_NEAR(d.u_p, 0.0038729833, 1e-9);
  EXPECT_NEAR(d.u_b, 0.0019364917, 1e-9);
  EXPECT_NEAR(d.own_master, 0.004, 1e-12);
  EXPECT_DOUBLE_EQ(v.conditions.magnification[0], 1.99);
  EXPECT_DOUBLE_EQ(v.conditions.magnification[1], 2.035);

  const Substitution s = substitute(10.030, 0.005, d, 2.0);
  EXPECT_NEAR(s.value, 10.0165, 1e-12);
  EXPECT_NEAR(s.u_w, 0.003, 1e-12);
  EXPECT_NEAR(s.combined, 0.0056347138, 1e-9);
  EXPECT_NEAR(s.effective_dof, 8.6021333333, 1e-8);
  EXPECT_NEAR(s.coverage_factor, 2.3368617277, 1e-8);
  EXPECT_NEAR(s.expanded, 0.0131675470, 1e-9);
  // A workpiece the model explains better than the master adds no u_w.
  EXPECT_EQ(substitute(10.030, 0.003, d, 2.0).u_w, 0.0);
}

// Student's t against the GUM's Table G.2 (p = 95.45 %): nu = 2 gives
// 4.53, nu = 10 gives 2.28, nu = 50 gives 2.05, and infinity 2.
TEST(Verification, TheCoverageFactorFollowsTheDegreesOfFreedom) {
  EXPECT_NEAR(studentCoverageFactor(2.0, 2.0), 4.53, 0.005);
  EXPECT_NEAR(studentCoverageFactor(10.0, 2.0), 2.28, 0.005);
  EXPECT_NEAR(studentCoverageFactor(50.0, 2.0), 2.05, 0.005);
  EXPECT_EQ(studentCoverageFactor(std::numeric_limits<double>::infinity(), 2.0), 2.0);
  // Three measurements of a master whose repeatability is all of u: k = 4.53.
  VerifiedDimension d;
  d.measurements = 3, d.u_p = 0.004, d.u_b = 0.004 / std::sqrt(3.0);
  const Substitution s = substitute(1.0, 0.0, d, 2.0);
  EXPECT_NEAR(s.effective_dof, 2.0, 1e-12);
  EXPECT_NEAR(s.expanded / s.combined, 4.5265, 1e-4);
  // A master measured identically every time: no repeatability to estimate,
  // the normal k.
  d.u_p = d.u_b = 0.0, d.u_cal = 0.002;
  EXPECT_EQ(substitute(1.0, 0.0, d, 2.0).coverage_factor, 2.0);
}

TEST(Verification, TheFileReadsBackAsWritten) {
  const Verification v =
      verifyOnMaster(fourMeasurements(), {{"width", {10.000, 0.002}}}, someConditions());
  const Verification back = Verification::fromConfig(
      ConfigNode::fromJson(v.toJson(), "verification.json"), "verification.json");
  ASSERT_EQ(back.dimensions.size(), 1u);
  EXPECT_EQ(back.dimensions[0].bias, v.dimensions[0].bias);
  EXPECT_EQ(back.dimensions[0].u_p, v.dimensions[0].u_p);
  EXPECT_EQ(back.conditions.machine_sha256, v.conditions.machine_sha256);
  EXPECT_EQ(back.conditions.magnification, v.conditions.magnification);
  ASSERT_EQ(back.measurements.size(), 4u);
  EXPECT_EQ(back.measurements[2].dimensions.at("width").first, 10.009);
  // A bias that is not mean - calibrated is a corrupt file.
  nlohmann::json broken = v.toJson();
  broken["dimensions"][0]["bias"] = 0.02;
  EXPECT_THROW(Verification::fromConfig(ConfigNode::fromJson(broken, "v.json"), "v.json"), Error);
}

TEST(Verification, IsRefusedOutsideItsConditions) {
  const Verification v =
      verifyOnMaster(fourMeasurements(), {{"width", {10.000, 0.002}}}, someConditions());
  const std::string a(64, 'a'), b(64, 'b'), c(64, 'c'), other(64, 'd');
  EXPECT_NO_THROW(checkVerificationConditions(v, a, b, c, {2.0, 2.02}));
  auto refusal = [&](const std::string& part, const std::string& machine,
                     const std::string& material, std::vector<double> magnifications) {
    try {
      checkVerificationConditions(v, part, machine, material, magnifications);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(refusal(other, b, c, {2.0}).find("another part model"), std::string::npos);
  EXPECT_NE(refusal(a, other, c, {2.0}).find("another machine"), std::string::npos);
  EXPECT_NE(refusal(a, b, other, {2.0}).find("another material"), std::string::npos);
  // 1.99 .. 2.035 widened by 2 %: 1.9502 .. 2.0757.
  EXPECT_EQ(refusal(a, b, c, {1.951, 2.075}), "accepted");
  EXPECT_NE(refusal(a, b, c, {2.0, 2.08}).find("magnification 2.080 lies outside"),
            std::string::npos);
  EXPECT_NE(refusal(a, b, c, {1.95}).find("lies outside"), std::string::npos);
}

// Three masters certified at 10.000, 10.050 and 9.980 mm (u_cal 0.001,
// 0.002, 0.002 mm), each measured twice:
//   master 1: 10.010, 10.014  (biases 0.010, 0.014; mean 0.012)
//   master 2: 10.054, 10.056  (biases 0.004, 0.006; mean 0.005)
//   master 3:  9.998, 10.000  (biases 0.018, 0.020; mean 0.019)
// By hand:
//   b = (0.012 + 0.005 + 0.019) / 3 = 0.012
//   s_B^2 = (0 + 49e-6 + 49e-6) / 2 = 49e-6;  u_b = 0.007 / sqrt(3) = 0.00404145
//   within: master 1's values 0.002 from their mean, 2's and 3's 0.001:
//   squares 2 x 4e-6 + 4 x 1e-6 = 12e-6 over N - M = 3: u_p^2 = 4e-6,
//   u_p = 0.002
//   u_s^2 = 49e-6 - 4e-6 x mean(1/2) = 47e-6;  u_s = 0.00685565
//   u_cal = sqrt((1e-6 + 4e-6 + 4e-6) / 3) = sqrt(3e-6) = 0.00173205, for
//   the record: the certificates' errors are in the biases' spread
// A workpiece with the masters' own u (u_w = 0):
//   u^2 = 4e-6 + 47e-6 + 49e-6 / 3 = 67.3333e-6;  u = 0.00820569
//   nu = u^4 / (u_p^4 / 3 + (u_s^2 + u_b^2)^2 / 2)
//      = 4533.78e-12 / (5.3333e-12 + 2005.56e-12) = 2.25461
// The same values as six masters measured once each: u_p = s of the six
// biases (0.010, 0.014, 0.004, 0.006, 0.018, 0.020; mean 0.012; squares
// 4 + 4 + 64 + 36 + 36 + 64 = 208e-6 over 5: 41.6e-6), u_b = u_p / sqrt(6),
// u_s = 0, nu = u^4 / ((u_p^2 + u_b^2)^2 / 5).
TEST(Verification, SeveralMastersMeasureTheSpecimensOwnVariation) {
  const double y[] = {10.010, 10.014, 10.054, 10.056, 9.998, 10.000};
  std::vector<MasterMeasurement> measured;
  for (int i = 0; i < 6; ++i) {
    MasterMeasurement m;
    m.job = fmt::format("m{}.json", i);
    m.master = i / 2;
    m.dimensions["width"] = {y[i], 0.004};
    m.magnifications = {2.0};
    measured.push_back(m);
  }
  const std::vector<std::map<std::string, CertifiedValue>> three = {
      {{"width", {10.000, 0.001}}}, {{"width", {10.050, 0.002}}}, {{"width", {9.980, 0.002}}}};
  const Verification v = verifyOnMasters(measured, three, someConditions());
  ASSERT_EQ(v.dimensions.size(), 1u);
  const VerifiedDimension& d = v.dimensions.front();
  EXPECT_EQ(d.masters, 3);
  EXPECT_EQ(d.measurements, 6);
  EXPECT_NEAR(d.bias, 0.012, 1e-12);
  EXPECT_NEAR(d.u_b, 0.0040414519, 1e-9);
  EXPECT_NEAR(d.u_p, 0.002, 1e-12);
  EXPECT_NEAR(d.u_s, 0.0068556546, 1e-9);
  EXPECT_NEAR(d.u_cal, 0.0017320508, 1e-9);
  const Substitution s = substitute(10.030, 0.004, d, 2.0);
  EXPECT_NEAR(s.value, 10.018, 1e-12);
  EXPECT_EQ(s.u_w, 0.0);
  EXPECT_NEAR(s.combined, 0.0082056891, 1e-9);
  EXPECT_NEAR(s.effective_dof, 2.2546138, 1e-6);
  EXPECT_NEAR(s.expanded, studentCoverageFactor(s.effective_dof, 2.0) * s.combined, 1e-15);
  // The file keeps the masters and u_s.
  const Verification back = Verification::fromConfig(
      ConfigNode::fromJson(v.toJson(), "verification.json"), "verification.json");
  EXPECT_EQ(back.dimensions[0].masters, 3);
  EXPECT_EQ(back.dimensions[0].u_s, d.u_s);
  EXPECT_EQ(back.measurements[5].master, 2);

  // Six masters measured once each.
  std::vector<std::map<std::string, CertifiedValue>> six;
  for (int i = 0; i < 6; ++i) {
    measured[static_cast<size_t>(i)].master = i;
    six.push_back(three[static_cast<size_t>(i / 2)]);
  }
  const VerifiedDimension once = verifyOnMasters(measured, six, someConditions()).dimensions[0];
  EXPECT_NEAR(once.u_p, std::sqrt(41.6e-6), 1e-12);
  EXPECT_NEAR(once.u_b, std::sqrt(41.6e-6 / 6.0), 1e-12);
  EXPECT_EQ(once.u_s, 0.0);
  const Substitution t = substitute(10.030, 0.004, once, 2.0);
  const double repeated = 41.6e-6 * (1.0 + 1.0 / 6.0);
  EXPECT_NEAR(t.effective_dof, std::pow(t.combined, 4) / (repeated * repeated / 5.0), 1e-9);

  // A master without a measurement, or a measurement without a master.
  EXPECT_THROW(verifyOnMasters(measured, {three[0]}, someConditions()), Error);
  std::vector<MasterMeasurement> first_two(measured.begin(), measured.begin() + 4);
  EXPECT_THROW(verifyOnMasters(first_two, six, someConditions()), Error);
}

// The job names one master ("master" and "measurements") or several
// ("masters", each with its own); either, not both; three jobs in all.
TEST(Verification, TheJobNamesOneMasterOrSeveral) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("xgauge_verify_job_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  auto load = [&](const nlohmann::json& text) {
    std::ofstream(dir / "verify.json") << text.dump();
    return VerificationJob::load(dir / "verify.json");
  };
  const nlohmann::json certificate = {
      {"width", {{"value", 10.0}, {"standard_uncertainty", 0.002}}}};
  auto master = [&](const std::vector<std::string>& jobs) {
    return nlohmann::json{{"certificate", certificate}, {"measurements", jobs}};
  };
  const VerificationJob several =
      load({{"masters", {master({"a.json", "b.json"}), master({"c.json"})}}});
  ASSERT_EQ(several.masters.size(), 2u);
  EXPECT_EQ(several.masters[1].measurements.front(), dir / "c.json");
  EXPECT_EQ(several.masters[0].certificate.at("width").value, 10.0);
  const nlohmann::json single = {{"master", {{"certificate", certificate}}},
                                 {"measurements", {"a.json", "b.json", "c.json"}}};
  EXPECT_EQ(load(single).masters.size(), 1u);
  auto message = [&](const nlohmann::json& text) {
    try {
      load(text);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  nlohmann::json both = single;
  both["masters"] = {master({"d.json"})};
  EXPECT_NE(message(both).find("either"), std::string::npos);
  EXPECT_NE(message({{"masters", {master({"a.json"}), master({"b.json"})}}}).find("at least 3"),
            std::string::npos);
  EXPECT_NE(message({{"masters", {master({}), master({"a.json", "b.json", "c.json"})}}})
                .find("at least one measurement"),
            std::string::npos);
  nlohmann::json misspelled = {{"masters", {master({"a.json", "b.json", "c.json"})}}};
  misspelled["masters"][0]["measurments"] = misspelled["masters"][0]["measurements"];
  misspelled["masters"][0].erase("measurements");
  EXPECT_NE(message(misspelled).find("measurements"), std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST(Verification, NeedsEnoughMeasurementsAndACertifiedDimension) {
  std::vector<MasterMeasurement> two = fourMeasurements();
  two.resize(2);
  EXPECT_THROW(verifyOnMaster(two, {{"width", {10.0, 0.002}}}, someConditions()), Error);
  EXPECT_THROW(verifyOnMaster(fourMeasurements(), {{"height", {10.0, 0.002}}}, someConditions()),
               Error);
}

}  // namespace
}  // namespace xgauge
