// The budget's influence quantities (docs/method.md, "Uncertainty"): one
// table, kInfluences, whose entries each list their moves of the model by
// the quantity's standard uncertainty u (one per calibration input or
// radiograph where there are several), with what the budget reports of it
// (name, quantity, unit, u) and how its shift is found (Propagation).
#include "budget_internal.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <utility>

namespace xgauge::budget_internal {

namespace {

// A material's curve move (a calibration input) smaller than this share of
// its largest is propagated with the rest of the curve's uncertainty.
constexpr double kMinorMoveShare = 0.1;

// What the influence quantities are read from.
struct InfluenceSource {
  const ForwardModel& model;
  const MeasurementInputs& inputs;  // the model's
  int fit_level = 0;                // the fit's level
  int level = 0;                    // the re-solves' (resolveLevel)
  // A model with the material free (a calibration) has parameters a moved
  // model would not: its influences are not propagated.
  bool propagate = true;
};

using InfluenceMoves = std::vector<InfluenceMove>;

InfluenceMove leftOut(std::string note) {
  InfluenceMove move;
  move.left_out = std::move(note);
  return move;
}

// An influence that moves the model's inputs, listed where its u is
// positive and the influences are propagated. change(inputs, amount) moves
// the influence by amount * u; `curve`, when given, is the material curve
// that goes with it.
void withInputs(const InfluenceSource& source, InfluenceMoves& out, Propagation how,
                const std::string& name, const std::string& quantity, const std::string& unit,
                double u, std::function<void(MeasurementInputs&, double)> change,
                const std::optional<ExponentialSum>& curve = std::nullopt) {
  if (!(u > 0.0) || !source.propagate) return;
  InfluenceMove move;
  move.influence = {name, quantity, unit, u, {}};
  move.how = how;
  move.change = std::move(change);
  move.curve = curve;
  out.push_back(std::move(move));
}

double largestCurveMove(const std::vector<CurveMove>& moves) {
  double largest = 0.0;
  for (const CurveMove& move : moves) largest = std::max(largest, move.curve_change);
  return largest;
}

// The curve's own moves (a wedge's caliper dimensions): each one is a
// component with its own curve. Those that move the curve by less than
// kMinorMoveShare of the largest go with the rest (materialRest), to save
// their renders. A model with the material free lists only the note that
// the budget is the statistical part alone.
void curveMoves(const InfluenceSource& source, InfluenceMoves& out) {
  if (!source.propagate) {
    out.push_back(leftOut(
        "the material is fitted with the dimensions (a calibration): only the statistical part "
        "is given"));
    return;
  }
  const std::vector<CurveMove>& moves = source.model.material().curveMoves();
  const double largest = largestCurveMove(moves);
  for (const CurveMove& move : moves) {
    if (move.curve_change < kMinorMoveShare * largest) continue;
    InfluenceMove moved;
    moved.influence = {"material: " + move.name,
                       fmt::format("{} = {:.4g} +- {:.2g} {}, the curve it calibrated", move.name,
                                   move.value, move.standard_uncertainty, move.unit),
                       move.unit,
                       move.standard_uncertainty,
                       {}};
    moved.how = Propagation::kLinearised;
    moved.curve = move.curve;
    out.push_back(std::move(moved));
  }
}

// The rest of the curve's uncertainty (the material's table's, or what the
// calibration inputs' own moves leave).
void materialRest(const InfluenceSource& source, InfluenceMoves& out) {
  if (!source.propagate) return;
  const ExponentialSum& material = source.model.material();
  double rest2 = material.transmissionUncertainty() * material.transmissionUncertainty();
  const std::vector<CurveMove>& moves = material.curveMoves();
  if (!moves.empty()) {
    rest2 = material.curveMovesBesides() * material.curveMovesBesides();
    const double largest = largestCurveMove(moves);
    for (const CurveMove& move : moves)
      if (move.curve_change < kMinorMoveShare * largest)
        rest2 += move.curve_change * move.curve_change;
  }
  // When the scatter comes from the material's calibration and the file
  // says how the curve moves with it, the scatter's share of the curve's
  // uncertainty goes with the scatter's components: what is left is
  // besides_scatter^2 - (u^2 - rest^2).
  if (const auto& curves = source.inputs.scatter_curves) {
    const double u = material.transmissionUncertainty();
    rest2 -=
        u * u - curves->transmission_uncertainty_besides * curves->transmission_uncertainty_besides;
  }
  const double u = std::sqrt(std::max(0.0, rest2));
  // The rest as a scale of the rates that moves the curve by u at the
  // worst path: dI/d(scale) = -x sum a_k mu_k exp(-mu_k x).
  const double scale = material.rateScaleFor(u, source.model.partSizeMm());
  if (!(scale > 0.0)) return;
  InfluenceMove moved;
  moved.influence = {"material",
                     fmt::format("transmission curve, u = {:.2g}{}", u,
                                 moves.empty() ? "" : " besides the calibration's inputs"),
                     "transmission",
                     u,
                     {},
                     scale};
  moved.how = Propagation::kLinearised;
  moved.curve = material.withScaledRates(scale);
  out.push_back(std::move(moved));
}

// A two-width halo's alternatives (image/scatter.h): the kernel at its
// equivalent width's end (the halo refitted to the edge shot with its
// Gaussian-equivalent width one u wider: the tail beyond the panel the
// shot cannot see) and the other kernel that fits the shot about as well,
// each with the curve calibrated with it where the material has one. Each
// shift is scaled by u over the alternative's distance in sigma_eq (the
// linearised shift is linear in the move; 1 for the other kernel, whose
// whole difference is its u). Beside the core width's component, not
// instead of it: the core's u holds the near edge's blur, these the far
// halo's.
void scatterKernels(const InfluenceSource& source, InfluenceMoves& out) {
  const ScatterModel& scatter = source.inputs.job.scatter;
  if (!source.propagate) return;
  const std::optional<ScatterCurves>& curves = source.inputs.scatter_curves;
  for (const HaloAlternative& a : scatter.alternatives()) {
    std::optional<ExponentialSum> curve;
    if (curves) curve = a.end ? curves->equivalent_end : curves->kernel_choice;
    InfluenceMove move;
    move.influence = {
        a.name,
        fmt::format(
            "sigma_eq = {:.4g} +- {:.2g} mm, {}{}", scatter.equivalentSigmaMm(), a.u,
            a.end ? "the kernel refitted at its end"
                  : fmt::format("the {} kernel that fits about as well", toString(a.kernel.shape)),
            curve ? ", with the curve it calibrated" : ""),
        "mm",
        a.u,
        {}};
    move.how = Propagation::kLinearised;
    // The move is the alternative's, whatever the amount (the budget moves by 1).
    move.change = [kernel = a.kernel](MeasurementInputs& in, double) { in.job.scatter = kernel; };
    move.curve = curve;
    move.scale = a.scale;
    out.push_back(std::move(move));
  }
}

// The scatter's weight and width. With the material's scatter curves, each
// scatter component moves the measurement's scatter and the curve its
// calibration would then have found, together.
void scatterComponents(const InfluenceSource& source, InfluenceMoves& out) {
  const ScatterModel& scatter = source.inputs.job.scatter;
  if (!scatter.enabled()) return;
  const std::optional<ScatterCurves>& curves = source.inputs.scatter_curves;
  const char* with_curve = curves ? ", with the curve it calibrated" : "";
  withInputs(
      source, out, Propagation::kLinearised, "scatter weight",
      fmt::format("w = {:.4g} +- {:.2g}{}", scatter.weight, scatter.weight_uncertainty, with_curve),
      "1", scatter.weight_uncertainty,
      [u = scatter.weight_uncertainty](MeasurementInputs& in, double amount) {
        in.job.scatter.weight += amount * u;
      },
      curves ? curves->weight_plus_u : std::nullopt);
  withInputs(
      source, out, Propagation::kLinearised, "scatter width",
      fmt::format("sigma = {:.4g} +- {:.2g} mm{}", scatter.sigma_mm, scatter.sigma_uncertainty_mm,
                  with_curve),
      "mm", scatter.sigma_uncertainty_mm,
      [u = scatter.sigma_uncertainty_mm](MeasurementInputs& in, double amount) {
        in.job.scatter.sigma_mm += amount * u;
      },
      curves ? curves->sigma_plus_u : std::nullopt);
  scatterKernels(source, out);
}

// The machine's source-detector distance and pixel pitch.
void machineGeometry(const InfluenceSource& source, InfluenceMoves& out) {
  const Machine& machine = source.inputs.machine;
  withInputs(
      source, out, Propagation::kIterated, "source-detector distance",
      fmt::format("D = {:.2f} +- {:.2g} mm", machine.source_detector_distance_mm,
                  machine.source_detector_distance_uncertainty_mm),
      "mm", machine.source_detector_distance_uncertainty_mm,
      [u = machine.source_detector_distance_uncertainty_mm](MeasurementInputs& in, double amount) {
        in.machine.source_detector_distance_mm += amount * u;
      });
  withInputs(source, out, Propagation::kIterated, "pixel pitch",
             fmt::format("pitch {:.4g} mm, relative u = {:.2g}", machine.pitch_u_mm,
                         machine.pixel_pitch_uncertainty_relative),
             "relative", machine.pixel_pitch_uncertainty_relative,
             [u = machine.pixel_pitch_uncertainty_relative](MeasurementInputs& in, double amount) {
               in.machine.pitch_u_mm *= 1.0 + amount * u;
               in.machine.pitch_v_mm *= 1.0 + amount * u;
             });
}

// The detector's pose as a geometry calibration stated it: each angle
// moved by its standard uncertainty.
void detectorPose(const InfluenceSource& source, InfluenceMoves& out) {
  const Machine& machine = source.inputs.machine;
  static constexpr std::array<const char*, 3> kNames{"detector tilt about u",
                                                     "detector tilt about v", "detector rotation"};
  for (size_t k = 0; k < 3; ++k) {
    const double u = machine.detector_pose_uncertainty_deg[k];
    const double angle = k < 2 ? machine.detector_tilt_deg[k] : machine.detector_rotation_deg;
    withInputs(source, out, Propagation::kIterated, kNames[k],
               fmt::format("{:.4f} +- {:.2g} deg", angle, u), "deg", u,
               [k, u](MeasurementInputs& in, double amount) {
                 std::array<double, 3> pose{in.machine.detector_tilt_deg[0],
                                            in.machine.detector_tilt_deg[1],
                                            in.machine.detector_rotation_deg};
                 pose[k] += amount * u;
                 in.machine.setDetectorPose(pose[0], pose[1], pose[2]);
               });
  }
}

// The known distance of each translated radiograph.
void translations(const InfluenceSource& source, InfluenceMoves& out) {
  const MeasurementInputs& inputs = source.inputs;
  for (size_t k = 0; k < inputs.job.radiographs.size(); ++k) {
    const RadiographSpec& spec = inputs.job.radiographs[k];
    if (spec.pattern != Acquisition::kTranslated) continue;
    const double u = spec.distance_uncertainty_mm;
    withInputs(source, out, Propagation::kIterated, "translation " + spec.name,
               fmt::format("distance {:.4f} +- {:.2g} mm", spec.distance_mm, u), "mm", u,
               [k, u](MeasurementInputs& in, double amount) {
                 in.job.radiographs[k].distance_mm += amount * u;
               });
  }
}

// The turntable of turned radiographs: each one's angle, and the machine's
// axis, its point moved across the axis and its direction tilted, each in
// two directions perpendicular to it (the first in the detector's plane).
void turntable(const InfluenceSource& source, InfluenceMoves& out) {
  const MeasurementInputs& inputs = source.inputs;
  bool turned = false;
  for (size_t k = 0; k < inputs.job.radiographs.size(); ++k) {
    const RadiographSpec& spec = inputs.job.radiographs[k];
    if (spec.pattern != Acquisition::kTurned) continue;
    turned = true;
    const double u = spec.angle_uncertainty_deg;
    withInputs(source, out, Propagation::kIterated, "turn " + spec.name,
               fmt::format("angle {:.4f} +- {:.2g} deg", spec.angle_deg, u), "deg", u,
               [k, u](MeasurementInputs& in, double amount) {
                 in.job.radiographs[k].angle_deg += amount * u;
               });
  }
  if (!turned || !inputs.machine.turntable) return;
  const Turntable& axis = *inputs.machine.turntable;
  Vec3 across = axis.direction.cross(Vec3::UnitZ());
  if (across.norm() < 1e-6) across = axis.direction.cross(Vec3::UnitX());
  across.normalize();
  const Vec3 other = axis.direction.cross(across).normalized();
  const std::pair<const char*, Vec3> ways[] = {{"across the beam", across},
                                               {"along the beam", other}};
  for (const auto& [way, e] : ways) {
    const double u = axis.point_uncertainty_mm;
    withInputs(source, out, Propagation::kIterated, fmt::format("turntable axis point ({})", way),
               fmt::format("moved +- {:.2g} mm", u), "mm", u,
               [e, u](MeasurementInputs& in, double amount) {
                 in.machine.turntable->point_mm += amount * u * e;
               });
    const double t = axis.direction_uncertainty_deg;
    withInputs(source, out, Propagation::kIterated,
               fmt::format("turntable axis direction (tilt about the {} direction)", way),
               fmt::format("tilted +- {:.2g} deg", t), "deg", t,
               [e, t](MeasurementInputs& in, double amount) {
                 Turntable& moved = *in.machine.turntable;
                 moved.direction =
                     (Eigen::AngleAxisd(amount * t * kDegToRad, e) * moved.direction).normalized();
               });
  }
}

// Radiograph k of `in` with its lag fraction moved by `step`.
void moveLag(MeasurementInputs& in, size_t k, const PreparedRadiograph& radiograph, double step) {
  auto moved = std::make_shared<PreparedRadiograph>(radiograph);
  const auto scale = static_cast<float>(1.0 / (1.0 - step * radiograph.lag_signal_white));
  for (size_t l = 0; l < moved->levels.size() && l < radiograph.lag_signal_levels.size(); ++l) {
    const Image& signal = radiograph.lag_signal_levels[l];
    if (signal.empty()) continue;
    Image level = radiograph.levels[l];
    auto pixels = level.pixels();
    auto lag = signal.pixels();
    for (size_t i = 0; i < pixels.size(); ++i)
      pixels[i] = (pixels[i] - static_cast<float>(step) * lag[i]) * scale;
    moved->levels.replace(l, std::move(level));
  }
  in.radiographs[k] = std::move(moved);
}

// The lag fraction, estimated from a radiograph and its previous frame or
// the machine's:
// moved by u, the radiograph loses u more of that frame's signal, and its
// white region as much of its own, by which it is divided again.
void detectorLags(const InfluenceSource& source, InfluenceMoves& out) {
  const MeasurementInputs& inputs = source.inputs;
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
    const Propagation how =
        kept(source.fit_level) ? Propagation::kLinearised : Propagation::kReSolved;
    if (how == Propagation::kReSolved && !kept(source.level)) {
      out.push_back(leftOut(
          fmt::format("{}: its signal is not kept at level {}; left out", name, source.level)));
      continue;
    }
    withInputs(source, out, how, name,
               fmt::format("g = {:.5f} +- {:.2g} ({})", radiograph.lag->fraction, u,
                           radiograph.lag->stated ? "the machine's" : "estimated"),
               "1", u,
               [k, u, prepared = inputs.radiographs[k]](MeasurementInputs& in, double amount) {
                 moveLag(in, k, *prepared, amount * u);
               });
  }
}

// The white region's mean, by which every pixel of a radiograph was
// divided: off by u (relative), the whole radiograph reads 1 / (1 + u) of
// what it should.
void normalisations(const InfluenceSource& source, InfluenceMoves& out) {
  const MeasurementInputs& inputs = source.inputs;
  for (size_t k = 0; k < inputs.radiographs.size(); ++k) {
    const double u = inputs.radiographs[k]->white_mean_uncertainty;
    withInputs(source, out, Propagation::kLinearised,
               "normalisation " + inputs.job.radiographs[k].name,
               fmt::format("white region's mean, relative u = {:.2g}", u), "relative", u,
               [k, u, prepared = inputs.radiographs[k]](MeasurementInputs& in, double amount) {
                 auto moved = std::make_shared<PreparedRadiograph>(*prepared);
                 const auto scale = static_cast<float>(1.0 / (1.0 + amount * u));
                 for (size_t l = 0; l < moved->levels.size(); ++l) {
                   Image level = prepared->levels[l];
                   for (float& p : level.pixels()) p *= scale;
                   moved->levels.replace(l, std::move(level));
                 }
                 in.radiographs[k] = std::move(moved);
               });
  }
}

// The share of the flat's slope that is the tube's heel (image/open_beam.h):
// the flat cannot tell it from the panel's gain, and the halo sees only the
// heel. One move of every radiograph's field (they share the machine's
// flat).
void openBeamHeel(const InfluenceSource& source, InfluenceMoves& out) {
  const MeasurementInputs& inputs = source.inputs;
  const bool sloped =
      std::any_of(inputs.radiographs.begin(), inputs.radiographs.end(),
                  [](const auto& radiograph) { return radiograph->open_beam.sloped(); });
  if (!sloped || !inputs.job.scatter.enabled()) return;
  const double u = OpenBeamField::kHeelShareUncertainty;
  withInputs(source, out, Propagation::kLinearised, "open beam's heel",
             fmt::format("share of the flat's slope that is the tube's heel, not the panel's gain: "
                         "h = {:.2g} +- {:.2g}",
                         OpenBeamField::kHeelShare, u),
             "1", u, [u](MeasurementInputs& in, double amount) {
               for (auto& radiograph : in.radiographs) {
                 auto moved = std::make_shared<PreparedRadiograph>(*radiograph);
                 moved->open_beam =
                     moved->open_beam.withHeelShare(OpenBeamField::kHeelShare + amount * u);
                 radiograph = std::move(moved);
               }
             });
}

// One influence quantity: the name of its components (NAME: a calibration
// input's or a radiograph's) and what lists its moves of the model.
struct InfluenceEntry {
  const char* name;
  void (*list)(const InfluenceSource&, InfluenceMoves&);
};

// The influence quantities, in the budget's order.
constexpr InfluenceEntry kInfluences[] = {
    {"material: INPUT", curveMoves},  // the curve each calibration input moves
    {"material", materialRest},       // the rest of the curve's uncertainty
    {"scatter weight, scatter width", scatterComponents},
    {"open beam's heel", openBeamHeel},
    {"source-detector distance, pixel pitch", machineGeometry},
    {"detector tilt about u and v, detector rotation", detectorPose},
    {"translation NAME", translations},
    {"turn NAME, turntable axis", turntable},
    {"detector lag NAME", detectorLags},
    {"normalisation NAME", normalisations},
};

}  // namespace

std::vector<InfluenceMove> listInfluences(const ForwardModel& model, int fit_level, int level) {
  const InfluenceSource source{model, model.inputs(), fit_level, level,
                               model.materialIndices().empty()};
  InfluenceMoves moves;
  for (const InfluenceEntry& entry : kInfluences) entry.list(source, moves);
  return moves;
}

}  // namespace xgauge::budget_internal
