// The measuring method verified on a calibrated master, and the substitution
// that carries that verification over to a workpiece (ISO 15530-3, the
// substitution method of coordinate metrology; VDI/VDE 2630-2.1 for CT).
//
// A lab measures a master, a specimen of the product's part type whose
// dimensions a CMM gave with their standard uncertainties u_cal, n times
// under the production conditions (`xgauge verify`). Per dimension, from the
// master's measured values y_1 .. y_n and its calibrated value x_cal:
//
//   b   = mean(y) - x_cal                   the method's bias
//   u_p = s(y), the sample standard deviation  (n - 1 in the denominator):
//                                           its repeatability
//   u_b = u_p / sqrt(n)                      the uncertainty of b as
//                                           estimated from n measurements
//
// A workpiece measured with value y and the measurement's own (model)
// combined standard uncertainty u_own then reports
//
//   y' = y - b
//   u  = sqrt(u_cal^2 + u_p^2 + u_b^2 + u_w^2)
//   U  = k u,  k = t_nu((1 + p) / 2)
//   u_w^2 = max(0, u_own^2 - u_own,master^2)
//
// u_p and u_b come from the same n measurements, so u is known only to
// n - 1 degrees of freedom where they dominate: k is Student's t quantile
// at the effective degrees of freedom of Welch and Satterthwaite (GUM,
// JCGM 100:2008, G.4) for the coverage probability p of the normal
// k = 2 (95.45 %),
//
//   nu = u^4 / ((u_p^2 + u_b^2)^2 / (n - 1)),
//
// u_cal and u_w being taken as exactly known (infinite degrees of
// freedom). Three measurements of the master where they dominate give
// nu = 2 and k = 4.53; twenty give k = 2.14.
//
// u_w stands for the workpiece's own variation, what makes it differ from
// the master in the method's eyes: u_own,master is the mean of the master's
// own combined standard uncertainties, so a workpiece whose fit the model
// explains as well as the master's adds nothing, and one with form
// deviations, residual regions or a worse fit adds what its own budget
// grew by. The rest of the own budget (the curve, the distances, the noise)
// is what b and u_p measured on the master, and is not counted twice.
//
// Several masters (specimens of the part type, each with its certificate,
// M >= 2) also measure what one cannot: how much the method's bias varies
// from specimen to specimen (their form deviations, chamfers, fillets and
// drilled holes differ, and the method sees each a little differently).
// With the biases b_ji = y_ji - x_cal,j of master j's n_j measurements,
// their means bbar_j and N = sum n_j:
//
//   b   = mean_j(bbar_j)                    the method's bias over masters
//   s_B = s(bbar_j)  (M - 1 in the denominator)
//   u_b = s_B / sqrt(M)                      the uncertainty of b
//   N > M:  u_p = the pooled standard deviation within masters (N - M
//           degrees of freedom), u_s^2 = max(0, s_B^2 - u_p^2 mean_j(1/n_j))
//           the specimens' own variation of the bias
//   N = M:  u_p = s_B (one measurement per master: repeatability and the
//           specimens' variation together), u_s = 0
//
// and u = sqrt(u_p^2 + u_s^2 + u_b^2 + u_w^2). The certificates' errors are
// in the masters' biases (bbar_j = y_j - x_cal,j), so s_B holds their
// variance and u_b their share of b: u_cal (the root mean square of the
// certificates', kept for the record) is not added again. Subtracting it
// from s_B^2 would give an unbiased variance, but s_B from a few masters
// is too uncertain to take a known variance from: on lab2's suite (three
// masters) that left the prism's groove_center within U 6 times in 10.
// Kept in, U is conservative by at most u_cal^2. For Welch-Satterthwaite
// the estimates from s_B have M - 1 degrees of freedom, the pooled u_p
// N - M; where u_p and u_b are the same estimate (one master, or one
// measurement per master) they count as one.
//
// A verification holds only for the conditions it was made under: the part
// model, the machine and the material (their files' SHA-256: the same bytes),
// and the range of magnifications of the master's radiographs (the part's
// centre, widened by kMagnificationMargin of itself at each end). A
// measurement outside them is refused (an Error naming the condition),
// never silently verified.
#pragma once

#include "xgauge/core/config.h"

#include <nlohmann/json.hpp>

#include <array>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace xgauge {

inline constexpr double kMagnificationMargin = 0.02;
inline constexpr int kMinVerificationMeasurements = 3;

// A master's certified dimension: its value and standard uncertainty (k = 1),
// in the dimension's unit.
struct CertifiedValue {
  double value = 0.0;
  double standard_uncertainty = 0.0;
};

struct VerifiedDimension {
  std::string name;
  int measurements = 0;     // n
  double calibrated = 0.0;  // x_cal
  double mean = 0.0;        // mean(y)
  double bias = 0.0;        // b
  double u_cal = 0.0;       // the certificate's
  double u_p = 0.0;         // repeatability
  double u_b = 0.0;         // of b
  double own_master = 0.0;  // mean own combined standard uncertainty on the master
  int masters = 1;          // M
  double u_s = 0.0;         // the specimens' own variation of the bias (M >= 2)
};

struct VerificationConditions {
  std::string part_sha256, machine_sha256, material_sha256;
  std::string part_file, machine_file, material_file;  // as the master's jobs named them
  std::array<double, 2> magnification{0.0, 0.0};       // of the master's radiographs
};

// One measurement of the master: each free dimension's value and own
// combined standard uncertainty, and the magnification of each radiograph.
struct MasterMeasurement {
  std::string job;  // the measurement job's file, for the record
  int master = 0;   // which master (an index into the certificates)
  std::map<std::string, std::pair<double, double>> dimensions;  // name -> (y, u_own)
  std::vector<double> magnifications;
};

struct Verification {
  std::filesystem::path file;  // where it was read from (empty when built)
  VerificationConditions conditions;
  std::vector<VerifiedDimension> dimensions;
  double coverage_factor = 2.0;
  std::vector<MasterMeasurement> measurements;  // the record it was made from

  const VerifiedDimension* find(const std::string& name) const;
  nlohmann::json toJson() const;
  // Reads a verification file (docs/formats.md); Error naming the key.
  static Verification fromConfig(const ConfigNode& root, const std::filesystem::path& file);
};

// The verification from n >= kMinVerificationMeasurements measurements of
// the master and its certificate (every certified dimension that every
// measurement gives; Error when none, or too few measurements).
Verification verifyOnMaster(const std::vector<MasterMeasurement>& measurements,
                            const std::map<std::string, CertifiedValue>& certificate,
                            VerificationConditions conditions);
// The same over several masters: certificates[j] is master j's, each
// measurement names its master (MasterMeasurement::master); every master
// needs at least one measurement, and a dimension is verified where every
// certificate names it and every measurement gives it.
Verification verifyOnMasters(const std::vector<MasterMeasurement>& measurements,
                             const std::vector<std::map<std::string, CertifiedValue>>& certificates,
                             VerificationConditions conditions);

// A workpiece's dimension by substitution (the header's equations).
struct Substitution {
  double value = 0.0;     // y' = y - b
  double expanded = 0.0;  // U
  double u_w = 0.0;
  double combined = 0.0;         // u = U / k
  double effective_dof = 0.0;    // nu (infinite where u_p = 0)
  double coverage_factor = 0.0;  // k
};
// `normal_coverage_factor` is k for infinite degrees of freedom (the
// verification's; 2): it fixes the coverage probability p.
Substitution substitute(double measured, double own_combined, const VerifiedDimension& verified,
                        double normal_coverage_factor);

// Student's t quantile k for nu degrees of freedom with the coverage
// probability of the normal quantile k_normal: the coverage factor of a
// standard uncertainty known to nu degrees of freedom (GUM G.3).
double studentCoverageFactor(double nu, double k_normal);

// Error (naming the verification file and the condition) unless a
// measurement with these digests and magnifications lies within the
// verification's conditions.
void checkVerificationConditions(const Verification& verification, const std::string& part_sha256,
                                 const std::string& machine_sha256,
                                 const std::string& material_sha256,
                                 const std::vector<double>& magnifications);

}  // namespace xgauge
