// Attenuation data from xraylib (Debian package libxrl-dev); no attenuation
// numbers are typed into xgauge's code.
#pragma once

#include <string>

namespace xgauge {

// Total mass attenuation coefficient (with coherent scattering) of a chemical
// formula ("Al", "SiO2", "Ca5(PO4)3") or a NIST compound name ("Water,
// Liquid") at `energy_kev`, in cm^2/g. Throws Error naming the compound.
double massAttenuationCm2PerG(const std::string& compound, double energy_kev);

// Linear attenuation coefficient in 1/mm for the given density (g/cm^3).
double linearAttenuationPerMm(const std::string& compound, double density_g_cm3, double energy_kev);

// The smallest linear attenuation (1/mm) of the material over the photon
// energies a tube at `tube_kv` can emit, 1 keV to tube_kv keV in 0.5 keV
// steps (and tube_kv itself). A polychromatic transmission curve
// sum_E w_E exp(-mu(E) x) falls at least as fast as exp(-mu_min x) for every
// x, so no rate of a physical exponential-sum curve lies below it (docs/method.md,
// "Physically sound curves"). Usually mu at tube_kv; below an absorption
// edge inside the spectrum (lead's K edge at 88 keV under a 100 kV tube) it
// is lower. Throws Error for tube_kv outside [5, 1000] keV.
double attenuationFloorPerMm(const std::string& compound, double density_g_cm3, double tube_kv);

}  // namespace xgauge
