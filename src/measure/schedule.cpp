#include "xgauge/measure/schedule.h"

namespace xgauge {

namespace {

// First steps of a 6-DOF pose stage: rx, ry, rz (deg), x, y, z (mm).
const std::vector<double> kPoseSteps{2.0, 5.0, 2.0, 1.0, 1.0, 10.0};

// The derivative-free schedule that was the default until the joint fit
// moved onto the render's derivatives; kept for comparison (schedule.h).
Schedule makeBobyqa() {
  Schedule s;
  s.kind = ScheduleKind::kBobyqa;
  PoseSchedule& p = s.pose;
  p.search = {Method::kUniformSampling, 256, 0, 150, {}};
  p.search_around_shadow = true;
  p.window_of_part_size = 0.25;
  p.multistart = 4;
  p.separation = 0.05;
  p.candidates = 4;
  p.local = {Method::kBobyqa, 256, 150, 0, kPoseSteps};
  p.finer = {{Method::kBobyqa, 512, 200, 0, {0.5, 1.0, 0.5, 0.2, 0.2, 2.0}}};
  p.axis_from_shadow_shift = true;
  p.axis_local = {Method::kBobyqa, 256, 120, 0, {5.0, 5.0}};
  p.axis_finer = {{Method::kBobyqa, 512, 80, 0, {1.0, 1.0}}};
  // Coarse to fine, up to 2048 px wide: beyond that the loss is dominated by
  // pixel noise and a 4096^2 stage costs more than it changes (measured:
  // 16 s for a loss change of 1e-4 relative). Where the images are small,
  // several stages share a level and act as restarts with smaller steps.
  s.joint = {{Method::kBobyqa, 512, 2, 1200, 1.0, 10.0},
             {Method::kBobyqa, 1024, 2, 700, 0.3, 10.0},
             {Method::kBobyqa, 2048, 2, 300, 0.1, 10.0}};
  s.least_squares.enabled = true;
  s.least_squares.min_width_px = 2048;
  s.least_squares.samples = 2;
  s.least_squares.max_iterations = 30;
  s.least_squares.edge_samples = 8;
  return s;
}

Schedule makeDefault() {
  Schedule s = makeBobyqa();
  s.kind = ScheduleKind::kDefault;
  // The joint fit by Levenberg-Marquardt on the render's derivatives (taken
  // again only after a large move or near the end: least_squares.cpp), and
  // a start from the pose steps converges in a handful of steps on each
  // level.
  JointStage coarse;
  coarse.gauss_newton = true;
  coarse.min_width_px = 512;
  coarse.samples = 2;
  coarse.evaluations = 20;
  JointStage finer = coarse;
  finer.min_width_px = 1024;
  finer.evaluations = 10;
  s.joint = {coarse, finer};
  // The least-squares stage on the derivatives of the refined render: its
  // edge pixels' 8 x 8 samples are differentiated as the others' are.
  s.least_squares.render_derivatives = true;
  // On a level about 1024 px wide rather than 2048: the refined render
  // integrates each pixel's area, so a coarser pixel still places an edge
  // by its partial value, and the replica's 21 Prism A pairs at 4096^2 came
  // out as accurate (mean |error| 0.0232 mm against 0.0226, max 0.0662
  // against 0.0645, every edge dimension within 0.0005 mm of it) in half the
  // time (docs/decisions/0017-final-stage-on-the-1024-level.md). A shadow narrower than 128 px
  // there keeps a finer level.
  s.least_squares.min_width_px = 1024;
  s.least_squares.min_roi_px = 128;
  return s;
}

Schedule makeGaussNewton() {
  Schedule s = makeDefault();
  s.kind = ScheduleKind::kGaussNewton;
  s.least_squares.edge_samples = 0;  // point samples only
  return s;
}

Schedule makeThesis() {
  Schedule s;
  s.kind = ScheduleKind::kThesis;
  PoseSchedule& p = s.pose;
  p.search = {Method::kUniformSampling, 256, 0, 5000, {}};
  p.local = {Method::kNelderMead, 256, 5000, 0, kPoseSteps};
  p.axis_search = {Method::kUniformSampling, 256, 0, 5000, {}};
  p.axis_local = {Method::kNelderMead, 256, 5000, 0, {5.0, 5.0}};
  s.joint = {{Method::kNelderMead, 0, 1, 5000, 1.0, 0.0}};
  return s;
}

}  // namespace

const Schedule& scheduleFor(ScheduleKind kind) {
  static const Schedule kDefault = makeDefault();
  static const Schedule kBobyqa = makeBobyqa();
  static const Schedule kGaussNewton = makeGaussNewton();
  static const Schedule kThesis = makeThesis();
  switch (kind) {
    case ScheduleKind::kDefault:
      break;
    case ScheduleKind::kBobyqa:
      return kBobyqa;
    case ScheduleKind::kGaussNewton:
      return kGaussNewton;
    case ScheduleKind::kThesis:
      return kThesis;
  }
  return kDefault;
}

std::string_view scheduleName(ScheduleKind kind) {
  switch (kind) {
    case ScheduleKind::kDefault:
      break;
    case ScheduleKind::kBobyqa:
      return "bobyqa";
    case ScheduleKind::kGaussNewton:
      return "gauss-newton";
    case ScheduleKind::kThesis:
      return "thesis";
  }
  return "default";
}

std::optional<ScheduleKind> scheduleKindFromName(std::string_view name) {
  for (ScheduleKind kind :
       {ScheduleKind::kDefault, ScheduleKind::kBobyqa, ScheduleKind::kGaussNewton,
        ScheduleKind::kThesis})
    if (name == scheduleName(kind)) return kind;
  return std::nullopt;
}

}  // namespace xgauge
