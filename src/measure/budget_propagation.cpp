// How an influence's shift of the parameters reaches the budget: linearised,
// by the chord iteration, or solved again (docs/method.md, "Uncertainty").
//
// Each influence is a model moved by its u, and its effect the shift of
// every parameter (including what the poses absorb) that the fit makes with
// it. Two ways, by what the influence does to the image:
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
#include "budget_internal.h"
#include "stages.h"

#include "xgauge/measure/schedule.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>

namespace xgauge::budget_internal {

namespace {

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

// The unmoved model's side of the propagations, found on the first
// influence that needs it and shared by every other.
struct UnmovedModel {
  // The unmoved model's iterates, shared by every influence (iterates[k]
  // after k steps), and why the next one failed (set on failure).
  std::vector<std::vector<double>> iterates;
  std::optional<std::string> failure;
  // The unmoved model solved on the re-solves' level, on the first re-solve.
  std::vector<double> reference;
  std::optional<bool> reference_solved;
};

// `with` solved again from theta on the re-solves' level into `solved`;
// false where its start point is invalid.
bool solveFrom(const FitAtSolution& ctx, ForwardModel& with, std::vector<double>& solved) {
  const LinearizedFit& fit = ctx.fit;
  solved.assign(ctx.theta.begin(), ctx.theta.end());
  // Every re-solve weighs the refinement's prior as the fit did, so that
  // a moved model's own residual scale does not move e.
  const StageReport report =
      solveLeastSquares(with, solved, fit.indices, ctx.radiographs, ctx.level, fit.samples,
                        kResolveIterations, ctx.robust, ctx.jacobian_kind, /*quiet=*/true, "joint",
                        fit.prior ? std::optional<double>(fit.prior->lambda) : std::nullopt);
  spdlog::debug("uncertainty: re-solve in {} evaluations, {:.2f} s ({})", report.evaluations,
                report.seconds, report.termination);
  return report.termination != "start point invalid";
}

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
std::optional<std::string> chordStep(const FitAtSolution& ctx, ForwardModel& with,
                                     std::vector<double>& x,
                                     const Eigen::VectorXd* at_theta = nullptr) {
  const LinearizedFit& fit = ctx.fit;
  const Eigen::Index m = fit.residuals.size(), n = fit.jacobian.cols();
  std::vector<double> rx;
  if (!at_theta && (!with.residuals(x, fit.level, fit.samples, ctx.radiographs, rx) ||
                    rx.size() != static_cast<size_t>(m)))
    return "the radiographs could not be simulated on the way";
  const Eigen::Map<const Eigen::VectorXd> residuals(at_theta ? at_theta->data() : rx.data(), m);
  Eigen::VectorXd g = fit.jacobian.transpose() * ctx.covariance.w.cwiseProduct(residuals);
  if (fit.prior) {
    const auto i = static_cast<size_t>(fit.indices[static_cast<size_t>(fit.prior->column)]);
    g(fit.prior->column) += fit.prior->lambda * fit.prior->lambda * x[i];
  }
  const Eigen::VectorXd step = -(ctx.covariance.a_inverse * (ctx.covariance.project * g));
  for (Eigen::Index k = 0; k < n; ++k)
    x[static_cast<size_t>(fit.indices[static_cast<size_t>(k)])] += step(k);
  return std::nullopt;
}

// The shift of the parameters that `moved` causes, by the chord method in
// lockstep with the unmoved model's iterates; why it failed, or nullopt.
std::optional<std::string> iterate(const FitAtSolution& ctx, UnmovedModel& unmoved,
                                   ForwardModel& moved, Eigen::VectorXd& shift) {
  const LinearizedFit& fit = ctx.fit;
  const Eigen::Index n = fit.jacobian.cols();
  std::vector<double> x(ctx.theta.begin(), ctx.theta.end());
  Eigen::VectorXd last = Eigen::VectorXd::Zero(n);
  double change = 0.0;
  std::vector<double> changes;
  for (int it = 1; it <= kChordIterations; ++it) {
    if (static_cast<int>(unmoved.iterates.size()) <= it) {
      if (unmoved.failure) return fmt::format("the unmoved fit: {}", *unmoved.failure);
      std::vector<double> next = unmoved.iterates.back();
      if (const auto failure = chordStep(ctx, ctx.model, next,
                                         unmoved.iterates.size() == 1 ? &fit.residuals : nullptr)) {
        unmoved.failure = *failure;
        return fmt::format("the unmoved fit: {}", *failure);
      }
      unmoved.iterates.push_back(std::move(next));
    }
    if (const auto failure = chordStep(ctx, moved, x)) return failure;
    double largest = 0.0;
    for (Eigen::Index k = 0; k < n; ++k) {
      const auto i = static_cast<size_t>(fit.indices[static_cast<size_t>(k)]);
      shift(k) = x[i] - unmoved.iterates[static_cast<size_t>(it)][i];
      largest = std::max(largest, std::abs(shift(k) - last(k)) / fit.steps[static_cast<size_t>(k)]);
    }
    const Eigen::VectorXd moved_by = shift - last;
    last = shift;
    change = largest;
    changes.push_back(largest);
    spdlog::debug(
        "uncertainty: chord step {}: the shift changed by {:.3g} of the linearisation's steps", it,
        largest);
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
}

// The shift of the parameters that `moved` causes, as the linearised
// re-solve -A^-1 J^T W dr from one render at theta; false where that
// render fails.
bool linearisedShift(const FitAtSolution& ctx, ForwardModel& moved, Eigen::VectorXd& shift) {
  const LinearizedFit& fit = ctx.fit;
  const Eigen::Index m = fit.residuals.size();
  std::vector<double> moved_r;
  if (!moved.residuals(ctx.theta, fit.level, fit.samples, ctx.radiographs, moved_r) ||
      moved_r.size() != static_cast<size_t>(m))
    return false;
  const Eigen::VectorXd dr = Eigen::Map<const Eigen::VectorXd>(moved_r.data(), m) - fit.residuals;
  shift =
      -(ctx.covariance.a_inverse *
        (ctx.covariance.project * (fit.jacobian.transpose() * ctx.covariance.w.cwiseProduct(dr))));
  return true;
}

// The shift of the parameters that `moved` causes, as the difference of
// `moved` and the unmoved model each solved again; false where either fails.
bool reSolvedShift(const FitAtSolution& ctx, UnmovedModel& unmoved, ForwardModel& moved,
                   Eigen::VectorXd& shift) {
  if (!unmoved.reference_solved)
    unmoved.reference_solved = solveFrom(ctx, ctx.model, unmoved.reference);
  std::vector<double> solved;
  if (!*unmoved.reference_solved || !solveFrom(ctx, moved, solved)) return false;
  for (Eigen::Index k = 0; k < ctx.fit.jacobian.cols(); ++k) {
    const auto i = static_cast<size_t>(ctx.fit.indices[static_cast<size_t>(k)]);
    shift(k) = solved[i] - unmoved.reference[i];
  }
  return true;
}

// `influence` with the shift `moved` causes, found as `how` says; nullopt,
// with a note in `notes`, where that fails.
std::optional<Influence> propagateInfluence(const FitAtSolution& ctx, UnmovedModel& unmoved,
                                            ForwardModel& moved, Influence influence,
                                            Propagation how, std::vector<std::string>& notes) {
  const auto influence_start = std::chrono::steady_clock::now();
  Eigen::VectorXd shift(ctx.fit.jacobian.cols());
  if (how == Propagation::kIterated) {
    if (const auto failure = iterate(ctx, unmoved, moved, shift)) {
      notes.push_back(
          fmt::format("{}: the fit's linearised steps with it moved by u failed ({}); left out",
                      influence.name, *failure));
      return std::nullopt;
    }
  } else if (how == Propagation::kLinearised) {
    if (!linearisedShift(ctx, moved, shift)) {
      notes.push_back(
          fmt::format("{}: the radiographs with it moved by u could not be simulated; left out",
                      influence.name));
      return std::nullopt;
    }
  } else if (!reSolvedShift(ctx, unmoved, moved, shift)) {
    notes.push_back(fmt::format(
        "{}: the fit could not be solved again with it moved by u; left out", influence.name));
    return std::nullopt;
  }
  influence.delta_theta = ctx.covariance.project * shift;
  spdlog::debug(
      "uncertainty: {} {} in {:.2f} s", influence.name,
      how == Propagation::kLinearised ? "linearised"
      : how == Propagation::kIterated ? "iterated"
                                      : "solved again",
      std::chrono::duration<double>(std::chrono::steady_clock::now() - influence_start).count());
  return influence;
}

}  // namespace

int resolveLevel(const ForwardModel& model, const LinearizedFit& fit) {
  return std::max(fit.level, model.levelForWidth(kResolveWidthPx));
}

// The re-solves take their Jacobian as the schedule's least-squares stage
// does: from the render with derivatives (reused between iterations:
// least_squares.cpp) where it does, else by forward differences (1 + n
// renders).
JacobianKind reSolveJacobian(const ForwardModel& model) {
  return leastSquaresStage(model, scheduleFor(model.job().schedule)).render_derivatives
             ? JacobianKind::kRenderDerivatives
             : JacobianKind::kForwardDifferences;
}

std::vector<Influence> propagateInfluences(const FitAtSolution& ctx,
                                           const std::vector<InfluenceMove>& moves,
                                           std::vector<std::string>& notes,
                                           std::vector<std::string>& failed) {
  UnmovedModel unmoved;
  unmoved.iterates.emplace_back(ctx.theta.begin(), ctx.theta.end());
  std::vector<Influence> influences;
  const MeasurementInputs& inputs = ctx.model.inputs();
  for (const InfluenceMove& move : moves) {
    if (!move.left_out.empty()) {
      notes.push_back(move.left_out);
      continue;
    }
    std::optional<MeasurementInputs> changed;  // the model below keeps a reference to it
    if (move.change) {
      changed = inputs;
      move.change(*changed, 1.0);
    }
    ForwardModel moved(changed ? *changed : inputs,
                       move.curve ? *move.curve : ctx.model.material());
    moved.setEdgeSamples(ctx.model.edgeSamples());
    if (auto influence = propagateInfluence(ctx, unmoved, moved, move.influence, move.how, notes)) {
      influence->delta_theta *= move.scale;
      influences.push_back(std::move(*influence));
    } else
      failed.push_back(move.influence.name);
  }
  return influences;
}

}  // namespace xgauge::budget_internal
