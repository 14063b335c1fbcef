#include "least_squares.h"

#include "xgauge/core/error.h"
#include "xgauge/core/progress.h"

#include <ceres/ceres.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>

namespace xgauge {

namespace {

constexpr double kStep = 2e-3;  // mm or deg: forward differences (least_squares.h)

// A material parameter's difference step: kStep, or a quarter of its range
// where that is narrower (a refinement's rate scale under a tight prior).
double materialStep(const ForwardModel& model, int index) {
  const auto i = static_cast<size_t>(index);
  return std::min(kStep, 0.25 * (model.upper()[i] - model.lower()[i]));
}

// The linearisation's steps move the part's projected edges by about this
// many pixels of the level (least_squares.h).
constexpr double kLinearStepPx = 0.2;

// Each parameter's step for the linearisation at theta, from the size of a
// pixel of `level` at the part (mm): a dimension or a lateral position moves
// an edge by it, a depth changes the magnification of the part's outline by
// it, an angle turns the outline's ends by it.
std::vector<double> linearSteps(const ForwardModel& model, std::span<const double> theta,
                                const std::vector<int>& indices, int level) {
  const Machine machine = model.machineAt(level);
  const double d = machine.source_detector_distance_mm;
  const double z = model.pose(theta, 0).apply(model.referenceCentre()).z();
  const double magnification = d / std::max(1e-6, d - z);
  const double edge_mm = kLinearStepPx * machine.pitch_u_mm / magnification;
  const double reach_mm = std::max(1.0, 0.5 * model.partSizeMm());
  std::vector<double> steps;
  for (int i : indices) {
    const std::string& name = model.parameters()[i].name;
    switch (model.kind(i)) {
      case ParameterKind::kDimension:
        steps.push_back(edge_mm);  // mm; a dimension in degrees turns by as much as a rotation
        if (model.part().dimensions()[static_cast<size_t>(i)].unit == "deg")
          steps.back() = edge_mm / reach_mm * kRadToDeg;
        break;
      case ParameterKind::kPosition:
        steps.push_back(name.ends_with("/z") ? edge_mm * (d - z) / reach_mm : edge_mm);
        break;
      case ParameterKind::kRotation:
        steps.push_back(edge_mm / reach_mm * kRadToDeg);
        break;
      case ParameterKind::kAxis: {
        double distance = 10.0;
        for (int r = 0; r < model.radiographCount(); ++r)
          if (name.starts_with(model.spec(r).name + "/"))
            distance = std::max(1.0, model.spec(r).distance_mm);
        steps.push_back(edge_mm / distance * kRadToDeg);
        break;
      }
      case ParameterKind::kMaterial:
        steps.push_back(materialStep(model, i));
        break;
      case ParameterKind::kDetector:  // turns the panel's edge by about an edge's step
        steps.push_back(machine.pitch_u_mm * kLinearStepPx /
                        (0.5 * machine.columns * machine.pitch_u_mm) * kRadToDeg);
        break;
    }
  }
  return steps;
}
// The smallest noise sigma (normalized intensity) the robust loss assumes: a
// tenth of what the quietest flat panels show per pixel.
constexpr double kNoiseFloor = 1e-4;

// Huber's loss as a residual: sign(r) sqrt(rho(r^2)) and its derivative.
double robustResidual(double r, double a, double* derivative) {
  const double m = std::abs(r);
  if (m <= a) {
    *derivative = 1.0;
    return r;
  }
  const double root = std::sqrt(2.0 * a * m - a * a);  // >= a > 0
  *derivative = a / root;
  return std::copysign(root, r);
}

double huberLoss(const std::vector<double>& r, const std::vector<ResidualSegment>& segments) {
  double sum = 0.0;
  for (size_t s = 0; s < segments.size(); ++s) {
    const size_t end = s + 1 < segments.size() ? segments[s + 1].first : r.size();
    const double a = segments[s].threshold;
    for (size_t i = segments[s].first; i < end; ++i) {
      const double m = std::abs(r[i]);
      sum += m <= a ? m * m : 2.0 * a * m - a * a;
    }
  }
  return sum;
}

// A stage on the render's derivatives takes them (a render with derivatives
// costs 6 to 8 plain ones) at its start, again where the fit has moved
// farther than kReuseFarSteps linearisation steps (0.4 px of the level) from
// where they were taken, and once more at the first step shorter than
// kReuseSmallSteps; in between, Levenberg-Marquardt steps with the last
// derivatives and the transform's slopes at the new point (a chord method).
// The steps then converge at the same linear rate as with derivatives at
// every point (which miss the strips of walls seen along the beam, so are
// not exact either), and the refresh at the end puts the stage's fixed point
// where the loss's gradient vanishes with the derivatives there. On a
// 4096^2 Prism A pair's final stage: 6 renders with derivatives and 7 plain
// ones became 2 and 8, the loss the same to 6e-4 of it and every dimension
// to 3e-5 mm; the 21-pair study's errors the same to 0.0001 mm.
constexpr double kReuseFarSteps = 2.0;
constexpr double kReuseSmallSteps = 0.05;

// The radiographs' residuals as one Ceres residual block: every evaluation
// renders every radiograph once, so the pixels cannot be separate blocks.
// Ceres asks for the Jacobian only at points it has accepted.
//
// Ceres sees the block compressed to n + 1 residuals (n parameters): with
// r the (transformed) residuals and J their Jacobian at a point, A = J^T J =
// V L V^T and g = J^T r, it gets R = L^(1/2) V^T as the Jacobian and r' =
// L^(-1/2) V^T g, then sqrt(|r|^2 - |r'|^2) with a zero row, as the
// residuals. R^T R = A, R^T r' = g and the squared sum is |r|^2, so its
// Levenberg-Marquardt steps, costs, gradients and Jacobi scaling are those of
// the full block, to rounding. A cost-only evaluation returns zeros and
// |r|. Ceres works single-threaded on the Jacobian it is given: at a million
// residuals it copied, checked, scaled and multiplied 16 columns of them, a
// tenth of a 4096^2 measurement, where A and g take one parallel pass here.
class ImageResiduals final : public ceres::CostFunction {
 public:
  ImageResiduals(ForwardModel& model, std::vector<double> theta, std::vector<int> indices,
                 std::vector<double> scales, std::vector<int> radiographs,
                 std::vector<ResidualSegment> segments, int level, int samples, size_t count,
                 JacobianKind jacobian, ProgressBar* progress)
      : model_(model),
        theta_(std::move(theta)),
        indices_(std::move(indices)),
        scales_(std::move(scales)),
        radiographs_(std::move(radiographs)),
        segments_(std::move(segments)),
        level_(level),
        samples_(samples),
        count_(count),
        jacobian_(jacobian),
        progress_(progress) {
    set_num_residuals(static_cast<int>(indices_.size()) + 1);
    mutable_parameter_block_sizes()->push_back(static_cast<int>(indices_.size()));
  }

  int evaluations() const { return evaluations_; }
  int withDerivatives() const { return with_derivatives_; }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const size_t n = indices_.size();
    std::vector<double> at = theta_;
    for (size_t k = 0; k < n; ++k)
      at[static_cast<size_t>(indices_[k])] = parameters[0][k] * scales_[k];
    const bool want_jacobian = jacobians != nullptr && jacobians[0] != nullptr;
    if (want_jacobian && jacobian_ == JacobianKind::kRenderDerivatives && reuseAt(parameters[0])) {
      if (!renderAt(parameters[0], at)) return false;
      compress(residuals, jacobians[0]);
      return true;
    }
    if (want_jacobian && jacobian_ == JacobianKind::kRenderDerivatives) {
      // The render with derivatives (xray/derivatives.h): one pass gives the
      // residuals and every column.
      anchor_.assign(parameters[0], parameters[0] + n);
      previous_ = anchor_;
      last_.clear();  // r_ and its transform are this point's from here
      count();
      ++with_derivatives_;
      if (!model_.residualsAndJacobian(at, indices_, level_, samples_, radiographs_, r_, j_) ||
          r_.size() != count_)
        return false;
      transform();
      last_.assign(parameters[0], parameters[0] + n);
      compress(residuals, jacobians[0]);
      return true;
    }
    // The same point as the last render of r_: Ceres' projected line search
    // (with bounds) evaluates the full step, the trust region then evaluates
    // the same candidate again and, when it accepts it, asks for the
    // Jacobian there. Everything else an evaluation reads is fixed for this
    // cost function, so r_ and its transform stand.
    if (!renderAt(parameters[0], at)) return false;
    if (!want_jacobian) {
      std::fill(residuals, residuals + n, 0.0);
      residuals[n] = std::sqrt(squared_sum_);
      return true;
    }
    // Forward differences of the raw residuals into j_.
    j_.resize(r_.size() * n);
    std::vector<double> shifted_r;
    for (size_t k = 0; k < n; ++k) {
      const auto i = static_cast<size_t>(indices_[k]);
      std::vector<double> shifted = at;
      const double h = model_.kind(indices_[k]) == ParameterKind::kMaterial
                           ? materialStep(model_, indices_[k])
                           : kStep;
      shifted[i] = at[i] + h <= model_.upper()[i] ? at[i] + h : at[i] - h;
      const double step = shifted[i] - at[i];
      if (!render(shifted, shifted_r)) return false;
      for (size_t m = 0; m < r_.size(); ++m) j_[m * n + k] = (shifted_r[m] - r_[m]) / step;
    }
    compress(residuals, jacobians[0]);
    return true;
  }

 private:
  static double distance(const std::vector<double>& a, const double* x) {
    double d = 0.0;
    for (size_t k = 0; k < a.size(); ++k) d += (x[k] - a[k]) * (x[k] - a[k]);
    return std::sqrt(d);
  }
  // Whether the Jacobian asked for at x (an accepted point) is the last
  // render's with derivatives, j_, with the transform's slopes at x
  // (kReuseFarSteps). Called once per accepted point.
  bool reuseAt(const double* x) const {
    if (anchor_.empty()) return false;
    const double step = distance(previous_, x);
    previous_.assign(x, x + anchor_.size());
    if (distance(anchor_, x) > kReuseFarSteps) return false;
    if (step < kReuseSmallSteps && !refreshed_) {
      refreshed_ = true;
      return false;
    }
    return true;
  }
  void count() const {
    ++evaluations_;
    if (progress_) progress_->advance();
  }
  // r_ and its transform at x (theta: the model's parameters there),
  // rendered unless they are that point's already; false where it cannot be
  // simulated.
  bool renderAt(const double* x, const std::vector<double>& theta) const {
    const size_t n = indices_.size();
    if (last_.size() == n && std::equal(last_.begin(), last_.end(), x)) return true;
    last_.clear();
    if (!render(theta, r_)) return false;
    transform();
    last_.assign(x, x + n);
    return true;
  }
  bool render(const std::vector<double>& theta, std::vector<double>& out) const {
    count();
    return model_.residuals(theta, level_, samples_, radiographs_, out) && out.size() == count_;
  }
  // t_ and slope_: Huber's transform of r_ per segment and its slope; and
  // their squared sum.
  void transform() const {
    t_.resize(r_.size());
    slope_.resize(r_.size());
    for (size_t s = 0; s < segments_.size(); ++s) {
      const size_t end = s + 1 < segments_.size() ? segments_[s + 1].first : r_.size();
      for (size_t i = segments_[s].first; i < end; ++i)
        t_[i] = robustResidual(r_[i], segments_[s].threshold, &slope_[i]);
    }
    squared_sum_ = 0.0;
    for (double v : t_) squared_sum_ += v * v;
  }
  // The compressed residuals and Jacobian (row-major, (n + 1) x n) of the
  // transformed residuals t_ with the Jacobian slope_ * j_ * scales_ (the
  // derivative of the transform: its slope at r times the raw residual's).
  // A and g are summed over fixed blocks of rows in order: the same at any
  // thread count.
  void compress(double* residuals, double* jacobian) const {
    const auto n = static_cast<Eigen::Index>(indices_.size());
    constexpr size_t kBlock = 8192;
    const size_t blocks = (r_.size() + kBlock - 1) / kBlock;
    std::vector<Eigen::MatrixXd> partial_a(blocks);
    std::vector<Eigen::VectorXd> partial_g(blocks);
    const Eigen::Map<const Eigen::VectorXd> scale(scales_.data(), n);
    tbb::parallel_for(size_t{0}, blocks, [&](size_t b) {
      const size_t first = b * kBlock, rows = std::min(kBlock, r_.size() - first);
      using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
      const Eigen::Map<const RowMajor> raw(j_.data() + first * static_cast<size_t>(n),
                                           static_cast<Eigen::Index>(rows), n);
      const auto m = static_cast<Eigen::Index>(rows);
      const RowMajor block = Eigen::Map<const Eigen::VectorXd>(slope_.data() + first, m)
                                 .asDiagonal() *
                             raw * scale.asDiagonal();
      partial_a[b].noalias() = block.transpose() * block;
      partial_g[b].noalias() =
          block.transpose() * Eigen::Map<const Eigen::VectorXd>(t_.data() + first, m);
    });
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd g = Eigen::VectorXd::Zero(n);
    for (size_t b = 0; b < blocks; ++b) a += partial_a[b], g += partial_g[b];
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(a);
    const Eigen::VectorXd lambda = eigen.eigenvalues().cwiseMax(0.0);
    // Directions with no curvature (a parameter that moves nothing) have no
    // gradient either; their share of r' is left at zero.
    const double floor = 1e-14 * std::max(lambda.maxCoeff(), 0.0);
    const Eigen::VectorXd projected = eigen.eigenvectors().transpose() * g;
    double compressed = 0.0;
    for (Eigen::Index k = 0; k < n; ++k) {
      residuals[k] = lambda(k) > floor ? projected(k) / std::sqrt(lambda(k)) : 0.0;
      compressed += residuals[k] * residuals[k];
      for (Eigen::Index l = 0; l < n; ++l)
        jacobian[k * n + l] = std::sqrt(lambda(k)) * eigen.eigenvectors()(l, k);
    }
    residuals[n] = std::sqrt(std::max(0.0, squared_sum_ - compressed));
    std::fill(jacobian + n * n, jacobian + n * n + n, 0.0);
  }

  ForwardModel& model_;
  std::vector<double> theta_;
  std::vector<int> indices_;
  std::vector<double> scales_;  // theta[indices_[k]] = x[k] * scales_[k]
  std::vector<int> radiographs_;
  std::vector<ResidualSegment> segments_;
  int level_, samples_;
  size_t count_;  // residuals per render
  JacobianKind jacobian_;
  ProgressBar* progress_;  // null: quiet
  // The raw residuals r_ at the point last_ (empty: none), their transform
  // t_ with its slope and squared sum, and the raw Jacobian j_ (row-major,
  // residuals x parameters) where one was asked for.
  mutable std::vector<double> r_, t_, slope_, j_, last_;
  mutable double squared_sum_ = 0.0;
  // Where j_ was rendered, the last point a Jacobian was asked for, and
  // whether the refresh at a short step is done (reuseAt).
  mutable std::vector<double> anchor_, previous_;
  mutable bool refreshed_ = false;
  mutable int evaluations_ = 0, with_derivatives_ = 0;
};

// The rate scale's prior (RateScalePrior) as a residual block of its own
// over the same parameters.
class PriorResidual final : public ceres::CostFunction {
 public:
  PriorResidual(RateScalePrior prior, double scale, int parameters)
      : prior_(prior), scale_(scale), n_(parameters) {
    set_num_residuals(1);
    mutable_parameter_block_sizes()->push_back(parameters);
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    residuals[0] = prior_.lambda * scale_ * parameters[0][prior_.column];
    if (jacobians != nullptr && jacobians[0] != nullptr)
      for (int k = 0; k < n_; ++k)
        jacobians[0][k] = k == prior_.column ? prior_.lambda * scale_ : 0.0;
    return true;
  }

 private:
  RateScalePrior prior_;
  double scale_;  // of the solver's variable (solveLeastSquares)
  int n_;
};

// Logs each iteration of a stage (at debug level), and ends the stage at a
// rejected step shorter than kRejectedSettled times its settled steps: the
// loss rose over a step that small because the float image cannot resolve
// it, not because the model bends there. Levenberg-Marquardt would shrink
// its trust region from a radius far larger than the step, so the next few
// steps come out nearly the same and are rejected too, a render each
// (measured: five in a row at the end of a 4096^2 pair's final stage).
// Ceres keeps the last accepted point.
constexpr double kRejectedSettled = 5.0;
class IterationLog final : public ceres::IterationCallback {
 public:
  explicit IterationLog(double settled_steps) : settled_steps_(settled_steps) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    spdlog::debug("  iteration {}: loss {:.9g}, step {:.3g} linearisation steps, {}", s.iteration,
                  2.0 * s.cost, s.step_norm, s.step_is_successful ? "taken" : "rejected");
    if (s.iteration > 0 && !s.step_is_successful && s.step_norm < kRejectedSettled * settled_steps_)
      return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    return ceres::SOLVER_CONTINUE;
  }

 private:
  double settled_steps_;
};

}  // namespace

Eigen::VectorXd LinearizedFit::weights() const {
  Eigen::VectorXd w = Eigen::VectorXd::Ones(residuals.size());
  for (size_t s = 0; s < segments.size(); ++s) {
    const auto end = static_cast<Eigen::Index>(s + 1 < segments.size() ? segments[s + 1].first
                                                                       : residuals.size());
    const double a = segments[s].threshold;
    for (auto i = static_cast<Eigen::Index>(segments[s].first); i < end; ++i)
      if (std::abs(residuals(i)) > a) w(i) = a / std::abs(residuals(i));
  }
  return w;
}

std::vector<ResidualSegment> residualSegments(const ForwardModel& model,
                                              std::span<const int> radiographs, int level,
                                              std::span<const double> residuals, bool robust) {
  std::vector<ResidualSegment> segments;
  size_t first = 0;
  for (int r : radiographs) {
    const PixelRect roi = model.radiograph(r).rois[static_cast<size_t>(level)];
    segments.push_back({r, roi, first, std::numeric_limits<double>::infinity()});
    first += static_cast<size_t>(roi.area());
  }
  if ((!robust && model.rateScaleIndex() < 0) || residuals.size() != first) return segments;
  for (size_t s = 0; s < segments.size(); ++s) {
    ResidualSegment& segment = segments[s];
    const size_t end = s + 1 < segments.size() ? segments[s + 1].first : residuals.size();
    if (end <= segment.first) continue;
    std::vector<double> r(residuals.begin() + static_cast<ptrdiff_t>(segment.first),
                          residuals.begin() + static_cast<ptrdiff_t>(end));
    for (double& v : r) v = std::abs(v);
    std::nth_element(r.begin(), r.begin() + static_cast<ptrdiff_t>(r.size() / 2), r.end());
    // The residuals are scaled by 1 / sqrt(pixels) (ForwardModel::residuals).
    // A perfect fit (a noise-free simulation) has a zero median: the scale
    // never drops below kNoiseFloor, so that such a fit is least squares
    // rather than a degenerate L1 that weighs every pixel by 1 / |r|.
    const double unscale = std::sqrt(static_cast<double>(segment.roi.area()));
    const double sigma = std::max(1.4826 * r[r.size() / 2] * unscale, kNoiseFloor);
    segment.scale = sigma / unscale;
    if (robust) segment.threshold = 1.345 * segment.scale;
  }
  return segments;
}

std::optional<RateScalePrior> rateScalePrior(const ForwardModel& model,
                                             const std::vector<int>& indices,
                                             const std::vector<ResidualSegment>& segments) {
  const auto it = std::find(indices.begin(), indices.end(), model.rateScaleIndex());
  if (model.rateScaleIndex() < 0 || it == indices.end()) return std::nullopt;
  double sum = 0.0;
  for (const ResidualSegment& segment : segments) {
    // A radiograph whose residuals could not be taken: the noise floor.
    const double scale = segment.scale > 0.0
                             ? segment.scale
                             : kNoiseFloor / std::sqrt(static_cast<double>(segment.roi.area()));
    sum += scale * scale;
  }
  const double tau = std::sqrt(sum / static_cast<double>(std::max<size_t>(1, segments.size())));
  return RateScalePrior{static_cast<int>(it - indices.begin()), tau / model.rateScalePrior()};
}

bool linearize(ForwardModel& model, std::span<const double> theta, const std::vector<int>& indices,
               std::span<const int> radiographs, int level, int samples, bool robust,
               LinearizedFit& out) {
  std::vector<double> r;
  if (!model.residuals(theta, level, samples, radiographs, r)) return false;
  out.indices = indices;
  out.segments = residualSegments(model, radiographs, level, r, robust);
  out.prior = rateScalePrior(model, indices, out.segments);
  out.level = level, out.samples = samples;
  const auto m = static_cast<Eigen::Index>(r.size());
  out.residuals = Eigen::Map<const Eigen::VectorXd>(r.data(), m);
  out.jacobian.setZero(m, static_cast<Eigen::Index>(indices.size()));
  // The segments (positions in `radiographs`) each column changes: a
  // parameter that moves no vertex of a radiograph's part (another
  // radiograph's pose) leaves its image as it is, to the bit. The material
  // changes every one.
  std::vector<std::vector<size_t>> seen(indices.size());
  for (size_t s = 0; s < radiographs.size(); ++s) {
    std::vector<int> moving;
    std::vector<Vec3> velocities;
    const bool known = model.poseVelocities(theta, indices, radiographs[s], moving, velocities);
    for (size_t k = 0; k < indices.size(); ++k)
      if (!known || model.kind(indices[k]) == ParameterKind::kMaterial ||
          model.kind(indices[k]) == ParameterKind::kDetector ||
          std::find(moving.begin(), moving.end(), static_cast<int>(k)) != moving.end())
        seen[k].push_back(s);
  }
  std::vector<double> shifted(theta.begin(), theta.end()), up_r, down_r;
  const std::vector<double> steps = linearSteps(model, theta, indices, level);
  out.steps = steps;
  for (size_t k = 0; k < indices.size(); ++k) {
    if (seen[k].empty()) continue;
    std::vector<int> changed;
    for (size_t s : seen[k]) changed.push_back(radiographs[s]);
    const auto i = static_cast<size_t>(indices[k]);
    const double h = steps[k];
    const bool up = theta[i] + h <= model.upper()[i];
    const bool down = theta[i] - h >= model.lower()[i];
    const double span = (up ? h : 0.0) + (down ? h : 0.0);
    if (!(span > 0.0)) return false;
    shifted[i] = theta[i] + (up ? h : 0.0);
    bool ok = model.residuals(shifted, level, samples, changed, up_r);
    shifted[i] = theta[i] - (down ? h : 0.0);
    ok = ok && model.residuals(shifted, level, samples, changed, down_r) &&
         down_r.size() == up_r.size();
    shifted[i] = theta[i];
    if (!ok) return false;
    // Each changed segment's rows, in the order model.residuals returns them.
    size_t from = 0;
    for (size_t s : seen[k]) {
      const ResidualSegment& segment = out.segments[s];
      const auto rows = static_cast<size_t>(segment.roi.area());
      if (from + rows > up_r.size()) return false;
      for (size_t j = 0; j < rows; ++j)
        out.jacobian(static_cast<Eigen::Index>(segment.first + j), static_cast<Eigen::Index>(k)) =
            (up_r[from + j] - down_r[from + j]) / span;
      from += rows;
    }
    if (from != up_r.size()) return false;
  }
  return true;
}

StageReport solveLeastSquares(ForwardModel& model, std::vector<double>& theta,
                              const std::vector<int>& indices, const std::vector<int>& radiographs,
                              int level, int samples, int max_iterations, bool robust,
                              JacobianKind jacobian, bool quiet, std::string_view label,
                              std::optional<double> prior_lambda, double settled_steps) {
  const auto start = std::chrono::steady_clock::now();
  StageReport report;
  report.name = fmt::format("{}, {}", label, robust ? "robust least squares" : "least squares");
  report.method = "ceres_levenberg_marquardt";
  report.level = level;
  report.samples = samples;
  std::vector<double> r;
  if (!model.residuals(theta, level, samples, radiographs, r)) {
    report.termination = "start point invalid";
    return report;
  }
  const std::vector<ResidualSegment> segments =
      residualSegments(model, radiographs, level, r, robust);
  std::optional<RateScalePrior> prior = rateScalePrior(model, indices, segments);
  if (prior && prior_lambda) prior->lambda = *prior_lambda;
  report.evaluations = 1;

  // The solver's variables are the parameters in units of their
  // linearisation steps (a step moves the outline by about 0.2 pixels of the
  // level), so that a step's norm says how far the outline moved, whatever
  // mixes of mm and degrees the stage frees (Levenberg-Marquardt with Jacobi
  // scaling takes the same steps in either units).
  const size_t n = indices.size();
  std::vector<double> scales = linearSteps(model, theta, indices, level);
  for (double& scale : scales)
    if (!(scale > 0.0 && std::isfinite(scale))) scale = 1.0;  // a parameter without range
  std::vector<double> x(n);
  for (size_t k = 0; k < n; ++k) {
    const auto i = static_cast<size_t>(indices[k]);
    x[k] = std::clamp(theta[i], model.lower()[i], model.upper()[i]) / scales[k];
  }
  const auto prior_column = prior ? static_cast<size_t>(prior->column) : 0;
  const double prior_loss =
      prior ? std::pow(prior->lambda * x[prior_column] * scales[prior_column], 2) : 0.0;
  report.loss_before = huberLoss(r, segments) + prior_loss;
  std::optional<ProgressBar> progress;
  if (!quiet)
    progress.emplace(report.name, jacobian == JacobianKind::kRenderDerivatives
                                      ? 2 * max_iterations + 1
                                      : max_iterations * static_cast<int>(n + 2));
  ImageResiduals cost(model, theta, indices, scales, radiographs, segments, level, samples,
                      r.size(), jacobian, progress ? &*progress : nullptr);
  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  problem.AddResidualBlock(&cost, nullptr, x.data());
  std::optional<PriorResidual> prior_cost;
  if (prior) {
    prior_cost.emplace(*prior, scales[prior_column], static_cast<int>(n));
    problem.AddResidualBlock(&*prior_cost, nullptr, x.data());
  }
  for (size_t k = 0; k < n; ++k) {
    const auto i = static_cast<size_t>(indices[k]);
    problem.SetParameterLowerBound(x.data(), static_cast<int>(k), model.lower()[i] / scales[k]);
    problem.SetParameterUpperBound(x.data(), static_cast<int>(k), model.upper()[i] / scales[k]);
  }
  ceres::Solver::Options options;
  options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  // Millions of residuals and a few dozen parameters: the normal equations
  // are small and dense.
  options.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  // With bounds, Ceres runs a projected Armijo line search along every
  // step; its default cubic interpolation asks for the gradient (here a
  // forward-difference Jacobian, 1 + n renders) at the full step, which
  // nearly doubled the renders per iteration. Bisection needs the cost
  // alone, and at a Gauss-Newton step that already decreases it enough
  // there is nothing to interpolate.
  options.line_search_interpolation_type = ceres::BISECTION;
  // The search only has to keep the step inside the bounds (Ceres projects
  // it there): whether the step is taken is the trust region's to decide.
  // Searching further cost a render per halving, and near the solution,
  // where the step is smaller than what the float image resolves, it
  // halved twenty times before giving up.
  options.max_num_line_search_step_size_iterations = 1;
  options.max_num_iterations = max_iterations;
  // Converged when a step would move the parameters, together, by less than
  // settled_steps of their linearisation steps (the variables' units; see
  // kSettledSteps). Ceres' tolerance is relative to the variables' norm,
  // which the start gives closely enough; it is checked before a step is
  // taken, so the last, negligible step costs one render and no render with
  // derivatives. Or when a step lowers the loss by less than 1 / (100 N) of
  // it, N residuals: for independent pixels, what a tenth of a standard
  // deviation in the parameters is worth.
  const double norm =
      Eigen::Map<const Eigen::VectorXd>(x.data(), static_cast<Eigen::Index>(n)).norm();
  options.parameter_tolerance = settled_steps / std::max(1.0, norm);
  options.function_tolerance = std::min(1e-6, 0.01 / static_cast<double>(r.size()));
  options.num_threads = 1;  // one residual block; the renderer is parallel itself
  options.logging_type = ceres::SILENT;
  options.minimizer_progress_to_stdout = false;
  IterationLog log(settled_steps);
  options.callbacks.push_back(&log);
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  if (progress) progress->finish();
  if (spdlog::should_log(spdlog::level::debug))
    spdlog::debug("{}: {}", report.name, summary.FullReport());

  report.evaluations += cost.evaluations();
  report.with_derivatives = cost.withDerivatives();
  for (const ceres::IterationSummary& it : summary.iterations)
    report.trace.push_back(2.0 * it.cost);
  report.loss_after = report.loss_before;
  const bool usable = summary.termination_type == ceres::CONVERGENCE ||
                      summary.termination_type == ceres::NO_CONVERGENCE ||
                      summary.termination_type == ceres::USER_SUCCESS;
  // Ceres' cost is half the squared sum of the (transformed) residuals.
  const double after = 2.0 * summary.final_cost;
  if (usable && after <= report.loss_before) {
    for (size_t k = 0; k < n; ++k) theta[static_cast<size_t>(indices[k])] = x[k] * scales[k];
    report.loss_after = after;
  }
  report.termination =
      fmt::format("{} ({} iterations, {} successful): {}",
                  ceres::TerminationTypeToString(summary.termination_type),
                  summary.iterations.size() > 0 ? summary.iterations.size() - 1 : 0,
                  summary.num_successful_steps, summary.message);
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!quiet)
    spdlog::info("{}: {} {:.6g} -> {:.6g} in {} evaluations, {:.2f} s ({})", report.name,
                 robust ? "Huber loss" : "squared residuals", report.loss_before, report.loss_after,
                 report.evaluations, report.seconds, report.termination);
  return report;
}

}  // namespace xgauge
