#include "xgauge/material/scatter_curves.h"

namespace xgauge {

// Each moved curve is written as a material of its own (model and terms),
// read back by the material's reader.
nlohmann::json ScatterCurves::toJson() const {
  nlohmann::json out = {{"transmission_uncertainty_besides", transmission_uncertainty_besides}};
  auto curve = [](const ExponentialSum& c) {
    nlohmann::json j = c.toJson();
    return nlohmann::json{{"model", j.at("model")}, {"terms", j.at("terms")}};
  };
  if (weight_plus_u) out["weight_plus_u"] = curve(*weight_plus_u);
  if (sigma_plus_u) out["sigma_mm_plus_u"] = curve(*sigma_plus_u);
  if (equivalent_end) out["equivalent_end"] = curve(*equivalent_end);
  if (kernel_choice) out["kernel_choice"] = curve(*kernel_choice);
  return out;
}

ScatterCurves ScatterCurves::fromConfig(const ConfigNode& node) {
  ScatterCurves out;
  out.transmission_uncertainty_besides =
      node.at("transmission_uncertainty_besides").number(0.0, 0.5);
  if (auto w = node.find("weight_plus_u")) out.weight_plus_u = ExponentialSum::fromConfig(*w);
  if (auto s = node.find("sigma_mm_plus_u")) out.sigma_plus_u = ExponentialSum::fromConfig(*s);
  if (auto e = node.find("equivalent_end")) out.equivalent_end = ExponentialSum::fromConfig(*e);
  if (auto k = node.find("kernel_choice")) out.kernel_choice = ExponentialSum::fromConfig(*k);
  return out;
}

}  // namespace xgauge
