#include "xgauge/lab/spectrum.h"

#include "xgauge/core/error.h"
#include "xgauge/material/attenuation.h"

#include <xraylib.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>

namespace xgauge {
namespace {

constexpr int kTungstenZ = 74;

// Calls an xraylib function fn(args..., &error); nullopt when xraylib reports
// an error (for example a line it has no data for).
template <typename Fn, typename... Args>
std::optional<double> tryXraylib(Fn fn, Args... args) {
  xrl_error* error = nullptr;
  const double value = fn(args..., &error);
  if (error != nullptr) {
    xrl_error_free(error);
    return std::nullopt;
  }
  return value;
}

// The same for data that must exist (tungsten's K and L shells).
template <typename Fn, typename... Args>
double xraylib(const char* what, Fn fn, Args... args) {
  const auto value = tryXraylib(fn, args...);
  XG_CHECK(value.has_value(), "xraylib has no {} for Z = {}", what, kTungstenZ);
  return *value;
}

// Throws Error (naming the compound) when xraylib does not know it.
void checkCompound(const std::string& compound) {
  if (compound.empty()) fail("empty compound name");
  massAttenuationCm2PerG(compound, 50.0);
}

// ---------------------------------------------------------------------------
// Characteristic lines.
//
// Shell ionisations per electron. The Bethe ionisation cross-section of shell
// s, Q_s ~ z_s ln(U) / (U E_s^2) (z_s electrons in the shell, U = E / E_s),
// integrated along the electron's slowing-down path (dE/ds ~ 1/E) gives a
// number of ionisations ~ z_s * f(U0) in which E_s cancels up to a slowly
// varying logarithm. For f we use the measured thick-target form of Green &
// Cosslett (1968, J. Phys. D 1, 425), f(U0) = (U0 - 1)^1.63, for K and, by
// assumption, for the L subshells. L1 and L2 vacancies move down by
// Coster-Kronig transitions before they radiate (xraylib CosKronTransProb).
// Photons of a line = vacancies * fluorescence yield * radiative rate
// (xraylib FluorYield, RadRate).
//
// Absolute scale relative to Kramers' continuum (whose k Z is 1 here): a
// calibration assumption, not a fit. Unfiltered at 150 kV, the K lines are
// taken to be 10 % of the photons above 50 keV, the middle of the 5-15 %
// range of published tungsten spectra (e.g. Tucker, Barnes & Chakraborty 1991,
// Med. Phys. 18, 211; Hernandez & Boone 2014, Med. Phys. 41, 042101). The
// L-line intensities are uncertain to a factor of about 2 and, without anode
// self-filtration, overestimated; any real filtration removes them.
constexpr double kGreenCosslettExponent = 1.63;
constexpr double kReferenceKv = 150.0;
constexpr double kReferenceFloorKev = 50.0;
constexpr double kReferenceKFraction = 0.10;

double primaryVacancies(int shell, double tube_kv) {
  const double edge_kev = xraylib("edge energy", EdgeEnergy, kTungstenZ, shell);
  if (tube_kv <= edge_kev) return 0.0;
  const double electrons = xraylib("electron configuration", ElectronConfig, kTungstenZ, shell);
  return electrons * std::pow((tube_kv - edge_kev) / edge_kev, kGreenCosslettExponent);
}

// Photons per K vacancy unit that make the reference K fraction come out.
double lineScale() {
  // Kramers photons in [50, 150) keV at E0 = 150: int (E0/E - 1) dE.
  const double continuum = kReferenceKv * std::log(kReferenceKv / kReferenceFloorKev) -
                           (kReferenceKv - kReferenceFloorKev);
  const double k_photons = primaryVacancies(K_SHELL, kReferenceKv) *
                           xraylib("fluorescence yield", FluorYield, kTungstenZ, K_SHELL);
  return continuum * kReferenceKFraction / (1.0 - kReferenceKFraction) / k_photons;
}

}  // namespace

// ---------------------------------------------------------------------------
// Layer

void Layer::validate() const {
  checkCompound(compound);
  if (!(density_g_cm3 > 0.0) || !std::isfinite(density_g_cm3))
    fail("layer '{}': density must be positive, got {} g/cm^3", compound, density_g_cm3);
  if (!(thickness_mm >= 0.0) || !std::isfinite(thickness_mm))
    fail("layer '{}': thickness must be >= 0, got {} mm", compound, thickness_mm);
}

double Layer::muPerMm(double energy_kev) const {
  return linearAttenuationPerMm(compound, density_g_cm3, energy_kev);
}

double Layer::transmission(double energy_kev) const {
  if (thickness_mm == 0.0) return 1.0;
  return std::exp(-muPerMm(energy_kev) * thickness_mm);
}

Layer Layer::fromConfig(const ConfigNode& node, bool with_thickness) {
  Layer layer;
  const ConfigNode compound = node.at("compound");
  layer.compound = compound.string();
  try {
    checkCompound(layer.compound);
  } catch (const Error& e) {
    compound.fail(e.message());
  }
  layer.density_g_cm3 = node.at("density_g_cm3").number(1e-6, 30.0);
  if (with_thickness) layer.thickness_mm = node.at("thickness_mm").number(0.0, 1000.0);
  return layer;
}

nlohmann::json Layer::toJson() const {
  return {{"compound", compound}, {"density_g_cm3", density_g_cm3}, {"thickness_mm", thickness_mm}};
}

// ---------------------------------------------------------------------------
// Spectrum

Spectrum::Spectrum(long first_bin, double bin_kev, std::vector<double> photons)
    : first_bin_(first_bin), bin_kev_(bin_kev), photons_(std::move(photons)) {
  if (first_bin_ < 0) fail("spectrum: first bin index must be >= 0, got {}", first_bin_);
  if (!(bin_kev_ > 0.0) || !std::isfinite(bin_kev_))
    fail("spectrum: bin width must be positive, got {} keV", bin_kev_);
  energies_kev_.resize(photons_.size());
  for (size_t i = 0; i < photons_.size(); ++i) {
    if (!(photons_[i] >= 0.0) || !std::isfinite(photons_[i]))
      fail("spectrum: bin {} holds {} photons; must be finite and >= 0", i, photons_[i]);
    energies_kev_[i] = lowerEdgeKev(i) + 0.5 * bin_kev_;
  }
}

Spectrum Spectrum::kramers(double tube_kv, double bin_kev, double max_energy_kev) {
  if (!(tube_kv > kMinEnergyKev) || !std::isfinite(tube_kv))
    fail("tube voltage must exceed {} kV, got {}", kMinEnergyKev, tube_kv);
  if (!(bin_kev > 0.0) || !std::isfinite(bin_kev) || !std::isfinite(max_energy_kev))
    fail("bad spectrum grid: bin {} keV, maximum {} keV", bin_kev, max_energy_kev);
  // Bins [k bin, (k + 1) bin) for first <= k < end; the small tolerance keeps
  // an energy that is a multiple of the bin width on the edge it names.
  const auto first = static_cast<long>(std::ceil(kMinEnergyKev / bin_kev - 1e-9));
  const double top_kev = std::max(max_energy_kev, tube_kv);
  const auto end = static_cast<long>(std::ceil(top_kev / bin_kev - 1e-9));
  std::vector<double> photons(static_cast<size_t>(std::max(0L, end - first)), 0.0);
  for (size_t i = 0; i < photons.size(); ++i) {
    // Exact integral of (E0/E - 1) over the part of the bin below E0.
    const double lo = static_cast<double>(first + static_cast<long>(i)) * bin_kev;
    const double hi = std::min(lo + bin_kev, tube_kv);
    if (hi > lo) photons[i] = std::max(0.0, tube_kv * std::log1p((hi - lo) / lo) - (hi - lo));
  }
  return Spectrum(first, bin_kev, std::move(photons));
}

Spectrum Spectrum::tungsten(double tube_kv, double bin_kev) {
  Spectrum spectrum = kramers(tube_kv, bin_kev);
  for (const EmissionLine& line : tungstenLines(tube_kv)) {
    const size_t i = spectrum.binOf(line.energy_kev);
    if (i < spectrum.size()) spectrum.photons_[i] += line.photons;
  }
  return spectrum;
}

void Spectrum::filter(const Layer& layer) {
  layer.validate();
  if (layer.thickness_mm == 0.0) return;
  for (size_t i = 0; i < photons_.size(); ++i) photons_[i] *= layer.transmission(energies_kev_[i]);
}

double Spectrum::lowerEdgeKev(size_t i) const {
  return static_cast<double>(first_bin_ + static_cast<long>(i)) * bin_kev_;
}

size_t Spectrum::binOf(double energy_kev) const {
  const double k = std::floor(energy_kev / bin_kev_) - static_cast<double>(first_bin_);
  if (!(k >= 0.0) || k >= static_cast<double>(photons_.size())) return photons_.size();
  return static_cast<size_t>(k);
}

double Spectrum::totalPhotons() const {
  double sum = 0.0;
  for (double n : photons_) sum += n;
  return sum;
}

double Spectrum::photonsBetween(double lo_kev, double hi_kev) const {
  double sum = 0.0;
  for (size_t i = 0; i < photons_.size(); ++i)
    if (energies_kev_[i] >= lo_kev && energies_kev_[i] < hi_kev) sum += photons_[i];
  return sum;
}

double Spectrum::meanEnergyKev() const {
  double photons = 0.0, energy = 0.0;
  for (size_t i = 0; i < photons_.size(); ++i) {
    photons += photons_[i];
    energy += photons_[i] * energies_kev_[i];
  }
  return photons > 0.0 ? energy / photons : 0.0;
}

std::vector<EmissionLine> tungstenLines(double tube_kv) {
  if (!(tube_kv > 0.0) || !std::isfinite(tube_kv))
    fail("tube voltage must be positive, got {} kV", tube_kv);

  // Vacancies per shell after the Coster-Kronig cascade L1 -> L2 -> L3.
  const auto ck = [](int transition) {
    return xraylib("Coster-Kronig probability", CosKronTransProb, kTungstenZ, transition);
  };
  double vacancies[4] = {};
  vacancies[K_SHELL] = primaryVacancies(K_SHELL, tube_kv);
  vacancies[L1_SHELL] = primaryVacancies(L1_SHELL, tube_kv);
  vacancies[L2_SHELL] = primaryVacancies(L2_SHELL, tube_kv) + ck(FL12_TRANS) * vacancies[L1_SHELL];
  vacancies[L3_SHELL] = primaryVacancies(L3_SHELL, tube_kv) + ck(FL13_TRANS) * vacancies[L1_SHELL] +
                        ck(FL23_TRANS) * vacancies[L2_SHELL];

  // xraylib numbers the lines of one shell consecutively (negative macros).
  struct ShellLines {
    int shell, first_line, last_line;
  };
  constexpr ShellLines kShells[] = {{K_SHELL, KL1_LINE, KP5_LINE},
                                    {L1_SHELL, L1L2_LINE, L1P5_LINE},
                                    {L2_SHELL, L2L3_LINE, L2Q1_LINE},
                                    {L3_SHELL, L3M1_LINE, L3Q1_LINE}};
  const double scale = lineScale();
  std::vector<EmissionLine> lines;
  for (const ShellLines& s : kShells) {
    if (vacancies[s.shell] <= 0.0) continue;
    const double shell_photons =
        scale * vacancies[s.shell] * xraylib("fluorescence yield", FluorYield, kTungstenZ, s.shell);
    for (int line = s.first_line; line >= s.last_line; --line) {
      const auto rate = tryXraylib(RadRate, kTungstenZ, line);
      const auto energy_kev = tryXraylib(LineEnergy, kTungstenZ, line);
      if (!rate || !energy_kev || *rate <= 0.0 || *energy_kev < Spectrum::kMinEnergyKev) continue;
      lines.push_back({line, *energy_kev, shell_photons * *rate});
    }
  }
  return lines;
}

// ---------------------------------------------------------------------------
// BeamModel

void BeamModel::validate() const {
  if (!(tube_kv >= 20.0 && tube_kv <= 450.0)) fail("tube_kv must be in [20, 450], got {}", tube_kv);
  if (!(bin_kev >= 0.01 && bin_kev <= 5.0)) fail("bin_kev must be in [0.01, 5], got {}", bin_kev);
  try {
    for (const Layer& f : filters) f.validate();
    detector_window.validate();
    scintillator.validate();
  } catch (const Error& e) {
    fail("beam: {}", e.message());
  }
  if (!(scintillator.thickness_mm > 0.0)) fail("beam: the scintillator must have a thickness > 0");
}

Spectrum BeamModel::spectrum() const {
  validate();
  Spectrum spectrum = Spectrum::tungsten(tube_kv, bin_kev);
  for (const Layer& f : filters) spectrum.filter(f);
  return spectrum;
}

std::vector<double> BeamModel::detectorWeights() const { return detectorWeights(spectrum()); }

std::vector<double> BeamModel::detectorWeights(const Spectrum& at_detector) const {
  validate();
  const auto& energies_kev = at_detector.energiesKev();
  const auto& photons = at_detector.photons();
  std::vector<double> weights(photons.size());
  for (size_t i = 0; i < photons.size(); ++i) {
    const double e = energies_kev[i];
    const double absorbed = -std::expm1(-scintillator.muPerMm(e) * scintillator.thickness_mm);
    weights[i] = photons[i] * detector_window.transmission(e) * e * absorbed;
  }
  return weights;
}

BeamModel BeamModel::fromConfig(const ConfigNode& node) {
  BeamModel beam;
  beam.tube_kv = node.at("tube_kv").number(20.0, 450.0);
  if (const auto bin = node.find("bin_kev")) beam.bin_kev = bin->number(0.01, 5.0);
  const ConfigNode filters = node.at("filters");
  if (!filters.isArray()) filters.fail("expected an array of layers");
  beam.filters.clear();
  for (size_t i = 0; i < filters.size(); ++i) beam.filters.push_back(Layer::fromConfig(filters[i]));
  beam.detector_window = Layer::fromConfig(node.at("detector_window"));
  if (const auto scintillator = node.find("scintillator")) {
    beam.scintillator = Layer::fromConfig(*scintillator);
    if (!(beam.scintillator.thickness_mm > 0.0))
      scintillator->at("thickness_mm").fail("a scintillator needs a thickness > 0");
  }
  return beam;
}

nlohmann::json BeamModel::toJson() const {
  nlohmann::json layers = nlohmann::json::array();
  for (const Layer& f : filters) layers.push_back(f.toJson());
  return {{"tube_kv", tube_kv},
          {"bin_kev", bin_kev},
          {"filters", layers},
          {"detector_window", detector_window.toJson()},
          {"scintillator", scintillator.toJson()}};
}

// ---------------------------------------------------------------------------
// PolychromaticMaterial

PolychromaticMaterial::PolychromaticMaterial(const BeamModel& beam, const Layer& material) {
  const Spectrum spectrum = beam.spectrum();
  *this = PolychromaticMaterial(spectrum.energiesKev(), beam.detectorWeights(spectrum), material);
}

PolychromaticMaterial::PolychromaticMaterial(const std::vector<double>& energies_kev,
                                             const std::vector<double>& weights,
                                             const Layer& material) {
  material.validate();
  if (energies_kev.size() != weights.size())
    fail("{} energies but {} weights", energies_kev.size(), weights.size());
  double total = 0.0;
  for (size_t i = 0; i < weights.size(); ++i) {
    if (!(weights[i] >= 0.0) || !std::isfinite(weights[i]))
      fail("weight {} is {}; must be finite and >= 0", i, weights[i]);
    if (weights[i] == 0.0) continue;  // contributes nothing at any x
    weights_.push_back(weights[i]);
    mu_per_mm_.push_back(material.muPerMm(energies_kev[i]));
    total += weights[i];
  }
  if (!(total > 0.0))
    fail("polychromatic material '{}': all detector weights are 0", material.compound);
  for (double& w : weights_) w /= total;
  // T sums in this same order, so T(0) = weight_sum_ / weight_sum_ = 1 exactly.
  for (double w : weights_) weight_sum_ += w;
}

double PolychromaticMaterial::transmission(double path_mm) const {
  double sum = 0.0;
  for (size_t k = 0; k < weights_.size(); ++k)
    sum += weights_[k] * std::exp(-mu_per_mm_[k] * path_mm);
  return sum / weight_sum_;
}

double PolychromaticMaterial::derivative(double path_mm) const {
  double sum = 0.0;
  for (size_t k = 0; k < weights_.size(); ++k)
    sum -= weights_[k] * mu_per_mm_[k] * std::exp(-mu_per_mm_[k] * path_mm);
  return sum / weight_sum_;
}

double PolychromaticMaterial::effectiveMuPerMm(double path_mm) const {
  // Ratio of the two sums with every exponent shifted by the smallest mu, so
  // that long paths do not underflow to 0 / 0.
  const double mu_min = *std::min_element(mu_per_mm_.begin(), mu_per_mm_.end());
  double numerator = 0.0, denominator = 0.0;
  for (size_t k = 0; k < weights_.size(); ++k) {
    const double term = weights_[k] * std::exp(-(mu_per_mm_[k] - mu_min) * path_mm);
    numerator += mu_per_mm_[k] * term;
    denominator += term;
  }
  return numerator / denominator;
}

double PolychromaticMaterial::tableStepMm() const {
  // |T''''(x)| <= T''''(0) = sum w mu^4 (weights sum to 1); h^4 M4 / 384 <= 1e-9.
  double m4 = 0.0;
  for (size_t k = 0; k < weights_.size(); ++k) m4 += weights_[k] * std::pow(mu_per_mm_[k], 4);
  if (!(m4 > 0.0)) return 0.01;
  return std::clamp(std::pow(384e-9 / m4, 0.25), 1e-4, 0.01);
}

TransmissionTable PolychromaticMaterial::table(double max_path_mm) const {
  if (!(max_path_mm > 0.0) || !std::isfinite(max_path_mm))
    fail("transmission table: maximum path must be positive, got {} mm", max_path_mm);
  return TransmissionTable([this](double x) { return transmission(x); },
                           [this](double x) { return derivative(x); }, max_path_mm, tableStepMm());
}

TransmissionTable polychromaticTransmission(const BeamModel& beam, const Layer& material,
                                            double max_path_mm) {
  return PolychromaticMaterial(beam, material).table(max_path_mm);
}

}  // namespace xgauge
