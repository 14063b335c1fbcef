#include "xgauge/measure/verification.h"

#include "xgauge/core/error.h"

#include <fmt/format.h>
#include <boost/math/distributions/normal.hpp>
#include <boost/math/distributions/students_t.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace xgauge {

const VerifiedDimension* Verification::find(const std::string& name) const {
  for (const VerifiedDimension& d : dimensions)
    if (d.name == name) return &d;
  return nullptr;
}

nlohmann::json Verification::toJson() const {
  nlohmann::json dims = nlohmann::json::array();
  for (const VerifiedDimension& d : dimensions)
    dims.push_back({{"name", d.name},
                    {"measurements", d.measurements},
                    {"calibrated", d.calibrated},
                    {"mean", d.mean},
                    {"bias", d.bias},
                    {"u_cal", d.u_cal},
                    {"u_p", d.u_p},
                    {"u_b", d.u_b},
                    {"own_standard_uncertainty", d.own_master}});
  nlohmann::json record = nlohmann::json::array();
  for (const MasterMeasurement& m : measurements) {
    nlohmann::json values = nlohmann::json::object();
    for (const auto& [name, yu] : m.dimensions)
      values[name] = {{"value", yu.first}, {"own_standard_uncertainty", yu.second}};
    record.push_back(
        {{"job", m.job}, {"dimensions", values}, {"magnifications", m.magnifications}});
  }
  const VerificationConditions& c = conditions;
  return {{"kind", "verification"},
          {"method", "ISO 15530-3 substitution on a calibrated master; docs/method.md"},
          {"coverage_factor", coverage_factor},
          {"conditions",
           {{"part", {{"file", c.part_file}, {"sha256", c.part_sha256}}},
            {"machine", {{"file", c.machine_file}, {"sha256", c.machine_sha256}}},
            {"material", {{"file", c.material_file}, {"sha256", c.material_sha256}}},
            {"magnification", c.magnification}}},
          {"dimensions", dims},
          {"master_measurements", record}};
}

Verification Verification::fromConfig(const ConfigNode& root, const std::filesystem::path& file) {
  Verification v;
  v.file = file;
  if (root.at("kind").string() != "verification")
    root.at("kind").fail("expected \"verification\" (a file `xgauge verify` wrote)");
  root.at("method").string();
  v.coverage_factor = root.at("coverage_factor").number(1.0, 10.0);
  const ConfigNode c = root.at("conditions");
  auto digest = [](const ConfigNode& node, std::string& file_out) {
    file_out = node.at("file").string();
    const std::string sha = node.at("sha256").string();
    if (sha.size() != 64 || sha.find_first_not_of("0123456789abcdef") != std::string::npos)
      node.at("sha256").fail("expected 64 lowercase hexadecimal digits");
    return sha;
  };
  v.conditions.part_sha256 = digest(c.at("part"), v.conditions.part_file);
  v.conditions.machine_sha256 = digest(c.at("machine"), v.conditions.machine_file);
  v.conditions.material_sha256 = digest(c.at("material"), v.conditions.material_file);
  const ConfigNode m = c.at("magnification");
  if (m.size() != 2) m.fail("expected [lowest, highest]");
  v.conditions.magnification = {m[0].number(1.0, 1e3), m[1].number(1.0, 1e3)};
  if (v.conditions.magnification[0] > v.conditions.magnification[1])
    m.fail("the lowest magnification exceeds the highest");
  const ConfigNode dims = root.at("dimensions");
  if (dims.size() == 0) dims.fail("a verification needs at least one dimension");
  for (size_t k = 0; k < dims.size(); ++k) {
    const ConfigNode d = dims[k];
    VerifiedDimension out;
    out.name = d.at("name").string();
    out.measurements =
        static_cast<int>(d.at("measurements").integer(kMinVerificationMeasurements, 1000000));
    out.calibrated = d.at("calibrated").number();
    out.mean = d.at("mean").number();
    out.bias = d.at("bias").number();
    out.u_cal = d.at("u_cal").number(0.0, 1e3);
    out.u_p = d.at("u_p").number(0.0, 1e3);
    out.u_b = d.at("u_b").number(0.0, 1e3);
    out.own_master = d.at("own_standard_uncertainty").number(0.0, 1e3);
    if (std::abs(out.mean - out.calibrated - out.bias) > 1e-9 * (1.0 + std::abs(out.mean)))
      d.at("bias").fail(
          fmt::format("is not mean - calibrated ({} - {})", out.mean, out.calibrated));
    if (v.find(out.name)) d.at("name").fail(fmt::format("'{}' is listed twice", out.name));
    v.dimensions.push_back(std::move(out));
  }
  // The record of the master's measurements: read back as written.
  const ConfigNode record = root.at("master_measurements");
  for (size_t k = 0; k < record.size(); ++k) {
    MasterMeasurement measured;
    measured.job = record[k].at("job").string();
    const ConfigNode values = record[k].at("dimensions");
    for (const std::string& name : values.keys())
      measured.dimensions[name] = {values.at(name).at("value").number(),
                                   values.at(name).at("own_standard_uncertainty").number(0.0, 1e3)};
    const ConfigNode magnifications = record[k].at("magnifications");
    for (size_t r = 0; r < magnifications.size(); ++r)
      measured.magnifications.push_back(magnifications[r].number(1.0, 1e3));
    v.measurements.push_back(std::move(measured));
  }
  return v;
}

Verification verifyOnMaster(const std::vector<MasterMeasurement>& measurements,
                            const std::map<std::string, CertifiedValue>& certificate,
                            VerificationConditions conditions) {
  const auto n = static_cast<int>(measurements.size());
  if (n < kMinVerificationMeasurements)
    fail("a verification needs at least {} measurements of the master, got {}",
         kMinVerificationMeasurements, n);
  Verification v;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const MasterMeasurement& m : measurements)
    for (double magnification : m.magnifications)
      lo = std::min(lo, magnification), hi = std::max(hi, magnification);
  conditions.magnification = {lo, hi};
  v.conditions = std::move(conditions);
  v.measurements = measurements;
  for (const auto& [name, certified] : certificate) {
    std::vector<double> y, own;
    for (const MasterMeasurement& m : measurements)
      if (const auto it = m.dimensions.find(name); it != m.dimensions.end())
        y.push_back(it->second.first), own.push_back(it->second.second);
    if (static_cast<int>(y.size()) < n) continue;  // not measured every time
    VerifiedDimension d;
    d.name = name;
    d.measurements = n;
    d.calibrated = certified.value;
    d.u_cal = certified.standard_uncertainty;
    double sum = 0.0, sum_own = 0.0;
    for (int i = 0; i < n; ++i)
      sum += y[static_cast<size_t>(i)], sum_own += own[static_cast<size_t>(i)];
    d.mean = sum / n;
    d.own_master = sum_own / n;
    double squares = 0.0;
    for (double v_i : y) squares += (v_i - d.mean) * (v_i - d.mean);
    d.u_p = std::sqrt(squares / (n - 1));
    d.u_b = d.u_p / std::sqrt(static_cast<double>(n));
    d.bias = d.mean - d.calibrated;
    v.dimensions.push_back(std::move(d));
  }
  if (v.dimensions.empty())
    fail(
        "no certified dimension of the master was measured in every one of its {} measurements "
        "(a dimension must be free in the master's jobs to be verified)",
        n);
  return v;
}

Substitution substitute(double measured, double own_combined, const VerifiedDimension& verified,
                        double normal_coverage_factor) {
  Substitution s;
  s.value = measured - verified.bias;
  s.u_w = std::sqrt(
      std::max(0.0, own_combined * own_combined - verified.own_master * verified.own_master));
  const double repeated = verified.u_p * verified.u_p + verified.u_b * verified.u_b;
  s.combined = std::sqrt(verified.u_cal * verified.u_cal + repeated + s.u_w * s.u_w);
  const double u4 = s.combined * s.combined * s.combined * s.combined;
  s.effective_dof = repeated > 0.0 && verified.measurements > 1
                        ? u4 / (repeated * repeated / (verified.measurements - 1))
                        : std::numeric_limits<double>::infinity();
  s.coverage_factor = studentCoverageFactor(s.effective_dof, normal_coverage_factor);
  s.expanded = s.coverage_factor * s.combined;
  return s;
}

double studentCoverageFactor(double nu, double k_normal) {
  XG_CHECK(nu > 0.0 && k_normal > 0.0, "nu = {}, k = {}", nu, k_normal);
  const double p = boost::math::cdf(boost::math::normal(), k_normal);
  if (!std::isfinite(nu) || nu > 1e7) return k_normal;
  return boost::math::quantile(boost::math::students_t(nu), p);
}

void checkVerificationConditions(const Verification& verification, const std::string& part_sha256,
                                 const std::string& machine_sha256,
                                 const std::string& material_sha256,
                                 const std::vector<double>& magnifications) {
  const VerificationConditions& c = verification.conditions;
  const std::string file = verification.file.string();
  auto refuse = [&](const std::string& why) {
    fail(
        "{}: the verification does not hold for this measurement: {}; verify the method "
        "under these conditions (xgauge verify) or measure without it",
        file, why);
  };
  if (part_sha256 != c.part_sha256)
    refuse(fmt::format("its master was another part model ({}), not this one", c.part_file));
  if (machine_sha256 != c.machine_sha256)
    refuse(fmt::format("it was made on another machine ({})", c.machine_file));
  if (material_sha256 != c.material_sha256)
    refuse(fmt::format("it was made with another material ({})", c.material_file));
  const double lo = c.magnification[0] * (1.0 - kMagnificationMargin),
               hi = c.magnification[1] * (1.0 + kMagnificationMargin);
  for (double m : magnifications)
    if (m < lo || m > hi)
      refuse(fmt::format(
          "a radiograph's magnification {:.3f} lies outside the master's {:.3f} .. "
          "{:.3f} (widened by {:.0f} %: {:.3f} .. {:.3f})",
          m, c.magnification[0], c.magnification[1], 100.0 * kMagnificationMargin, lo, hi));
}

}  // namespace xgauge
