// A transmission curve I(x) tabulated on a uniform grid of path lengths and
// evaluated by cubic Hermite interpolation (values and exact derivatives at
// the nodes), so the renderer pays a table look-up instead of M exponentials
// per sample. The interpolant is C1 and, for a decreasing curve sampled finely
// enough, decreasing. Interpolation error for a curve with bounded fourth
// derivative: |I''''|max h^4 / 384.
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

namespace xgauge {

class ExponentialSum;

class TransmissionTable {
 public:
  TransmissionTable() = default;
  // Tabulates value(x) and derivative(x) (dI/dx) on [0, max_path_mm] with node
  // spacing step_mm. Paths outside the range are clamped to it.
  TransmissionTable(const std::function<double(double)>& value,
                    const std::function<double(double)>& derivative, double max_path_mm,
                    double step_mm);
  // Node spacing chosen from the largest mu so that the interpolation error
  // stays below 1e-10 (and at most 0.01 mm).
  static TransmissionTable forMaterial(const ExponentialSum& material, double max_path_mm);

  double maxPathMm() const { return max_path_mm_; }
  double stepMm() const { return step_mm_; }

  // dI/dx of the interpolant (0 beyond the table, where I is held constant).
  double slope(double path_mm) const {
    if (!(path_mm >= 0.0 && path_mm <= max_path_mm_)) return 0.0;
    const double u = path_mm * inv_step_;
    const size_t i = std::min(static_cast<size_t>(u), intervals_ - 1);
    const double t = u - static_cast<double>(i);
    const double t2 = t * t;
    const Node& a = nodes_[i];
    const Node& b = nodes_[i + 1];
    return ((6 * t2 - 6 * t) * (a.value - b.value) + (3 * t2 - 4 * t + 1) * a.slope +
            (3 * t2 - 2 * t) * b.slope) *
           inv_step_;
  }

  // I(x); path in mm.
  double operator()(double path_mm) const {
    const double u = std::clamp(path_mm, 0.0, max_path_mm_) * inv_step_;
    const size_t i = std::min(static_cast<size_t>(u), intervals_ - 1);
    const double t = u - static_cast<double>(i);
    const double t2 = t * t, t3 = t2 * t;
    const Node& a = nodes_[i];
    const Node& b = nodes_[i + 1];
    return (2 * t3 - 3 * t2 + 1) * a.value + (t3 - 2 * t2 + t) * a.slope +
           (-2 * t3 + 3 * t2) * b.value + (t3 - t2) * b.slope;
  }

 private:
  struct Node {
    double value;
    double slope;  // dI/dx times the step
  };
  std::vector<Node> nodes_;
  size_t intervals_ = 0;
  double max_path_mm_ = 0.0;
  double step_mm_ = 0.0;
  double inv_step_ = 0.0;
};

}  // namespace xgauge
