#include "budget.h"
#include "stages.h"

#include "xgauge/measure/schedule.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <Eigen/Eigenvalues>
#include <Eigen/QR>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <ranges>

namespace xgauge {

namespace {

constexpr int kBlockPx = 16;  // cluster size of the sandwich (uncertainty.h)
// A pair of dimensions is reported as a measurable sum or difference when
// their errors correlate beyond kCombinationCorrelation and the combination's
// U is below kCombinationGain times the smaller of theirs. On the replica
// prism pairs, 0.95 and 0.5 also let through pairs whose common bias (the
// detector's ghost, which the budget has no component for) the combination
// does not cancel (groove_left - groove_right: U 0.010 mm, error 0.078 mm).
constexpr double kCombinationCorrelation = 0.99;
constexpr double kCombinationGain = 0.2;
// A material's curve move (a calibration input) smaller than this share of
// its largest is propagated with the rest of the curve's uncertainty.
constexpr double kMinorMoveShare = 0.1;
constexpr int kResolveIterations = 10;  // from theta, for an influence moved by u
constexpr int kResolveWidthPx = 1024;   // level of those re-solves (at least the fit's)
constexpr int kChordIterations = 10;
// The chord iteration converges geometrically: after step k (at least
// kChordMinSteps) with change c_k and ratio rho (the larger of the last two
// c_k / c_(k-1)), the rest of the way is about c_k rho / (1 - rho). It stops
// when that tail is below kChordTolerance of the linearisation's steps and
// adds it along the last change (Aitken's extrapolation). A fixed bound on
// c_k alone (a thousandth) took ten steps on a 4096^2 Prism A pair's
// source-detector distance, creeping by 0.57 per step, where six and the tail
// agreed with the tenth to 2e-4 steps.
constexpr int kChordMinSteps = 3;
constexpr double kChordTolerance = 5e-3;
// After kChordIterations, a shift whose last change is at most this share of
// its largest component (both in linearisation steps) is taken: at a creep
// that slows by a tenth per step, the rest of the way is about ten last
// changes, a fifth of the shift at most (an uncertainty component's own
// uncertainty), where leaving it out would drop it whole.
constexpr double kChordCreep = 0.02;
constexpr double kGeometricNullRatio = 1e-10;  // of the vertex velocities' scaled normal
                                                // matrix: exact up to the vertex map's
                                                // finite differences (about 1e-8 relative)
constexpr double kNullRatio = 1e-9;     // eigenvalue of the scaled normal matrix below which a
                                        // direction is taken as not determined at all

// The pseudo-inverse of the symmetric positive semi-definite A, scaled to a
// unit diagonal first so that millimetres and degrees compare; `null` gets
// the directions (in unscaled parameters) it drops.
Eigen::MatrixXd pseudoInverse(const Eigen::MatrixXd& a, std::vector<Eigen::VectorXd>& null) {
  const Eigen::Index n = a.rows();
  Eigen::VectorXd s(n);
  for (Eigen::Index k = 0; k < n; ++k) s(k) = a(k, k) > 0.0 ? 1.0 / std::sqrt(a(k, k)) : 0.0;
  const Eigen::MatrixXd scaled = s.asDiagonal() * a * s.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(scaled);
  const Eigen::VectorXd& lambda = eigen.eigenvalues();
  const double largest = lambda.maxCoeff();
  spdlog::debug("uncertainty: the scaled normal matrix's smallest eigenvalues relative to its "
                "largest: {:.3g}",
                fmt::join(std::vector<double>(lambda.data(), lambda.data() + std::min<Eigen::Index>(n, 4)) |
                              std::views::transform([&](double l) { return l / largest; }),
                          ", "));
  Eigen::VectorXd inverse(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const bool dropped = !(lambda(k) > kNullRatio * largest);
    inverse(k) = dropped ? 0.0 : 1.0 / lambda(k);
    if (dropped) null.push_back((s.asDiagonal() * eigen.eigenvectors().col(k)).normalized());
  }
  for (Eigen::Index k = 0; k < n; ++k)
    if (s(k) == 0.0) null.push_back(Eigen::VectorXd::Unit(n, k));  // a parameter nothing sees
  return s.asDiagonal() * eigen.eigenvectors() * inverse.asDiagonal() *
         eigen.eigenvectors().transpose() * s.asDiagonal();
}

// The directions of the parameters `indices` along which no vertex of the
// posed part moves in any of `radiographs`: pose and dimensions that
// describe the same placed part, which no radiograph can tell apart. The
// wedge's four pocket edges, measured from a centre line the part does not
// show, are the standing example: moving them all one way and the part the
// other leaves every vertex where it was. The image Jacobian sees such a
// direction only blurred by its finite differences over point samples (on
// the wedge its eigenvalue came out 0.3 % of the largest, as large as the
// genuine ones), so it is found from the vertex velocities, which are exact.
// Returns orthonormal columns in the parameters' own units; empty when there
// are none or the velocities cannot be evaluated.
Eigen::MatrixXd geometricNullSpace(ForwardModel& model, std::span<const double> theta,
                                   std::span<const int> indices, std::span<const int> radiographs) {
  const auto n = static_cast<Eigen::Index>(indices.size());
  const auto vertices = static_cast<Eigen::Index>(model.part().vertexCount());
  Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(n, n);  // M^T M of the stacked velocities
  std::vector<int> moving;
  std::vector<Vec3> velocities;
  std::vector<bool> geometric(indices.size(), false);
  for (int r : radiographs) {
    if (!model.poseVelocities(theta, indices, r, moving, velocities)) return {};
    Eigen::MatrixXd m(3 * vertices, static_cast<Eigen::Index>(moving.size()));
    for (size_t k = 0; k < moving.size(); ++k) {
      geometric[static_cast<size_t>(moving[k])] = true;
      for (Eigen::Index v = 0; v < vertices; ++v)
        m.block<3, 1>(3 * v, static_cast<Eigen::Index>(k)) =
            velocities[k * static_cast<size_t>(vertices) + static_cast<size_t>(v)];
    }
    const Eigen::MatrixXd mm = m.transpose() * m;
    for (size_t i = 0; i < moving.size(); ++i)
      for (size_t j = 0; j < moving.size(); ++j)
        normal(moving[i], moving[j]) += mm(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j));
  }
  // Over the parameters that move something, scaled to a unit diagonal.
  std::vector<Eigen::Index> cols;
  for (Eigen::Index k = 0; k < n; ++k)
    if (geometric[static_cast<size_t>(k)] && normal(k, k) > 0.0) cols.push_back(k);
  const auto g = static_cast<Eigen::Index>(cols.size());
  if (g == 0) return {};
  Eigen::MatrixXd scaled(g, g);
  Eigen::VectorXd s(g);
  for (Eigen::Index i = 0; i < g; ++i) s(i) = 1.0 / std::sqrt(normal(cols[i], cols[i]));
  for (Eigen::Index i = 0; i < g; ++i)
    for (Eigen::Index j = 0; j < g; ++j) scaled(i, j) = normal(cols[i], cols[j]) * s(i) * s(j);
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(scaled);
  const double largest = eigen.eigenvalues().maxCoeff();
  std::vector<Eigen::VectorXd> found;
  for (Eigen::Index k = 0; k < g; ++k) {
    if (!(eigen.eigenvalues()(k) < kGeometricNullRatio * largest)) continue;
    Eigen::VectorXd direction = Eigen::VectorXd::Zero(n);
    for (Eigen::Index i = 0; i < g; ++i) direction(cols[i]) = s(i) * eigen.eigenvectors()(i, k);
    found.push_back(direction);
  }
  if (found.empty()) return {};
  Eigen::MatrixXd basis(n, static_cast<Eigen::Index>(found.size()));
  for (size_t k = 0; k < found.size(); ++k) basis.col(static_cast<Eigen::Index>(k)) = found[k];
  return Eigen::HouseholderQR<Eigen::MatrixXd>(basis).householderQ() *
         Eigen::MatrixXd::Identity(n, basis.cols());
}

// A re-simulation with one influence moved by its standard uncertainty.
struct Influence {
  std::string name, quantity, unit;
  double u = 0.0;               // standard uncertainty, in unit
  Eigen::VectorXd delta_theta;  // the parameters' shift for q + u
  // When the influence scales the rates of the file's curve (the material's
  // rest): by how much, relative.
  double curve_scale = 0.0;
};

}  // namespace

UncertaintyBudget estimateUncertainty(ForwardModel& model, std::span<const double> theta,
                                      const LinearizedFit& fit) {
  UncertaintyBudget budget;
  budget.level = fit.level;
  const Eigen::MatrixXd& jacobian = fit.jacobian;
  const Eigen::VectorXd& r = fit.residuals;
  const Eigen::VectorXd w = fit.weights();
  const Eigen::Index m = r.size(), n = jacobian.cols();
  budget.pixels = static_cast<double>(m);

  // A = J^T W J, accumulated in row chunks (J has millions of rows).
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n);
  constexpr Eigen::Index kChunk = 8192;
  for (Eigen::Index i = 0; i < m; i += kChunk) {
    const Eigen::Index rows = std::min(kChunk, m - i);
    const auto block = jacobian.middleRows(i, rows);
    a.noalias() += block.transpose() * w.segment(i, rows).asDiagonal() * block;
  }
  // The refinement's prior is a row of its own (least_squares.h): in A, not
  // in B, since its centre is not noise; the curve's uncertainty it stands
  // for is propagated as the material's components below, which the fit
  // with the rate scale free absorbs as far as the radiographs allow.
  if (fit.prior) a(fit.prior->column, fit.prior->column) += fit.prior->lambda * fit.prior->lambda;
  // Directions no radiograph can see are taken out of A (and below of B
  // and of every influence's shift), so that the pseudo-inverse drops them
  // exactly and the dimensions along them are reported as not identifiable.
  std::vector<int> radiographs;
  for (const ResidualSegment& s : fit.segments) radiographs.push_back(s.radiograph);
  const Eigen::MatrixXd unseen = geometricNullSpace(model, theta, fit.indices, radiographs);
  Eigen::MatrixXd project = Eigen::MatrixXd::Identity(n, n);
  if (unseen.cols() > 0) {
    project -= unseen * unseen.transpose();
    a = project * a * project;
    spdlog::debug("uncertainty: {} direction(s) of the parameters move no vertex of the part",
                  unseen.cols());
  }
  std::vector<Eigen::VectorXd> null;
  const Eigen::MatrixXd a_inverse = pseudoInverse(a, null);

  // B: the scores J_i psi_i summed per block of pixels, then their outer
  // products (the blocks' sums are taken as independent, the pixels within a
  // block not).
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(n, n);
  for (const ResidualSegment& segment : fit.segments) {
    const int bw = (segment.roi.width + kBlockPx - 1) / kBlockPx;
    const int bh = (segment.roi.height + kBlockPx - 1) / kBlockPx;
    Eigen::MatrixXd scores = Eigen::MatrixXd::Zero(n, static_cast<Eigen::Index>(bw) * bh);
    for (int y = 0; y < segment.roi.height; ++y)
      for (int x = 0; x < segment.roi.width; ++x) {
        const auto i = static_cast<Eigen::Index>(segment.first) +
                       static_cast<Eigen::Index>(y) * segment.roi.width + x;
        scores.col(static_cast<Eigen::Index>(y / kBlockPx) * bw + x / kBlockPx) +=
            jacobian.row(i).transpose() * (w(i) * r(i));
      }
    b.noalias() += scores * scores.transpose();
  }
  b = project * b * project;
  const double small_sample =
      static_cast<double>(m) / static_cast<double>(std::max<Eigen::Index>(1, m - n));
  const Eigen::MatrixXd statistical = small_sample * a_inverse * b * a_inverse;

  // The influences. Each is a model moved by its u, and its effect the
  // shift of every parameter (including what the poses absorb) that the
  // fit makes with it. Two ways, by what the influence does to the image:
  //
  // - Intensity (material, scatter, lag): one render of the moved model at
  //   theta on the final stage's level gives the change of the residuals
  //   dr, and the shift is the linearised re-solve -A^-1 J^T W dr with the
  //   fit's own Jacobian. On a 1024^2 prism B pair and a wedge pair it
  //   agreed with ten-iteration Ceres re-solves to 2-5 % on every component
  //   above 0.002 mm (the re-solves, not converged after ten iterations,
  //   are the less exact of the two), for one render instead of about 200.
  // - Geometry (source-detector distance, pixel pitch, translation): the
  //   pose absorbs most of such a change along a weakly determined direction
  //   that one linearised step does not follow (on a prism B pair it moved
  //   slot_depth by 0.0045 mm per 0.5 mm of source-detector distance, where
  //   a re-solve, and uncertainty_test's measurement of radiographs taken
  //   with the distance changed, move it by 0.0001). These take the
  //   linearised step again from where the last one ended, with the fit's
  //   A and J held fixed and the moved model's residuals there (the chord
  //   method), in lockstep with the unmoved model iterated in the same way
  //   from theta, until the difference of their iterates has settled
  //   (kChordTolerance: its geometric tail under 0.005 of the
  //   linearisation's steps, then added; 3 to 7 steps, one render each, the
  //   unmoved model's shared by every influence). On that
  //   pair and on a 4096^2 prism A pair the shifts agreed with ten-iteration
  //   Ceres re-solves at 1024 px (about 200 renders each, what this did
  //   until now) to 0.0004 mm per component on the prism B pair and 0.0015
  //   mm on the prism A pair, against U of 0.0005 to 0.4 mm; every U the
  //   same to 0.0002 mm.
  //   The detector lag, where its signal is not kept on the fit's level, is
  //   still solved again (Ceres, as the final stage) on the level about 1024
  //   pixels wide, against the unmoved model solved there from the same
  //   start. At 512 pixels with 2 x 2 point samples the 1024^2 demo's
  //   slot_width (a 4 mm slot, 19 pixels there) got a U of 0.021 mm where
  //   50 Monte Carlo repetitions spread by 0.008 (2 s).
  const bool robust = model.job().loss == LossKind::kMeanAbsolute;
  const int level = std::max(fit.level, model.levelForWidth(kResolveWidthPx));
  const int samples = fit.samples;
  std::vector<Influence> influences;
  const bool material_free = !model.materialIndices().empty();
  // The re-solves take their Jacobian as the schedule's least-squares stage
  // does: from the render with derivatives (reused between iterations:
  // least_squares.cpp) where it does, else by forward differences (1 + n
  // renders).
  const JacobianKind jacobian_kind =
      leastSquaresStage(model, scheduleFor(model.job().schedule)).render_derivatives
          ? JacobianKind::kRenderDerivatives
          : JacobianKind::kForwardDifferences;
  auto solveFrom = [&](ForwardModel& with, std::vector<double>& solved) {
    solved.assign(theta.begin(), theta.end());
    // Every re-solve weighs the refinement's prior as the fit did, so that
    // a moved model's own residual scale does not move e.
    const StageReport report = solveLeastSquares(
        with, solved, fit.indices, radiographs, level, samples, kResolveIterations, robust,
        jacobian_kind, /*quiet=*/true, "joint",
        fit.prior ? std::optional<double>(fit.prior->lambda) : std::nullopt);
    spdlog::debug("uncertainty: re-solve in {} evaluations, {:.2f} s ({})", report.evaluations,
                  report.seconds, report.termination);
    return report.termination != "start point invalid";
  };
  // A model with the material free (a calibration) has parameters a moved
  // model would not: its influences are not propagated.
  const bool propagate = !material_free;
  // The unmoved model solved on the re-solves' level, on the first re-solve.
  std::vector<double> reference;
  std::optional<bool> reference_solved;
  enum class Propagation { kLinearised, kIterated, kReSolved };
  // The chord method: from theta, steps -A^-1 J^T W r(x) with the fit's own
  // A and J held fixed and the residuals r of `with` at each new x. Its
  // fixed point is where J^T W r = 0, as the fit's. The moved and the
  // unmoved model take their steps in lockstep and the influence's shift is
  // the difference of their iterates, done when it changes by less than
  // kChordTolerance of the linearisation's steps (or kChordIterations): the
  // iteration creeps along a weakly determined direction at the same pace
  // for both (on a 1024^2 Prism B pair each iterate still moved by 0.002 of
  // a step after ten, slowing by a tenth per step, where their difference
  // had settled), so it is the difference that has to settle.
  // One step of `with` from x; why it failed, or nullopt. The unmoved
  // model's residuals at theta are the fit's own (`at_theta`): not rendered
  // again.
  auto chordStep = [&](ForwardModel& with, std::vector<double>& x,
                       const Eigen::VectorXd* at_theta = nullptr) -> std::optional<std::string> {
    std::vector<double> rx;
    if (!at_theta && (!with.residuals(x, fit.level, samples, radiographs, rx) ||
                      rx.size() != static_cast<size_t>(m)))
      return "the radiographs could not be simulated on the way";
    const Eigen::Map<const Eigen::VectorXd> residuals(at_theta ? at_theta->data() : rx.data(), m);
    Eigen::VectorXd g = jacobian.transpose() * w.cwiseProduct(residuals);
    if (fit.prior) {
      const auto i = static_cast<size_t>(fit.indices[static_cast<size_t>(fit.prior->column)]);
      g(fit.prior->column) += fit.prior->lambda * fit.prior->lambda * x[i];
    }
    const Eigen::VectorXd step = -(a_inverse * (project * g));
    for (Eigen::Index k = 0; k < n; ++k)
      x[static_cast<size_t>(fit.indices[static_cast<size_t>(k)])] += step(k);
    return std::nullopt;
  };
  // The unmoved model's iterates, shared by every influence (unmoved[k]
  // after k steps), and why the next one failed (set on failure).
  std::vector<std::vector<double>> unmoved{std::vector<double>(theta.begin(), theta.end())};
  std::optional<std::string> unmoved_failure;
  // The shift of the parameters that `moved` causes; why it failed, or nullopt.
  auto iterate = [&](ForwardModel& moved, Eigen::VectorXd& shift) -> std::optional<std::string> {
    std::vector<double> x(theta.begin(), theta.end());
    Eigen::VectorXd last = Eigen::VectorXd::Zero(n);
    double change = 0.0;
    std::vector<double> changes;
    for (int it = 1; it <= kChordIterations; ++it) {
      if (static_cast<int>(unmoved.size()) <= it) {
        if (unmoved_failure) return fmt::format("the unmoved fit: {}", *unmoved_failure);
        std::vector<double> next = unmoved.back();
        if (const auto failure = chordStep(model, next, unmoved.size() == 1 ? &r : nullptr)) {
          unmoved_failure = *failure;
          return fmt::format("the unmoved fit: {}", *failure);
        }
        unmoved.push_back(std::move(next));
      }
      if (const auto failure = chordStep(moved, x)) return failure;
      double largest = 0.0;
      for (Eigen::Index k = 0; k < n; ++k) {
        const auto i = static_cast<size_t>(fit.indices[static_cast<size_t>(k)]);
        shift(k) = x[i] - unmoved[static_cast<size_t>(it)][i];
        largest =
            std::max(largest, std::abs(shift(k) - last(k)) / fit.steps[static_cast<size_t>(k)]);
      }
      const Eigen::VectorXd moved_by = shift - last;
      last = shift;
      change = largest;
      changes.push_back(largest);
      spdlog::debug(
          "uncertainty: chord step {}: the shift changed by {:.3g} of the linearisation's steps",
          it, largest);
      if (largest == 0.0) return std::nullopt;
      if (it < kChordMinSteps) continue;
      const size_t k = changes.size() - 1;
      const double rho = std::max(changes[k] / changes[k - 1], changes[k - 1] / changes[k - 2]);
      if (rho < 1.0 && largest * rho / (1.0 - rho) < kChordTolerance) {
        shift += moved_by * (rho / (1.0 - rho));
        return std::nullopt;
      }
    }
    // Still creeping, but by a small share of the shift itself (kChordCreep).
    double size = 0.0;
    for (Eigen::Index k = 0; k < n; ++k)
      size = std::max(size, std::abs(shift(k)) / fit.steps[static_cast<size_t>(k)]);
    if (change <= kChordCreep * size) return std::nullopt;
    return fmt::format("its shift did not settle in {} iterations", kChordIterations);
  };
  auto propagateInfluence = [&](ForwardModel& moved, Influence influence, Propagation how) {
    const auto influence_start = std::chrono::steady_clock::now();
    Eigen::VectorXd shift(n);
    if (how == Propagation::kIterated) {
      if (const auto failure = iterate(moved, shift)) {
        budget.notes.push_back(
            fmt::format("{}: the fit's linearised steps with it moved by u failed ({}); left out",
                        influence.name, *failure));
        return;
      }
    } else if (how == Propagation::kLinearised) {
      std::vector<double> moved_r;
      if (!moved.residuals(theta, fit.level, samples, radiographs, moved_r) ||
          moved_r.size() != static_cast<size_t>(m)) {
        budget.notes.push_back(fmt::format(
            "{}: the radiographs with it moved by u could not be simulated; left out",
            influence.name));
        return;
      }
      const Eigen::VectorXd dr = Eigen::Map<const Eigen::VectorXd>(moved_r.data(), m) - r;
      shift = -(a_inverse * (project * (jacobian.transpose() * w.cwiseProduct(dr))));
    } else {
      if (!reference_solved) reference_solved = solveFrom(model, reference);
      std::vector<double> solved;
      if (!*reference_solved || !solveFrom(moved, solved)) {
        budget.notes.push_back(fmt::format(
            "{}: the fit could not be solved again with it moved by u; left out",
            influence.name));
        return;
      }
      for (Eigen::Index k = 0; k < n; ++k) {
        const auto i = static_cast<size_t>(fit.indices[static_cast<size_t>(k)]);
        shift(k) = solved[i] - reference[i];
      }
    }
    influence.delta_theta = project * shift;
    spdlog::debug(
        "uncertainty: {} {} in {:.2f} s", influence.name,
        how == Propagation::kLinearised ? "linearised"
        : how == Propagation::kIterated ? "iterated"
                                        : "solved again",
        std::chrono::duration<double>(std::chrono::steady_clock::now() - influence_start).count());
    influences.push_back(std::move(influence));
  };
  const MeasurementInputs& inputs = model.inputs();
  if (material_free) {
    budget.notes.push_back(
        "the material is fitted with the dimensions (a calibration): only the statistical part "
        "is given");
  } else {
    const ExponentialSum& material = model.material();
    // The curve's own moves (a wedge's caliper dimensions): each one is a
    // component with its own curve. Those that move the curve by less than
    // kMinorMoveShare of the largest go with the rest, to save their renders.
    double rest2 = material.transmissionUncertainty() * material.transmissionUncertainty();
    const std::vector<CurveMove>& moves = material.curveMoves();
    if (!moves.empty()) {
      rest2 = material.curveMovesBesides() * material.curveMovesBesides();
      double largest = 0.0;
      for (const CurveMove& move : moves) largest = std::max(largest, move.curve_change);
      for (const CurveMove& move : moves) {
        if (move.curve_change < kMinorMoveShare * largest) {
          rest2 += move.curve_change * move.curve_change;
          continue;
        }
        ForwardModel moved(inputs, move.curve);
        moved.setEdgeSamples(model.edgeSamples());
        propagateInfluence(
            moved,
            {"material: " + move.name,
             fmt::format("{} = {:.4g} +- {:.2g} {}, the curve it calibrated", move.name,
                         move.value, move.standard_uncertainty, move.unit),
             move.unit, move.standard_uncertainty, {}},
            Propagation::kLinearised);
      }
    }
    // When the scatter comes from the material's calibration and the file
    // says how the curve moves with it, the scatter's share of the curve's
    // uncertainty goes with the scatter's components below: what is left is
    // besides_scatter^2 - (u^2 - rest^2).
    if (const auto& curves = inputs.scatter_curves) {
      const double u = material.transmissionUncertainty();
      rest2 -= u * u - curves->transmission_uncertainty_besides *
                           curves->transmission_uncertainty_besides;
    }
    const double u = std::sqrt(std::max(0.0, rest2));
    // The rest as a scale of the rates that moves the curve by u at the
    // worst path: dI/d(scale) = -x sum a_k mu_k exp(-mu_k x).
    const double scale = material.rateScaleFor(u, model.partSizeMm());
    if (scale > 0.0) {
      ForwardModel moved(inputs, material.withScaledRates(scale));
      moved.setEdgeSamples(model.edgeSamples());
      propagateInfluence(
          moved,
          {"material",
           fmt::format("transmission curve, u = {:.2g}{}", u,
                       moves.empty() ? "" : " besides the calibration's inputs"),
           "transmission", u, {}, scale},
          Propagation::kLinearised);
    }
  }
  // change(inputs, amount) moves the influence by amount * u; `curve`, when
  // given, is the material curve that goes with it.
  auto withInputs = [&](Propagation how, const std::string& name, const std::string& quantity,
                        const std::string& unit, double u, auto change,
                        const std::optional<ExponentialSum>& curve = std::nullopt) {
    if (!(u > 0.0) || !propagate) return;
    MeasurementInputs moved = inputs;  // the model below keeps a reference to it
    change(moved, 1.0);
    ForwardModel moved_model(moved, curve ? *curve : model.material());
    moved_model.setEdgeSamples(model.edgeSamples());
    propagateInfluence(moved_model, {name, quantity, unit, u, {}}, how);
  };
  const ScatterModel& scatter = inputs.job.scatter;
  if (scatter.enabled()) {
    // With the material's scatter curves, each scatter component moves the
    // measurement's scatter and the curve its calibration would then have
    // found, together.
    const std::optional<ScatterCurves>& curves = inputs.scatter_curves;
    const char* with_curve = curves ? ", with the curve it calibrated" : "";
    withInputs(
        Propagation::kLinearised, "scatter weight",
        fmt::format("w = {:.4g} +- {:.2g}{}", scatter.weight, scatter.weight_uncertainty, with_curve),
        "1", scatter.weight_uncertainty,
        [&](MeasurementInputs& in, double amount) {
          in.job.scatter.weight += amount * scatter.weight_uncertainty;
        },
        curves ? curves->weight_plus_u : std::nullopt);
    withInputs(Propagation::kLinearised, "scatter width",
               fmt::format("sigma = {:.4g} +- {:.2g} mm{}", scatter.sigma_mm,
                           scatter.sigma_uncertainty_mm, with_curve),
               "mm", scatter.sigma_uncertainty_mm,
               [&](MeasurementInputs& in, double amount) {
                 in.job.scatter.sigma_mm += amount * scatter.sigma_uncertainty_mm;
               },
               curves ? curves->sigma_plus_u : std::nullopt);
  }
  const Machine& machine = inputs.machine;
  withInputs(Propagation::kIterated, "source-detector distance",
             fmt::format("D = {:.2f} +- {:.2g} mm", machine.source_detector_distance_mm,
                         machine.source_detector_distance_uncertainty_mm),
             "mm", machine.source_detector_distance_uncertainty_mm,
             [&](MeasurementInputs& in, double amount) {
               in.machine.source_detector_distance_mm +=
                   amount * machine.source_detector_distance_uncertainty_mm;
             });
  withInputs(Propagation::kIterated, "pixel pitch",
             fmt::format("pitch {:.4g} mm, relative u = {:.2g}", machine.pitch_u_mm,
                         machine.pixel_pitch_uncertainty_relative),
             "relative", machine.pixel_pitch_uncertainty_relative,
             [&](MeasurementInputs& in, double amount) {
               in.machine.pitch_u_mm *= 1.0 + amount * machine.pixel_pitch_uncertainty_relative;
               in.machine.pitch_v_mm *= 1.0 + amount * machine.pixel_pitch_uncertainty_relative;
             });
  for (size_t k = 0; k < inputs.job.radiographs.size(); ++k) {
    const RadiographSpec& spec = inputs.job.radiographs[k];
    if (spec.pattern != Acquisition::kTranslated) continue;
    const double u = spec.distance_uncertainty_mm;
    withInputs(Propagation::kIterated, "translation " + spec.name,
               fmt::format("distance {:.4f} +- {:.2g} mm", spec.distance_mm, u), "mm", u,
               [&](MeasurementInputs& in, double amount) {
                 in.job.radiographs[k].distance_mm += amount * u;
               });
  }

  // The lag fraction, estimated from a radiograph and its previous frame or
  // the machine's:
  // moved by u, the radiograph loses u more of that frame's signal, and its
  // white region as much of its own, by which it is divided again.
  for (size_t k = 0; k < inputs.radiographs.size(); ++k) {
    const PreparedRadiograph& radiograph = *inputs.radiographs[k];
    if (!radiograph.lag || !(radiograph.lag->uncertainty > 0.0)) continue;
    const double u = radiograph.lag->uncertainty;
    const std::string name = "detector lag " + inputs.job.radiographs[k].name;
    // Linearised on the fit's level where the signal is kept there (it is
    // not on levels kLagSignalWidthPx wide or more, to save memory), else
    // solved again on the re-solves' level.
    const auto kept = [&](int at) {
      return radiograph.lag_signal_levels.size() > static_cast<size_t>(at) &&
             !radiograph.lag_signal_levels[static_cast<size_t>(at)].empty();
    };
    const Propagation how = kept(fit.level) ? Propagation::kLinearised : Propagation::kReSolved;
    if (how == Propagation::kReSolved && !kept(level)) {
      budget.notes.push_back(
          fmt::format("{}: its signal is not kept at level {}; left out", name, level));
      continue;
    }
    withInputs(how, name,
               fmt::format("g = {:.5f} +- {:.2g} ({})", radiograph.lag->fraction, u,
                           radiograph.lag->stated ? "the machine's" : "estimated"),
               "1", u, [&](MeasurementInputs& in, double amount) {
                 auto moved = std::make_shared<PreparedRadiograph>(radiograph);
                 const double step = amount * u;
                 const auto scale = static_cast<float>(1.0 / (1.0 - step * radiograph.lag_signal_white));
                 for (size_t l = 0; l < moved->levels.size(); ++l) {
                   const Image& signal = radiograph.lag_signal_levels[l];
                   if (signal.empty()) continue;
                   auto pixels = moved->levels[l].pixels();
                   auto lag = signal.pixels();
                   for (size_t i = 0; i < pixels.size(); ++i)
                     pixels[i] = (pixels[i] - static_cast<float>(step) * lag[i]) * scale;
                 }
                 in.radiographs[k] = std::move(moved);
               });
  }

  // The white region's mean, by which every pixel of a radiograph was
  // divided: off by u (relative), the whole radiograph reads 1 / (1 + u) of
  // what it should.
  for (size_t k = 0; k < inputs.radiographs.size(); ++k) {
    const PreparedRadiograph& radiograph = *inputs.radiographs[k];
    const double u = radiograph.white_mean_uncertainty;
    withInputs(Propagation::kLinearised, "normalisation " + inputs.job.radiographs[k].name,
               fmt::format("white region's mean, relative u = {:.2g}", u), "relative", u,
               [&](MeasurementInputs& in, double amount) {
                 auto moved = std::make_shared<PreparedRadiograph>(radiograph);
                 const auto scale = static_cast<float>(1.0 / (1.0 + amount * u));
                 for (Image& image : moved->levels)
                   for (float& p : image.pixels()) p *= scale;
                 in.radiographs[k] = std::move(moved);
               });
  }

  // The total covariance and each free dimension's budget.
  Eigen::MatrixXd total = statistical;
  for (const Influence& f : influences) total += f.delta_theta * f.delta_theta.transpose();
  const auto& dims = model.part().dimensions();
  std::vector<Eigen::Index> column;  // of each free dimension in fit.indices
  for (int d : model.freeDimensionIndices()) {
    const auto it = std::find(fit.indices.begin(), fit.indices.end(), d);
    XG_CHECK(it != fit.indices.end(), "free dimension {} is not in the linearisation", d);
    column.push_back(it - fit.indices.begin());
  }
  const auto& free = model.freeDimensionIndices();
  for (size_t j = 0; j < free.size(); ++j) {
    const Eigen::Index c = column[j];
    DimensionUncertainty du;
    du.name = dims[static_cast<size_t>(free[j])].name;
    const std::string unit = dims[static_cast<size_t>(free[j])].unit;
    for (const Eigen::VectorXd& v : null) du.identifiable &= std::abs(v(c)) < 1e-3;
    const double u_stat = std::sqrt(std::max(0.0, statistical(c, c)));
    du.components.push_back({"statistical", fmt::format("noise and misfit over {} pixels", m),
                             u_stat, unit, 1.0, u_stat});
    for (const Influence& f : influences) {
      const double d = f.delta_theta(c);
      du.components.push_back({f.name, f.quantity, f.u, f.unit, d / f.u, std::abs(d)});
    }
    du.combined = std::sqrt(std::max(0.0, total(c, c)));
    du.expanded = du.identifiable ? budget.coverage_factor * du.combined : 0.0;
    budget.dimensions.push_back(std::move(du));
  }

  // The drawing's combinations (the part model's "combinations") whose
  // dimensions are all free: their value and U from the total covariance,
  // whether or not the single dimensions are identifiable.
  const auto freeColumn = [&](const std::string& name) -> std::optional<size_t> {
    for (size_t j = 0; j < free.size(); ++j)
      if (dims[static_cast<size_t>(free[j])].name == name) return j;
    return std::nullopt;
  };
  std::vector<std::vector<std::pair<size_t, double>>> declared_pairs;
  for (const DeclaredCombination& declared : model.part().combinations()) {
    std::vector<std::pair<size_t, double>> at;
    for (const auto& [name, coefficient] : declared.terms)
      if (const auto j = freeColumn(name)) at.emplace_back(*j, coefficient);
    if (at.size() != declared.terms.size()) continue;
    Eigen::VectorXd t = Eigen::VectorXd::Zero(total.rows());
    MeasurableCombination combination;
    combination.name = declared.name;
    std::string expression;
    for (size_t k = 0; k < at.size(); ++k) {
      const auto [j, coefficient] = at[k];
      t(column[j]) = coefficient;
      combination.terms.emplace_back(budget.dimensions[j].name, coefficient);
      combination.value += coefficient * theta[static_cast<size_t>(free[j])];
      const std::string factor =
          std::abs(coefficient) == 1.0 ? "" : fmt::format("{:g} ", std::abs(coefficient));
      expression += k == 0 ? fmt::format("{}{}{}", coefficient < 0 ? "-" : "", factor,
                                         budget.dimensions[j].name)
                           : fmt::format(" {} {}{}", coefficient < 0 ? "-" : "+", factor,
                                         budget.dimensions[j].name);
    }
    combination.expression = expression;
    bool identifiable = true;
    for (const Eigen::VectorXd& v : null)
      identifiable &= std::abs(t.dot(v)) < 1e-3 * t.norm() * v.norm();  // as a dimension's test
    combination.expanded =
        identifiable ? budget.coverage_factor * std::sqrt(std::max(0.0, t.dot(total * t))) : 0.0;
    if (at.size() == 2) declared_pairs.push_back(at);
    budget.combinations.push_back(std::move(combination));
  }

  // Measurable combinations: two dimensions whose errors are (anti)correlated
  // so strongly that their sum (difference) is known much better than either.
  for (size_t i = 0; i < free.size(); ++i)
    for (size_t j = i + 1; j < free.size(); ++j) {
      const Eigen::Index ci = column[i], cj = column[j];
      const double vi = total(ci, ci), vj = total(cj, cj), cov = total(ci, cj);
      const bool either_lost =
          !budget.dimensions[i].identifiable || !budget.dimensions[j].identifiable;
      if (!(vi > 0.0 && vj > 0.0) && !either_lost) continue;
      const double rho = vi > 0.0 && vj > 0.0 ? cov / std::sqrt(vi * vj) : 0.0;
      const double sign = either_lost ? 0.0 : (rho < 0.0 ? 1.0 : -1.0);
      double coefficient = sign;
      if (either_lost) {
        // The combination orthogonal to every null direction, if a sum or
        // difference is.
        for (double s : {1.0, -1.0}) {
          bool orthogonal = true;
          for (const Eigen::VectorXd& v : null)
            orthogonal &= std::abs(v(ci) + s * v(cj)) < 1e-3 * (std::abs(v(ci)) + std::abs(v(cj)));
          if (orthogonal) coefficient = s;
        }
        if (coefficient == 0.0) continue;
      } else if (std::abs(rho) < kCombinationCorrelation) {
        continue;
      }
      const double var = vi + vj + 2.0 * coefficient * cov;
      const double u = std::sqrt(std::max(0.0, var));
      if (!either_lost && !(u < kCombinationGain * std::sqrt(std::min(vi, vj)))) continue;
      const bool already = std::any_of(
          declared_pairs.begin(), declared_pairs.end(), [&](const auto& at) {
            return at[0].first == i && at[1].first == j &&
                   at[1].second / at[0].second == coefficient;
          });
      if (already) continue;
      MeasurableCombination combination;
      combination.terms = {{budget.dimensions[i].name, 1.0},
                           {budget.dimensions[j].name, coefficient}};
      combination.expression = fmt::format("{} {} {}", budget.dimensions[i].name,
                                           coefficient > 0 ? "+" : "-", budget.dimensions[j].name);
      combination.value =
          theta[static_cast<size_t>(free[i])] + coefficient * theta[static_cast<size_t>(free[j])];
      combination.expanded = budget.coverage_factor * u;
      budget.combinations.push_back(std::move(combination));
    }
  if (fit.prior) {
    const Eigen::Index c = fit.prior->column;
    MaterialRefinementResult refined;
    refined.rate_scale = theta[static_cast<size_t>(model.rateScaleIndex())];
    refined.prior_standard_uncertainty = model.rateScalePrior();
    // e corrects the file's curve: a scale s of that curve moves e by about
    // -s and the refined curve, (1 + s)(1 + e), by s + de, which is what the
    // prior holds back. So e's uncertainty as the radiographs determine it
    // (that of the refined curve's scale) is the statistical part, the
    // material's rest as s + de, and the other influences. The calibration
    // inputs' curve moves are not scales and are left out of it.
    double variance = statistical(c, c);
    for (const Influence& f : influences) {
      if (f.curve_scale != 0.0) {
        const double refined_scale = f.curve_scale + f.delta_theta(c);
        variance += refined_scale * refined_scale;
      } else if (!f.name.starts_with("material")) {
        variance += f.delta_theta(c) * f.delta_theta(c);
      }
    }
    refined.standard_uncertainty = std::sqrt(std::max(0.0, variance));
    const ExponentialSum used = model.materialOf(theta);
    const ExponentialSum& stated = model.material();
    constexpr int kPaths = 400;
    for (int k = 0; k <= kPaths; ++k) {
      const double x = model.partSizeMm() * k / kPaths;
      const double change = used.transmission(x) - stated.transmission(x);
      if (std::abs(change) > std::abs(refined.transmission_change))
        refined.transmission_change = change, refined.at_path_mm = x;
    }
    budget.refinement = refined;
  }
  if (!null.empty())
    budget.notes.push_back(
        fmt::format("{} direction(s) of the parameters are not determined by the "
                    "radiographs",
                    null.size()));
  return budget;
}

}  // namespace xgauge
