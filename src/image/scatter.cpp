#include "xgauge/image/scatter.h"

#include "xgauge/image/blur.h"
#include "xgauge/image/stats.h"

namespace xgauge {

ScatterModel ScatterModel::fromConfig(const ConfigNode& node) {
  ScatterModel out;
  out.weight = node.at("weight").number(0.0, 0.9);
  out.sigma_mm = node.at("sigma_mm").number(0.01, 1e4);
  out.weight_uncertainty = 0.05 * out.weight;
  out.sigma_uncertainty_mm = 0.1 * out.sigma_mm;
  if (auto u = node.find("weight_uncertainty")) out.weight_uncertainty = u->number(0.0, 0.5);
  if (auto u = node.find("sigma_uncertainty_mm")) out.sigma_uncertainty_mm = u->number(0.0, 1e4);
  return out;
}

nlohmann::json ScatterModel::toJson() const {
  return {{"weight", weight},
          {"sigma_mm", sigma_mm},
          {"weight_uncertainty", weight_uncertainty},
          {"sigma_uncertainty_mm", sigma_uncertainty_mm}};
}

Image ScatterModel::apply(Image image, double pitch_mm) const {
  return scatterBlur(std::move(image), weight, sigmaPx(pitch_mm));
}

Image ScatterModel::remove(const Image& normalized, double pitch_mm, const PixelRect& white,
                           int iterations) const {
  if (!(weight >= 0.0 && weight <= 0.9)) fail("scatter weight must be in [0, 0.9], got {}", weight);
  if (white.empty() || !normalized.rect().contains(white))
    fail("white region {} lies outside the {}x{} image", toString(white), normalized.width(),
         normalized.height());
  Image estimate = normalized;
  if (weight == 0.0) return estimate;
  for (int iteration = 0; iteration < iterations; ++iteration) {
    const Image spread = gaussianBlur(estimate, sigmaPx(pitch_mm));
    const double open = mix(1.0, meanOf(spread, white));
    const auto n = normalized.pixels();
    const auto g = spread.pixels();
    auto out = estimate.pixels();
    for (size_t i = 0; i < out.size(); ++i)
      out[i] = static_cast<float>(
          unmix(static_cast<double>(n[i]), static_cast<double>(g[i]), open));
  }
  return estimate;
}

}  // namespace xgauge
