#include "xgauge/measure/measure.h"

#include "budget.h"
#include "checks.h"
#include "least_squares.h"
#include "pose_candidates.h"
#include "stages.h"
#include "xgauge/loss/loss.h"
#include "xgauge/measure/model.h"
#include "xgauge/measure/schedule.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <array>
#include <chrono>
#include <cmath>
#include <limits>

namespace xgauge {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The first step of a joint stage for a kind of parameter, in its physical
// unit: what remains uncertain after the stages per radiograph.
double firstStep(ParameterKind kind) {
  switch (kind) {
    case ParameterKind::kDimension:
      return 0.3;  // mm
    case ParameterKind::kRotation:
      return 1.0;  // deg
    case ParameterKind::kPosition:
      return 1.0;  // mm
    case ParameterKind::kAxis:
      return 1.0;  // deg
    case ParameterKind::kMaterial:
      return 0.02;  // fraction, or 1/mm
    case ParameterKind::kDetector:
      return 0.2;  // deg
  }
  return 1.0;
}

constexpr int kLineIterationFactor = 10;

StagePlan poseStage(const std::string& name, const PoseStage& stage, std::vector<int> indices,
                    int radiograph, const ForwardModel& model) {
  StagePlan plan{name,
                 stage.method,
                 std::move(indices),
                 {radiograph},
                 model.levelForWidth(stage.min_width_px),
                 1,
                 stage.evaluations,
                 stage.sampling_points};
  plan.step = stage.steps;
  return plan;
}

// A translated radiograph: the 2-DOF axis of its known move.
void fitAxis(ForwardModel& model, std::vector<double>& theta, Runner& runner,
             const PoseSchedule& schedule, int r) {
  const RadiographSpec& spec = model.spec(r);
  const std::vector<int> axis = model.poseIndices(r);
  const ParameterLayout& p = model.parameters();
  const int coarse = model.levelForWidth(schedule.axis_local.min_width_px);
  const std::vector<int> only{r};
  if (schedule.axis_from_shadow_shift) {
    // The lateral part of the move from the shift of the shadow's centroid;
    // the depth part, of either sign, from the known distance.
    const Machine& machine = model.machine();
    const int q = spec.reference;
    const Vec2 shift =
        shadowCentroid(model.radiograph(r), coarse) - shadowCentroid(model.radiograph(q), coarse);
    const Vec3 centre = model.pose(theta, q).apply(model.referenceCentre());
    const double d = machine.source_detector_distance_mm;
    const double magnification = d / (d - centre.z());
    const double dx = shift.x() * machine.pitch_u_mm / magnification;
    const double dy = -shift.y() * machine.pitch_v_mm / magnification;
    const double m = spec.distance_mm;
    const double lateral = std::min(m, std::hypot(dx, dy));
    const double dz = std::sqrt(std::max(0.0, m * m - lateral * lateral));
    double best = kInf;
    std::vector<double> best_theta = theta;
    for (double sign : {1.0, -1.0}) {
      std::vector<double> t = theta;
      t[static_cast<size_t>(p.index(spec.name + "/axis/azimuth"))] =
          std::atan2(sign * dz, dx) * kRadToDeg;
      const auto elevation = static_cast<size_t>(p.index(spec.name + "/axis/elevation"));
      t[elevation] = std::clamp(std::asin(std::clamp(dy / m, -1.0, 1.0)) * kRadToDeg,
                                model.lower()[elevation], model.upper()[elevation]);
      const double loss = model.loss(t, coarse, 1, only).value_or(kInf);
      if (loss < best) best = loss, best_theta = t;
    }
    theta = best_theta;
  } else {
    runner.run(poseStage(spec.name + ": axis search", schedule.axis_search, axis, r, model));
  }
  runner.run(poseStage(spec.name + ": axis", schedule.axis_local, axis, r, model));
  for (const PoseStage& finer : schedule.axis_finer)
    runner.run(poseStage(spec.name + ": axis, finer", finer, axis, r, model));
}

// A free or rotated radiograph's pose refined on the finer levels.
void refinePoseFiner(const ForwardModel& model, Runner& runner, const PoseSchedule& schedule,
                     int r) {
  for (const PoseStage& finer : schedule.finer)
    runner.run(
        poseStage(model.spec(r).name + ": pose, finer", finer, model.poseIndices(r), r, model));
}

// A free or rotated radiograph: a global search of (r, x, y) (r the
// schedule's search rotation), at one depth or several, then 6-DOF.
// Returns its pose candidates, the best (theta's) first.
std::vector<PoseCandidate> fitPose(ForwardModel& model, std::vector<double>& theta, Runner& runner,
                                   const PoseSchedule& schedule, int r) {
  const RadiographSpec& spec = model.spec(r);
  const ParameterLayout& p = model.parameters();
  const std::vector<int> pose = model.poseIndices(r);
  static constexpr std::array<const char*, 3> kRotations{"rx", "ry", "rz"};
  const std::vector<int> search{
      p.index(fmt::format("{}/rotation/{}", spec.name,
                          kRotations.at(static_cast<size_t>(schedule.search_rotation)))),
      p.index(spec.name + "/position/x"), p.index(spec.name + "/position/y")};
  const auto z = static_cast<size_t>(p.index(spec.name + "/position/z"));
  const Machine& machine = model.machine();
  const double d = machine.source_detector_distance_mm;
  // The global search at the depth theta[z].
  auto globalStage = [&](const std::string& name) {
    StagePlan global = poseStage(name, schedule.search, search, r, model);
    if (!schedule.search_around_shadow) return global;
    // Start at the shadow's centroid seen at this depth; search a window of
    // a fraction of the part's size around it (the absorption's centroid is
    // near the projected centre), the rotation over its bounds.
    const Vec2 centroid = shadowCentroid(model.radiograph(r), global.level);
    const Vec3 c = machine.detectorPoint(centroid.x(), centroid.y());
    const double lambda = 1.0 - theta[z] / d;
    const auto ix = static_cast<size_t>(search[1]), iy = static_cast<size_t>(search[2]);
    theta[ix] = std::clamp(lambda * c.x(), model.lower()[ix], model.upper()[ix]);
    theta[iy] = std::clamp(lambda * c.y(), model.lower()[iy], model.upper()[iy]);
    const double window = schedule.window_of_part_size * model.partSizeMm();
    for (size_t k = 0; k < search.size(); ++k) {
      const auto i = static_cast<size_t>(search[k]);
      const double lo = model.lower()[i], hi = model.upper()[i];
      const bool rotation = k == 0;
      global.lower.push_back(rotation ? lo : std::max(lo, theta[i] - window));
      global.upper.push_back(rotation ? hi : std::min(hi, theta[i] + window));
    }
    return global;
  };
  std::vector<std::pair<double, std::vector<double>>> record;
  std::vector<int> searched = search;
  if (schedule.search_depths > 0) {
    // Depths evenly spread in magnification M = D / (D - z) over the bounds.
    searched.push_back(static_cast<int>(z));
    const double m_lo = d / (d - model.lower()[z]), m_hi = d / (d - model.upper()[z]);
    runner.recordInto(&record);
    for (int k = 0; k < schedule.search_depths; ++k) {
      const double t = schedule.search_depths > 1 ? k / (schedule.search_depths - 1.0) : 0.5;
      const double m = m_lo * std::pow(m_hi / m_lo, t);
      theta[z] = std::clamp(d * (1.0 - 1.0 / m), model.lower()[z], model.upper()[z]);
      runner.run(globalStage(
          fmt::format("{}: pose search at magnification {:.2f}", spec.name, d / (d - theta[z]))));
    }
    runner.recordInto(nullptr);
  } else if (schedule.multistart > 0) {
    runner.recordInto(&record);
    runner.run(globalStage(spec.name + ": pose search"));
    runner.recordInto(nullptr);
  } else {
    runner.run(globalStage(spec.name + ": pose search"));
    runner.run(poseStage(spec.name + ": pose", schedule.local, pose, r, model));
  }
  std::vector<PoseCandidate> candidates;
  if (!record.empty()) {
    // Refine the best few distinct samples: the best is the pose, the others
    // stay candidates for the joint fit (tryCandidates).
    std::vector<std::vector<double>> refined =
        distinctBest(record, searched, model, static_cast<size_t>(std::max(1, schedule.multistart)),
                     schedule.separation);
    std::vector<std::string> names;
    for (size_t k = 0; k < refined.size(); ++k)
      names.push_back(fmt::format("{}: pose from start {}", spec.name, k + 1));
    const std::vector<double> losses =
        runner.refineEach(refined, poseStage("", schedule.local, pose, r, model), names);
    for (size_t k = 0; k < refined.size(); ++k)
      candidates.push_back(
          {poseValues(model, refined[k], r), losses[k], fmt::format("search start {}", k + 1)});
    // Best first; of equal losses the earlier start's.
    std::stable_sort(
        candidates.begin(), candidates.end(),
        [](const PoseCandidate& a, const PoseCandidate& b) { return a.loss < b.loss; });
    if (candidates.front().loss < kInf) setPose(model, theta, r, candidates.front().pose);
  } else {
    candidates.push_back({{}, 0.0, "search"});
  }
  refinePoseFiner(model, runner, schedule, r);
  candidates.front().pose = poseValues(model, theta, r);
  return distinctCandidates(model, r, candidates, schedule.candidate_separation_deg);
}

// Every free parameter of every radiograph together, coarse to fine.
void fitJointly(ForwardModel& model, std::vector<double>& theta, Runner& runner,
                const Schedule& schedule, const MeasureOptions& options) {
  // The derivative-free stages leave the material's refinement (it has a
  // prior only a least-squares stage weighs) where it starts.
  const std::vector<int> all = model.jointIndices();
  const std::vector<int> least_squares = model.leastSquaresIndices();
  std::vector<int> every_radiograph;
  for (int r = 0; r < model.radiographCount(); ++r) every_radiograph.push_back(r);
  // A line detector's images (a few rows) cost little per iteration and its
  // fits run along long valleys (the depth against the move's axis):
  // kLineIterationFactor times the final stage's iterations.
  const bool line = onLineDetector(model, schedule);
  const int iteration_factor = line ? kLineIterationFactor : 1;
  // On a line detector the joint fit is BOBYQA's (stages.h, leastSquaresStage).
  const bool derivatives = std::any_of(schedule.joint.begin(), schedule.joint.end(),
                                       [](const JointStage& s) { return s.gauss_newton; });
  const std::vector<JointStage>& joint =
      line && derivatives ? scheduleFor(ScheduleKind::kBobyqa).joint : schedule.joint;
  for (const JointStage& stage : joint) {
    if (!options.joint_search) break;
    const int level = model.levelForWidth(stage.min_width_px);
    const std::string name =
        stage.min_width_px > 0
            ? fmt::format("joint, {} px",
                          model.radiograph(0).levels[static_cast<size_t>(level)].width())
            : std::string("joint");
    if (stage.gauss_newton) {
      runner.report(solveLeastSquares(
          model, theta, least_squares, every_radiograph, level, stage.samples, stage.evaluations,
          model.job().loss == LossKind::kMeanAbsolute, JacobianKind::kRenderDerivatives, false,
          name, std::nullopt, kCoarseSettledSteps));
      continue;
    }
    StagePlan plan{name,          stage.method,      all, every_radiograph, level,
                   stage.samples, stage.evaluations, 0};
    for (int i : all) {
      const auto index = static_cast<size_t>(i);
      plan.step.push_back(std::min(stage.step_scale * firstStep(model.kind(i)),
                                   0.5 * (model.upper()[index] - model.lower()[index])));
    }
    if (stage.window_steps > 0.0)
      for (size_t k = 0; k < all.size(); ++k) {
        const auto i = static_cast<size_t>(all[k]);
        plan.lower.push_back(
            std::max(model.lower()[i], theta[i] - stage.window_steps * plan.step[k]));
        plan.upper.push_back(
            std::min(model.upper()[i], theta[i] + stage.window_steps * plan.step[k]));
      }
    runner.run(plan);
  }
  const LeastSquaresStage ls = leastSquaresStage(model, schedule);
  const int ls_level = leastSquaresLevel(model, schedule);
  if (ls.enabled) {
    // From here on (this stage, the budget and the self-checks) the pixels
    // on edges are sampled finer (schedule.h, LeastSquaresStage::edge_samples).
    model.setEdgeSamples(ls.edge_samples);
    runner.report(solveLeastSquares(model, theta, least_squares, every_radiograph, ls_level,
                                    ls.samples, ls.max_iterations * iteration_factor,
                                    model.job().loss == LossKind::kMeanAbsolute,
                                    ls.render_derivatives ? JacobianKind::kRenderDerivatives
                                                          : JacobianKind::kForwardDifferences));
  }
}

// The uncertainty budget and the self-checks, from the residuals and their
// Jacobian at the solution, on the least-squares stage's level.
void assess(ForwardModel& model, const std::vector<double>& theta, MeasurementResult& result) {
  // What the acceptance rule calls a failure is reported by measure(), after
  // its retries.
  const auto start = std::chrono::steady_clock::now();
  const Schedule& schedule = scheduleFor(model.job().schedule);
  const LeastSquaresStage ls = leastSquaresStage(model, schedule);
  const int level = leastSquaresLevel(model, schedule);
  std::vector<int> every_radiograph;
  for (int r = 0; r < model.radiographCount(); ++r) every_radiograph.push_back(r);
  const bool robust = model.job().loss == LossKind::kMeanAbsolute;
  LinearizedFit fit;
  if (!linearize(model, theta, model.leastSquaresIndices(), every_radiograph, level, ls.samples,
                 robust, fit)) {
    result.check.warnings.push_back(
        "the solution lies so close to what cannot be simulated that its uncertainty could not "
        "be estimated");
    return;
  }
  const auto secondsSince = [](std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
  };
  const double jacobian_seconds = secondsSince(start);
  const auto budget_start = std::chrono::steady_clock::now();
  result.uncertainty = estimateUncertainty(model, theta, fit);
  const double budget_seconds = secondsSince(budget_start);
  const auto checks_start = std::chrono::steady_clock::now();
  std::vector<char> region_pixels;
  result.check = checkMeasurement(model, theta, fit, model.job().acceptance, &region_pixels);
  // Where the part differs from its model, U includes how far the
  // dimensions move without those pixels.
  addMisfitTerm(model, fit, region_pixels, result.uncertainty);
  addExtrapolationTerm(model, theta, fit, result.check, result.uncertainty);
  // Warned about where the shift is a large part of a dimension's
  // uncertainty (kMisfitWarnShare of u_c); smaller ones are in the budget.
  double largest = 0.0, share = 0.0;
  std::string moved;
  for (const DimensionUncertainty& u : result.uncertainty.dimensions)
    for (const UncertaintyComponent& c : u.components)
      if (c.name == "misfit" && u.combined > 0.0 && c.contribution / u.combined > share)
        share = c.contribution / u.combined, largest = c.contribution, moved = u.name;
  if (share > kMisfitWarnShare)
    result.check.warnings.push_back(fmt::format(
        "the {} residual region(s) left out move {} by {:.4f}, {:.0f} % of its standard "
        "uncertainty: each dimension's U includes its shift as the component \"misfit\"",
        result.check.regions.size(), moved, largest, 100.0 * share));
  const double checks_seconds = secondsSince(checks_start);
  // An influence whose shift could not be found is left out of U, which is
  // then smaller than it should be: said, not only logged.
  if (!result.uncertainty.unpropagated.empty())
    result.check.warnings.push_back(fmt::format(
        "U leaves out {}: the fit's shift with {} moved by its uncertainty could not be found (see "
        "the budget's notes), so every U is smaller than it should be",
        fmt::join(result.uncertainty.unpropagated, ", "),
        result.uncertainty.unpropagated.size() == 1 ? "it" : "each"));
  for (const std::string& note : result.uncertainty.notes) spdlog::info("uncertainty: {}", note);
  for (const std::string& warning : result.check.warnings) spdlog::warn("{}", warning);
  spdlog::info(
      "uncertainty budget and self-checks in {:.2f} s (the Jacobian at the solution {:.2f} s, the "
      "influences {:.2f} s, the self-checks {:.2f} s)",
      secondsSince(start), jacobian_seconds, budget_seconds, checks_seconds);
}

// Each free dimension's U: by substitution where the job's verification
// covers it (measure/verification.h; refused with an Error outside its
// conditions), else the budget's, unverified. Then its verdict where it has
// a tolerance (measure/tolerance.h), if its U is verified or the job
// accepts unverified verdicts.
void decideConformity(const ForwardModel& model, MeasurementResult& result) {
  const MeasurementJob& job = model.job();
  const MeasurementInputs& inputs = model.inputs();
  const Verification* verification = inputs.verification ? &*inputs.verification : nullptr;
  if (verification) {
    auto digest = [&](const std::filesystem::path& file) {
      const auto it = inputs.sha256.find(file.string());
      if (it == inputs.sha256.end())
        fail(
            "{}: a verification needs the job's part, machine and material files ({} was not "
            "read)",
            job.file.string(), file.string());
      return it->second;
    };
    std::vector<double> magnifications;
    for (const MeasuredRadiograph& r : result.radiographs)
      magnifications.push_back(r.magnification);
    checkVerificationConditions(*verification, digest(job.part_file), digest(job.machine_file),
                                digest(job.material_file), magnifications);
  }
  const std::map<std::string, Tolerance> tolerances = tolerancesFor(job, model.part());
  std::vector<std::string> withheld;
  for (MeasuredDimension& d : result.dimensions) {
    d.fitted_value = d.value;
    if (!d.free) continue;
    const DimensionUncertainty* own = nullptr;
    for (const DimensionUncertainty& u : result.uncertainty.dimensions)
      if (u.name == d.name && u.identifiable) own = &u;
    if (own) d.expanded_uncertainty = d.own_expanded_uncertainty = own->expanded;
    const VerifiedDimension* verified = verification ? verification->find(d.name) : nullptr;
    if (own && verified) {
      d.substitution = substitute(d.value, own->combined, *verified, verification->coverage_factor);
      d.value = d.substitution->value;
      d.expanded_uncertainty = d.substitution->expanded;
      d.verified = true;
    }
    const auto t = tolerances.find(d.name);
    if (t == tolerances.end()) continue;
    d.tolerance = t->second;
    if (!d.verified && !job.unverified_verdicts) {
      withheld.push_back(d.name);
      continue;
    }
    d.decision = decide(d.value, d.expanded_uncertainty.value_or(kInf), t->second);
    if (d.decision->cannot_decide && own && !d.verified)
      d.decision->cannot_decide_reason = discrepancyReason(*own, result.uncertainty.coverage_factor,
                                                           t->second, result.check);
    if (d.decision->cannot_decide)
      result.check.warnings.push_back(fmt::format(
          "{}: U = {:.4f} exceeds a third of the tolerance ({:.4f}): this measurement cannot "
          "reliably decide conformity{}",
          d.name, d.expanded_uncertainty.value_or(kInf), t->second.width() / 3.0,
          d.decision->cannot_decide_reason.empty() ? ""
                                                   : ", because of " + d.decision->cannot_decide_reason));
  }
  if (!withheld.empty())
    result.check.warnings.push_back(fmt::format(
        "no verdict on {}: their U is unverified (no verification of the method on a master "
        "covers them; measure a master with `xgauge verify` and name it in the job's "
        "\"verification\", or set \"unverified_verdicts\": true to judge by the model's U)",
        fmt::join(withheld, ", ")));
}

// Whether attempt a is a better fit than b: one that passes the acceptance
// rule first, then the smaller worst misfit, then the smaller share of
// residual regions.
bool betterAttempt(const MeasurementResult& a, const MeasurementResult& b) {
  if (a.check.failures.empty() != b.check.failures.empty()) return a.check.failures.empty();
  const double ma = a.check.worstMisfitRatio(), mb = b.check.worstMisfitRatio();
  if (ma != mb) return ma < mb;
  return a.check.region_share < b.check.region_share;
}

// Whether a fit needs no other pose candidate: the acceptance rule passes
// it and every radiograph fits within `misfit_ratio` of its noise (schedule.h,
// PoseSchedule::settled_misfit_ratio).
bool settled(const MeasurementResult& fit, double misfit_ratio) {
  return fit.check.failures.empty() && fit.check.worstMisfitRatio() <= misfit_ratio;
}

// The joint fit from theta (the poses found), the final figures, the budget
// and the self-checks; `result` holds the stages run before.
MeasurementResult fitFrom(ForwardModel& model, std::vector<double> theta,
                          const MeasureOptions& options, const Schedule& schedule, uint64_t seed,
                          MeasurementResult result) {
  const MeasurementJob& job = model.job();
  Runner runner(model, theta, result, seed, true, options.on_stage);
  // 2-3. Everything together.
  fitJointly(model, theta, runner, schedule, options);

  // Final figures at full size.
  result.theta = theta;
  if (const auto why = model.infeasibility(theta))
    fail(
        "{}: no stage found parameters that can be simulated: {}; check the pose bounds and the "
        "dimensions' bounds",
        job.file.string(), *why);
  const auto& dims = model.part().dimensions();
  const auto& free = model.freeDimensionIndices();
  for (size_t i = 0; i < dims.size(); ++i) {
    MeasuredDimension d;
    d.name = dims[i].name;
    d.value = theta[i];
    d.free = std::find(free.begin(), free.end(), static_cast<int>(i)) != free.end();
    d.unit = dims[i].unit;
    result.dimensions.push_back(std::move(d));
  }
  if (options.assess) assess(model, theta, result);
  for (int r = 0; r < model.radiographCount(); ++r) {
    double loss = std::numeric_limits<double>::quiet_NaN();
    if (options.full_size_losses) {
      const int only[] = {r};
      loss = model.loss(theta, 0, 2, only).value_or(kInf);
    }
    const RadiographSpec& spec = model.spec(r);
    const Pose pose = model.pose(theta, r);
    const double d = model.machine().source_detector_distance_mm;
    const double magnification = d / (d - pose.apply(model.referenceCentre()).z());
    result.radiographs.push_back(
        {spec.name, std::string(acquisitionName(spec.pattern)), pose, loss, magnification});
    result.total_loss += loss;
  }
  return result;
}

// A fit the acceptance rule refuses, or one that leaves more than the
// noise (settled), from the radiographs' other pose candidates (schedule.h,
// PoseSchedule::candidates; docs/method.md, "Pose candidates"): the worst
// fitting radiograph's first, each radiograph's
// search minima in the order of their loss together with its mirrored
// poses (refined only now that they are needed), the others' poses as the
// search left them. Stops at the first settled fit; keeps the better
// (betterAttempt: one the rule passes, then the smallest misfit). `searched`: theta and the stages
// after the pose searches.
void tryCandidates(ForwardModel& model, const std::vector<double>& searched_theta,
                   const MeasurementResult& searched, const MeasureOptions& options,
                   const Schedule& schedule, uint64_t seed,
                   std::vector<std::vector<PoseCandidate>> candidates, MeasurementResult& best) {
  const PoseSchedule& ps = schedule.pose;
  std::vector<int> order;
  std::vector<double> misfit(candidates.size(), 0.0);
  for (int r = 0; r < static_cast<int>(candidates.size()); ++r) {
    if (candidates[static_cast<size_t>(r)].empty()) continue;
    order.push_back(r);
    if (static_cast<size_t>(r) < best.check.radiographs.size())
      misfit[static_cast<size_t>(r)] = best.check.radiographs[static_cast<size_t>(r)].misfit_ratio;
  }
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return misfit[static_cast<size_t>(a)] > misfit[static_cast<size_t>(b)];
  });
  int tried = 1, evaluations = best.evaluations;
  // The sampling every joint fit ends with (fitJointly), in which the kept
  // fit's figures were taken, for the caller's full-size simulation (the
  // pose stages below sample without the edges).
  const LeastSquaresStage ls = leastSquaresStage(model, schedule);
  const int edges = ls.enabled ? ls.edge_samples : 0;
  for (const int r : order) {
    if (tried >= ps.candidates || settled(best, ps.settled_misfit_ratio)) break;
    const RadiographSpec& spec = model.spec(r);
    std::vector<PoseCandidate>& list = candidates[static_cast<size_t>(r)];
    std::vector<double> theta = searched_theta;
    MeasurementResult mirrored = searched;
    model.setEdgeSamples(0);  // the pose stages' sampling (the joint fit refined the edges)
    Runner runner(model, theta, mirrored, seed, true, options.on_stage);
    for (PoseCandidate& m :
         mirroredCandidates(model, searched_theta, r,
                            poseStage("", ps.local, model.poseIndices(r), r, model), runner))
      list.push_back(std::move(m));
    evaluations += mirrored.evaluations - searched.evaluations;
    std::stable_sort(
        list.begin() + 1, list.end(),
        [](const PoseCandidate& a, const PoseCandidate& b) { return a.loss < b.loss; });
    list = distinctCandidates(model, r, list, ps.candidate_separation_deg);
    for (size_t k = 1; k < list.size() && tried < ps.candidates; ++k) {
      if (!(list[k].loss < kInf)) continue;
      spdlog::warn(
          "{}; trying {}'s pose candidate {} ({}, search loss {:.4g} against {:.4g})",
          best.check.failures.empty()
              ? fmt::format("the fit leaves {:.2f} times the noise", best.check.worstMisfitRatio())
              : fmt::format("the fit is not a measurement ({})", best.check.failures.front()),
          spec.name, k + 1, list[k].origin, list[k].loss, list.front().loss);
      theta = searched_theta;
      setPose(model, theta, r, list[k].pose);
      MeasurementResult stages = mirrored;
      model.setEdgeSamples(0);
      Runner finer(model, theta, stages, seed, true, options.on_stage);
      refinePoseFiner(model, finer, ps, r);
      MeasurementResult next = fitFrom(model, theta, options, schedule, seed, stages);
      evaluations += next.evaluations - mirrored.evaluations;
      ++tried;
      next.candidate_taken = tried;
      next.candidate_origin = fmt::format("{}: {}", spec.name, list[k].origin);
      if (betterAttempt(next, best)) best = std::move(next);
      if (settled(best, ps.settled_misfit_ratio)) break;
    }
  }
  model.setEdgeSamples(edges);
  best.candidates_tried = tried;
  best.evaluations = evaluations;
}

// Whether a fit is kept without trying the pipeline again from other starts:
// the rule passes it and no radiograph leaves more than the rule's
// retry_misfit_ratio times its noise.
bool acceptedAsIs(const MeasurementResult& fit, const AcceptanceRule& rule) {
  return fit.check.failures.empty() && fit.check.worstMisfitRatio() <= rule.retry_misfit_ratio;
}

// One run of the pipeline from theta: the poses, the joint fit from their
// candidates until one passes the acceptance rule (when `judge`), the
// budget and the self-checks; `seed` for its searches.
MeasurementResult runPipeline(ForwardModel& model, std::vector<double> theta,
                              const MeasureOptions& options, const Schedule& schedule,
                              uint64_t seed, bool judge) {
  const auto start = std::chrono::steady_clock::now();
  XG_CHECK(theta.size() == static_cast<size_t>(model.size()), "theta has the wrong size");
  model.setEdgeSamples(0);  // until the least-squares stage
  if (const auto why = model.infeasibility(theta))
    spdlog::warn(
        "the starting parameters cannot be simulated ({}); the searches start from "
        "infeasible points",
        *why);
  MeasurementResult searched;
  Runner runner(model, theta, searched, seed, true, options.on_stage);

  // 1. Each radiograph's pose alone, the part at its starting dimensions.
  std::vector<std::vector<PoseCandidate>> candidates(static_cast<size_t>(model.radiographCount()));
  for (int r = 0; options.search_poses && r < model.radiographCount(); ++r) {
    switch (model.spec(r).pattern) {
      case Acquisition::kTranslated:
        fitAxis(model, theta, runner, schedule.pose, r);
        break;
      case Acquisition::kFree:
      case Acquisition::kRotated:
        candidates[static_cast<size_t>(r)] = fitPose(model, theta, runner, schedule.pose, r);
        break;
      case Acquisition::kTurned:  // its reference's pose turned about the stage axis
      case Acquisition::kKnown:
        break;
    }
  }
  MeasurementResult result = fitFrom(model, theta, options, schedule, seed, searched);
  if (judge && !settled(result, schedule.pose.settled_misfit_ratio))
    tryCandidates(model, theta, searched, options, schedule, seed, std::move(candidates), result);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

// The seed of retry k: well apart from the job's (SplitMix64's increment).
uint64_t retrySeed(uint64_t seed, int k) {
  return seed + static_cast<uint64_t>(k) * 0x9E3779B97F4A7C15ULL;
}

}  // namespace

std::string_view measurementStatusName(MeasurementStatus status) {
  switch (status) {
    case MeasurementStatus::kMeasured:
      return "measured";
    case MeasurementStatus::kNotMeasured:
      return "not measured";
  }
  return "unknown";
}

MeasurementResult measure(ForwardModel& model, std::vector<double> theta,
                          const MeasureOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  const MeasurementJob& job = model.job();
  const Schedule& schedule = options.schedule ? *options.schedule : scheduleFor(job.schedule);
  const AcceptanceRule& rule = job.acceptance;
  const bool judge = options.assess && options.judge;
  MeasurementResult best = runPipeline(model, theta, options, schedule, job.seed, judge);
  int evaluations = best.evaluations;
  // A fit the rule refuses, or a doubtful one (AcceptanceRule::
  // retry_misfit_ratio): again from other starts, the pose searches with
  // another seed and twice their starts.
  Schedule wider = schedule;
  wider.pose.multistart = 2 * std::max(2, schedule.pose.multistart);
  for (int k = 1; judge && k <= rule.retries && !acceptedAsIs(best, rule); ++k) {
    if (best.check.failures.empty())
      spdlog::warn(
          "attempt {} leaves {:.2f} times the noise (above {:.2f}); trying again from other "
          "starts",
          k, best.check.worstMisfitRatio(), rule.retry_misfit_ratio);
    else
      spdlog::warn(
          "attempt {} is not a measurement ({} failure(s), the first: {}); trying again "
          "from other starts",
          k, best.check.failures.size(), best.check.failures.front());
    MeasurementResult next =
        runPipeline(model, theta, options, wider, retrySeed(job.seed, k), judge);
    evaluations += next.evaluations;
    next.attempts = k + 1;
    if (betterAttempt(next, best)) best = std::move(next);
    best.attempts = k + 1;
  }
  best.evaluations = evaluations;
  if (!judge) {
    // A calibration's fit: the failures are warnings (it has its own checks).
    best.check.warnings.insert(best.check.warnings.begin(), best.check.failures.begin(),
                               best.check.failures.end());
    best.check.failures.clear();
  }
  if (best.check.failures.empty()) {
    decideConformity(model, best);
  } else {
    best.status = MeasurementStatus::kNotMeasured;
    for (const std::string& failure : best.check.failures)
      spdlog::error("not measured: {}", failure);
  }
  best.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return best;
}

MeasurementResult measure(const MeasurementInputs& inputs) {
  ForwardModel model(inputs);
  return measure(model, model.start());
}

void takeFullSizeLosses(const ForwardModel& model, const std::vector<Image>& simulated_full,
                        MeasurementResult& result) {
  XG_CHECK(simulated_full.size() == result.radiographs.size(),
           "one full-size simulation per radiograph");
  result.total_loss = 0.0;
  for (int r = 0; r < model.radiographCount(); ++r) {
    const PreparedRadiograph& rad = model.radiograph(r);
    const PixelRect roi = rad.rois.front();
    const double loss = imageLoss(simulated_full[static_cast<size_t>(r)].crop(roi),
                                  rad.levels.front(), roi, model.job().loss);
    result.radiographs[static_cast<size_t>(r)].loss = loss;
    result.total_loss += loss;
  }
}

}  // namespace xgauge
