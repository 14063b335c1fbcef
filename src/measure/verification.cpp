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
                    {"masters", d.masters},
                    {"u_s", d.u_s},
                    {"own_standard_uncertainty", d.own_master}});
  nlohmann::json record = nlohmann::json::array();
  for (const MasterMeasurement& m : measurements) {
    nlohmann::json values = nlohmann::json::object();
    for (const auto& [name, yu] : m.dimensions)
      values[name] = {{"value", yu.first}, {"own_standard_uncertainty", yu.second}};
    record.push_back({{"job", m.job},
                      {"master", m.master + 1},
                      {"dimensions", values},
                      {"magnifications", m.magnifications}});
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
    // Files from before several masters: one master, no u_s.
    if (auto masters = d.find("masters"))
      out.masters = static_cast<int>(masters->integer(1, out.measurements));
    if (auto u_s = d.find("u_s")) out.u_s = u_s->number(0.0, 1e3);
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
    if (auto master = record[k].find("master"))
      measured.master = static_cast<int>(master->integer(1, 1000000)) - 1;
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
  std::vector<MasterMeasurement> one = measurements;
  for (MasterMeasurement& m : one) m.master = 0;
  return verifyOnMasters(one, {certificate}, std::move(conditions));
}

namespace {

double sampleVariance(const std::vector<double>& values, double mean) {
  double squares = 0.0;
  for (double v : values) squares += (v - mean) * (v - mean);
  return squares / static_cast<double>(values.size() - 1);
}

double meanOf(const std::vector<double>& values) {
  double sum = 0.0;
  for (double v : values) sum += v;
  return sum / static_cast<double>(values.size());
}

// One dimension over the masters (the header's equations); y[j] master j's
// values, own the measurements' own combined standard uncertainties.
VerifiedDimension verifiedOver(const std::string& name, const std::vector<std::vector<double>>& y,
                               const std::vector<CertifiedValue>& certified,
                               const std::vector<double>& own) {
  VerifiedDimension d;
  d.name = name;
  d.masters = static_cast<int>(y.size());
  std::vector<double> means, calibrated, u_cal2;
  double within = 0.0, inverse_n = 0.0;
  int n = 0;
  for (size_t j = 0; j < y.size(); ++j) {
    const double mean = meanOf(y[j]);
    means.push_back(mean);
    calibrated.push_back(certified[j].value);
    u_cal2.push_back(certified[j].standard_uncertainty * certified[j].standard_uncertainty);
    for (double v : y[j]) within += (v - mean) * (v - mean);
    inverse_n += 1.0 / static_cast<double>(y[j].size()) / static_cast<double>(y.size());
    n += static_cast<int>(y[j].size());
  }
  d.measurements = n;
  d.mean = meanOf(means);
  d.calibrated = meanOf(calibrated);
  d.bias = d.mean - d.calibrated;
  d.u_cal = std::sqrt(meanOf(u_cal2));
  d.own_master = meanOf(own);
  if (d.masters == 1) {
    d.u_p = std::sqrt(within / (n - 1));
    d.u_b = d.u_p / std::sqrt(static_cast<double>(n));
    return d;
  }
  std::vector<double> biases;
  for (size_t j = 0; j < y.size(); ++j) biases.push_back(means[j] - calibrated[j]);
  const double between = sampleVariance(biases, d.bias);
  d.u_b = std::sqrt(between / d.masters);
  if (n == d.masters) {
    d.u_p = std::sqrt(between);
  } else {
    d.u_p = std::sqrt(within / (n - d.masters));
    d.u_s = std::sqrt(std::max(0.0, between - d.u_p * d.u_p * inverse_n));
  }
  return d;
}

}  // namespace

Verification verifyOnMasters(const std::vector<MasterMeasurement>& measurements,
                             const std::vector<std::map<std::string, CertifiedValue>>& certificates,
                             VerificationConditions conditions) {
  const auto n = static_cast<int>(measurements.size());
  if (n < kMinVerificationMeasurements)
    fail("a verification needs at least {} measurements of its masters, got {}",
         kMinVerificationMeasurements, n);
  const size_t masters = certificates.size();
  std::vector<int> per_master(masters, 0);
  for (const MasterMeasurement& m : measurements) {
    if (m.master < 0 || static_cast<size_t>(m.master) >= masters)
      fail("{}: master {} has no certificate (there are {})", m.job, m.master + 1, masters);
    ++per_master[static_cast<size_t>(m.master)];
  }
  for (size_t j = 0; j < masters; ++j)
    if (per_master[j] == 0) fail("master {} of {} has no measurement", j + 1, masters);
  Verification v;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const MasterMeasurement& m : measurements)
    for (double magnification : m.magnifications)
      lo = std::min(lo, magnification), hi = std::max(hi, magnification);
  conditions.magnification = {lo, hi};
  v.conditions = std::move(conditions);
  v.measurements = measurements;
  for (const auto& [name, first] : certificates.front()) {
    std::vector<CertifiedValue> certified;
    for (const auto& certificate : certificates)
      if (const auto it = certificate.find(name); it != certificate.end())
        certified.push_back(it->second);
    if (certified.size() < masters) continue;  // not certified on every master
    std::vector<std::vector<double>> y(masters);
    std::vector<double> own;
    for (const MasterMeasurement& m : measurements)
      if (const auto it = m.dimensions.find(name); it != m.dimensions.end())
        y[static_cast<size_t>(m.master)].push_back(it->second.first),
            own.push_back(it->second.second);
    if (static_cast<int>(own.size()) < n) continue;  // not measured every time
    v.dimensions.push_back(verifiedOver(name, y, certified, own));
  }
  if (v.dimensions.empty())
    fail(
        "no dimension certified on every master was measured in every one of the {} "
        "measurements (a dimension must be free in the masters' jobs to be verified)",
        n);
  return v;
}

Substitution substitute(double measured, double own_combined, const VerifiedDimension& verified,
                        double normal_coverage_factor) {
  Substitution s;
  s.value = measured - verified.bias;
  s.u_w = std::sqrt(
      std::max(0.0, own_combined * own_combined - verified.own_master * verified.own_master));
  const double p2 = verified.u_p * verified.u_p,
               between = verified.u_s * verified.u_s + verified.u_b * verified.u_b;
  // Several masters' certificates are in their biases' spread (the header).
  const double cal2 = verified.masters > 1 ? 0.0 : verified.u_cal * verified.u_cal;
  s.combined = std::sqrt(cal2 + p2 + between + s.u_w * s.u_w);
  const double u4 = s.combined * s.combined * s.combined * s.combined;
  // Welch-Satterthwaite over the estimates (the header): one where u_p and
  // u_b are the same estimate, two where the masters were measured again.
  const int n = verified.measurements, m = verified.masters;
  double denominator = 0.0;
  if (m <= 1 && n > 1)
    denominator = (p2 + between) * (p2 + between) / (n - 1);
  else if (m > 1 && n == m)
    denominator = (p2 + between) * (p2 + between) / (m - 1);
  else if (m > 1)
    denominator = p2 * p2 / (n - m) + between * between / (m - 1);
  s.effective_dof = denominator > 0.0 ? u4 / denominator : std::numeric_limits<double>::infinity();
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
