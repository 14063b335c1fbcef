// Box-constrained, derivative-free minimisation: the one interface every
// fitting stage of xgauge uses (thesis 3.8, docs/method.md). The objective is
// a loss between simulated and measured radiographs: no derivatives, a few ms
// per evaluation, noisy at about 1e-6, 1 to 30 parameters.
//
//   minimize f(x)  subject to  lower <= x <= upper.
//
// Contract of minimize():
// - The best point ever evaluated is returned with its value, whatever the
//   method reports itself (with a noisy f a method's own answer can be worse
//   than a point it passed through). So result.value <= every value f
//   returned during the run, and result.value <= f(start) for every method
//   (each evaluates the start point).
// - At most max_evaluations calls of f, counted by minimize itself (NLopt's
//   own count is not trusted); a run that ends on the budget used them all.
//   The start point is always evaluated, even with an expired time budget.
// - Methods work in normalised coordinates u in [0, 1]^n,
//   x_i = lower_i + u_i (upper_i - lower_i), so steps and tolerances are
//   fractions of each coordinate's range, whatever its unit.
// - Not converging is a result (OptimizeResult::termination and message),
//   never an exception. Exceptions come only from bad input (Error, thrown
//   before f is first called) and from f itself, which propagate unchanged.
// - Deterministic: the same objective, options and seed give the same
//   result, at any thread count. Only max_seconds makes a run depend on
//   timing.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace xgauge {

// f(x) for x within [lower, upper]; all vectors have the objective's
// dimension n >= 1.
struct Objective {
  std::vector<double> lower, upper;  // finite bounds, lower_i < upper_i
  std::vector<double> start;         // within the bounds; empty = centre of the box
  // Scale of the first moves per coordinate, in the units of x, in
  // (0, upper_i - lower_i]; empty = 10 % of each range. Local methods only.
  std::vector<double> initial_step;
  // Called with x of size n, always within the bounds. Returns a finite value,
  // or +inf where x is infeasible (a NaN or -inf is an Error). The NLopt
  // methods need finite values: they are shown 10 max(1, the largest |f| seen
  // in the run) for an infeasible point, worse than every feasible one; the
  // result keeps the true +inf. May throw; the
  // exception leaves minimize() unchanged. Must be thread-safe when
  // OptimizeOptions::parallel_evaluations is set.
  std::function<double(std::span<const double> x)> f;

  size_t dimension() const { return lower.size(); }
  // Throws Error naming the field that breaks the contract above.
  void validate() const;
};

enum class Method {
  // Global: the start point and the first sampling_points points of a
  // low-discrepancy sequence over the box (Roberts' R_n sequence, shifted by
  // the seed); the best one wins, ties to the lowest index.
  kUniformSampling,
  // Local: compass search. Tries +/- step along each coordinate in turn,
  // moves to the first improvement, halves every step after a sweep without
  // one, converges when every step is below x_tolerance.
  kHillClimbing,
  kNelderMead,  // local: NLopt LN_NELDERMEAD (bounds by projection)
  kBobyqa,      // local: NLopt LN_BOBYQA, Powell's quadratic trust region
  kCobyla,      // local: NLopt LN_COBYLA, Powell's linear trust region
  // Global: NLopt GN_DIRECT_L (locally biased DIRECT, deterministic). Divides
  // the box; ignores initial_step (the start point is still evaluated first).
  kDirect,
};

// "uniform", "hill_climb", "nelder_mead", "bobyqa", "cobyla", "direct".
std::string_view methodName(Method method);
// Inverse of methodName; an unknown name throws Error listing the known ones.
Method methodFromName(std::string_view name);
// True for the methods that start from a point and restart (thesis 3.8).
bool isLocal(Method method);

struct OptimizeOptions {
  Method method = Method::kNelderMead;
  // Hard limit on calls of f, the start point included; >= 1. The main
  // stopping rule of every stage (thesis 3.8: stop by iteration budget).
  int max_evaluations = 1000;
  // Wall-clock limit in seconds; 0 = none. Checked before each evaluation,
  // so a run may overshoot by one evaluation.
  double max_seconds = 0.0;
  // NLopt methods converge when a step improves f by less than this times |f|
  // (ftol_rel; DIRECT: an improvement of its best value); 0 = off. Not used by
  // compass search or uniform sampling.
  double relative_tolerance = 1e-9;
  // Local methods converge when a step moves every coordinate by less than
  // this fraction of its range (xtol_abs in normalised coordinates); DIRECT
  // when the rectangle it divides is this small (rarely before the budget);
  // restarts stop once their first step would be below it; 0 = off. In [0, 1).
  double x_tolerance = 1e-7;
  // A local method that stops before the budget (converged or stopped early)
  // is restarted from the best point with half its previous initial step, at
  // most this many times, while budget remains; >= 0. Ignored by the global
  // methods.
  int max_restarts = 3;
  // Shift of the uniform-sampling sequence. The NLopt methods used are
  // deterministic and do not use it.
  uint64_t seed = 0;
  // Points of the low-discrepancy sequence for kUniformSampling (m, thesis:
  // 5000), evaluated in addition to the start point; >= 1.
  int sampling_points = 5000;
  // kUniformSampling only: evaluate the points with tbb::parallel_for. The
  // result is identical to the sequential one (the best is picked in index
  // order afterwards), but f must then be thread-safe. With max_seconds the
  // set of points evaluated in time may differ.
  bool parallel_evaluations = false;

  // Throws Error naming the first invalid field.
  void validate() const;
};

struct OptimizeResult {
  enum class Termination {
    kConverged,         // tolerances met (uniform sampling: all points evaluated)
    kEvaluationBudget,  // max_evaluations used
    kTimeBudget,        // max_seconds passed
    kStoppedEarly,      // the method could not progress (e.g. NLopt roundoff-limited)
    // The method failed (NLopt error), or f was +inf at every point
    // evaluated; x is still the best point seen.
    kFailure,
  };

  std::vector<double> x;                            // best point evaluated, within the bounds
  double value = 0.0;                               // f(x), <= every value f returned in this run
  int evaluations = 0;                              // calls of f, <= max_evaluations
  int restarts = 0;                                 // restarts of a local method
  double seconds = 0.0;                             // wall-clock time of minimize()
  Termination termination = Termination::kFailure;  // of the last (re)start
  std::string message;  // human-readable: method, why it stopped, counts
};

// "converged", "evaluation_budget", "time_budget", "stopped_early", "failure".
std::string_view terminationName(OptimizeResult::Termination termination);

// Validates both arguments (Error), then minimises; see the contract at the
// top of this header.
OptimizeResult minimize(const Objective& objective, const OptimizeOptions& options);

}  // namespace xgauge
