#include "xgauge/calibrate/part.h"

#include "xgauge/core/config.h"
#include "xgauge/image/stats.h"
#include "xgauge/measure/model.h"

#include <spdlog/spdlog.h>
#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>

namespace xgauge {

namespace {

// A part seen in part (a calibration wedge's thin end and one wall) shows
// its tilt about each axis by little more than the slope of its shadow,
// which a free curve can partly take up: the local fit then stops a few
// degrees off, or at the tilt's mirror image (seen on the calibration
// grid's corner views: 2.7 degrees off, and tilts of (3.8, 6.0) for the
// lab's (-4.6, -4.9), each with a table fitted ten times worse than its
// noise). Where the fit leaves a tilt in doubt (tiltDoubt), that tilt is
// moved by +-step_deg and to its mirror (-tilt, when it is more than half a
// step from 0) within its bounds, the joint fit run from there, and the
// first start that ends at another tilt (kOtherTiltDeg away) with a loss
// lower by more than kTiltGain taken; one that ends where the fit was with
// a lower loss (it converged further) is kept and the search goes on.
// Passes repeat until one finds no other tilt, at most kTiltPasses. A
// doubtful pose that was right costs one pass: two to six joint fits; one
// the fit does not doubt, none.
constexpr int kTiltPasses = 3;
constexpr double kTiltGain = 1e-4;
constexpr double kOtherTiltDeg = 0.5;
// A tilt is in doubt when its standard uncertainty exceeds this.
constexpr double kDoubtfulTiltDeg = 0.1;
// The part's outline lies this far inside the detector (pixels) for a
// whole view.
constexpr double kWholeViewMarginPx = 2.0;

// The level and samples the fit with the curve free ends on: its last
// joint stage's (its least squares' when it has none).
std::pair<int, int> jointLevel(const ForwardModel& model, const Schedule& schedule) {
  if (schedule.joint.empty())
    return {leastSquaresLevel(model, schedule), schedule.least_squares.samples};
  return {model.levelForWidth(schedule.joint.back().min_width_px), schedule.joint.back().samples};
}

// The loss of `theta` on the radiograph at the joint fit's last level, by
// which retryTilts compares the fits from its starts (each joint fit's own
// robust loss weighs the residuals by their scale at its start).
double jointLoss(ForwardModel& model, const std::vector<double>& theta, const Schedule& schedule,
                 int radiograph) {
  const auto [level, samples] = jointLevel(model, schedule);
  const int only[] = {radiograph};
  return model.loss(theta, level, samples, only).value_or(HUGE_VAL);
}

// What the fit says of the radiograph's tilts (rx, ry) at `theta`: whether
// the part is seen whole (its outline inside the detector), and each
// tilt's standard uncertainty from the residuals and their Jacobian (the
// render's derivatives) at the joint fit's last level: the least squares'
// covariance, the residual's variance times (J'J)^-1, with every joint
// parameter free, the curve's too (how much of the tilt the curve takes
// up). A tilt is in doubt in a part seen in part, at its bound, or where
// its uncertainty exceeds kDoubtfulTiltDeg. In a whole view every wall's
// front and back edges are seen, in perspective, and pin both tilts and
// their signs; the local fits that stopped at another tilt were all of
// views in part.
struct TiltDoubt {
  bool whole = false;
  std::array<double, 2> uncertainty_deg{HUGE_VAL, HUGE_VAL};
  std::array<bool, 2> doubtful{true, true};
};
TiltDoubt tiltDoubt(ForwardModel& model, const std::vector<double>& theta, const Schedule& schedule,
                    int radiograph) {
  TiltDoubt out;
  const Machine& machine = model.machine();
  out.whole = true;
  for (const Segment2& segment : model.outline(theta, radiograph))
    for (const Vec2& end : segment)
      out.whole = out.whole && end.x() >= kWholeViewMarginPx &&
                  end.x() <= machine.columns - kWholeViewMarginPx &&
                  end.y() >= kWholeViewMarginPx && end.y() <= machine.rows - kWholeViewMarginPx;
  const std::vector<int> pose = model.poseIndices(radiograph);
  auto decide = [&] {
    for (size_t t = 0; t < 2; ++t) {
      const auto i = static_cast<size_t>(pose[t]);
      const bool at_bound =
          std::min(theta[i] - model.lower()[i], model.upper()[i] - theta[i]) < 0.05;
      out.doubtful[t] = !out.whole || at_bound || out.uncertainty_deg[t] > kDoubtfulTiltDeg;
    }
    return out;
  };
  const auto [level, samples] = jointLevel(model, schedule);
  const std::vector<int> indices = model.jointIndices();
  const int only[] = {radiograph};
  std::vector<double> r, j;
  if (!model.residualsAndJacobian(theta, indices, level, samples, only, r, j)) return decide();
  const auto m = static_cast<Eigen::Index>(r.size());
  const auto p = static_cast<Eigen::Index>(indices.size());
  if (m <= p) return decide();
  const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>
      jacobian(j.data(), m, p);
  // (J'J)^-1 through its correlation matrix: the columns mix degrees,
  // millimetres and the curve's units. A tilt that nothing determines keeps
  // an infinite uncertainty.
  const Eigen::MatrixXd normal = jacobian.transpose() * jacobian;
  for (Eigen::Index k = 0; k < p; ++k)
    if (!(normal(k, k) > 0.0)) return decide();
  const Eigen::VectorXd scale = normal.diagonal().cwiseSqrt().cwiseInverse();
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(scale.asDiagonal() * normal * scale.asDiagonal());
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return decide();
  const Eigen::MatrixXd inverse =
      scale.asDiagonal() * ldlt.solve(Eigen::MatrixXd::Identity(p, p)) * scale.asDiagonal();
  const double variance =
      Eigen::Map<const Eigen::VectorXd>(r.data(), m).squaredNorm() / static_cast<double>(m - p);
  for (size_t t = 0; t < 2; ++t) {
    const auto column = std::find(indices.begin(), indices.end(), pose[t]) - indices.begin();
    out.uncertainty_deg[t] = std::sqrt(variance * std::max(0.0, inverse(column, column)));
  }
  return decide();
}

MeasurementResult retryTilts(ForwardModel& model, MeasurementResult fitted,
                             const MeasureOptions& options, int radiograph, double step_deg) {
  const std::vector<int> pose = model.poseIndices(radiograph);
  if (pose.size() < 2) return fitted;  // a translated or known pose: no tilt of its own
  const Schedule& schedule =
      options.schedule ? *options.schedule : scheduleFor(model.job().schedule);
  const auto rx = static_cast<size_t>(pose[0]), ry = static_cast<size_t>(pose[1]);
  const double from_x = fitted.theta[rx], from_y = fitted.theta[ry];
  double loss = jointLoss(model, fitted.theta, schedule, radiograph);
  const double from_loss = loss;
  bool improved = true;
  for (int pass = 0; improved && pass < kTiltPasses; ++pass) {
    improved = false;
    const TiltDoubt doubt = tiltDoubt(model, fitted.theta, schedule, radiograph);
    spdlog::info(
        "tilts ({:.2f}, {:.2f}) deg, standard uncertainties ({:.2g}, {:.2g}) deg, the part seen "
        "{}: {}",
        fitted.theta[rx], fitted.theta[ry], doubt.uncertainty_deg[0], doubt.uncertainty_deg[1],
        doubt.whole ? "whole" : "in part",
        doubt.doubtful[0] || doubt.doubtful[1] ? "searched again" : "not in doubt");
    for (size_t t = 0; t < 2; ++t) {
      if (!doubt.doubtful[t]) continue;
      const size_t i = t == 0 ? rx : ry;
      const double at = fitted.theta[i];
      std::vector<double> moves = {step_deg, -step_deg};
      if (std::abs(at) > 0.5 * step_deg) moves.push_back(-2.0 * at);
      for (const double move : moves) {
        std::vector<double> start = fitted.theta;
        start[i] = std::clamp(at + move, model.lower()[i], model.upper()[i]);
        if (start[i] == at) continue;
        MeasurementResult other = measure(model, start, options);
        const double other_loss = jointLoss(model, other.theta, schedule, radiograph);
        spdlog::debug("tilt from ({:.2f}, {:.2f}): loss {:.6g} at ({:.2f}, {:.2f}), best {:.6g}",
                      start[rx], start[ry], other_loss, other.theta[rx], other.theta[ry], loss);
        if (!(other_loss < (1.0 - kTiltGain) * loss)) continue;
        const bool elsewhere = std::abs(other.theta[rx] - fitted.theta[rx]) > kOtherTiltDeg ||
                               std::abs(other.theta[ry] - fitted.theta[ry]) > kOtherTiltDeg;
        fitted = std::move(other);
        loss = other_loss;
        if (elsewhere) {
          improved = true;
          break;
        }
      }
    }
  }
  if (fitted.theta[rx] != from_x || fitted.theta[ry] != from_y)
    spdlog::info(
        "tilts searched again: ({:.2f}, {:.2f}) deg -> ({:.2f}, {:.2f}), loss {:.6g} -> {:.6g}",
        from_x, from_y, fitted.theta[rx], fitted.theta[ry], from_loss, loss);
  return fitted;
}

// The schedule a part calibration follows (PartCalibrationJob::
// pose_schedule, or the job's).
const Schedule& scheduleOf(const PartCalibrationJob& job) {
  return job.pose_schedule ? *job.pose_schedule : scheduleFor(job.measurement().schedule);
}

// Eq. 3.8's exponential bent as beam hardening bends a curve through the
// same point (step 2 without a uniform region: the darkest pixels, at the
// longest path): two terms of 0.8 and 2 times its rate, about equal to it
// at the longest path and falling faster at short ones (eq. 3.8's
// exponential makes a part's thin paths look thicker, which pulls the pose
// of a part seen in part).
ExponentialSum bentCurve(const PartCalibration& out) {
  const double mu = out.initial_mu_per_mm;
  return ExponentialSum({{0.7, 0.8 * mu}, {0.3, 2.0 * mu}}, "eq. 3.8, bent");
}

// Path bins: up to kMaxBins of at least kMinBinPixels pixels each; fewer and
// smaller for few pixels (a line detector's row: hundreds, not hundreds of
// thousands), about kPixelsPerBin per bin, at least kMinBins.
constexpr int kMaxBins = 300;
constexpr int kMinBins = 20;
constexpr int64_t kPixelsPerBin = 100;
constexpr int64_t kMinBinPixels = 20;
constexpr double kSmoothPathMm = 0.01;  // largest second difference of the path around a pixel
constexpr double kSettled = 2e-4;       // material change that ends the rounds
// The misfit a round's provisional curve may leave (relative to the
// intensity): far beyond what a registered table shows, short of a table of
// no part at all.
constexpr double kProvisionalResidual = 0.5;

}  // namespace

void addStepSeconds(std::vector<StepSeconds>& into, std::string step,
                    std::chrono::steady_clock::time_point& since) {
  const auto now = std::chrono::steady_clock::now();
  into.push_back({std::move(step), std::chrono::duration<double>(now - since).count()});
  since = now;
}

RegisteredTable registeredTable(ForwardModel& model, const std::vector<double>& theta,
                                int width_px) {
  const int level = model.levelForWidth(width_px);
  const ScatterModel& scatter = model.job().scatter;
  std::vector<std::pair<double, double>> pairs;
  for (int r = 0; r < model.radiographCount(); ++r) {
    const PreparedRadiograph& rad = model.radiograph(r);
    const PixelRect roi = rad.rois[static_cast<size_t>(level)];
    const Image& measured = rad.levels[static_cast<size_t>(level)];
    const Image path = model.pathLengths(theta, r, level, roi);
    std::optional<ScatterEstimate> spread;
    if (scatter.enabled()) spread = model.scatter(theta, r, level);
    auto p = [&](int x, int y) { return static_cast<double>(path(x, y)); };
    // A pixel is smooth when the path is, around it: over its 3 x 3
    // neighbourhood, or along the row for a one-row (line) detector, whose
    // rows have no neighbours.
    const int reach = roi.height >= 5 ? 1 : 0;
    for (int y = 2 * reach; y + 2 * reach < roi.height; ++y)
      for (int x = 2; x + 2 < roi.width; ++x) {
        bool smooth = p(x, y) > 0.0;
        for (int j = -reach; j <= reach && smooth; ++j)
          for (int i = -1; i <= 1 && smooth; ++i) {
            const int u = x + i, v = y + j;
            smooth =
                p(u, v) > 0.0 &&
                std::abs(p(u - 1, v) - 2 * p(u, v) + p(u + 1, v)) <= kSmoothPathMm &&
                (reach == 0 || std::abs(p(u, v - 1) - 2 * p(u, v) + p(u, v + 1)) <= kSmoothPathMm);
          }
        if (!smooth) continue;
        double intensity = static_cast<double>(measured(roi.x + x, roi.y + y));
        if (spread) {
          const ScatterEstimate::Tap tap = spread->tap(roi.x + x + 0.5, roi.y + y + 0.5);
          intensity = scatter.unmix(intensity, spread->at(tap), spread->openAt(tap));
        }
        pairs.push_back({p(x, y), intensity});
      }
  }
  RegisteredTable table;
  table.pixels = static_cast<int64_t>(pairs.size());
  double longest = 0.0;
  for (const auto& [x, i] : pairs) longest = std::max(longest, x);
  if (pairs.empty() || !(longest > 0.0))
    fail(
        "no pixel of the rois sees the part away from its edges: the poses do not put the part in "
        "the rois");
  const int bins =
      static_cast<int>(std::clamp<int64_t>(table.pixels / kPixelsPerBin, kMinBins, kMaxBins));
  const int64_t min_pixels =
      std::clamp<int64_t>(table.pixels / (4 * bins), kMinBinPixels / 4, kMinBinPixels);
  std::vector<double> sum_x(static_cast<size_t>(bins), 0.0), sum_i(sum_x), sum_ii(sum_x);
  std::vector<int64_t> count(static_cast<size_t>(bins), 0);
  for (const auto& [x, i] : pairs) {
    const auto b = static_cast<size_t>(std::min(bins - 1, static_cast<int>(x / longest * bins)));
    sum_x[b] += x, sum_i[b] += i, sum_ii[b] += i * i, ++count[b];
  }
  std::vector<double> errors;
  for (size_t b = 0; b < static_cast<size_t>(bins); ++b) {
    if (count[b] < min_pixels) continue;
    const double n = static_cast<double>(count[b]);
    const double mean = sum_i[b] / n;
    if (!(mean > 0.0 && mean <= 1.5)) continue;  // noise may lift a short path above 1
    table.path_mm.push_back(sum_x[b] / n);
    table.transmission.push_back(mean);
    errors.push_back(std::sqrt(std::max(0.0, sum_ii[b] / n - mean * mean) / n));
  }
  if (table.path_mm.size() < 10)
    fail(
        "only {} path bins have {} or more smooth pixels: the radiographs show too few thicknesses "
        "of the part to calibrate from",
        table.path_mm.size(), min_pixels);
  std::nth_element(errors.begin(), errors.begin() + static_cast<ptrdiff_t>(errors.size() / 2),
                   errors.end());
  table.noise = errors[errors.size() / 2];
  return table;
}

PartCalibrationJob PartCalibrationJob::load(const std::filesystem::path& path) {
  const ConfigNode root = ConfigNode::loadFile(path);
  PartCalibrationJob job;
  if (root.has("material"))
    root.at("material").fail("a calibration finds the material: leave \"material\" out");
  // A job's tolerances would pass the measurement job's reader and be ignored.
  if (root.has("tolerances"))
    root.at("tolerances").fail("a calibration judges no part: leave \"tolerances\" out");
  job.inputs = std::make_shared<const MeasurementInputs>(loadMeasurementInputs(root, path, false));
  const ConfigNode c = root.at("calibration");
  job.terms = static_cast<int>(c.get<double>("terms", 3.0));
  if (job.terms < 1 || job.terms > 4) c.at("terms").fail("expected 1 to 4");
  job.rounds = static_cast<int>(c.get<double>("rounds", 4.0));
  if (job.rounds < 1 || job.rounds > 10) c.at("rounds").fail("expected 1 to 10");
  const ConfigNode initial = c.at("initial");
  const std::string name = initial.get<std::string>("radiograph");
  job.initial_radiograph = -1;
  for (size_t k = 0; k < job.measurement().radiographs.size(); ++k)
    if (job.measurement().radiographs[k].name == name) job.initial_radiograph = static_cast<int>(k);
  if (job.initial_radiograph < 0)
    initial.at("radiograph").fail(fmt::format("no radiograph named '{}'", name));
  job.initial_region = pixelRectFromConfig(initial.at("region"));
  job.initial_path_mm = initial.at("path_mm").number(1e-3, 1e4);
  if (auto floor = c.find("rate_floor")) job.rate_floor = RateFloor::fromConfig(*floor);
  root.finish();
  return job;
}

PartCalibration calibrateFromPart(const PartCalibrationJob& job) {
  PartCalibration out;
  calibrateFromPart(job, out);
  return out;
}

void calibrateFromPart(const PartCalibrationJob& job, PartCalibration& out) {
  const auto start = std::chrono::steady_clock::now();
  out = PartCalibration{};
  std::vector<double> theta = poseKnownPart(job, out);
  refineKnownPart(job, std::move(theta), out);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::vector<double> poseKnownPart(const PartCalibrationJob& job, PartCalibration& out) {
  std::vector<double> theta = searchKnownPart(job, out);
  if (!job.initial_region) theta = freeCurvePoses(job, std::move(theta), out);
  return theta;
}

std::vector<double> searchKnownPart(const PartCalibrationJob& job, PartCalibration& out) {
  auto clock = std::chrono::steady_clock::now();
  out.step = "the initial material (thesis eq. 3.8)";
  if (!job.rate_floor)
    spdlog::warn(
        "no calibration.rate_floor: the curve's rates are not bounded by the material's "
        "attenuation at the tube voltage, and it may level off beyond the calibrated paths");

  // 1. Eq. 3.8 from the uniform region, or from the darkest pixels.
  const RadiographSpec& spec =
      job.measurement().radiographs[static_cast<size_t>(job.initial_radiograph)];
  const PreparedRadiograph& prepared =
      *job.inputs->radiographs[static_cast<size_t>(job.initial_radiograph)];
  std::string region = "the darkest 2 % of the roi";
  if (job.initial_region) {
    const Image& image = prepared.levels.front();
    region = "the initial region " + toString(*job.initial_region);
    if (!image.rect().contains(*job.initial_region))
      fail("{}: {} lies outside the {}x{} image", spec.image.string(), region, image.width(),
           image.height());
    out.initial_intensity = meanOf(image, *job.initial_region);
  } else {
    // On a copy about 256 px wide: the percentile of a few tens of thousands
    // of pixels, with the noise averaged down.
    size_t level = 0;
    while (level + 1 < prepared.levels.size() && prepared.levels[level + 1].width() >= 256) ++level;
    out.initial_intensity =
        percentileOf(prepared.levels[level].crop(prepared.rois[level]), kDarkestPercent);
  }
  if (!(out.initial_intensity > 0.0 && out.initial_intensity < 1.0))
    fail(
        "{}: {} has mean intensity {:.4f}; eq. 3.8 needs one in (0, 1), where the part "
        "attenuates",
        spec.image.string(), region, out.initial_intensity);
  out.initial_mu_per_mm = -std::log(out.initial_intensity) / job.initial_path_mm;
  const ExponentialSum initial({{1.0, out.initial_mu_per_mm}}, "thesis eq. 3.8");
  spdlog::info("initial material (eq. 3.8): I1 = {:.4f} over {:.3f} mm, mu1 = {:.4f} /mm",
               out.initial_intensity, job.initial_path_mm, out.initial_mu_per_mm);

  // 2. Poses with that material or, without a uniform region, with it
  // bent (bentCurve).
  out.step = "the poses with the initial material";
  ForwardModel model(*job.inputs, job.initial_region ? initial : bentCurve(out));
  std::vector<double> theta = model.start();
  const Schedule& schedule = scheduleOf(job);
  MeasureOptions provisional;
  provisional.assess = false;
  provisional.schedule = &schedule;
  // Where the curve is a guess, the pose stages alone (part.h); the losses
  // at full size come with the last round.
  Schedule pose_only = schedule;
  pose_only.joint.clear();
  pose_only.least_squares.enabled = false;
  if (!job.initial_region) {
    provisional.schedule = &pose_only;
    provisional.full_size_losses = false;
  }
  out.measurement = measure(model, theta, provisional);
  addStepSeconds(out.step_seconds, out.step, clock);
  return out.measurement.theta;
}

std::vector<double> freeCurvePoses(const PartCalibrationJob& job, std::vector<double> theta,
                                   PartCalibration& out) {
  auto clock = std::chrono::steady_clock::now();
  // The bent curve is a guess: the poses again with it free (its rates no
  // lower than the floor), by the schedule's joint stages.
  out.step = "the poses with a free curve";
  const ExponentialSum bent = bentCurve(out);
  Schedule joint_only = scheduleOf(job);
  joint_only.least_squares.enabled = false;
  MeasureOptions joint;
  joint.search_poses = false;
  joint.assess = false;
  joint.full_size_losses = false;
  joint.schedule = &joint_only;
  ForwardModel free(*job.inputs, bent);
  std::vector<double> with = theta;
  free.freeMaterial(bent, with, job.rate_floor ? job.rate_floor->per_mm : 0.0);
  MeasurementResult fitted = measure(free, with, joint);
  addStepSeconds(out.step_seconds, out.step, clock);
  if (job.tilt_retry_deg > 0.0) {
    out.step = "the tilts searched again";
    fitted = retryTilts(free, std::move(fitted), joint, job.initial_radiograph, job.tilt_retry_deg);
    addStepSeconds(out.step_seconds, out.step, clock);
  }
  ForwardModel guessed(*job.inputs, bent);
  spdlog::info("poses with a free curve: loss {:.6g} at {} px (with eq. 3.8's curve: {:.6g})",
               jointLoss(free, fitted.theta, joint_only, job.initial_radiograph),
               free.radiograph(job.initial_radiograph)
                   .levels[static_cast<size_t>(jointLevel(free, joint_only).first)]
                   .width(),
               jointLoss(guessed, theta, joint_only, job.initial_radiograph));
  fitted.theta.resize(theta.size());
  return fitted.theta;
}

void refineKnownPart(const PartCalibrationJob& job, std::vector<double> theta,
                     PartCalibration& out) {
  const CurveOptions curve{.max_terms = job.terms,
                           .rate_floor_per_mm = job.rate_floor ? job.rate_floor->per_mm : 0.0};
  auto clock = std::chrono::steady_clock::now();
  const ExponentialSum initial({{1.0, out.initial_mu_per_mm}}, "thesis eq. 3.8");
  ForwardModel model(*job.inputs, initial);

  const Schedule& schedule = scheduleOf(job);
  std::vector<int> radiographs;
  for (int r = 0; r < model.radiographCount(); ++r) radiographs.push_back(r);

  // 3-4. The material from the registered pixels, then everything together
  // (poses, material, any free dimension) by least squares on the residuals,
  // continued until the material settles.
  ExponentialSum material = initial;
  for (int round = 0; round < job.rounds; ++round) {
    out.step = fmt::format("round {}: the table of registered pixels", round + 1);
    const RegisteredTable table = registeredTable(model, theta, job.table_width_px);
    out.path_mm = table.path_mm, out.transmission = table.transmission;
    out.step = fmt::format("round {}: fit the curve", round + 1);
    CurveOptions round_curve = curve;
    round_curve.noise = table.noise;
    // Provisional: the joint fit below corrects the poses that bend it.
    round_curve.max_relative_residual = kProvisionalResidual;
    const CurveFit fit = fitCurve(table.path_mm, table.transmission, round_curve,
                                  "calibration round " + std::to_string(round + 1), &out.fit);
    const TermsFit& asked = fit.fits.back();  // the job's number of terms
    PartCalibrationRound r;
    r.report = asked.report;
    r.pixels = table.pixels;
    if (round == 0) {
      // The joint fit starts from the table's fit.
      const ExponentialSum tabulated(asked.fitted, "fitted to the registered pixels");
      model.setMaterial(tabulated);
      model.freeMaterial(tabulated, theta, curve.rate_floor_per_mm);
    }
    MeasureOptions options;
    options.search_poses = false;
    options.joint_search = false;
    options.assess = false;
    options.full_size_losses = false;  // once, after the last round
    options.schedule = &schedule;
    out.step = fmt::format("round {}: the joint fit of poses and material", round + 1);
    out.measurement = measure(model, theta, options);
    theta = out.measurement.theta;
    r.material = model.materialOf(theta);
    r.material = ExponentialSum(r.material.terms(),
                                fmt::format("calibrated from the known part in {} (round {})",
                                            job.measurement().file.filename().string(), round + 1));
    r.pose_loss = model
                      .loss(theta, leastSquaresLevel(model, schedule),
                            schedule.least_squares.samples, radiographs)
                      .value_or(HUGE_VAL);
    r.change = largestDifference(material, r.material, table.path_mm.back());
    if (spdlog::should_log(spdlog::level::debug)) {
      const Pose pose = model.pose(theta, 0);
      spdlog::debug(
          "round {}: {} rotation ({:.4f}, {:.4f}, {:.4f}) deg, at ({:.4f}, {:.4f}, {:.4f}) mm",
          round + 1, model.spec(0).name, pose.eulerDeg().x(), pose.eulerDeg().y(),
          pose.eulerDeg().z(), pose.translation_mm.x(), pose.translation_mm.y(),
          pose.translation_mm.z());
    }
    spdlog::info(
        "round {}: {} pixels in {} bins up to {:.2f} mm, {}-term fit rms {:.3g} (noise {:.3g}); "
        "after the joint fit the material changed by {:.5f}",
        round + 1, table.pixels, table.path_mm.size(), table.path_mm.back(),
        asked.report.terms_used, asked.report.rms_residual, table.noise, r.change);
    material = r.material;
    out.rounds.push_back(r);
    addStepSeconds(out.step_seconds, fmt::format("round {}", round + 1), clock);
    if (round > 0 && r.change < kSettled) break;
  }
  // The last pose fit's losses at full size, as measure() has them.
  out.measurement.total_loss = 0.0;
  for (int r : radiographs) {
    const int only[] = {r};
    const double loss = model.loss(theta, 0, 2, only).value_or(HUGE_VAL);
    out.measurement.radiographs[static_cast<size_t>(r)].loss = loss;
    out.measurement.total_loss += loss;
  }

  // The final material: the exponential fit to the pixels registered at the
  // final poses. The joint fit's own material follows the image loss, which
  // barely sees short paths (they occur only next to edges); the binned table
  // gives every path length the same weight, as a wedge would.
  out.step = "the final table of registered pixels";
  const RegisteredTable table = registeredTable(model, theta, job.table_width_px);
  out.path_mm = table.path_mm, out.transmission = table.transmission;
  out.step = "fit the final curve";
  CurveOptions final_curve = curve;
  final_curve.noise = table.noise;
  out.fit = fitCurve(table.path_mm, table.transmission, final_curve, "final calibration", &out.fit);
  out.max_path_mm = table.path_mm.back();
  out.material = ExponentialSum(
      out.fit.best().fitted,
      fmt::format("calibrated from the known part of {}: {} exponentials fitted to {} pixels in {} "
                  "path bins up to {:.2f} mm at the jointly fitted poses",
                  job.measurement().file.filename().string(), out.fit.best().report.terms_used,
                  table.pixels, table.path_mm.size(), out.max_path_mm));
  out.material.setTransmissionUncertainty(out.fit.tableUncertainty());
  out.material.setCalibratedRange(std::array<double, 2>{table.path_mm.front(), out.max_path_mm});
  addExtrapolation(out.material, table.path_mm, table.transmission, out.fit);
  addStepSeconds(out.step_seconds, "the final table and curve", clock);
  out.step = "done";
}

}  // namespace xgauge
