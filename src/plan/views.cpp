// The candidate views simulated once and a set's job, inputs and parameters
// (views.h).
#include "views.h"

#include "xgauge/image/radiograph.h"
#include "xgauge/lab/random.h"

#include <fmt/format.h>

#include <cmath>
#include <random>

namespace xgauge::plan_internal {

namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;
constexpr uint64_t kNoisePurpose = 0x706c616e6e6f6973ULL;  // "plannois"

// The measurement job of one view with a free pose: the view's share of the
// linearisation is a one-view measurement's (the refinement of the curve
// needs a second view of its own, so it is left out).
nlohmann::json oneViewJob(const PlanJob& job, int view, const PixelRect& white) {
  nlohmann::json j = job.job;
  j.erase("refine_material");
  const std::string& name = job.views[static_cast<size_t>(view)].name;
  j["radiographs"] = nlohmann::json::array(
      {{{"name", name},
        {"image", name + ".tif"},
        {"white_region", {white.x, white.y, white.width, white.height}}}});
  return j;
}

MeasurementInputs inputsOf(const PlanJob& job, const nlohmann::json& measurement_job,
                           std::vector<std::shared_ptr<const PreparedRadiograph>> radiographs) {
  MeasurementInputs inputs = job.inputs;
  const ConfigNode node =
      ConfigNode::fromJson(measurement_job, job.file.string() + " (a set's measurement job)");
  inputs.job = MeasurementJob::fromConfig(node, job.file, *inputs.part, true);
  inputs.job.scatter = job.inputs.job.scatter;  // as the plan's job took it (detector, material)
  inputs.radiographs = std::move(radiographs);
  return inputs;
}

// A corner of the open beam for the white region: of the four corner
// squares (a twentieth of the detector's width, inset by a fiftieth) of the
// noise-free shot, the brightest, if its mean is within 2 % of the
// brightest pixel's (the open beam).
PixelRect openCorner(const Image& image, const std::string& view) {
  const int side = std::max(8, image.width() / 20), inset = std::max(2, image.width() / 50);
  float brightest = 0.0f;
  for (float v : image.pixels()) brightest = std::max(brightest, v);
  const int xs[2] = {inset, image.width() - inset - side};
  const int ys[2] = {inset, image.height() - inset - side};
  PixelRect best;
  double best_mean = -1.0;
  for (int y0 : ys)
    for (int x0 : xs) {
      const PixelRect r{x0, y0, side, side};
      if (!image.rect().contains(r)) continue;
      double sum = 0.0;
      for (int y = r.y; y < r.bottom(); ++y)
        for (int x = r.x; x < r.right(); ++x) sum += static_cast<double>(image(x, y));
      const double mean = sum / static_cast<double>(r.area());
      if (mean > best_mean) best_mean = mean, best = r;
    }
  if (!(best_mean >= 0.98 * static_cast<double>(brightest)))
    fail("view {}: no corner of the detector sees the open beam (the white region needs one): "
         "the part's shadow reaches every corner",
         view);
  return best;
}

}  // namespace

Relation relationOf(const PlanJob& job, int first, int view) {
  const CandidateView& a = job.views[static_cast<size_t>(first)];
  const CandidateView& b = job.views[static_cast<size_t>(view)];
  Relation out;
  const bool same_fixture = a.rotation_deg == b.rotation_deg;
  if (same_fixture && a.turntable_deg == b.turntable_deg && a.stage_mm != b.stage_mm) {
    // The stage's own move: its distance as the positions state it (not the
    // poses' difference, which rounds), along its axis.
    out.pattern = Acquisition::kTranslated;
    out.distance_mm = std::abs(b.stage_mm - a.stage_mm);
    out.direction = (b.stage_mm > a.stage_mm ? 1.0 : -1.0) * job.stage_axis;
  } else if (same_fixture && a.stage_mm == b.stage_mm && a.turntable_deg != b.turntable_deg) {
    out.pattern = Acquisition::kTurned;
    out.angle_deg = b.turntable_deg - a.turntable_deg;
  }
  return out;
}

nlohmann::json measurementJobFrom(const PlanJob& job, const std::vector<int>& views,
                                  const std::vector<PixelRect>& white) {
  nlohmann::json j = job.job;
  nlohmann::json list = nlohmann::json::array();
  for (size_t k = 0; k < views.size(); ++k) {
    const std::string& name = job.views[static_cast<size_t>(views[k])].name;
    nlohmann::json r = {{"name", name},
                        {"image", name + ".tif"},
                        {"white_region", {white[k].x, white[k].y, white[k].width, white[k].height}}};
    const Relation rel = k == 0 ? Relation{} : relationOf(job, views[0], views[k]);
    const std::string& first = job.views[static_cast<size_t>(views[0])].name;
    if (rel.pattern == Acquisition::kTranslated) {
      r["pattern"] = "translated", r["reference"] = first, r["distance_mm"] = rel.distance_mm;
      if (job.stage_uncertainty_mm) r["distance_uncertainty_mm"] = *job.stage_uncertainty_mm;
    } else if (rel.pattern == Acquisition::kTurned) {
      r["pattern"] = "turned", r["reference"] = first, r["angle_deg"] = rel.angle_deg;
      if (job.turn_uncertainty_deg) r["angle_uncertainty_deg"] = *job.turn_uncertainty_deg;
    } else {
      r["pattern"] = "free";
    }
    list.push_back(std::move(r));
  }
  j["radiographs"] = std::move(list);
  return j;
}

SimulatedView simulateView(const PlanJob& job, int view) {
  const Machine& machine = job.inputs.machine;
  const CandidateView& v = job.views[static_cast<size_t>(view)];
  // A stand-in radiograph of the open beam gives the model its size; the
  // view is then rendered at the nominal part as the fit's last stage does.
  RadiographSpec stand_in;
  stand_in.name = v.name;
  stand_in.image = v.name + ".tif";
  stand_in.roi = machine.detectorRect();
  const PixelRect corner{0, 0, 8, 8};
  stand_in.white_region = corner;
  auto open = std::make_shared<const PreparedRadiograph>(prepareRadiograph(
      Image(machine.columns, machine.rows, 1.0f), RadiographFrames{}, stand_in, machine));
  Image image;
  double longest = 0.0;
  {
    MeasurementInputs inputs = inputsOf(job, oneViewJob(job, view, corner), {open});
    ForwardModel model(inputs);
    const std::vector<double> theta = nominalTheta(job, model, {view});
    if (const auto why = model.infeasibility(theta))
      fail("view {}: the nominal part cannot be simulated there: {}", v.name, *why);
    for (const Segment2& s : model.outline(theta, 0))
      for (const Vec2& p : s)
        if (p.x() < 0.0 || p.y() < 0.0 || p.x() > machine.columns || p.y() > machine.rows)
          fail("view {}: the part's shadow leaves the {}x{} detector (at pixel {:.0f}, {:.0f})",
               v.name, machine.columns, machine.rows, p.x(), p.y());
    image = simulatedShot(model, theta, 0);
    const Image paths = model.pathLengths(theta, 0, 0, machine.detectorRect());
    for (float p : paths.pixels()) longest = std::max(longest, static_cast<double>(p));
  }
  SimulatedView out;
  out.white_region = openCorner(image, v.name);
  // The shot's noise, photon-limited with a floor; a stream per row (lab/random.h).
  for (int y = 0; y < image.height(); ++y) {
    SplitMix64 stream = SplitMix64::stream(job.seed, kNoisePurpose, static_cast<uint64_t>(view),
                                           static_cast<uint64_t>(y));
    std::normal_distribution<double> normal;
    float* row = image.row(y);
    for (int x = 0; x < image.width(); ++x) {
      const double i = static_cast<double>(row[x]);
      const double sigma = std::sqrt(job.open_beam_noise * job.open_beam_noise * std::max(0.0, i) +
                                     job.noise_floor * job.noise_floor);
      row[x] = static_cast<float>(i + sigma * normal(stream));
    }
  }
  RadiographSpec spec;
  spec.name = v.name;
  spec.image = v.name + ".tif";
  spec.white_region = out.white_region;
  out.radiograph = std::make_shared<const PreparedRadiograph>(
      prepareRadiograph(image, RadiographFrames{}, spec, machine));
  out.image = std::move(image);
  out.longest_path_mm = longest;
  MeasurementInputs inputs = inputsOf(job, oneViewJob(job, view, out.white_region), {out.radiograph});
  ForwardModel model(inputs);
  const std::optional<ViewInformation> information =
      viewInformationAt(model, nominalTheta(job, model, {view}));
  if (!information) fail("view {}: its Jacobian could not be simulated", v.name);
  out.information = *information;
  return out;
}

MeasurementInputs inputsFor(const PlanJob& job, const std::vector<int>& views,
                            const std::vector<SimulatedView>& simulated) {
  std::vector<PixelRect> white;
  std::vector<std::shared_ptr<const PreparedRadiograph>> radiographs;
  for (int v : views) {
    white.push_back(simulated[static_cast<size_t>(v)].white_region);
    radiographs.push_back(simulated[static_cast<size_t>(v)].radiograph);
  }
  return inputsOf(job, measurementJobFrom(job, views, white), std::move(radiographs));
}

std::vector<double> nominalTheta(const PlanJob& job, const ForwardModel& model,
                                 const std::vector<int>& views) {
  std::vector<double> theta = model.start();
  const ParameterLayout& layout = model.parameters();
  for (const auto& [name, value] : job.nominal) {
    const int i = layout.index("dim/" + name);
    theta[static_cast<size_t>(i)] = value;
  }
  for (int r = 0; r < model.radiographCount(); ++r) {
    const RadiographSpec& spec = model.spec(r);
    const CandidateView& v = job.views[static_cast<size_t>(views[static_cast<size_t>(r)])];
    if (spec.pattern == Acquisition::kFree || spec.pattern == Acquisition::kRotated) {
      const Vec3 euler = v.pose.eulerDeg();
      const Vec3 centre = v.pose.apply(model.referenceCentre());
      const std::vector<int> rotation = layout.block(spec.name + "/rotation");
      const std::vector<int> position = layout.block(spec.name + "/position");
      for (int k = 0; k < 3; ++k) {
        theta[static_cast<size_t>(rotation[static_cast<size_t>(k)])] = euler[k];
        theta[static_cast<size_t>(position[static_cast<size_t>(k)])] = centre[k];
      }
    } else if (spec.pattern == Acquisition::kTranslated) {
      const Relation rel = relationOf(job, views[0], views[static_cast<size_t>(r)]);
      const std::vector<int> axis = layout.block(spec.name + "/axis");
      // model_parameters.cpp: (cos el cos az, sin el, cos el sin az).
      theta[static_cast<size_t>(axis[0])] =
          std::atan2(rel.direction.z(), rel.direction.x()) * kRadToDeg;
      theta[static_cast<size_t>(axis[1])] = std::asin(std::clamp(rel.direction.y(), -1.0, 1.0)) * kRadToDeg;
    }
  }
  return theta;
}

}  // namespace xgauge::plan_internal
