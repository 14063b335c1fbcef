// The budget's component for the material curve beyond its calibrated range
// (docs/method.md, "The curve beyond its calibrated range"): the pixels
// whose path through the fitted part is longer than the calibration saw
// move by the curve's extrapolation envelope e(path), and the linearised
// fit says how far the dimensions follow.
#include "budget.h"
#include "budget_internal.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace xgauge {

void addExtrapolationTerm(ForwardModel& model, std::span<const double> theta,
                          const LinearizedFit& fit, const SelfCheck& check,
                          UncertaintyBudget& budget) {
  XG_CHECK(check.radiographs.size() == fit.segments.size(),
           "one radiograph check per segment of the fit");
  const ExponentialSum material = model.materialOf(theta);
  if (material.extrapolation().empty()) return;
  const double from = material.extrapolation().front().path_mm;
  const ScatterModel& scatter = model.job().scatter;
  // The change of each residual when the curve moves by e(path): a pixel's
  // simulated value is (1 - w) I + w G(I), over the open beam's level, each
  // residual scaled by 1 / sqrt(its radiograph's pixels).
  Eigen::VectorXd dr = Eigen::VectorXd::Zero(fit.residuals.size());
  int64_t beyond = 0;
  double longest = 0.0, largest = 0.0;
  for (size_t k = 0; k < fit.segments.size(); ++k) {
    // The self-checks found each radiograph's longest path at this level
    // and roi: paths are rendered again only where some go beyond.
    if (!(check.radiographs[k].longest_path_mm > from)) continue;
    const ResidualSegment& segment = fit.segments[k];
    const PixelRect& roi = segment.roi;
    const Image paths = model.pathLengths(theta, segment.radiograph, fit.level, roi);
    std::optional<ScatterEstimate> spread;
    if (scatter.enabled()) spread = model.scatter(theta, segment.radiograph, fit.level);
    const double scale = 1.0 / std::sqrt(static_cast<double>(roi.area()));
    for (int y = 0; y < roi.height; ++y)
      for (int x = 0; x < roi.width; ++x) {
        const auto path = static_cast<double>(paths(x, y));
        const double e = material.extrapolationHalfWidth(path);
        if (!(e > 0.0)) continue;
        ++beyond;
        longest = std::max(longest, path), largest = std::max(largest, e);
        double change = e;
        if (spread) {
          const ScatterEstimate::Tap tap = spread->tap(roi.x + x + 0.5, roi.y + y + 0.5);
          change = (1.0 - scatter.weight) * e / spread->openAt(tap);
        }
        dr(static_cast<Eigen::Index>(segment.first) + static_cast<Eigen::Index>(y) * roi.width +
           x) = scale * change;
      }
  }
  if (beyond == 0) return;
  const Eigen::VectorXd shift = budget_internal::linearShift(fit, fit.weights(), dr);
  const std::string quantity = fmt::format(
      "the curve beyond its calibrated {:.2f} mm: {} pixels with paths up to {:.2f} mm, where it "
      "may be off by up to {:.2g} (rectangular)",
      from, beyond, longest, largest);
  // The envelope bounds the curve; nothing in the table prefers one
  // admitted curve to another: a rectangular distribution over +-e.
  budget_internal::addShiftComponent(
      model, fit, shift, 1.0 / std::sqrt(3.0), "material: curve beyond its calibrated range",
      quantity, budget_internal::ShiftSource{largest / std::sqrt(3.0), "transmission"}, budget);
  budget.notes.push_back(fmt::format(
      "the material curve beyond its calibrated range: {}; each dimension's shift with the curve "
      "moved by its envelope there, over sqrt(3), is a component of its U",
      quantity));
}

}  // namespace xgauge
