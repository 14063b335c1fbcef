#include "xgauge/optimize/minimize.h"

#include "xgauge/core/error.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <thread>

namespace xgauge {
namespace {

using Termination = OptimizeResult::Termination;

constexpr Method kAllMethods[] = {Method::kUniformSampling, Method::kHillClimbing,
                                  Method::kNelderMead,      Method::kBobyqa,
                                  Method::kCobyla,          Method::kDirect};
constexpr Method kNloptLocal[] = {Method::kNelderMead, Method::kBobyqa, Method::kCobyla};

// A tolerance on |x - x*| as a fraction of each range: global methods only
// get close (uniform sampling: 5000 points in 3-D are ~0.06 apart).
double tolerance(Method method) {
  switch (method) {
    case Method::kUniformSampling:
      return 0.05;
    case Method::kDirect:
      return 1e-3;
    default:
      return 1e-5;
  }
}

// A non-separable quadratic on a box whose coordinates have very different
// scales (so normalisation matters); minimum 0 at `centre`.
Objective shiftedQuadratic(const std::vector<double>& centre) {
  Objective o;
  o.lower = {-1.0, 0.0, 10.0, -50.0};
  o.upper = {2.0, 100.0, 10.5, 50.0};
  o.lower.resize(centre.size());
  o.upper.resize(centre.size());
  for (size_t i = 0; i < centre.size(); ++i)
    o.start.push_back(o.lower[i] + 0.2 * (o.upper[i] - o.lower[i]));
  o.f = [o, centre](std::span<const double> x) {
    double sum = 0.0, previous = 0.0;
    for (size_t i = 0; i < x.size(); ++i) {
      const double d = (x[i] - centre[i]) / (o.upper[i] - o.lower[i]);
      sum += d * d + 0.5 * d * previous;
      previous = d;
    }
    return sum;
  };
  return o;
}

void expectNear(const OptimizeResult& r, const std::vector<double>& expected, const Objective& o,
                double tol) {
  ASSERT_EQ(r.x.size(), expected.size());
  for (size_t i = 0; i < expected.size(); ++i)
    EXPECT_NEAR(r.x[i], expected[i], tol * (o.upper[i] - o.lower[i])) << "coordinate " << i;
}

OptimizeOptions optionsFor(Method method, int budget = 4000) {
  OptimizeOptions options;
  options.method = method;
  options.max_evaluations = budget;
  return options;
}

TEST(Minimize, MethodNamesRoundTrip) {
  for (Method m : kAllMethods) EXPECT_EQ(methodFromName(methodName(m)), m);
  try {
    methodFromName("simplex");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("nelder_mead"), std::string::npos) << e.what();
  }
}

class EveryMethod : public testing::TestWithParam<Method> {};

TEST_P(EveryMethod, ShiftedQuadraticInside) {
  const Method method = GetParam();
  for (const std::vector<double>& centre :
       {std::vector<double>{0.3, 61.8}, std::vector<double>{0.3, 61.8, 10.123},
        std::vector<double>{0.3, 61.8, 10.123, -12.5}}) {
    if (method == Method::kUniformSampling && centre.size() > 3) continue;  // m = 5000 too sparse
    const Objective o = shiftedQuadratic(centre);
    const auto r =
        minimize(o, optionsFor(method, method == Method::kUniformSampling ? 6000 : 4000));
    SCOPED_TRACE(r.message);
    expectNear(r, centre, o, tolerance(method));
    EXPECT_EQ(r.value, o.f(r.x));
    EXPECT_LE(r.evaluations, 6000);
  }
}

TEST_P(EveryMethod, OneDimension) {
  const Method method = GetParam();
  const Objective o = shiftedQuadratic({0.7});
  const auto r = minimize(o, optionsFor(method));
  SCOPED_TRACE(r.message);
  expectNear(r, {0.7}, o, tolerance(method) / 10);
}

TEST_P(EveryMethod, MinimumOnTheBoundary) {
  const Method method = GetParam();
  // Unconstrained minimum at (2.6, -20, ...), outside the box: the
  // constrained one has x0 = 2 (active bound) and x1 = 0 (active bound).
  Objective o = shiftedQuadratic({2.6, -20.0});
  const auto r = minimize(o, optionsFor(method));
  SCOPED_TRACE(r.message);
  EXPECT_NEAR(r.x[0], 2.0, 3 * tolerance(method) * 3.0);
  EXPECT_NEAR(r.x[1], 0.0, 3 * tolerance(method) * 100.0);
  EXPECT_GE(r.x[0], o.lower[0]);
  EXPECT_LE(r.x[0], o.upper[0]);
  EXPECT_GE(r.x[1], o.lower[1]);
}

// Deterministic pseudo-noise of amplitude 1e-6 from the bits of x: the same
// x always gives the same value, neighbouring x look random.
double noise(std::span<const double> x) {
  uint64_t h = 0x9e3779b97f4a7c15ULL;
  for (double v : x) {
    h ^= std::bit_cast<uint64_t>(v);
    h *= 0xbf58476d1ce4e5b9ULL;
    h ^= h >> 31;
  }
  return 1e-6 * (static_cast<double>(h >> 11) * 0x1.0p-53 - 0.5);
}

TEST_P(EveryMethod, NoisyReturnsTheBestValueSeen) {
  const Method method = GetParam();
  Objective o = shiftedQuadratic({0.3, 61.8, 10.123});
  std::vector<double> seen;
  o.f = [f = o.f, &seen](std::span<const double> x) {
    seen.push_back(f(x) + noise(x));
    return seen.back();
  };
  const auto r = minimize(o, optionsFor(method, 3000));
  SCOPED_TRACE(r.message);
  ASSERT_EQ(static_cast<size_t>(r.evaluations), seen.size());
  EXPECT_EQ(r.value, *std::ranges::min_element(seen));
  for (double v : seen) EXPECT_LE(r.value, v);
  EXPECT_EQ(r.value, o.f(r.x));  // the value belongs to the point returned
  seen.clear();
  if (method != Method::kUniformSampling)
    expectNear(r, {0.3, 61.8, 10.123}, o, std::max(tolerance(method), 1e-3));
}

TEST_P(EveryMethod, EvaluationBudgetIsExact) {
  const Method method = GetParam();
  Objective o = shiftedQuadratic({0.3, 61.8, 10.123, -12.5});
  int calls = 0;
  o.f = [f = o.f, &calls](std::span<const double> x) {
    ++calls;
    return f(x);
  };
  for (const int budget : {1, 2, 37}) {
    calls = 0;
    OptimizeOptions options = optionsFor(method, budget);
    options.x_tolerance = 0;
    options.relative_tolerance = 0;
    const auto r = minimize(o, options);
    SCOPED_TRACE(r.message);
    EXPECT_EQ(calls, budget);
    EXPECT_EQ(r.evaluations, budget);
    EXPECT_EQ(r.termination, Termination::kEvaluationBudget);
    EXPECT_NE(r.message.find("evaluation_budget"), std::string::npos);
  }
}

TEST_P(EveryMethod, ObjectiveExceptionsPropagateUnchanged) {
  const Method method = GetParam();
  Objective o = shiftedQuadratic({0.3, 61.8, 10.123});
  int calls = 0;
  o.f = [f = o.f, &calls](std::span<const double> x) {
    if (++calls == 5) fail("bad part model at call {}", calls);
    return f(x);
  };
  try {
    minimize(o, optionsFor(method));
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.message(), "bad part model at call 5");
  }
  struct Custom {};
  o.f = [](std::span<const double>) -> double { throw Custom{}; };
  EXPECT_THROW(minimize(o, optionsFor(method)), Custom);
}

TEST(Minimize, ParallelSamplingPropagatesExceptions) {
  Objective o = shiftedQuadratic({0.3, 61.8});
  o.f = [](std::span<const double> x) {
    if (x[0] > 1.5) fail("bad part model");
    return 1.0;
  };
  OptimizeOptions options = optionsFor(Method::kUniformSampling, 6000);
  options.parallel_evaluations = true;
  EXPECT_THROW(minimize(o, options), Error);
}

TEST_P(EveryMethod, RejectsNanFromTheObjective) {
  Objective o = shiftedQuadratic({0.3, 61.8});
  o.f = [](std::span<const double> x) { return x[0] > 0.2 ? std::nan("") : 1.0; };
  o.start = {0.0, 50.0};
  EXPECT_THROW(minimize(o, optionsFor(GetParam())), Error);
}

TEST_P(EveryMethod, InfeasibleRegionIsAvoided) {
  const Method method = GetParam();
  Objective o = shiftedQuadratic({0.3, 61.8});
  o.f = [f = o.f](std::span<const double> x) {
    return x[1] > 70.0 ? std::numeric_limits<double>::infinity() : f(x);
  };
  const auto r = minimize(o, optionsFor(method));
  SCOPED_TRACE(r.message);
  EXPECT_LE(r.x[1], 70.0);
  expectNear(r, {0.3, 61.8}, o, std::max(tolerance(method), 1e-3));
}

TEST_P(EveryMethod, MinimumBeyondTheInfeasibleBorderIsApproached) {
  // The unconstrained minimum (x1 = 75) lies where f is +inf (x1 > 70): the
  // NLopt methods see a finite stand-in there (worse than every feasible
  // value) and still walk up to the border; the result is never the stand-in.
  const Method method = GetParam();
  Objective o = shiftedQuadratic({0.3, 75.0});
  o.f = [f = o.f](std::span<const double> x) {
    return x[1] > 70.0 ? std::numeric_limits<double>::infinity() : f(x);
  };
  o.start = {0.0, 50.0};
  const auto r = minimize(o, optionsFor(method));
  SCOPED_TRACE(r.message);
  EXPECT_LE(r.x[1], 70.0);
  EXPECT_GT(r.x[1], isLocal(method) ? 69.5 : 66.0);  // the global methods divide coarsely
  EXPECT_EQ(r.value, o.f(r.x));
}

TEST_P(EveryMethod, NoFeasiblePointIsAFailureResult) {
  Objective o = shiftedQuadratic({0.3, 61.8});
  o.f = [](std::span<const double>) { return std::numeric_limits<double>::infinity(); };
  const auto r = minimize(o, optionsFor(GetParam(), 200));
  SCOPED_TRACE(r.message);
  EXPECT_EQ(r.termination, Termination::kFailure);
  EXPECT_EQ(r.value, std::numeric_limits<double>::infinity());
  EXPECT_LE(r.evaluations, 200);
}

INSTANTIATE_TEST_SUITE_P(Minimize, EveryMethod, testing::ValuesIn(kAllMethods),
                         [](const auto& p) { return std::string(methodName(p.param)); });

double rosenbrock(std::span<const double> x) {
  return 100 * std::pow(x[1] - x[0] * x[0], 2) + std::pow(1 - x[0], 2);
}

TEST(Minimize, RosenbrockLocalMethods) {
  Objective o;
  o.lower = {-2.0, -1.0};
  o.upper = {2.0, 3.0};
  o.start = {-1.2, 1.0};
  o.f = rosenbrock;
  for (Method method : kNloptLocal) {
    OptimizeOptions options = optionsFor(method, 20000);
    options.relative_tolerance = 1e-12;
    options.x_tolerance = 1e-9;
    const auto r = minimize(o, options);
    SCOPED_TRACE(r.message);
    EXPECT_NEAR(r.x[0], 1.0, 1e-4);
    EXPECT_NEAR(r.x[1], 1.0, 1e-4);
  }
}

TEST(Minimize, RestartsHelpWhenTheFirstRunStopsEarly) {
  Objective o;
  o.lower = {-2.0, -1.0};
  o.upper = {2.0, 3.0};
  o.start = {-1.2, 1.0};
  o.f = rosenbrock;
  // Loose tolerances make the first run stop far from (1, 1) with budget left.
  // `gain`: the factor by which restarts must at least lower the value.
  struct Case {
    Method method;
    double relative_tolerance, x_tolerance, gain;
  };
  for (const Case& c :
       {Case{Method::kNelderMead, 1e-1, 1e-7, 0.5}, Case{Method::kBobyqa, 1e-3, 1e-3, 0.9},
        Case{Method::kCobyla, 1e-2, 0.0, 0.1}}) {
    OptimizeOptions options = optionsFor(c.method, 20000);
    options.relative_tolerance = c.relative_tolerance;
    options.x_tolerance = c.x_tolerance;
    options.max_restarts = 0;
    const auto once = minimize(o, options);
    SCOPED_TRACE(once.message);
    EXPECT_EQ(once.termination, Termination::kConverged);
    EXPECT_EQ(once.restarts, 0);
    EXPECT_GT(once.value, 1e-3);
    options.max_restarts = 10;
    const auto restarted = minimize(o, options);
    SCOPED_TRACE(restarted.message);
    EXPECT_GT(restarted.restarts, 0);
    EXPECT_LE(restarted.restarts, 10);
    EXPECT_LT(restarted.value, c.gain * once.value);
    EXPECT_LT(restarted.evaluations, 20000);
  }
}

TEST(Minimize, RestartsStopAtTheBudgetOrTheTolerance) {
  const Objective o = shiftedQuadratic({0.3, 61.8, 10.123});
  OptimizeOptions options = optionsFor(Method::kHillClimbing, 150);
  options.x_tolerance = 1e-4;
  options.max_restarts = 1000;
  const auto r = minimize(o, options);
  SCOPED_TRACE(r.message);
  EXPECT_GT(r.restarts, 0);
  EXPECT_EQ(r.evaluations, 150);
  EXPECT_EQ(r.termination, Termination::kEvaluationBudget);
  // First steps 0.1, 0.05, 0.025, 0.0125, then 0.00625 < x_tolerance: 3 restarts.
  options.max_evaluations = 100000;
  options.x_tolerance = 1e-2;
  for (Method method : {Method::kHillClimbing, Method::kNelderMead}) {
    options.method = method;
    const auto again = minimize(o, options);
    SCOPED_TRACE(again.message);
    EXPECT_EQ(again.restarts, 3);
    EXPECT_EQ(again.termination, Termination::kConverged);
  }
}

TEST(Minimize, DeterministicForTheSeed) {
  const Objective o = shiftedQuadratic({0.3, 61.8, 10.123});
  for (Method method : kAllMethods) {
    OptimizeOptions options = optionsFor(method, 500);
    options.sampling_points = 400;
    options.seed = 7;
    const auto a = minimize(o, options);
    const auto b = minimize(o, options);
    EXPECT_EQ(a.x, b.x) << methodName(method);
    EXPECT_EQ(a.value, b.value);
    EXPECT_EQ(a.evaluations, b.evaluations);
  }
  OptimizeOptions options = optionsFor(Method::kUniformSampling, 6000);
  options.seed = 7;
  const auto a = minimize(o, options);
  options.seed = 8;
  EXPECT_NE(minimize(o, options).x, a.x);
  options.seed = 7;
  options.parallel_evaluations = true;
  const auto parallel = minimize(o, options);
  EXPECT_EQ(parallel.x, a.x);
  EXPECT_EQ(parallel.value, a.value);
  EXPECT_EQ(parallel.evaluations, a.evaluations);
  EXPECT_EQ(a.evaluations, 5001);
  EXPECT_EQ(a.termination, Termination::kConverged);
}

TEST(Minimize, ParallelTiesGoToTheLowestIndex) {
  // A flat objective: every point ties, so the start point (index 0) wins.
  Objective o = shiftedQuadratic({0.3, 61.8});
  o.f = [](std::span<const double>) { return 1.0; };
  OptimizeOptions options = optionsFor(Method::kUniformSampling, 10000);
  options.parallel_evaluations = true;
  const auto r = minimize(o, options);
  EXPECT_NEAR(r.x[0], o.start[0], 1e-12);
  EXPECT_NEAR(r.x[1], o.start[1], 1e-12);
}

TEST(Minimize, TimeBudget) {
  Objective o = shiftedQuadratic({0.3, 61.8});
  o.f = [f = o.f](std::span<const double> x) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
    return f(x);
  };
  for (Method method : {Method::kUniformSampling, Method::kHillClimbing, Method::kBobyqa}) {
    OptimizeOptions options = optionsFor(method, 100000);
    options.max_seconds = 0.1;
    options.x_tolerance = 0;
    options.relative_tolerance = 0;
    const auto r = minimize(o, options);
    SCOPED_TRACE(r.message);
    EXPECT_EQ(r.termination, Termination::kTimeBudget);
    EXPECT_LT(r.seconds, 0.5);
    EXPECT_LT(r.evaluations, 100);
  }
  // An expired time budget still evaluates the start point.
  OptimizeOptions options = optionsFor(Method::kNelderMead);
  options.max_seconds = 1e-9;
  const auto r = minimize(o, options);
  EXPECT_EQ(r.evaluations, 1);
  EXPECT_EQ(r.termination, Termination::kTimeBudget);
  EXPECT_NEAR(r.x[1], o.start[1], 1e-12);
}

TEST(Minimize, RejectsBadOptions) {
  const Objective o = shiftedQuadratic({0.3, 61.8});
  const auto expectError = [&](OptimizeOptions options, const std::string& field) {
    try {
      minimize(o, options);
      ADD_FAILURE() << "accepted bad " << field;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  OptimizeOptions options;
  EXPECT_NO_THROW(options.validate());
  options.max_evaluations = 0;
  expectError(options, "max_evaluations");
  options = {};
  options.max_seconds = -1;
  expectError(options, "max_seconds");
  options = {};
  options.relative_tolerance = std::nan("");
  expectError(options, "relative_tolerance");
  options = {};
  options.x_tolerance = 1.0;
  expectError(options, "x_tolerance");
  options = {};
  options.max_restarts = -1;
  expectError(options, "max_restarts");
  options = {};
  options.sampling_points = 0;
  expectError(options, "sampling_points");
  options = {};
  options.method = static_cast<Method>(42);
  expectError(options, "method");
}

TEST(Minimize, RejectsBadObjectives) {
  const auto expectError = [](const Objective& o, const std::string& field) {
    try {
      minimize(o, {});
      ADD_FAILURE() << "accepted bad " << field;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  const Objective good = shiftedQuadratic({0.3, 61.8});
  EXPECT_NO_THROW(good.validate());
  Objective o = good;
  o.upper.pop_back();
  expectError(o, "upper");
  o = good;
  o.lower = {};
  expectError(o, "lower");
  o = good;
  o.upper[1] = o.lower[1];
  expectError(o, "bounds of parameter 1");
  o = good;
  o.lower[0] = -std::numeric_limits<double>::infinity();
  expectError(o, "bounds of parameter 0");
  o = good;
  o.start[1] = 101.0;
  expectError(o, "start[1]");
  o = good;
  o.initial_step = {0.1, 0.0};
  expectError(o, "initial_step[1]");
  o = good;
  o.f = nullptr;
  expectError(o, "f");
}

TEST(Minimize, EmptyStartIsTheCentre) {
  Objective o = shiftedQuadratic({0.3, 61.8});
  o.start.clear();
  const auto r = minimize(o, optionsFor(Method::kHillClimbing, 1));
  EXPECT_DOUBLE_EQ(r.x[0], 0.5);
  EXPECT_DOUBLE_EQ(r.x[1], 50.0);
}

}  // namespace
}  // namespace xgauge
