#include "xgauge/calibrate/wedge.h"

#include "wedge_part.h"

#include "xgauge/core/config.h"
#include "xgauge/image/blur.h"
#include "xgauge/image/radiograph.h"
#include "xgauge/image/radiograph_file.h"
#include "xgauge/measure/job.h"
#include "xgauge/xray/detector_file.h"
#include "xgauge/xray/machine.h"

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <cmath>
#include <exception>
#include <functional>

namespace xgauge {

namespace {

// Steps 3 and 4 on an image with the scatter taken out and its ramp found:
// the geometry and the table, for the wedge's `thickness_mm` and
// `ramp_length_mm` (the job's, or shifted by their uncertainties to
// propagate them). Fills `out` as far as it gets.
void rampTable(const WedgeCalibrationJob& job, const Machine& machine, const Image& image,
               const RampDetection& ramp, double thickness_mm, double ramp_length_mm,
               WedgeCalibration& out) {
  const std::string name = job.radiograph.image.string();
  out.rows.clear(), out.path_mm.clear(), out.transmission.clear();
  // 3. Geometry: both ends on the back face.
  out.step = "the wedge's geometry";
  const double d = machine.source_detector_distance_mm;
  const double y_thin_det = (machine.cy_px - ramp.thin_row) * machine.pitch_v_mm;
  const double y_thick_det = (machine.cy_px - ramp.thick_row) * machine.pitch_v_mm;
  out.magnification = std::abs(y_thin_det - y_thick_det) / ramp_length_mm;
  if (!(out.magnification > 1.0))
    fail(
        "{}: the ramp spans {:.1f} rows, {:.2f} mm on the detector, less than its length of {} mm: "
        "check ramp_length_mm and the machine's pixel pitch",
        name, std::abs(ramp.thick_row - ramp.thin_row), std::abs(y_thin_det - y_thick_det),
        ramp_length_mm);
  out.back_face_z_mm = d * (1.0 - 1.0 / out.magnification);
  const double y_thin = y_thin_det / out.magnification, y_thick = y_thick_det / out.magnification;
  const double t = thickness_mm, delta = y_thick - y_thin;
  const double lambda_back = 1.0 - out.back_face_z_mm / d;
  auto path = [&](double u, double v) {  // continuous pixel coordinate
    const Vec3 p = machine.detectorPoint(u, v);
    const double lambda_floor =
        (d - out.back_face_z_mm + t * y_thin / delta) / (d + t * p.y() / delta);
    return std::sqrt(p.x() * p.x() + p.y() * p.y() + d * d) * (lambda_back - lambda_floor);
  };
  out.x_max_mm = path(0.5 * (ramp.column_begin + ramp.column_end), ramp.thick_row);

  // 4. The table, thin end first.
  out.step = "the intensity table";
  const bool down = ramp.thin_row < ramp.thick_row;
  const int first =
      static_cast<int>(std::ceil(down ? ramp.thin_row : ramp.thick_row)) + job.margin_rows;
  const int last =
      static_cast<int>(std::floor(down ? ramp.thick_row : ramp.thin_row)) - 1 - job.margin_rows;
  if (last - first < 20)
    fail("{}: only {} rows of ramp remain between rows {:.1f} and {:.1f} after the margins", name,
         std::max(0, last - first + 1), ramp.thin_row, ramp.thick_row);
  for (int k = 0; k <= last - first; ++k) {
    const int row = down ? first + k : last - k;
    double sum_path = 0.0, sum_i = 0.0;
    for (int x = ramp.column_begin; x < ramp.column_end; ++x) {
      sum_path += path(x + 0.5, row + 0.5);
      sum_i += static_cast<double>(image(x, row));
    }
    const double n = ramp.column_end - ramp.column_begin;
    const double x_mean = sum_path / n, i_mean = sum_i / n;
    if (!out.path_mm.empty() && !(x_mean > out.path_mm.back())) continue;
    if (!(x_mean >= 0.0)) continue;
    if (!(i_mean > 0.0))
      fail("{}: row {} of the ramp averages {:.4g}, not a positive intensity", name, row, i_mean);
    out.rows.push_back(row);
    out.path_mm.push_back(x_mean);
    out.transmission.push_back(i_mean);
  }
}

// Steps 5 and 6 on the table rampTable made: the fit, then eq. 3.7.
void fitRampCurve(const WedgeCalibrationJob& job, const RampDetection& ramp,
                  WedgeCalibration& out) {
  const std::string name = job.radiograph.image.string();
  out.step = "fit the curve";
  const CurveOptions curve{.max_terms = job.max_terms,
                           .noise = ramp.row_noise,
                           .free_amplitude = true,
                           .rate_floor_per_mm = job.rate_floor ? job.rate_floor->per_mm : 0.0};
  out.fit = fitCurve(out.path_mm, out.transmission, curve, name, &out.fit);
  out.material = shiftAndScale(out.fit.best().fitted, out.x_max_mm, &out.x0_mm);
  if (curve.rate_floor_per_mm > 0.0) {
    // Eq. 3.7 scales the rates by (x_max - x0) / x_max, below 1 when the thin
    // end looked thinner than 0 mm (x0 > 0): keep them on the floor.
    std::vector<ExponentialTerm> terms = out.material.terms();
    for (ExponentialTerm& term : terms)
      term.mu_per_mm = std::max(term.mu_per_mm, curve.rate_floor_per_mm);
    out.material = ExponentialSum(std::move(terms));
  }
  out.material = ExponentialSum(
      out.material.terms(),
      fmt::format(
          "wedge calibration from {}: {} exponentials fitted to {} rows, shifted and scaled "
          "by thesis eq. 3.7 (x0 = {:.4f} mm, x_max = {:.4f} mm)",
          job.radiograph.image.filename().string(), out.fit.best().report.terms_used,
          out.rows.size(), out.x0_mm, out.x_max_mm));
}

// Steps 3 to 6: rampTable, then fitRampCurve.
void curveFromRamp(const WedgeCalibrationJob& job, const Machine& machine, const Image& image,
                   const RampDetection& ramp, double thickness_mm, double ramp_length_mm,
                   WedgeCalibration& out) {
  rampTable(job, machine, image, ramp, thickness_mm, ramp_length_mm, out);
  fitRampCurve(job, ramp, out);
}

// A wedge turned by 90 or 270 degrees has its ramp along the rows; the ramp
// finder and the geometry above read it along the columns of the transposed
// image, seen by the transposed machine (columns and rows, pitches and the
// principal point swapped: a mirror image of the set-up, whose paths are the
// same). Written here because no image library the project uses has it.
Image transposed(const Image& image) {
  Image out(image.height(), image.width());
  for (int y = 0; y < image.height(); ++y)
    for (int x = 0; x < image.width(); ++x) out(y, x) = image(x, y);
  return out;
}
Machine transposed(Machine machine) {
  std::swap(machine.columns, machine.rows);
  std::swap(machine.pitch_u_mm, machine.pitch_v_mm);
  std::swap(machine.cx_px, machine.cy_px);
  return machine;
}

}  // namespace

WedgeCalibrationJob WedgeCalibrationJob::load(const std::filesystem::path& path) {
  const ConfigNode root = ConfigNode::loadFile(path);
  const auto folder = path.parent_path();
  WedgeCalibrationJob job;
  job.file = path;
  job.description = root.get<std::string>("description", "");
  job.machine_file = folder / root.get<std::string>("machine");
  const ConfigNode r = root.at("radiograph");
  job.radiograph.name = "wedge";
  job.radiograph.image = folder / r.get<std::string>("image");
  if (r.has("dark") != r.has("flat")) r.fail("give both dark and flat, or neither");
  if (r.has("dark")) {
    job.radiograph.dark = folder / r.get<std::string>("dark");
    job.radiograph.flat = folder / r.get<std::string>("flat");
  }
  if (r.has("previous")) job.radiograph.previous = folder / r.get<std::string>("previous");
  job.radiograph.white_region = pixelRectFromConfig(r.at("white_region"));
  const ConfigNode wedge = root.at("wedge");
  if (auto model = wedge.find("model")) {
    // The wedge as a known part: its model and every caliper value.
    for (const char* key : {"max_thickness_mm", "ramp_length_mm"})
      if (wedge.has(key))
        wedge.at(key).fail("the wedge's model gives its dimensions: leave this key out");
    if (root.has("ramp"))
      root.at("ramp").fail("a wedge fitted as a known part has no ramp to give");
    job.model_file = folder / model->string();
    try {
      job.model = std::make_shared<const PartModel>(PartModel::load(job.model_file));
    } catch (const Error& e) {
      model->fail(e.message());  // names the job's key as well as the model's file
    }
    const ConfigNode dims = wedge.at("dimensions");
    for (const std::string& name : dims.keys()) {
      try {
        job.model->dimensionIndex(name);
      } catch (const Error& e) {
        dims.at(name).fail(e.message());
      }
      job.caliper[name] = dims.at(name).number();
    }
    for (const Dimension& d : job.model->dimensions())
      if (!job.caliper.contains(d.name))
        dims.fail(fmt::format(
            "the caliper value of '{}' is missing: a calibration wedge's every dimension is "
            "measured, not taken from its drawing",
            d.name));
    try {
      job.model->validate(job.model->values(job.caliper));
    } catch (const Error& e) {
      dims.fail(e.message());
    }
    if (auto u = wedge.find("dimension_uncertainty_mm"))
      job.caliper_uncertainty_mm = u->number(0.0, 10.0);
  } else {
    job.max_thickness_mm = wedge.at("max_thickness_mm").number(0.01, 1e4);
    job.ramp_length_mm = wedge.at("ramp_length_mm").number(0.1, 1e5);
    if (auto u = wedge.find("max_thickness_uncertainty_mm"))
      job.max_thickness_uncertainty_mm = u->number(0.0, 10.0);
    if (auto u = wedge.find("ramp_length_uncertainty_mm"))
      job.ramp_length_uncertainty_mm = u->number(0.0, 10.0);
  }
  if (auto floor = root.find("rate_floor")) job.rate_floor = RateFloor::fromConfig(*floor);
  if (auto scatter = root.find("scatter"))
    job.scatter = ScatterModel::fromConfig(*scatter), job.estimate_scatter = false;
  if (auto ramp = root.find("ramp")) {
    if (auto columns = ramp->find("columns")) {
      if (columns->size() != 2) columns->fail("expected [begin, end]");
      job.ramp.columns = std::array<int, 2>{static_cast<int>((*columns)[0].integer(0, 1000000)),
                                            static_cast<int>((*columns)[1].integer(0, 1000000))};
    }
    if (auto rows = ramp->find("rows")) {
      if (rows->size() != 2) rows->fail("expected [thin end, thick end]");
      job.ramp.rows = std::array<double, 2>{(*rows)[0].number(0, 1e6), (*rows)[1].number(0, 1e6)};
    }
  }
  job.max_terms = static_cast<int>(root.get<double>("max_terms", 4.0));
  if (job.max_terms < 1 || job.max_terms > 4) root.at("max_terms").fail("expected 1 to 4");
  job.margin_rows = static_cast<int>(root.get<double>("margin_rows", 4.0));
  if (job.margin_rows < 0 || job.margin_rows > 1000)
    root.at("margin_rows").fail("expected 0 to 1000");
  root.finish();
  job.machine = Machine::load(job.machine_file);
  // A characterised detector's halo, for a job without a "scatter" of its own.
  if (job.estimate_scatter) {
    if (const auto detector = detectorFileOf(job.machine_file); detector && detector->halo) {
      job.scatter = *detector->halo, job.estimate_scatter = false;
      spdlog::info(
          "{}: the characterised halo: {} kernel, {} border, weight {:.4f}, sigma {:.1f} mm",
          detector->file.string(), toString(job.scatter.shape), toString(job.scatter.border),
          job.scatter.weight, job.scatter.sigma_mm);
    } else {
      spdlog::warn(
          "{}: the detector is not characterised (no detector.characterization in the "
          "machine file, xgauge characterize): the halo is estimated from the wedge's shot "
          "alone, with the thesis's Gaussian and a mirror border",
          path.string());
    }
  }
  return job;
}

std::vector<HaloAlternative> kernelAlternatives(const WedgeCalibration& calibration) {
  if (calibration.halo || !calibration.scatter.enabled()) return {};
  return calibration.scatter.alternatives();
}

// Five times the default uncertainty of a material's transmission: a curve
// this uncertain moves a 12 mm thickness by about 0.2 mm.
void combineCurveUncertainty(const std::string& name, WedgeCalibration& out) {
  // A halo too faint to measure, left out: what it could change the shadow
  // by, as a standard uncertainty.
  if (out.halo && out.halo->unseen_change > 0.0)
    out.influences.push_back(
        {"unmeasured scatter halo", 0.0, 0.0, out.halo->unseen_change, std::nullopt});
  double variance = out.table_uncertainty * out.table_uncertainty;
  for (const CurveInfluence& influence : out.influences)
    variance += influence.change * influence.change;
  out.material.setTransmissionUncertainty(std::sqrt(variance));
  // The inputs whose curve moves the measurement's budget propagates one by
  // one (material/exponential_sum.h): all but the scatter's, which go with
  // the scatter's own components (material/scatter_curves.h).
  std::vector<CurveMove> moves;
  double besides = variance;
  for (const CurveInfluence& influence : out.influences) {
    if (!influence.moved || influence.name == kScatterWeightInfluence ||
        influence.name == kScatterWidthInfluence || influence.name == kScatterKernelInfluence ||
        influence.name == kScatterKernelChoiceInfluence)
      continue;
    moves.push_back({influence.name, influence.unit, influence.value, influence.uncertainty,
                     influence.change, *influence.moved});
    besides -= influence.change * influence.change;
  }
  out.material.setCurveMoves(std::move(moves), std::sqrt(std::max(0.0, besides)));
  if (std::sqrt(variance) > kLargeCurveUncertainty) {
    std::string largest = "table";
    double change = out.table_uncertainty;
    for (const CurveInfluence& influence : out.influences)
      if (influence.change > change) largest = influence.name, change = influence.change;
    spdlog::warn(
        "{}: the curve's standard uncertainty, {:.4f}, is large (mostly from the {}, {:.4f}): "
        "every dimension measured along the beam with it carries it; check the shot and the "
        "wedge's dimensions",
        name, std::sqrt(variance), largest, change);
  }
}

Image WedgeCalibration::primaryWith(const Image& radiograph, double pitch_mm,
                                    const PixelRect& white_region, double weight, double sigma_mm,
                                    double heel_share) const {
  if (halo) {
    HaloFit moved = *halo;
    moved.field = moved.field.withHeelShare(heel_share);
    return moved.primaryWith(radiograph, pitch_mm, weight, sigma_mm);
  }
  ScatterModel moved = scatter;
  moved.weight = weight, moved.sigma_mm = sigma_mm;
  return moved.remove(radiograph, pitch_mm, white_region, open_beam.withHeelShare(heel_share));
}

namespace {

// Step 7 of the ramp method, what the table cannot show: the curve's
// change when the scatter's weight and width, the heel's share of the
// flat's slope and the wedge's dimensions
// move by their standard uncertainties (GUM, sensitivity by re-solving),
// into out.influences. `geometry` and `image` are as the ramp was read
// (transposed for a turned wedge), `normalized` the radiograph before the
// scatter's removal.
void rampInfluences(const WedgeCalibrationJob& job, const Machine& geometry,
                    const Image& normalized, const Image& image, WedgeCalibration& out) {
  const Machine& machine = job.machine;
  const RadiographSpec& spec = job.radiograph;
  const RampDetection& ramp = out.ramp;
  out.step = "the curve's uncertainty";
  const ExponentialSum material = out.material;
  const double range = out.x_max_mm;
  // Each influence's move: the image the ramp is read from (made when the
  // move is solved; `given` where it is the calibration's own), the wedge's
  // dimensions, and the scale of its change (a halo's alternative kernel
  // stands for its u over its distance).
  struct Move {
    std::string name;
    double value = 0.0, u = 0.0;
    std::function<Image()> make;
    const Image* given = nullptr;
    double thickness = 0.0, length = 0.0;
    const char* unit = "mm";
    double scale = 1.0;
  };
  std::vector<Move> moves;
  const ScatterModel& scatter = out.scatter;
  if (scatter.enabled()) {
    auto without = [&](double weight, double sigma_mm, double heel = OpenBeamField::kHeelShare) {
      return [&, weight, sigma_mm, heel] {
        Image removed = out.primaryWith(normalized, machine.pitch_u_mm, spec.white_region, weight,
                                        sigma_mm, heel);
        return out.turned ? transposed(removed) : removed;
      };
    };
    moves.push_back({kScatterWeightInfluence, scatter.weight, scatter.weight_uncertainty,
                     without(scatter.weight + scatter.weight_uncertainty, scatter.sigma_mm)});
    moves.push_back({kScatterWidthInfluence, scatter.sigma_mm, scatter.sigma_uncertainty_mm,
                     without(scatter.weight, scatter.sigma_mm + scatter.sigma_uncertainty_mm)});
    if (out.open_beam.sloped()) {
      moves.push_back({kOpenBeamHeelInfluence, OpenBeamField::kHeelShare,
                       OpenBeamField::kHeelShareUncertainty,
                       without(scatter.weight, scatter.sigma_mm,
                               OpenBeamField::kHeelShare + OpenBeamField::kHeelShareUncertainty)});
      moves.back().unit = "1";
    }
    for (const HaloAlternative& a : kernelAlternatives(out)) {
      moves.push_back({a.name, scatter.equivalentSigmaMm(), a.u, [&, kernel = a.kernel] {
                         Image removed = kernel.remove(normalized, machine.pitch_u_mm,
                                                       spec.white_region, out.open_beam);
                         return out.turned ? transposed(removed) : removed;
                       }});
      moves.back().scale = std::abs(a.scale);
    }
  }
  for (Move& move : moves) move.thickness = job.max_thickness_mm, move.length = job.ramp_length_mm;
  moves.push_back({"wedge max_thickness_mm",
                   job.max_thickness_mm,
                   job.max_thickness_uncertainty_mm,
                   {},
                   &image,
                   job.max_thickness_mm + job.max_thickness_uncertainty_mm,
                   job.ramp_length_mm});
  moves.push_back({"wedge ramp_length_mm",
                   job.ramp_length_mm,
                   job.ramp_length_uncertainty_mm,
                   {},
                   &image,
                   job.max_thickness_mm,
                   job.ramp_length_mm + job.ramp_length_uncertainty_mm});
  std::erase_if(moves, [](const Move& move) { return !(move.u > 0.0); });
  // Each move's table from its image, one after another (an image of the
  // halo removed takes a 3072^2 shot's memory several times over), then
  // the curves fitted side by side (the fits took most of a 3072^2 shot's
  // calibration on one core); the first failure in this order the error.
  std::vector<WedgeCalibration> moved(moves.size());
  std::vector<std::exception_ptr> errors(moves.size());
  for (size_t i = 0; i < moves.size(); ++i) {
    const Move& move = moves[i];
    try {
      if (move.given) {
        rampTable(job, geometry, *move.given, ramp, move.thickness, move.length, moved[i]);
      } else {
        const Image shifted = move.make();
        rampTable(job, geometry, shifted, ramp, move.thickness, move.length, moved[i]);
      }
    } catch (...) {
      errors[i] = std::current_exception();
    }
  }
  tbb::parallel_for(size_t{0}, moves.size(), [&](size_t i) {
    if (errors[i]) return;
    try {
      fitRampCurve(job, ramp, moved[i]);
    } catch (...) {
      errors[i] = std::current_exception();
    }
  });
  for (size_t i = 0; i < moves.size(); ++i) {
    const Move& move = moves[i];
    if (errors[i]) {
      try {
        std::rethrow_exception(errors[i]);
      } catch (const Error& e) {
        fail("the calibration does not survive its {} moved by its standard uncertainty ({}): {}",
             move.name, move.u, e.message());
      }
    }
    out.influences.push_back({move.name, move.value, move.u,
                              move.scale * largestDifference(material, moved[i].material, range),
                              moved[i].material, move.unit});
  }
}

}  // namespace

WedgeCalibration calibrateFromWedge(const WedgeCalibrationJob& job) {
  WedgeCalibration out;
  calibrateFromWedge(job, out);
  return out;
}

namespace {

// 1. The wedge's shot normalized (the whole image: the ramp finder looks for
// the wedge itself, and says so clearly when there is none): dark, flat,
// crosstalk, bad pixels and lag; out.open_beam from the dark and flat.
Image normalizeWedgeShot(const WedgeCalibrationJob& job, WedgeCalibration& out) {
  const Machine& machine = job.machine;
  const RadiographSpec& spec = job.radiograph;
  const std::string name = spec.image.string();
  std::optional<Image> dark, flat;
  if (!spec.dark.empty())
    dark = readRadiograph(spec.dark).image, flat = readRadiograph(spec.flat).image;
  out.open_beam = OpenBeamField::fromFrames(machine.openBeamGeometry(), dark ? &*dark : nullptr,
                                            flat ? &*flat : nullptr);
  Image raw = readRadiograph(spec.image).image;
  if (raw.width() != machine.columns || raw.height() != machine.rows)
    fail("{} is {}x{} pixels but the machine's detector is {}x{}", name, raw.width(), raw.height(),
         machine.columns, machine.rows);
  RadiographFrames frames;
  frames.dark = dark ? &*dark : nullptr;
  frames.flat = flat ? &*flat : nullptr;
  frames.column_crosstalk = machine.column_crosstalk;
  frames.bad_pixels = machine.bad_pixels.get();
  if (dark && machine.column_crosstalk > 0.0)
    spdlog::info("{}: the detector's column crosstalk, {:.5f}, is undone on the raw frames", name,
                 machine.column_crosstalk);
  std::optional<Image> previous;
  if (!spec.previous.empty()) {
    previous = readRadiograph(spec.previous).image;
    frames.previous = &*previous;
    frames.previous_name = spec.previous.string();
    frames.lag_fraction = machine.lag_fraction;
    frames.lag_fraction_uncertainty = machine.lagFractionUncertainty();
  }
  NormalizedRadiograph prepared =
      normalizeRadiograph(std::move(raw), frames, spec.white_region, ClampPolicy::kNone, name);
  if (prepared.lag)
    spdlog::info("{}: lag of {} subtracted, {}", name, spec.previous.string(),
                 describeLag(*prepared.lag));
  out.lag = prepared.lag;
  return std::move(prepared.image);
}

}  // namespace

void calibrateFromWedge(const WedgeCalibrationJob& job, WedgeCalibration& out) {
  const auto start = std::chrono::steady_clock::now();
  auto clock = start;
  const Machine& machine = job.machine;
  const std::string name = job.radiograph.image.string();
  out = WedgeCalibration{};
  out.step = "normalize the radiograph";
  if (!job.rate_floor)
    spdlog::warn(
        "{}: no rate_floor: the curve's rates are not bounded by the material's attenuation at "
        "the tube voltage, and it may level off beyond the wedge's thickness",
        job.file.string());

  // 1. Normalize; remove the scatter.
  const RadiographSpec& spec = job.radiograph;
  const Image normalized = normalizeWedgeShot(job, out);
  addStepSeconds(out.step_seconds, out.step, clock);
  Image image = normalized;
  out.normalized = normalized;  // what a failure below shows
  std::optional<HaloFit> found;
  if (job.estimate_scatter) {
    out.step = "estimate the scatter";
    try {
      HaloOptions options;
      options.field = out.open_beam;
      found = fitScatterHalo(normalized, machine.pitch_u_mm, name, options);
    } catch (const Error& e) {
      if (!job.model) {
        // A radiograph without a wedge says so rather than that it has no
        // halo.
        out.step = "find the ramp";
        detectRamp(normalized, job.ramp, name);
        out.step = "estimate the scatter";
        throw;
      }
      // The known part's paths decide it once the wedge is posed.
      spdlog::info(
          "{}: the open beam alone does not give the scatter ({}); it is fitted with the "
          "wedge's paths, once the wedge is posed",
          name, e.message());
    }
    if (found && !job.model) {
      HaloFit& halo = *found;
      spdlog::info(
          "{}: scatter from the halo around the wedge: weight {:.4f} +- {:.2g}, sigma {:.1f} +- "
          "{:.2g} mm; residual correlation {:.1f}; column darkening {:.4f} per unit attenuation",
          name, halo.scatter.weight, halo.scatter.weight_uncertainty, halo.scatter.sigma_mm,
          halo.scatter.sigma_uncertainty_mm, halo.correlation, halo.column_darkening);
      image = std::move(halo.primary);
      halo.primary = Image();
      out.scatter = halo.scatter;
      out.halo = std::move(halo);
    }
    addStepSeconds(out.step_seconds, "estimate the scatter around the box of the edges", clock);
  } else {
    out.scatter = job.scatter;
    if (job.scatter.enabled())
      image = job.scatter.remove(image, machine.pitch_u_mm, spec.white_region, out.open_beam);
  }
  out.normalized = image;
  if (job.model) {
    // 2-7. The wedge fitted as a known part (wedge_part.h), posed in the
    // radiograph as it is (an outline does not need the scatter removed);
    // the halo around the box of its edges stays only a fallback for the
    // one around the posed wedge.
    calibrateKnownWedge(job, normalized, image, std::move(found), out);
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    out.step = "done";
    return;
  }

  // 2-6. The ramp and the curve along the columns or, when that fails and
  // the job gives no ramp, along the rows (the wedge turned by 90 degrees).
  Machine geometry = machine;
  auto readRamp = [&](const Image& oriented, const Machine& seen, const std::string& label) {
    out.step = "find the ramp";
    out.ramp_found = false;
    out.ramp = detectRamp(oriented, job.ramp, label);
    out.ramp_found = true;
    spdlog::debug("{}: ramp in columns {}..{}, thin end at row {:.2f}, thick end at row {:.2f}{}",
                  label, out.ramp.column_begin, out.ramp.column_end - 1, out.ramp.thin_row,
                  out.ramp.thick_row, out.ramp.automatic_rows ? " (found)" : " (given)");
    curveFromRamp(job, seen, oriented, out.ramp, job.max_thickness_mm, job.ramp_length_mm, out);
  };
  try {
    readRamp(image, machine, name);
  } catch (const Error& along_columns) {
    if (job.ramp.columns || job.ramp.rows) throw;  // given along the columns
    const std::string step = out.step;
    WedgeCalibration along_columns_found = out;
    try {
      out.turned = true;
      readRamp(transposed(image), transposed(machine), name + " (transposed)");
    } catch (const Error&) {
      out = std::move(along_columns_found);  // the diagnostic of the first reading
      out.step = step;
      throw along_columns;
    }
    image = transposed(image);
    geometry = transposed(machine);
    out.normalized = image;
    spdlog::info(
        "{}: the ramp runs along the rows (the wedge is turned by 90 degrees): read from the "
        "transposed radiograph ({})",
        name, along_columns.message());
  }
  out.table_uncertainty = out.fit.tableUncertainty();

  // 7. What the table cannot show: each influence moved by its standard
  // uncertainty.
  rampInfluences(job, geometry, normalized, image, out);
  combineCurveUncertainty(name, out);
  // The table's first row, on the curve's path axis after eq. 3.7.
  const double first =
      (out.path_mm.front() - out.x0_mm) * out.x_max_mm / (out.x_max_mm - out.x0_mm);
  out.material.setCalibratedRange(std::array<double, 2>{std::max(0.0, first), out.x_max_mm});
  // The table on the curve's axis after eq. 3.7 for its extrapolation.
  std::vector<double> scaled;
  for (double x : out.path_mm)
    scaled.push_back((x - out.x0_mm) * out.x_max_mm / (out.x_max_mm - out.x0_mm));
  addExtrapolation(out.material, scaled, out.transmission, out.fit);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  out.step = "done";
}

}  // namespace xgauge
