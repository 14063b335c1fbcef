#include "xgauge/material/transmission_table.h"

#include "xgauge/core/error.h"
#include "xgauge/material/exponential_sum.h"

namespace xgauge {

TransmissionTable::TransmissionTable(const std::function<double(double)>& value,
                                     const std::function<double(double)>& derivative,
                                     double max_path_mm, double step_mm) {
  XG_CHECK(max_path_mm > 0 && step_mm > 0, "bad table range {} / step {}", max_path_mm, step_mm);
  intervals_ = std::max<size_t>(1, static_cast<size_t>(std::ceil(max_path_mm / step_mm)));
  step_mm_ = max_path_mm / static_cast<double>(intervals_);
  inv_step_ = 1.0 / step_mm_;
  max_path_mm_ = max_path_mm;
  nodes_.resize(intervals_ + 1);
  for (size_t i = 0; i <= intervals_; ++i) {
    const double x = static_cast<double>(i) * step_mm_;
    nodes_[i] = {value(x), derivative(x) * step_mm_};
  }
}

TransmissionTable TransmissionTable::forMaterial(const ExponentialSum& material,
                                                 double max_path_mm) {
  double mu_max = 0.0;
  for (const auto& t : material.terms()) mu_max = std::max(mu_max, t.mu_per_mm);
  // h^4 mu^4 / 384 <= 1e-10  ->  h <= (3.84e-8)^(1/4) / mu ~= 0.014 / mu.
  const double step = mu_max > 0 ? std::min(0.01, 0.014 / mu_max) : 0.01;
  return TransmissionTable([&](double x) { return material.transmission(x); },
                           [&](double x) { return material.derivative(x); }, max_path_mm, step);
}

}  // namespace xgauge
