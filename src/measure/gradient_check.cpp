#include "xgauge/measure/gradient_check.h"

#include "xgauge/core/error.h"

#include <algorithm>
#include <cmath>

namespace xgauge {

namespace {

// Restores the model's edge refinement however the check ends.
class EdgeSamplesOff {
 public:
  explicit EdgeSamplesOff(ForwardModel& model) : model_(model), saved_(model.edgeSamples()) {
    model_.setEdgeSamples(0);
  }
  ~EdgeSamplesOff() { model_.setEdgeSamples(saved_); }
  EdgeSamplesOff(const EdgeSamplesOff&) = delete;
  EdgeSamplesOff& operator=(const EdgeSamplesOff&) = delete;

 private:
  ForwardModel& model_;
  int saved_;
};

}  // namespace

GradientCheck checkModelGradients(ForwardModel& model, std::span<const double> theta,
                                  std::span<const int> indices, std::span<const int> radiographs,
                                  const ModelGradientOptions& options) {
  XG_CHECK(theta.size() == static_cast<size_t>(model.size()), "{} values for {} parameters",
           theta.size(), model.size());
  XG_CHECK(options.steps.empty() || options.steps.size() == indices.size(),
           "{} steps for {} parameters", options.steps.size(), indices.size());
  for (int i : indices)
    XG_CHECK(i >= 0 && i < model.size(), "parameter index {} outside 0..{}", i, model.size() - 1);
  EdgeSamplesOff refinement(model);

  std::vector<double> r, jacobian;
  if (!model.residualsAndJacobian(theta, indices, options.level, options.samples, radiographs, r,
                                  jacobian))
    fail("cannot check gradients: {}",
         model.infeasibility(theta).value_or("the parameters cannot be simulated"));

  auto difference = [&](size_t i, double h, std::vector<double>& out) {
    std::vector<double> at(theta.begin(), theta.end()), plus, minus;
    at[i] = theta[i] + h;
    const bool up = model.residuals(at, options.level, options.samples, radiographs, plus);
    at[i] = theta[i] - h;
    const bool down = model.residuals(at, options.level, options.samples, radiographs, minus);
    if (!up || !down || plus.size() != r.size() || minus.size() != r.size())
      fail("cannot check gradients: {} at {} +- {} cannot be simulated",
           model.parameters()[static_cast<int>(i)].name, theta[i], h);
    out.resize(r.size());
    for (size_t m = 0; m < r.size(); ++m) out[m] = (plus[m] - minus[m]) / (2.0 * h);
  };

  GradientCheck check;
  const size_t n = indices.size();
  for (size_t k = 0; k < n; ++k) {
    const auto i = static_cast<size_t>(indices[k]);
    const double h = options.steps.empty() ? ModelGradientOptions::kDefaultStep : options.steps[k];
    std::vector<double> coarse, fine;
    difference(i, h, coarse);
    difference(i, 0.5 * h, fine);
    check.columns.push_back(compareWithDifferences(
        model.parameters()[static_cast<int>(i)].name, coarse, fine,
        [&jacobian, n, k](size_t m) { return jacobian[m * n + k]; }, options.agreement));
  }
  return check;
}

}  // namespace xgauge
