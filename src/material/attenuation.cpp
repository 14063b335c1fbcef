#include "xgauge/material/attenuation.h"

#include "xgauge/core/error.h"

#include <xraylib.h>

#include <algorithm>
#include <cmath>
#include <memory>

namespace xgauge {

double massAttenuationCm2PerG(const std::string& compound, double energy_kev) {
  if (!(energy_kev > 0.0) || !std::isfinite(energy_kev))
    fail("photon energy must be positive, got {} keV", energy_kev);
  xrl_error* error = nullptr;
  const double value = CS_Total_CP(compound.c_str(), energy_kev, &error);
  if (error != nullptr) {
    std::unique_ptr<xrl_error, decltype(&xrl_error_free)> owned(error, xrl_error_free);
    fail("xraylib cannot compute attenuation of '{}' at {} keV: {}", compound, energy_kev,
         owned->message ? owned->message : "unknown error");
  }
  return value;
}

double linearAttenuationPerMm(const std::string& compound, double density_g_cm3,
                              double energy_kev) {
  if (!(density_g_cm3 > 0.0) || !std::isfinite(density_g_cm3))
    fail("density of '{}' must be positive, got {} g/cm^3", compound, density_g_cm3);
  // cm^2/g * g/cm^3 = 1/cm = 0.1/mm.
  return massAttenuationCm2PerG(compound, energy_kev) * density_g_cm3 * 0.1;
}

double attenuationFloorPerMm(const std::string& compound, double density_g_cm3, double tube_kv) {
  if (!(tube_kv >= 5.0 && tube_kv <= 1000.0))
    fail("tube voltage must be 5 to 1000 kV, got {}", tube_kv);
  double floor = linearAttenuationPerMm(compound, density_g_cm3, tube_kv);
  for (double e = 1.0; e < tube_kv; e += 0.5)
    floor = std::min(floor, linearAttenuationPerMm(compound, density_g_cm3, e));
  return floor;
}

}  // namespace xgauge
