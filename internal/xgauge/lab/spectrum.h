// The physics of the virtual X-ray lab's beam: a tungsten-anode tube
// spectrum, the filters in its path, the detector's energy response, and the
// resulting polychromatic transmission curve T(x) of a homogeneous material.
//
// All attenuation data and line energies come from xraylib; no attenuation
// number is typed into xgauge. Energies in keV, lengths in mm, densities in
// g/cm^3, attenuation coefficients in 1/mm. Photon numbers are relative (the
// tube current and solid angle are not modelled).
//
// Beam JSON (BeamModel::fromConfig):
//   key               meaning                                           default
//   tube_kv           tube voltage E0 in kV, 20..450                    required
//   bin_kev           width of the energy bins, 0.01..5 keV             0.5
//   filters           array of Layer: inherent (tube window) + added    required
//   detector_window   Layer: the detector's entrance window             required
//   scintillator      Layer: the converter that absorbs the photons     CsI 4.51, 0.6 mm
// Layer JSON: {"compound": "Al", "density_g_cm3": 2.699, "thickness_mm": 1}.
#pragma once

#include "xgauge/core/config.h"
#include "xgauge/material/transmission_table.h"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace xgauge {

// A homogeneous slab: a chemical formula ("Al", "CsI", "SiO2") or a NIST
// compound name ("Water, Liquid") as xraylib knows it, its density and its
// thickness along the beam.
struct Layer {
  std::string compound;
  double density_g_cm3 = 0.0;  // > 0
  double thickness_mm = 0.0;   // >= 0

  // Throws Error unless the compound is known to xraylib, the density is
  // positive and the thickness is >= 0 (all finite).
  void validate() const;
  // Linear attenuation coefficient (total, with coherent scattering), 1/mm.
  double muPerMm(double energy_kev) const;
  // exp(-mu(E) * thickness): the fraction of photons of energy E passing the
  // slab without interacting.
  double transmission(double energy_kev) const;

  // Keys compound, density_g_cm3, thickness_mm; validated, errors name the
  // key. Does not call finish().
  // `compound` (checked against xraylib, errors at the key), `density_g_cm3`
  // and, unless `with_thickness` is false (a part's material), `thickness_mm`.
  static Layer fromConfig(const ConfigNode& node, bool with_thickness = true);
  nlohmann::json toJson() const;
};

// One characteristic emission line of the anode.
struct EmissionLine {
  int xraylib_line = 0;     // xraylib line macro, e.g. KL3_LINE (= KA1_LINE)
  double energy_kev = 0.0;  // xraylib LineEnergy
  double photons = 0.0;     // same relative units as Spectrum::kramers
};

// Photon fluence in energy bins of equal width bin_kev. Bin i covers
// [lowerEdgeKev(i), lowerEdgeKev(i) + bin_kev); its representative energy is
// the centre (attenuation is evaluated there). Edges are integer multiples of
// bin_kev, so spectra with the same bin width share a grid.
class Spectrum {
 public:
  // Lowest photon energy of any spectrum built here: Kramers' 1/E diverges at
  // 0, xraylib's tables start at 1 keV, and nothing below passes any window.
  static constexpr double kMinEnergyKev = 1.0;

  // Bins starting at first_bin * bin_kev (first_bin >= 0); photons >= 0 per
  // bin, finite. Throws Error otherwise.
  Spectrum(long first_bin, double bin_kev, std::vector<double> photons);

  // Kramers' thick-target bremsstrahlung continuum (Kramers 1923, Phil. Mag.
  // 46, 836): N(E) dE = k Z (E0 - E) / E dE photons for E < E0 = tube_kv,
  // zero above; k Z is set to 1 (relative units). Each bin holds the exact
  // integral over the part of the bin below E0. The grid runs from
  // kMinEnergyKev to the bin containing max(max_energy_kev, tube_kv).
  static Spectrum kramers(double tube_kv, double bin_kev = 0.5, double max_energy_kev = 0.0);
  // Kramers' continuum plus the tungsten K and L characteristic lines
  // (tungstenLines), each line's photons added to the bin containing its
  // energy. Self-filtration in the anode is NOT modelled, so the spectrum is
  // unrealistically soft below ~20 keV until a filter is applied.
  static Spectrum tungsten(double tube_kv, double bin_kev = 0.5);

  // Multiplies every bin by exp(-mu(E) t) of the layer, mu at the bin centre.
  void filter(const Layer& layer);

  size_t size() const { return photons_.size(); }
  double binKev() const { return bin_kev_; }
  double lowerEdgeKev(size_t i) const;
  // Bin centres, keV; photons per bin. Same length.
  const std::vector<double>& energiesKev() const { return energies_kev_; }
  const std::vector<double>& photons() const { return photons_; }
  // Index of the bin containing energy_kev, or size() if it is off the grid.
  size_t binOf(double energy_kev) const;

  double totalPhotons() const;
  // Photons in the bins whose centre lies in [lo_kev, hi_kev).
  double photonsBetween(double lo_kev, double hi_kev) const;
  // Photon-weighted mean of the bin centres, keV; 0 for an empty spectrum.
  double meanEnergyKev() const;

 private:
  long first_bin_;
  double bin_kev_;
  std::vector<double> energies_kev_;
  std::vector<double> photons_;
};

// The tungsten lines emitted by a tube at tube_kv, in Spectrum::kramers units.
// A shell's lines appear only when tube_kv exceeds its edge energy (K, L1, L2,
// L3; xraylib EdgeEnergy). Model (documented in spectrum.cpp): vacancies per
// electron ~ occupancy * ((E0 - E_edge) / E_edge)^1.63 (Green & Cosslett
// 1968), L vacancies redistributed by Coster-Kronig transitions, photons =
// vacancies * fluorescence yield * radiative rate of the line (all xraylib);
// one overall scale fixed so that the K lines are 10 % of the photons above
// 50 keV from an unfiltered 150 kV tube. Lines below kMinEnergyKev are left
// out.
std::vector<EmissionLine> tungstenLines(double tube_kv);

// Source, filtration and detector of a radiograph: what sets the energy
// weighting of the signal. Defaults describe the thesis set-up
// (docs/method.md: 220 kV tungsten tube, 1 mm Be window + 1 mm Al, Al
// entrance window, CsI panel).
struct BeamModel {
  double tube_kv = 220.0;
  double bin_kev = 0.5;
  std::vector<Layer> filters = {{"Be", 1.848, 1.0}, {"Al", 2.699, 1.0}};
  Layer detector_window = {"Al", 2.699, 0.5};
  Layer scintillator = {"CsI", 4.51, 0.6};

  // Throws Error on a value out of the ranges in the table above or a bad layer.
  void validate() const;

  // The tube spectrum after every filter (not the detector window).
  Spectrum spectrum() const;
  // Per bin of spectrum(): the signal of an energy-integrating scintillator,
  //   w(E) = N(E) * T_window(E) * E * (1 - exp(-mu_scint(E) t_scint)),
  // the energy of the photons that interact in the scintillator. Ignores
  // K-fluorescence escape (Cs/I K x-rays leaving the screen), Compton photons
  // that deposit only part of E, and light-yield non-proportionality.
  std::vector<double> detectorWeights() const;
  // The same for any spectrum on this beam's grid that reaches the detector.
  std::vector<double> detectorWeights(const Spectrum& at_detector) const;

  // Keys in the table above; validated, errors name the key. Does not call
  // finish().
  static BeamModel fromConfig(const ConfigNode& node);
  nlohmann::json toJson() const;
};

// The normalized detector signal behind a path x (mm) through one homogeneous
// material, for a polychromatic beam:
//
//   T(x) = sum_E w(E) exp(-mu(E) x) / sum_E w(E),   w = detector weights,
//
// so T(0) = 1 exactly. T is a function of x alone, decreasing and convex; its
// effective attenuation -d ln T / dx falls with x (beam hardening: it equals
// the w-weighted mean of mu over the spectrum hardened by x, whose derivative
// is minus that spectrum's variance of mu).
class PolychromaticMaterial {
 public:
  // Weights from beam.detectorWeights(); material.thickness_mm is ignored (the
  // path length is the variable). Throws Error on a bad beam or material.
  PolychromaticMaterial(const BeamModel& beam, const Layer& material);
  // Explicit weights (>= 0, not all 0) at the given energies.
  PolychromaticMaterial(const std::vector<double>& energies_kev, const std::vector<double>& weights,
                        const Layer& material);

  double transmission(double path_mm) const;      // T(x)
  double derivative(double path_mm) const;        // dT/dx, 1/mm
  double effectiveMuPerMm(double path_mm) const;  // -T'(x) / T(x), 1/mm

  // Tabulated T on [0, max_path_mm] with exact node derivatives. The step
  // bounds the cubic Hermite error |T''''|max h^4 / 384 by 1e-9, using
  // |T''''| <= sum w mu^4 / sum w (the value at x = 0); it is at most 0.01 mm
  // and at least 1e-4 mm (that floor is reached only by beams with almost no
  // filtration, where the bound is then not guaranteed).
  TransmissionTable table(double max_path_mm) const;
  double tableStepMm() const;

  // The retained terms (bins with w > 0): weights normalised to sum 1, and mu.
  const std::vector<double>& weights() const { return weights_; }
  const std::vector<double>& muPerMm() const { return mu_per_mm_; }

 private:
  std::vector<double> weights_;
  std::vector<double> mu_per_mm_;
  double weight_sum_ = 0.0;  // sum of weights_ in storage order (exactly as T sums)
};

// PolychromaticMaterial(beam, material).table(max_path_mm).
TransmissionTable polychromaticTransmission(const BeamModel& beam, const Layer& material,
                                            double max_path_mm);

}  // namespace xgauge
