#include "xgauge/optimize/minimize.h"

#include "xgauge/core/error.h"

#include <fmt/ranges.h>
#include <tbb/parallel_for.h>
#include <nlopt.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <exception>
#include <limits>
#include <optional>

namespace xgauge {
namespace {

using Clock = std::chrono::steady_clock;
using Termination = OptimizeResult::Termination;
constexpr double kInf = std::numeric_limits<double>::infinity();
// Smallest first step of a restart, as a fraction of the range: far below any
// useful precision, far above where NLopt's steps would underflow.
constexpr double kMinStep = 1e-12;

constexpr std::array<std::pair<Method, std::string_view>, 6> kMethodNames{{
    {Method::kUniformSampling, "uniform"},
    {Method::kHillClimbing, "hill_climb"},
    {Method::kNelderMead, "nelder_mead"},
    {Method::kBobyqa, "bobyqa"},
    {Method::kCobyla, "cobyla"},
    {Method::kDirect, "direct"},
}};

// Every call of f goes through here: maps unit coordinates to x, counts
// calls, enforces both budgets and keeps the best point seen.
class Evaluator {
 public:
  Evaluator(const Objective& objective, const OptimizeOptions& options, Clock::time_point t0)
      : objective_(objective),
        max_evaluations_(options.max_evaluations),
        deadline_(options.max_seconds > 0
                      ? std::optional(t0 + std::chrono::duration_cast<Clock::duration>(
                                               std::chrono::duration<double>(options.max_seconds)))
                      : std::nullopt),
        x_(objective.dimension()) {}

  // Whether one more call of f is allowed; once not, stopReason() says why.
  bool canEvaluate() {
    if (evaluations_ >= max_evaluations_) {
      stop_ = Termination::kEvaluationBudget;
      return false;
    }
    if (timeUp()) {
      stop_ = Termination::kTimeBudget;
      return false;
    }
    return true;
  }

  // f at the unit point u (clamped into [0, 1]^n), or nullopt when the budget
  // is used. The best point's value is reused without calling f: the NLopt
  // methods evaluate their start point, which on every (re)start is the best.
  std::optional<double> evaluate(std::span<const double> u) {
    if (evaluations_ > 0 && std::ranges::equal(u, best_u_)) return best_value_;
    if (!canEvaluate()) return std::nullopt;
    toReal(u, x_);
    const double value = call(x_);
    record(u, value);
    return value;
  }

  // f at x (real coordinates) without the bookkeeping (see record()); const,
  // so parallel sampling can call it from several threads.
  double call(std::span<const double> x) const {
    const double value = objective_.f(x);
    if (std::isnan(value) || value == -kInf)
      fail("the objective returned {} at x = [{}]; it must return a finite value or +inf", value,
           fmt::join(x, ", "));
    return value;
  }

  // Counts one call of f made by call(); keeps the first of equal values.
  void record(std::span<const double> u, double value) {
    ++evaluations_;
    if (evaluations_ == 1 || value < best_value_) {
      best_u_.assign(u.begin(), u.end());
      for (double& c : best_u_) c = std::clamp(c, 0.0, 1.0);
      best_value_ = value;
    }
  }

  // x_i = lower_i + u_i (upper_i - lower_i), clamped so that rounding never
  // leaves the box.
  void toReal(std::span<const double> u, std::span<double> x) const {
    for (size_t i = 0; i < x.size(); ++i) {
      const double lo = objective_.lower[i], hi = objective_.upper[i];
      x[i] = std::clamp(lo + std::clamp(u[i], 0.0, 1.0) * (hi - lo), lo, hi);
    }
  }

  // Thread-safe, for parallel sampling.
  bool timeUp() const { return deadline_ && Clock::now() >= *deadline_; }
  int evaluations() const { return evaluations_; }
  int remaining() const { return max_evaluations_ - evaluations_; }
  double secondsLeft() const {
    return deadline_ ? std::chrono::duration<double>(*deadline_ - Clock::now()).count() : 0.0;
  }
  bool hasDeadline() const { return deadline_.has_value(); }
  Termination stopReason() const { return stop_; }
  const std::vector<double>& bestU() const { return best_u_; }
  double bestValue() const { return best_value_; }

 private:
  const Objective& objective_;
  int max_evaluations_;
  std::optional<Clock::time_point> deadline_;
  std::vector<double> x_;
  int evaluations_ = 0;
  std::vector<double> best_u_;
  double best_value_ = kInf;
  Termination stop_ = Termination::kEvaluationBudget;
};

// How one run of a method (one start or restart) ended.
struct RunEnd {
  Termination termination;
  std::string reason;
};

RunEnd budgetEnd(const Evaluator& ev) {
  return ev.stopReason() == Termination::kTimeBudget
             ? RunEnd{Termination::kTimeBudget, "time budget used"}
             : RunEnd{Termination::kEvaluationBudget, "evaluation budget used"};
}

// 64-bit SplitMix (Steele et al. 2014): a well-mixed value per (seed, index).
uint64_t splitMix64(uint64_t z) {
  z += 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// Point k >= 1 of Roberts' R_n sequence: u_i = frac(shift_i + k alpha_i) with
// alpha_i = phi^-(i+1), phi the positive root of phi^(n+1) = phi + 1 (the
// generalised golden ratio). A Kronecker lattice with the lowest known
// discrepancy among the simple ones, no prime bases to run out of in 30-D.
// The shift (a Cranley-Patterson rotation) comes from the seed.
class RSequence {
 public:
  RSequence(size_t n, uint64_t seed) : alpha_(n), shift_(n) {
    double phi = 2.0;
    for (int iter = 0; iter < 60; ++iter)
      phi = std::pow(1.0 + phi, 1.0 / static_cast<double>(n + 1));
    for (size_t i = 0; i < n; ++i) {
      alpha_[i] = std::pow(phi, -static_cast<double>(i + 1));
      shift_[i] = static_cast<double>(splitMix64(splitMix64(seed) + i) >> 11) * 0x1.0p-53;
    }
  }
  void point(int64_t k, std::span<double> u) const {
    for (size_t i = 0; i < u.size(); ++i) {
      const double v = shift_[i] + static_cast<double>(k) * alpha_[i];
      u[i] = v - std::floor(v);
    }
  }

 private:
  std::vector<double> alpha_, shift_;
};

RunEnd uniformSampling(const Objective& objective, const OptimizeOptions& options, Evaluator& ev) {
  const size_t n = objective.dimension();
  const RSequence sequence(n, options.seed);
  const int count = std::min(options.sampling_points, ev.remaining());
  std::vector<double> u(n);
  if (!options.parallel_evaluations) {
    for (int k = 1; k <= count; ++k) {
      sequence.point(k, u);
      if (!ev.evaluate(u)) return budgetEnd(ev);
    }
  } else {
    // Evaluate in parallel, then record in index order: the same best point,
    // ties included, as the sequential loop.
    std::vector<double> values(static_cast<size_t>(count), std::nan(""));
    tbb::parallel_for(0, count, [&](int k) {
      if (ev.timeUp()) return;
      std::vector<double> uk(n), xk(n);
      sequence.point(k + 1, uk);
      ev.toReal(uk, xk);
      values[static_cast<size_t>(k)] = ev.call(xk);
    });
    bool all = true;
    for (int k = 0; k < count; ++k) {
      const double value = values[static_cast<size_t>(k)];
      all = all && !std::isnan(value);  // NaN: skipped for time (f never returns NaN)
      if (std::isnan(value)) continue;
      sequence.point(k + 1, u);
      ev.record(u, value);
    }
    if (!all) return {Termination::kTimeBudget, "time budget used"};
  }
  if (count < options.sampling_points)
    return {Termination::kEvaluationBudget, "evaluation budget used"};
  return {Termination::kConverged, fmt::format("all {} sample points evaluated", count)};
}

// Compass search (Kolda, Lewis & Torczon 2003) from the best point, with
// `step` in unit coordinates.
RunEnd compassSearch(const OptimizeOptions& options, Evaluator& ev, std::vector<double> step) {
  std::vector<double> u = ev.bestU(), trial;
  double fu = ev.bestValue();
  while (std::ranges::any_of(step, [&](double s) { return s >= options.x_tolerance; })) {
    bool improved = false, moved = false;
    for (size_t i = 0; i < u.size(); ++i) {
      for (const double sign : {1.0, -1.0}) {
        trial = u;
        trial[i] = std::clamp(u[i] + sign * step[i], 0.0, 1.0);
        if (trial[i] == u[i]) continue;  // on the bound, or the step is below resolution
        moved = true;
        const auto ft = ev.evaluate(trial);
        if (!ft) return budgetEnd(ev);
        if (*ft < fu) {
          u = trial;
          fu = *ft;
          improved = true;
          break;
        }
      }
    }
    if (!moved) return {Termination::kStoppedEarly, "steps below floating-point resolution"};
    if (!improved)
      for (double& s : step) s *= 0.5;
  }
  return {Termination::kConverged, "every step below x_tolerance"};
}

nlopt::algorithm nloptAlgorithm(Method method) {
  switch (method) {
    case Method::kNelderMead:
      return nlopt::LN_NELDERMEAD;
    case Method::kBobyqa:
      return nlopt::LN_BOBYQA;
    case Method::kCobyla:
      return nlopt::LN_COBYLA;
    case Method::kDirect:
      return nlopt::GN_DIRECT_L;
    default:
      XG_CHECK(false, "{} is not an NLopt method", methodName(method));
  }
  return nlopt::LN_NELDERMEAD;
}

struct NloptContext {
  Evaluator* ev;
  nlopt::opt* opt;
  std::exception_ptr error;  // thrown by f: NLopt's C++ wrapper would swallow it
  bool nan_point = false;    // NLopt asked for f at NaN (COBYLA after +inf values)
  double largest_finite = 0.0;
};

// What an NLopt method is shown for an infeasible point (f = +inf): its
// quadratic or simplex models need finite values, so a value worse than every
// feasible one seen in this run, in the same units. The Evaluator keeps the
// true +inf, so the stand-in can never be returned as the best value.
double infeasibleStandIn(const NloptContext& context) {
  return 10.0 * std::max(1.0, context.largest_finite);
}

double nloptObjective(unsigned n, const double* u, double* /*grad: derivative-free*/, void* data) {
  auto& context = *static_cast<NloptContext*>(data);
  context.nan_point = std::any_of(u, u + n, [](double c) { return std::isnan(c); });
  if (!context.nan_point) {
    try {
      if (const auto value = context.ev->evaluate({u, n})) {
        if (*value == kInf) return infeasibleStandIn(context);
        context.largest_finite = std::max(context.largest_finite, std::abs(*value));
        return *value;
      }
    } catch (...) {
      context.error = std::current_exception();
    }
  }
  context.opt->force_stop();
  return HUGE_VAL;
}

// One NLopt run in unit coordinates from the best point (DIRECT ignores it).
RunEnd runNlopt(Method method, const OptimizeOptions& options, Evaluator& ev,
                const std::vector<double>& step) {
  nlopt::opt opt(nloptAlgorithm(method), static_cast<unsigned>(step.size()));
  NloptContext context{&ev, &opt, nullptr};
  RunEnd end{Termination::kFailure, ""};
  try {
    opt.set_lower_bounds(0.0);
    opt.set_upper_bounds(1.0);
    opt.set_ftol_rel(options.relative_tolerance);
    opt.set_xtol_abs(options.x_tolerance);
    // Stop NLopt near the budget; the evaluator enforces it exactly. NLopt
    // also counts its calls at the cached best point, hence the + 1.
    opt.set_maxeval(ev.remaining() + 1);
    if (ev.hasDeadline()) opt.set_maxtime(std::max(ev.secondsLeft(), 1e-6));
    if (isLocal(method)) opt.set_initial_step(step);
    opt.set_min_objective(nloptObjective, &context);
    std::vector<double> u = ev.bestU();
    double value = 0.0;
    switch (opt.optimize(u, value)) {
      case nlopt::SUCCESS:
        end = {Termination::kConverged, "NLopt success"};
        break;
      case nlopt::STOPVAL_REACHED:
        end = {Termination::kConverged, "stop value reached"};
        break;
      case nlopt::FTOL_REACHED:
        end = {Termination::kConverged, "relative change of f below relative_tolerance"};
        break;
      case nlopt::XTOL_REACHED:
        end = {Termination::kConverged, "step below x_tolerance"};
        break;
      case nlopt::MAXEVAL_REACHED:
        // With budget left, NLopt's count ran out on repeated (cached) points:
        // DIRECT at floating-point resolution does that with x_tolerance = 0.
        end = ev.remaining() > 0
                  ? RunEnd{Termination::kStoppedEarly, "NLopt repeats points: no progress left"}
                  : RunEnd{Termination::kEvaluationBudget, "evaluation budget used"};
        break;
      case nlopt::MAXTIME_REACHED:
        end = {Termination::kTimeBudget, "time budget used"};
        break;
      default:
        end = {Termination::kFailure, "unexpected NLopt result"};
    }
  } catch (const nlopt::roundoff_limited&) {
    end = {Termination::kStoppedEarly, "NLopt roundoff-limited: no further progress possible"};
  } catch (const nlopt::forced_stop&) {
    end = context.nan_point
              ? RunEnd{Termination::kStoppedEarly, "NLopt asked for f at NaN (degenerate model)"}
              : budgetEnd(ev);
  } catch (const std::exception& e) {  // nlopt's runtime_error, invalid_argument, bad_alloc
    end = {Termination::kFailure, fmt::format("NLopt failed: {}", e.what())};
  }
  if (context.error) std::rethrow_exception(context.error);
  return end;
}

void checkVector(const std::vector<double>& v, size_t n, std::string_view name) {
  if (v.size() != n) fail("Objective.{} has {} entries, the bounds have {}", name, v.size(), n);
}

}  // namespace

std::string_view methodName(Method method) {
  for (const auto& [m, name] : kMethodNames)
    if (m == method) return name;
  XG_CHECK(false, "unknown Method {}", static_cast<int>(method));
  return {};
}

Method methodFromName(std::string_view name) {
  for (const auto& [m, known] : kMethodNames)
    if (known == name) return m;
  std::vector<std::string_view> names;
  for (const auto& entry : kMethodNames) names.push_back(entry.second);
  fail("unknown optimisation method '{}' (known: {})", name, fmt::join(names, ", "));
}

bool isLocal(Method method) {
  return method != Method::kUniformSampling && method != Method::kDirect;
}

std::string_view terminationName(Termination termination) {
  switch (termination) {
    case Termination::kConverged:
      return "converged";
    case Termination::kEvaluationBudget:
      return "evaluation_budget";
    case Termination::kTimeBudget:
      return "time_budget";
    case Termination::kStoppedEarly:
      return "stopped_early";
    case Termination::kFailure:
      return "failure";
  }
  return "failure";
}

void Objective::validate() const {
  const size_t n = lower.size();
  if (n == 0) fail("Objective.lower is empty: at least one parameter is needed");
  checkVector(upper, n, "upper");
  if (!start.empty()) checkVector(start, n, "start");
  if (!initial_step.empty()) checkVector(initial_step, n, "initial_step");
  if (!f) fail("Objective.f is empty");
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(lower[i]) || !std::isfinite(upper[i]) || !(lower[i] < upper[i]))
      fail("Objective bounds of parameter {}: need finite lower < upper, got [{}, {}]", i, lower[i],
           upper[i]);
    if (!start.empty() && !(start[i] >= lower[i] && start[i] <= upper[i]))
      fail("Objective.start[{}] = {} is outside [{}, {}]", i, start[i], lower[i], upper[i]);
    if (!initial_step.empty() && !(initial_step[i] > 0 && initial_step[i] <= upper[i] - lower[i]))
      fail("Objective.initial_step[{}] = {} must be in (0, {}] (the range)", i, initial_step[i],
           upper[i] - lower[i]);
  }
}

void OptimizeOptions::validate() const {
  if (!std::ranges::any_of(kMethodNames, [&](const auto& e) { return e.first == method; }))
    fail("OptimizeOptions.method: unknown value {}", static_cast<int>(method));
  if (max_evaluations < 1)
    fail("OptimizeOptions.max_evaluations must be >= 1, got {}", max_evaluations);
  if (!(max_seconds >= 0 && std::isfinite(max_seconds)))
    fail("OptimizeOptions.max_seconds must be finite and >= 0 (0 = none), got {}", max_seconds);
  if (!(relative_tolerance >= 0 && std::isfinite(relative_tolerance)))
    fail("OptimizeOptions.relative_tolerance must be finite and >= 0, got {}", relative_tolerance);
  if (!(x_tolerance >= 0 && x_tolerance < 1))
    fail("OptimizeOptions.x_tolerance must be in [0, 1) (a fraction of each range), got {}",
         x_tolerance);
  if (max_restarts < 0) fail("OptimizeOptions.max_restarts must be >= 0, got {}", max_restarts);
  if (sampling_points < 1)
    fail("OptimizeOptions.sampling_points must be >= 1, got {}", sampling_points);
}

OptimizeResult minimize(const Objective& objective, const OptimizeOptions& options) {
  objective.validate();
  options.validate();
  const auto t0 = Clock::now();
  const size_t n = objective.dimension();
  Evaluator ev(objective, options, t0);

  // The start point first, for every method and whatever the time budget:
  // the result is never worse than the start.
  std::vector<double> u(n, 0.5), step(n, 0.1), x(n);
  for (size_t i = 0; i < n; ++i) {
    const double range = objective.upper[i] - objective.lower[i];
    if (!objective.start.empty())
      u[i] = std::clamp((objective.start[i] - objective.lower[i]) / range, 0.0, 1.0);
    // BOBYQA needs 2 rhobeg <= the range; steps beyond half the box help no method.
    if (!objective.initial_step.empty()) step[i] = std::min(objective.initial_step[i] / range, 0.5);
  }
  ev.toReal(u, x);
  ev.record(u, ev.call(x));

  std::optional<RunEnd> end;
  OptimizeResult result;
  while (!end) {
    if (!ev.canEvaluate()) {
      end = budgetEnd(ev);
      break;
    }
    switch (options.method) {
      case Method::kUniformSampling:
        end = uniformSampling(objective, options, ev);
        break;
      case Method::kHillClimbing:
        end = compassSearch(options, ev, step);
        break;
      default:
        end = runNlopt(options.method, options, ev, step);
    }
    // Thesis 3.8 (docs/method.md): restart a local method that stopped early
    // from its best point, with half the previous first step, while budget
    // remains and the step is still above x_tolerance (else the restart could
    // not move).
    const bool early = end->termination == Termination::kConverged ||
                       end->termination == Termination::kStoppedEarly;
    const double min_step = std::max(options.x_tolerance, kMinStep);
    if (isLocal(options.method) && early && result.restarts < options.max_restarts &&
        std::ranges::any_of(step, [&](double s) { return 0.5 * s >= min_step; }) &&
        ev.canEvaluate()) {
      ++result.restarts;
      for (double& s : step) s *= 0.5;
      end.reset();
    }
  }

  result.x = std::move(x);
  ev.toReal(ev.bestU(), result.x);
  result.value = ev.bestValue();
  result.evaluations = ev.evaluations();
  result.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  if (result.value == kInf)
    end = {Termination::kFailure, "no feasible point: f was +inf wherever it was evaluated"};
  result.termination = end->termination;
  result.message = fmt::format("{}: {} ({}) after {} evaluations, {} restarts; best f = {:.10g}",
                               methodName(options.method), terminationName(end->termination),
                               end->reason, result.evaluations, result.restarts, result.value);
  return result;
}

}  // namespace xgauge
