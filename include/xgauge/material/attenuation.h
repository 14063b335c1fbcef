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

}  // namespace xgauge
