#include "wedge_part.h"

#include "xgauge/core/error.h"
#include "xgauge/geometry/mesh.h"
#include "xgauge/measure/inputs.h"
#include "xgauge/measure/model.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <span>

namespace xgauge {

namespace {

constexpr double kMinMagnification = 1.05;

// The known wedge's fit (wedge_part.h, steps 2, 4 and 5), one schedule
// whose parts run apart (part.h): its pose stages alone with the guessed
// curve, its joint stages with the curve free, its least squares in the
// rounds.
// - The pose: the search over rz at 21 depths (magnifications about 8 %
//   apart) on the level about 128 px wide (600 samples each: about 15
//   degrees and a tenth of the window apart), 10 of its best distinct
//   samples refined on the level about 192 px wide (a start's depth may be
//   4 % off), the best again about 384 px wide: the outline placed to a
//   fraction of those pixels, which is all the joint fit needs to start.
// - The joint fit with the curve free: Levenberg-Marquardt on the render's
//   derivatives (the default schedule's), on the levels about 384 and 768
//   px wide, 2 x 2 samples.
// - The rounds' least squares: the default's (the render's derivatives, the
//   edges sampled 8 x 8) on the level about 768 px wide, finer where the
//   shadow is under 128 px across there, at most 5 iterations a round: it
//   only places the pose (the curve comes from the table), to a small
//   fraction of those pixels, which moves a path by micrometres.
// Keyed to widths, so that a 256^2 shot fits on its full size throughout
// and a 4096^2 one at 1024 px at most.
Schedule wedgeSchedule() {
  Schedule s = scheduleFor(ScheduleKind::kDefault);
  PoseSchedule& p = s.pose;
  p.search = {Method::kUniformSampling, 128, 0, 600, {}};
  p.search_rotation = 2;
  p.search_depths = 21;
  p.search_around_shadow = true;
  // A partly seen wedge's shadow centroid lies up to about a third of its
  // size from the projection of its centre.
  p.window_of_part_size = 0.35;
  p.multistart = 10;
  p.separation = 0.03;
  p.local = {Method::kBobyqa, 192, 500, 0, {1.0, 1.0, 10.0, 5.0, 5.0, 30.0}};
  p.finer = {{Method::kBobyqa, 384, 500, 0, {0.5, 0.5, 1.0, 1.0, 1.0, 10.0}}};
  // The default's joint fit (Levenberg-Marquardt on the render's
  // derivatives: 20, then 10 iterations with 2 x 2 samples) and least
  // squares, on coarser levels.
  XG_CHECK(s.joint.size() == 2 && s.joint.front().gauss_newton,
           "the default schedule's joint fit has changed");
  s.joint[0].min_width_px = 384;
  s.joint[1].min_width_px = 768;
  s.least_squares.min_width_px = 768;
  s.least_squares.max_iterations = 5;
  return s;
}

// The loaded inputs of the known-part fit: the wedge's model at the caliper
// values (every dimension fixed), `image` (normalized, the scatter removed:
// the model adds none) and pose bounds that cover every sensible set-up.
MeasurementInputs knownWedgeInputs(const WedgeCalibrationJob& job, const Image& image,
                                   const std::map<std::string, double>& caliper) {
  MeasurementInputs in;
  MeasurementJob& m = in.job;
  m.file = job.file;
  m.description = job.description;
  m.part_file = job.model_file;
  m.machine_file = job.machine_file;
  m.fixed_dimensions = caliper;
  RadiographSpec spec = job.radiograph;
  spec.dark.clear(), spec.flat.clear();  // `image` is normalized already
  m.radiographs = {spec};
  const Machine& machine = job.machine;
  const double d = machine.source_detector_distance_mm;
  const double width_mm =
      std::max(machine.columns * machine.pitch_u_mm, machine.rows * machine.pitch_v_mm);
  const double max_magnification = std::max(2.0 * kMinMagnification, width_mm / kMinVisibleMm);
  const double size = boundingBox(job.model->mesh(job.model->values(caliper))).diagonal();
  m.rotation_bounds_deg = {
      {{-kMaxTiltDeg, kMaxTiltDeg}, {-kMaxTiltDeg, kMaxTiltDeg}, {-180.0, 180.0}}};
  // World x along the columns, y against the rows, 0 on the principal point.
  m.centre_bounds_mm = {
      {{-machine.cx_px * machine.pitch_u_mm - size,
        (machine.columns - machine.cx_px) * machine.pitch_u_mm + size},
       {-(machine.rows - machine.cy_px) * machine.pitch_v_mm - size,
        machine.cy_px * machine.pitch_v_mm + size},
       {d * (1.0 - 1.0 / kMinMagnification), d * (1.0 - 1.0 / max_magnification)}}};
  in.part = job.model;
  in.machine = machine;
  in.radiographs = {
      std::make_shared<const PreparedRadiograph>(prepareRadiograph(image, {}, spec, machine))};
  return in;
}

// The wedge's smallest extent at its caliper values: its thickness.
double smallestExtent(const PartModel& model, const std::map<std::string, double>& caliper) {
  const BoundingBox box = boundingBox(model.mesh(model.values(caliper)));
  const Vec3 extent = box.max_mm - box.min_mm;
  return extent.minCoeff();
}

// Step 7, the curve's uncertainty: the table read again at the fitted pose
// `theta` with each influence (the scatter's weight and width, each caliper
// value) moved by its standard uncertainty, into out.influences.
void knownWedgeInfluences(const WedgeCalibrationJob& job, const PartCalibrationJob& part_job,
                          const Image& normalized, const std::vector<double>& theta,
                          WedgeCalibration& out) {
  const std::string name = job.radiograph.image.string();
  const Machine& machine = job.machine;
  out.step = "the curve's uncertainty";
  const int terms = out.fit.best().terms;
  auto propagate = [&](const std::string& influence, double value, double u,
                       const MeasurementInputs& moved, const std::vector<double>& at,
                       const char* unit = "mm") {
    if (!(u > 0.0)) return;
    try {
      ForwardModel model(moved, out.material);
      const RegisteredTable table = registeredTable(model, at, part_job.table_width_px);
      const CurveOptions options{
          .max_terms = terms,
          .noise = table.noise,
          .rate_floor_per_mm = job.rate_floor ? job.rate_floor->per_mm : 0.0};
      const CurveFit fit = fitCurve(table.path_mm, table.transmission, options, name);
      const ExponentialSum curve(fit.best().fitted);
      out.influences.push_back(
          {influence, value, u, largestDifference(out.material, curve, out.x_max_mm), curve, unit});
    } catch (const Error& e) {
      fail("the calibration does not survive its {} moved by its standard uncertainty ({}): {}",
           influence, u, e.message());
    }
  };
  const ScatterModel& scatter = out.scatter;
  if (scatter.enabled()) {
    auto without = [&](double weight, double sigma_mm, double heel = OpenBeamField::kHeelShare) {
      return out.primaryWith(normalized, machine.pitch_u_mm, job.radiograph.white_region, weight,
                             sigma_mm, heel);
    };
    propagate(kScatterWeightInfluence, scatter.weight, scatter.weight_uncertainty,
              knownWedgeInputs(
                  job, without(scatter.weight + scatter.weight_uncertainty, scatter.sigma_mm),
                  job.caliper),
              theta);
    propagate(kScatterWidthInfluence, scatter.sigma_mm, scatter.sigma_uncertainty_mm,
              knownWedgeInputs(
                  job, without(scatter.weight, scatter.sigma_mm + scatter.sigma_uncertainty_mm),
                  job.caliper),
              theta);
    if (out.open_beam.sloped())
      propagate(kOpenBeamHeelInfluence, OpenBeamField::kHeelShare,
                OpenBeamField::kHeelShareUncertainty,
                knownWedgeInputs(
                    job,
                    without(scatter.weight, scatter.sigma_mm,
                            OpenBeamField::kHeelShare + OpenBeamField::kHeelShareUncertainty),
                    job.caliper),
                theta, "1");
    for (const HaloAlternative& a : kernelAlternatives(out)) {
      propagate(a.name, scatter.equivalentSigmaMm(), a.u,
                knownWedgeInputs(job,
                                 a.kernel.remove(normalized, machine.pitch_u_mm,
                                                 job.radiograph.white_region, out.open_beam),
                                 job.caliper),
                theta);
      if (!out.influences.empty() && out.influences.back().name == a.name)
        out.influences.back().change *= std::abs(a.scale);
    }
  }
  // A dimension's value is in theta (the model's first entries, fixed or
  // free): moved up, or down where up breaks its bounds or a constraint.
  for (const auto& [dimension, value] : job.caliper) {
    std::vector<double> moved = theta;
    const auto i = static_cast<size_t>(job.model->dimensionIndex(dimension));
    moved[i] = value + job.caliper_uncertainty_mm;
    if (job.model->invalidity(std::span(moved).first(job.model->dimensions().size())))
      moved[i] = value - job.caliper_uncertainty_mm;
    propagate("wedge " + dimension, value, job.caliper_uncertainty_mm, *part_job.inputs, moved);
  }
}

}  // namespace

void calibrateKnownWedge(const WedgeCalibrationJob& job, const Image& normalized,
                         const Image& image, std::optional<HaloFit> box_halo,
                         WedgeCalibration& out) {
  const std::string name = job.radiograph.image.string();
  const Machine& machine = job.machine;
  out.step = "the wedge's model in the radiograph";
  auto part_job = std::make_shared<PartCalibrationJob>();
  part_job->inputs =
      std::make_shared<const MeasurementInputs>(knownWedgeInputs(job, image, job.caliper));
  part_job->terms = job.max_terms;
  part_job->initial_radiograph = 0;
  part_job->initial_path_mm = smallestExtent(*job.model, job.caliper);
  part_job->rate_floor = job.rate_floor;
  part_job->pose_schedule = wedgeSchedule();
  part_job->tilt_retry_deg = kTiltRetryDeg;
  part_job->table_width_px = kTableWidthPx;
  out.part_job = part_job;
  out.part.emplace();
  PartCalibration& part = *out.part;
  const auto start = std::chrono::steady_clock::now();
  auto clock = start;
  // The part calibration's steps' seconds, then this one's own.
  auto takeSteps = [&] {
    for (StepSeconds& s : part.step_seconds) out.step_seconds.push_back(std::move(s));
    part.step_seconds.clear();
    clock = std::chrono::steady_clock::now();
  };
  try {
    std::vector<double> theta = searchKnownPart(*part_job, part);
    takeSteps();
    if (job.estimate_scatter) {
      // The scatter from the open beam the posed wedge leaves (halo.h: the
      // pose search's outline is the shadow's), then the rest on the
      // radiograph without it; where that does not decide, the one around
      // the box of the radiograph's sharp edges.
      part.step = "the scatter around the posed wedge";
      const PreparedRadiograph& prepared = *part_job->inputs->radiographs.front();
      HaloOptions options;
      options.field = out.open_beam;
      size_t level = 0;
      while (level + 1 < prepared.levels.size() &&
             std::max(prepared.levels[level].width(), prepared.levels[level].height()) >
                 options.max_side)
        ++level;
      ForwardModel model(*part_job->inputs, ExponentialSum({{1.0, part.initial_mu_per_mm}}));
      const Image path =
          model.pathLengths(theta, 0, static_cast<int>(level), prepared.levels[level].rect());
      std::optional<HaloFit> halo;
      try {
        halo = fitScatterWithPaths(normalized, path, machine.pitch_u_mm, name, options);
        spdlog::info(
            "{}: scatter around the posed wedge: weight {:.4f} +- {:.2g}, sigma {:.1f} +- {:.2g} "
            "mm; residual correlation {:.1f}; column darkening {:.4f} per unit attenuation{}",
            name, halo->scatter.weight, halo->scatter.weight_uncertainty, halo->scatter.sigma_mm,
            halo->scatter.sigma_uncertainty_mm, halo->correlation, halo->column_darkening,
            box_halo ? fmt::format(" (around the box of its edges: weight {:.4f}, sigma {:.1f} mm)",
                                   box_halo->scatter.weight, box_halo->scatter.sigma_mm)
                     : std::string());
      } catch (const Error& e) {
        if (!box_halo) throw;
        spdlog::warn(
            "{}: the open beam around the posed wedge does not decide the scatter ({}); the one "
            "around the box of the radiograph's sharp edges is taken: weight {:.4f}, sigma "
            "{:.1f} mm",
            name, e.message(), box_halo->scatter.weight, box_halo->scatter.sigma_mm);
        halo = std::move(box_halo);
      }
      part_job->inputs = std::make_shared<const MeasurementInputs>(
          knownWedgeInputs(job, halo->primary, job.caliper));
      out.normalized = std::move(halo->primary);
      halo->primary = Image();
      out.scatter = halo->scatter;
      out.halo = std::move(halo);
      addStepSeconds(out.step_seconds, part.step, clock);
    }
    theta = freeCurvePoses(*part_job, std::move(theta), part);
    refineKnownPart(*part_job, std::move(theta), part);
    takeSteps();
  } catch (const Error&) {
    out.step = "the wedge as a known part: " + part.step;
    out.path_mm = part.path_mm, out.transmission = part.transmission, out.fit = part.fit;
    throw;
  }
  part.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  out.path_mm = part.path_mm, out.transmission = part.transmission, out.fit = part.fit;
  out.material = part.material;
  out.x_max_mm = part.max_path_mm;
  const Pose pose = part.measurement.radiographs.front().pose;
  const Vec3 angles = pose.eulerDeg();
  const double d = machine.source_detector_distance_mm;
  const BoundingBox box = boundingBox(job.model->mesh(job.model->values(job.caliper)));
  out.magnification = d / (d - pose.apply(0.5 * (box.min_mm + box.max_mm)).z());
  spdlog::info(
      "{}: the wedge's pose: rotation ({:.2f}, {:.2f}, {:.2f}) deg, centre at magnification "
      "{:.3f}; {} rounds, final table of {} path bins up to {:.2f} mm",
      name, angles.x(), angles.y(), angles.z(), out.magnification, part.rounds.size(),
      out.path_mm.size(), out.x_max_mm);
  if (std::max(std::abs(angles.x()), std::abs(angles.y())) > kMaxTiltDeg - 0.05)
    spdlog::warn(
        "{}: the wedge's tilt ({:.2f}, {:.2f}) deg ends at the search's bound of {} deg: the pose, "
        "and with it the curve, is probably wrong; check that the wedge lies flat",
        name, angles.x(), angles.y(), kMaxTiltDeg);
  std::vector<double> theta = part.measurement.theta;
  theta.resize(static_cast<size_t>(ForwardModel(*part_job->inputs, out.material).size()));
  out.table_uncertainty = out.fit.tableUncertainty();

  // 7. The curve's uncertainty: each influence moved by its standard
  // uncertainty.
  knownWedgeInfluences(job, *part_job, normalized, theta, out);
  combineCurveUncertainty(name, out);
  out.material.setCalibratedRange(std::array<double, 2>{out.path_mm.front(), out.x_max_mm});
  part.material = out.material;  // what the outputs write
  addStepSeconds(out.step_seconds, out.step, clock);
}

}  // namespace xgauge
