// Schedules: how a measurement fits, as data (thesis 3.8, docs/method.md).
//
// Every schedule has the same three steps:
//   1. each radiograph's pose alone, the part at its starting dimensions:
//      free and rotated radiographs by a global search of (ry, x, y) and a
//      local 6-DOF fit; translated ones by their 2-DOF axis;
//   2. every free parameter of every radiograph together, coarse to fine;
//   3. optionally, (reweighted) least squares on the residuals.
// The tables below differ only in their fields; `measure()` reads them.
//
//   thesis   per radiograph: uniform sampling of 5000 points over the whole
//            bounds on the level about 256 px wide, then Nelder-Mead, 5000
//            evaluations (translated: the axis sampled over the sphere, then
//            Nelder-Mead); then everything together at full size by
//            Nelder-Mead, 5000 evaluations.
//   default  the same structure, faster: the position starts at the shadow's
//            centroid and the sampling (150 points) searches a window of a
//            quarter of the part's size around it; the best 4 distinct samples
//            are refined by BOBYQA (multi-start) and the best is refined on
//            a level about 512 px wide (the others, and the poses mirrored
//            as a silhouette allows, are pose candidates the joint fit
//            starts from when the acceptance rule refuses its fit); a translated radiograph's axis
//            comes from the shift of its shadow's centroid. The joint fit runs by Gauss-Newton /
//            Levenberg-Marquardt (Ceres) with the Jacobian of the render with derivatives
//            (xray/derivatives.h) on levels about 512 and 1024 px wide with 2 x 2 area samples;
//            then least squares on the residuals (reweighted for the L1 loss) on the level about
//            1024 px wide (finer where a shadow would be under 128 px across
//            there), of renders whose pixels on edges and silhouettes
//            are sampled 8 x 8 (there and in the uncertainty budget), its
//            Jacobian from the same refined render with derivatives. The
//            derivatives are those of the samples: a wall seen along the
//            beam moves the sampled image only in a strip of samples, and
//            where that strip holds none the exact derivative of its edge is
//            zero (docs/method.md, "Derivatives of the radiograph"); the 8 x 8
//            samples on the edges make such strips four times narrower than
//            the 2 x 2 ones do.
//   bobyqa   the default until the joint fit moved onto the derivatives,
//            kept for comparison: the same pose steps, then the joint fit by
//            BOBYQA on levels about 512, 1024 and 2048 px wide with 2 x 2
//            area samples, each in a window of ten first steps around the
//            estimate so far, then least squares as the default's but on
//            the level about 2048 px wide (the default's until it moved to
//            1024), its Jacobian by forward differences of the refined
//            renders.
//   gauss-newton  the default with point samples alone in its least-squares
//            stage and budget (no edge refinement): faster, but on Prism B
//            at 1024^2 slot_depth's mean error doubled against a refined
//            fit's (docs/decisions/0012-gauss-newton-stays-opt-in.md).
#pragma once

#include "xgauge/optimize/minimize.h"

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace xgauge {

class ForwardModel;

// A local or global stage over one radiograph's pose.
struct PoseStage {
  Method method = Method::kBobyqa;
  int min_width_px = 256;   // the coarsest pyramid level at least this wide
  int evaluations = 0;      // local methods
  int sampling_points = 0;  // uniform sampling
  // First steps, in the units of the parameters they move: (rx, ry, rz in
  // deg, x, y, z in mm) for a pose, (azimuth, elevation in deg) for an axis.
  std::vector<double> steps;
};

struct PoseSchedule {
  // Free and rotated radiographs.
  PoseStage search;  // global search of (r, x, y), r the rotation below
  // The rotation the global search samples over its whole bounds: 0 rx,
  // 1 ry (a turntable's axis, default), 2 rz (a part turned in the plane
  // facing the detector, as a calibration wedge lies).
  int search_rotation = 1;
  // When the part's depth (its magnification) is unknown: the global search
  // runs at this many depths spread evenly in magnification over the z
  // bounds, each with its own window around the shadow, and the multistart
  // refines the best distinct samples of all of them; 0: at the start's depth.
  int search_depths = 0;
  // Start the search at the shadow's centroid seen at the middle depth, and
  // search only a window of `window_of_part_size` x the part's size around it
  // (the rotation over its whole bounds); false: the whole bounds.
  bool search_around_shadow = false;
  double window_of_part_size = 0.25;
  // Refine the best `multistart` distinct samples (at least `separation` of
  // the bounds apart) with `local` and keep the best; 0: refine the best
  // point once.
  int multistart = 0;
  double separation = 0.05;
  // Pose candidates (docs/method.md, "Pose candidates"): a joint fit that
  // has not settled (below) is started again from the next candidate pose
  // of a free or rotated radiograph (the multistart's other distinct
  // minima and the poses mirrored as a silhouette allows, in the order of
  // their search loss), the worst fitting radiograph's first, until one
  // settles or `candidates` joint fits (the first included) have run; the
  // better fit is kept. 1: the search's best alone. Minima whose rotations
  // lie within `candidate_separation_deg` of each other are one.
  int candidates = 1;
  double candidate_separation_deg = 2.0;
  // Settled: the acceptance rule passes the fit and no radiograph's misfit
  // ratio (rms residual over noise) exceeds this; of fits the rule passes
  // the smallest worst ratio is kept: on a stepped shaft a pose mirrored by its symmetry
  // passed with 1.98 where the true pose left 1.0 to 1.3.
  double settled_misfit_ratio = 1.5;
  PoseStage local;                    // 6-DOF
  std::vector<PoseStage> finer = {};  // 6-DOF refinements, in order

  // Translated radiographs.
  bool axis_from_shadow_shift = false;  // else: axis_search samples the sphere
  PoseStage axis_search;
  PoseStage axis_local;
  std::vector<PoseStage> axis_finer = {};
};

// One stage of the joint fit.
struct JointStage {
  Method method = Method::kBobyqa;
  int min_width_px = 0;  // 0: full size
  int samples = 1;       // area samples per pixel axis
  int evaluations = 0;
  // First steps: this times each kind's first step (measure.cpp firstStep).
  double step_scale = 1.0;
  // The stage searches within `window_steps` first steps of the estimate so
  // far (bounds of similar sensitivity keep a trust region well shaped); 0:
  // within the whole bounds.
  double window_steps = 0.0;
  // Gauss-Newton (Ceres' Levenberg-Marquardt, measure/least_squares.h) for at
  // most `evaluations` iterations instead of `method`, within the bounds.
  bool gauss_newton = false;
};

struct LeastSquaresStage {
  bool enabled = false;
  // The stage's level (leastSquaresLevel below): the coarsest
  // at least min_width_px wide, and finer while some radiograph's region of
  // interest is narrower than min_roi_px on its shorter side there (a small
  // shadow on a large detector keeps its pixels).
  int min_width_px = 2048;
  int min_roi_px = 0;
  int samples = 2;
  int max_iterations = 30;
  // The Jacobian from the render with derivatives (else forward differences).
  bool render_derivatives = false;
  // Pixels on the projection of an edge or a silhouette sampled again with
  // edge_samples x edge_samples points (xray/renderer.h) in this stage and
  // in the uncertainty budget and self-checks after it; 0: never. With
  // `samples` x `samples` points alone, a wall seen along the beam moves the
  // image only when it passes a point, so the fit lands anywhere within
  // 1/samples of a pixel and the budget's re-solves stick (docs/method.md,
  // "The pixel's integral").
  int edge_samples = 0;
};

enum class ScheduleKind { kDefault, kBobyqa, kGaussNewton, kThesis };

struct Schedule {
  ScheduleKind kind = ScheduleKind::kDefault;
  PoseSchedule pose;
  std::vector<JointStage> joint;
  LeastSquaresStage least_squares;
};

// The tables described at the top of this file.
const Schedule& scheduleFor(ScheduleKind kind);

// The pyramid level of the schedule's least-squares stage for this model,
// of the budget and of the self-checks after it (LeastSquaresStage::
// min_width_px and min_roi_px).
int leastSquaresLevel(const ForwardModel& model, const Schedule& schedule);
// "default", "bobyqa", "gauss-newton", "thesis".
std::string_view scheduleName(ScheduleKind kind);
// Inverse of scheduleName; nullopt for an unknown name.
std::optional<ScheduleKind> scheduleKindFromName(std::string_view name);

}  // namespace xgauge
