#include "xgauge/measure/job.h"

#include "xgauge/core/config.h"
#include "xgauge/xray/machine.h"

namespace xgauge {

std::string_view acquisitionName(Acquisition pattern) {
  switch (pattern) {
    case Acquisition::kFree:
      return "free";
    case Acquisition::kTranslated:
      return "translated";
    case Acquisition::kRotated:
      return "rotated";
    case Acquisition::kKnown:
      return "known";
    case Acquisition::kTurned:
      return "turned";
  }
  return "?";
}

PixelRect pixelRectFromConfig(const ConfigNode& node) {
  if (node.size() != 4) node.fail("expected [x, y, width, height]");
  PixelRect r;
  int* fields[] = {&r.x, &r.y, &r.width, &r.height};
  for (size_t i = 0; i < 4; ++i) {
    const double v = node[i].number(-1e6, 1e6);
    if (v != std::floor(v)) node[i].fail("expected a whole number of pixels");
    *fields[i] = static_cast<int>(v);
  }
  if (r.empty()) node.fail("the region is empty");
  return r;
}

namespace {

std::array<std::array<double, 2>, 3> ranges(const ConfigNode& node, double limit) {
  if (node.size() != 3) node.fail("expected three [min, max] pairs");
  std::array<std::array<double, 2>, 3> out{};
  for (size_t i = 0; i < 3; ++i) {
    const ConfigNode pair = node[i];
    if (pair.size() != 2) pair.fail("expected [min, max]");
    out[i] = {pair[0].number(-limit, limit), pair[1].number(-limit, limit)};
    if (!(out[i][0] <= out[i][1])) pair.fail("min must not exceed max");
  }
  return out;
}

// The index of a dimension the job names, or a failure at `node`.
int knownDimension(const PartModel& model, const ConfigNode& node, const std::string& name) {
  try {
    return model.dimensionIndex(name);
  } catch (const Error& e) {
    node.fail(e.message());
  }
}

const Dimension& dimensionNamed(const PartModel& model, const std::string& name) {
  return model.dimensions()[static_cast<size_t>(model.dimensionIndex(name))];
}

// "free" (only those, when given; all by default) and "fixed" (with their
// values); returns which dimensions are free.
std::vector<bool> readFreeAndFixed(const ConfigNode& dims, const PartModel& model,
                                   MeasurementJob& job) {
  std::vector<bool> is_free(model.dimensions().size(), true);
  if (auto free = dims.find("free")) {
    std::fill(is_free.begin(), is_free.end(), false);
    for (size_t i = 0; i < free->size(); ++i)
      is_free[static_cast<size_t>(knownDimension(model, (*free)[i], (*free)[i].string()))] = true;
  }
  if (auto fixed = dims.find("fixed"))
    for (const auto& name : fixed->keys()) {
      const int index = knownDimension(model, fixed->at(name), name);
      if (is_free[static_cast<size_t>(index)] && dims.has("free"))
        fixed->at(name).fail(fmt::format("'{}' is listed as free and as fixed", name));
      is_free[static_cast<size_t>(index)] = false;
      job.fixed_dimensions[name] = fixed->at(name).number();
    }
  return is_free;
}

// "start" values and "bounds", within the part model's.
void readStartsAndBounds(const ConfigNode& dims, const PartModel& model, MeasurementJob& job) {
  if (auto start = dims.find("start"))
    for (const auto& name : start->keys()) {
      knownDimension(model, start->at(name), name);
      job.start[name] = start->at(name).number();
    }
  if (auto bounds = dims.find("bounds"))
    for (const auto& name : bounds->keys()) {
      const ConfigNode b = bounds->at(name);
      knownDimension(model, b, name);
      if (b.size() != 2) b.fail("expected [min, max]");
      job.bounds[name] = {b[0].number(), b[1].number()};
      if (!(job.bounds[name][0] < job.bounds[name][1])) b.fail("min must be below max");
      const Dimension& d = dimensionNamed(model, name);
      if (job.bounds[name][0] < d.min || job.bounds[name][1] > d.max)
        b.fail(fmt::format("bounds [{}, {}] reach beyond the part model's [{}, {}] {}",
                           job.bounds[name][0], job.bounds[name][1], d.min, d.max, d.unit));
    }
}

// A fixed dimension lies within the part model's bounds and takes neither a
// start value nor bounds.
void checkFixedDimensions(const ConfigNode& dims, const PartModel& model,
                          const MeasurementJob& job) {
  for (const auto& [name, value] : job.fixed_dimensions) {
    const Dimension& d = dimensionNamed(model, name);
    if (value < d.min || value > d.max)
      dims.at("fixed").at(name).fail(
          fmt::format("fixed value {} lies outside the part model's bounds [{}, {}] {}", value,
                      d.min, d.max, d.unit));
    for (const char* key : {"start", "bounds"})
      if (auto node = dims.find(key); node && node->has(name))
        node->at(name).fail(fmt::format("'{}' is fixed; a {} does not apply to it", name,
                                        key == std::string("start") ? "start value" : "bound"));
  }
}

// Starts inside the bounds, and the part model's constraints at the values
// the fit starts from.
void checkStarts(const ConfigNode& root, const PartModel& model, MeasurementJob& job) {
  for (const auto& [name, value] : job.start) {
    const Dimension& d = dimensionNamed(model, name);
    const auto b = job.bounds.count(name) ? job.bounds[name] : std::array<double, 2>{d.min, d.max};
    if (value < b[0] || value > b[1])
      root.at("dimensions")
          .at("start")
          .at(name)
          .fail(fmt::format("start {} lies outside the bounds [{}, {}]", value, b[0], b[1]));
  }
  std::vector<double> values = model.nominalValues();
  for (const auto& [name, value] : job.fixed_dimensions)
    values[static_cast<size_t>(model.dimensionIndex(name))] = value;
  for (const auto& [name, value] : job.start)
    values[static_cast<size_t>(model.dimensionIndex(name))] = value;
  if (const auto why = model.invalidity(values)) {
    const ConfigNode dims = root.has("dimensions") ? root.at("dimensions") : root;
    dims.fail(fmt::format("the start values ({}) do not make a valid part: {}",
                          root.has("dimensions")
                              ? "the nominal values with the job's start and fixed values"
                              : "the part model's nominal values",
                          *why));
  }
}

// Dimensions: free ones, fixed values, starts, bounds; names checked against
// the model. Returns which dimensions are free.
std::vector<bool> readDimensions(const ConfigNode& root, const PartModel& model,
                                 MeasurementJob& job) {
  std::vector<bool> is_free(model.dimensions().size(), true);
  if (auto dims = root.find("dimensions")) {
    is_free = readFreeAndFixed(*dims, model, job);
    readStartsAndBounds(*dims, model, job);
    checkFixedDimensions(*dims, model, job);
  }
  for (size_t i = 0; i < is_free.size(); ++i)
    if (is_free[i]) job.free_dimensions.push_back(model.dimensions()[i].name);
  checkStarts(root, model, job);
  return is_free;
}

// Tolerances, of measured dimensions only (a fixed one has no measured
// value to judge). As in a part model, a zone that misses the model's
// [min, max] entirely is a slip, not a specification.
// "nominals": the nominal values of this part number, per free dimension
// (a drawing's, where the part model's defaults are another part's): what a
// report's deviations are taken from, and a job tolerance's default nominal.
void readNominals(const ConfigNode& root, const PartModel& model, const std::vector<bool>& is_free,
                  MeasurementJob& job) {
  auto nominals = root.find("nominals");
  if (!nominals) return;
  if (!nominals->isObject()) nominals->fail("expected {dimension: nominal value}");
  for (const auto& name : nominals->keys()) {
    const ConfigNode node = nominals->at(name);
    const auto index = static_cast<size_t>(knownDimension(model, node, name));
    if (!is_free[index])
      node.fail(fmt::format("'{}' is not a free dimension of this job: a nominal applies to "
                            "measured dimensions only",
                            name));
    const Dimension& d = model.dimensions()[index];
    job.nominals[name] = node.number(d.min, d.max);
  }
}

void readTolerances(const ConfigNode& root, const PartModel& model,
                    const std::vector<bool>& is_free, MeasurementJob& job) {
  auto tolerances = root.find("tolerances");
  if (!tolerances) return;
  for (const auto& name : tolerances->keys()) {
    const ConfigNode node = tolerances->at(name);
    const auto index = static_cast<size_t>(knownDimension(model, node, name));
    if (!is_free[index])
      node.fail(
          fmt::format("'{}' is not a free dimension of this job: a tolerance applies to measured "
                      "dimensions only",
                      name));
    const Dimension& d = model.dimensions()[index];
    const auto stated = job.nominals.find(name);
    const double nominal = stated != job.nominals.end() ? stated->second : d.nominal;
    Tolerance tolerance{node.get<double>("nominal", nominal), node.get<double>("lower"),
                        node.get<double>("upper"), "job"};
    if (!(tolerance.lower < tolerance.upper))
      node.fail(
          fmt::format("lower ({}) must be below upper ({})", tolerance.lower, tolerance.upper));
    if (tolerance.upperLimit() < d.min || tolerance.lowerLimit() > d.max)
      node.fail(fmt::format(
          "the tolerance zone [{}, {}] {} lies outside the part model's [min, max] = [{}, {}]",
          tolerance.lowerLimit(), tolerance.upperLimit(), d.unit, d.min, d.max));
    job.tolerances[name] = std::move(tolerance);
  }
}

Acquisition patternOf(const ConfigNode& r) {
  const std::string pattern = r.get<std::string>("pattern", "free");
  if (pattern == "free") return Acquisition::kFree;
  if (pattern == "translated") return Acquisition::kTranslated;
  if (pattern == "rotated") return Acquisition::kRotated;
  if (pattern == "known") return Acquisition::kKnown;
  if (pattern == "turned") return Acquisition::kTurned;
  r.at("pattern").fail(fmt::format(
      "unknown pattern '{}' (known: free, translated, rotated, turned, known)", pattern));
}

// A translated, rotated or turned radiograph's reference, an earlier one,
// and a translated or turned one's known move.
void readReference(const ConfigNode& r, const MeasurementJob& job, RadiographSpec& spec) {
  const std::string ref = r.get<std::string>("reference");
  for (size_t k = 0; k < job.radiographs.size(); ++k)
    if (job.radiographs[k].name == ref) spec.reference = static_cast<int>(k);
  if (spec.reference < 0)
    r.at("reference").fail(fmt::format("no earlier radiograph named '{}'", ref));
  if (spec.pattern == Acquisition::kTurned) {
    spec.angle_deg = r.at("angle_deg").number(-360.0, 360.0);
    if (r.has("angle_uncertainty_deg"))
      spec.angle_uncertainty_deg = r.at("angle_uncertainty_deg").number(0.0, 10.0);
    return;
  }
  if (spec.pattern != Acquisition::kTranslated) return;
  if (job.radiographs[static_cast<size_t>(spec.reference)].pattern == Acquisition::kTranslated)
    r.at("reference")
        .fail("the reference of a translated radiograph must not be translated itself");
  spec.distance_mm = r.at("distance_mm").number(1e-6, 1e4);
  if (r.has("distance_uncertainty_mm"))
    spec.distance_uncertainty_mm = r.at("distance_uncertainty_mm").number(0.0, 100.0);
  if (auto e = r.find("axis_elevation_bounds_deg")) {
    if (e->size() != 2) e->fail("expected [lo, hi] in degrees");
    spec.axis_elevation_bounds_deg = {(*e)[0].number(-90.0, 90.0), (*e)[1].number(-90.0, 90.0)};
    if (!(spec.axis_elevation_bounds_deg[0] <= spec.axis_elevation_bounds_deg[1]))
      e->fail("lo must not exceed hi");
  }
}

// One entry of "radiographs", after the job's earlier ones.
RadiographSpec readRadiograph(const ConfigNode& r, const std::filesystem::path& folder,
                              const MeasurementJob& job) {
  RadiographSpec spec;
  spec.name = r.get<std::string>("name");
  for (const auto& other : job.radiographs)
    if (other.name == spec.name)
      r.at("name").fail(fmt::format("two radiographs named '{}'", spec.name));
  spec.image = folder / r.get<std::string>("image");
  if (r.has("dark") != r.has("flat")) r.fail("give both dark and flat, or neither");
  if (r.has("dark")) {
    spec.dark = folder / r.get<std::string>("dark");
    spec.flat = folder / r.get<std::string>("flat");
  }
  if (r.has("previous")) spec.previous = folder / r.get<std::string>("previous");
  spec.white_region = pixelRectFromConfig(r.at("white_region"));
  if (auto roi = r.find("roi")) spec.roi = pixelRectFromConfig(*roi);
  spec.pattern = patternOf(r);
  if (spec.pattern == Acquisition::kTranslated || spec.pattern == Acquisition::kRotated ||
      spec.pattern == Acquisition::kTurned)
    readReference(r, job, spec);
  if (spec.pattern == Acquisition::kKnown) spec.known_pose = poseFromConfig(r.at("pose"));
  return spec;
}

void readSchedule(const ConfigNode& root, MeasurementJob& job) {
  const std::string schedule = root.get<std::string>("schedule", "default");
  const auto kind = scheduleKindFromName(schedule);
  if (!kind)
    root.at("schedule")
        .fail(fmt::format("unknown schedule '{}' (known: default, bobyqa, gauss-newton, thesis)",
                          schedule));
  job.schedule = *kind;
  const std::string loss = root.get<std::string>("loss", "l1");
  if (loss != "l1" && loss != "l2") root.at("loss").fail("expected \"l1\" or \"l2\"");
  job.loss = lossKindFromName(loss);
}

// "refine_material", which needs a least-squares stage and a view from
// another direction.
void readRefinement(const ConfigNode& root, MeasurementJob& job) {
  auto refine = root.find("refine_material");
  if (!refine) return;
  const std::string what = refine->string();
  if (what == "rate_scale")
    job.refine_material = MaterialRefinement::kRateScale;
  else if (what != "none")
    refine->fail(fmt::format("unknown refinement '{}' (known: none, rate_scale)", what));
  // Along the beam of translated shots the curve and the part's depth
  // trade; only a view from another direction puts an edge across it.
  int own_poses = 0;
  for (const RadiographSpec& spec : job.radiographs)
    own_poses += spec.pattern == Acquisition::kFree || spec.pattern == Acquisition::kRotated ||
                 spec.pattern == Acquisition::kTurned;
  if (job.refine_material != MaterialRefinement::kNone && job.schedule == ScheduleKind::kThesis)
    refine->fail(
        "the thesis schedule has no least-squares stage to refine the material in (use "
        "\"default\", \"bobyqa\" or \"gauss-newton\")");
  if (job.refine_material != MaterialRefinement::kNone && own_poses < 2)
    refine->fail(
        "refining the material needs a radiograph that sees the part from another direction "
        "(a \"rotated\" or \"turned\" one, or a second \"free\" one): translated shots alone "
        "cannot tell "
        "the curve from the part's depth");
}

void readAcceptance(const ConfigNode& root, MeasurementJob& job) {
  auto acceptance = root.find("acceptance");
  if (!acceptance) return;
  AcceptanceRule& rule = job.acceptance;
  if (auto v = acceptance->find("max_misfit_ratio")) rule.max_misfit_ratio = v->number(1.0, 1e3);
  if (auto v = acceptance->find("max_region_share")) rule.max_region_share = v->number(0.0, 1.0);
  if (auto v = acceptance->find("retry_misfit_ratio"))
    rule.retry_misfit_ratio = v->number(1.0, 1e3);
  if (auto v = acceptance->find("fail_at_bound")) rule.fail_at_bound = v->as<bool>();
  if (auto v = acceptance->find("retries")) rule.retries = static_cast<int>(v->integer(0, 10));
}

}  // namespace

std::filesystem::path MeasurementJob::partFileOf(const ConfigNode& root,
                                                 const std::filesystem::path& path) {
  return path.parent_path() / root.get<std::string>("part");
}

MeasurementJob MeasurementJob::fromConfig(const ConfigNode& root, const std::filesystem::path& path,
                                          const PartModel& model, bool needs_material) {
  const auto folder = path.parent_path();
  MeasurementJob job;
  job.file = path;
  job.description = root.get<std::string>("description", "");
  job.part_file = partFileOf(root, path);
  job.machine_file = folder / root.get<std::string>("machine");
  if (needs_material || root.has("material"))
    job.material_file = folder / root.get<std::string>("material");
  const std::vector<bool> is_free = readDimensions(root, model, job);
  readNominals(root, model, is_free, job);
  readTolerances(root, model, is_free, job);
  if (auto scatter = root.find("scatter")) job.scatter = ScatterModel::fromConfig(*scatter);

  // Radiographs, in order: a reference names an earlier one.
  const ConfigNode list = root.at("radiographs");
  if (list.size() < 1) list.fail("at least one radiograph is needed");
  for (size_t i = 0; i < list.size(); ++i)
    job.radiographs.push_back(readRadiograph(list[i], folder, job));

  const ConfigNode bounds = root.at("pose_bounds");
  job.rotation_bounds_deg = ranges(bounds.at("rotation_deg"), 360.0);
  job.centre_bounds_mm = ranges(bounds.at("centre_mm"), 1e5);
  readSchedule(root, job);
  readRefinement(root, job);
  readAcceptance(root, job);
  if (root.has("verification"))
    job.verification_file = folder / root.get<std::string>("verification");
  if (auto unverified = root.find("unverified_verdicts"))
    job.unverified_verdicts = unverified->as<bool>();
  if (auto seed = root.find("seed"))
    job.seed = static_cast<uint64_t>(seed->integer(0, int64_t{1} << 53));
  return job;
}

}  // namespace xgauge
