// The plan job (docs/formats.md, "Plan job"): the measurement job the sets
// are measured with, the shot's noise, the grid of candidate views and what
// ranks them; every file it names read once, every view checked against
// the stage's and turntable's limits and the job's pose bounds.
#include "xgauge/plan/plan.h"

#include "xgauge/core/error.h"
#include "xgauge/geometry/mesh.h"
#include "xgauge/measure/tolerance.h"

#include <fmt/format.h>

#include <cmath>

namespace xgauge {

namespace fs = std::filesystem;

namespace {

// How far inside a bound's range a view's pose and the nominal part must
// lie (a share of the range): a fit from noisy shots ends near where they
// lie, and one within 1e-4 of the range of a bound is refused.
constexpr double kBoundMargin = 0.02;

Vec3 vec3Of(const ConfigNode& node, double limit) {
  if (!node.isArray() || node.size() != 3) node.fail("expected [x, y, z]");
  return {node[0].number(-limit, limit), node[1].number(-limit, limit),
          node[2].number(-limit, limit)};
}

std::array<double, 2> rangeOf(const ConfigNode& node, double limit) {
  if (!node.isArray() || node.size() != 2) node.fail("expected [lo, hi]");
  const std::array<double, 2> r{node[0].number(-limit, limit), node[1].number(-limit, limit)};
  if (!(r[0] <= r[1])) node.fail("lo must not exceed hi");
  return r;
}

// The values a list of numbers holds, each checked against `range` (a
// stage's travel, a turntable's reach) where given.
std::vector<double> valuesOf(const ConfigNode& node, double limit,
                             const std::optional<std::array<double, 2>>& range,
                             std::string_view what) {
  if (!node.isArray() || node.size() < 1) node.fail("expected a list of at least one number");
  std::vector<double> out;
  for (size_t i = 0; i < node.size(); ++i) {
    const double v = node[i].number(-limit, limit);
    if (range && (v < (*range)[0] || v > (*range)[1]))
      node[i].fail(fmt::format("{} lies outside the {} [{}, {}]", v, what, (*range)[0],
                               (*range)[1]));
    out.push_back(v);
  }
  return out;
}

// The measurement job the sets are measured with, its paths made absolute
// and checked with a stand-in radiograph (the plan chooses the real ones).
void readJob(const ConfigNode& root, PlanJob& plan) {
  const ConfigNode job = root.at("job");
  if (!job.isObject()) job.fail("expected the measurement job (an object)");
  if (job.has("radiographs"))
    job.at("radiographs").fail("a plan's job names no radiographs: the plan chooses them");
  plan.job = job.json();
  const fs::path folder = plan.file.parent_path();
  for (const char* key : {"part", "machine", "material", "verification"})
    if (plan.job.contains(key) && plan.job[key].is_string())
      plan.job[key] = fs::absolute(folder / plan.job[key].get<std::string>()).string();
  nlohmann::json check = plan.job;
  check["radiographs"] = nlohmann::json::array(
      {{{"name", "view"}, {"image", "view.tif"}, {"white_region", {0, 0, 1, 1}}}});
  // A refinement needs two views of their own; the stand-in has one.
  check.erase("refine_material");
  const ConfigNode node = job.derived(check);
  plan.inputs = loadJobInputs(node, plan.file, true);
  node.finish();
  plan.tolerances = tolerancesFor(plan.inputs.job, *plan.inputs.part);
  for (const Dimension& d : plan.inputs.part->dimensions()) {
    const auto stated = plan.inputs.job.nominals.find(d.name);
    double value = stated != plan.inputs.job.nominals.end() ? stated->second : d.nominal;
    if (auto fixed = plan.inputs.job.fixed_dimensions.find(d.name);
        fixed != plan.inputs.job.fixed_dimensions.end())
      value = fixed->second;
    plan.nominal[d.name] = value;
    if (const auto b = plan.inputs.job.bounds.find(d.name); b != plan.inputs.job.bounds.end()) {
      const double margin = kBoundMargin * (b->second[1] - b->second[0]);
      if (value < b->second[0] + margin || value > b->second[1] - margin)
        job.at("dimensions").fail(fmt::format(
            "{}'s value {} (the part the views are simulated at) lies outside its bounds [{}, {}] "
            "or within {} % of their range from an edge, where the measurement would refuse the "
            "fit",
            d.name, value, b->second[0], b->second[1], 100.0 * kBoundMargin));
    }
  }
}

// The grid of candidate views: rotations x turntable angles x stage
// positions, named v00, v01, ... in that order.
void readViews(const ConfigNode& root, PlanJob& plan) {
  const ConfigNode views = root.at("views");
  const Vec3 centre = vec3Of(views.at("centre_mm"), 1e5);
  std::vector<Vec3> rotations{Vec3::Zero()};
  if (auto r = views.find("rotations_deg")) {
    if (!r->isArray() || r->size() < 1) r->fail("expected a list of at least one [rx, ry, rz]");
    rotations.clear();
    for (size_t i = 0; i < r->size(); ++i) rotations.push_back(vec3Of((*r)[i], 360.0));
  }
  std::vector<double> positions{0.0}, angles{0.0};
  if (auto stage = views.find("stage")) {
    std::optional<std::array<double, 2>> travel;
    if (auto t = stage->find("travel_mm")) travel = rangeOf(*t, 1e5);
    plan.stage_axis = vec3Of(stage->at("axis"), 1e3);
    if (!(plan.stage_axis.norm() > 0.0)) stage->at("axis").fail("the axis must not be zero");
    plan.stage_axis.normalize();
    positions = valuesOf(stage->at("positions_mm"), 1e5, travel, "stage's travel_mm");
    if (auto u = stage->find("uncertainty_mm")) plan.stage_uncertainty_mm = u->number(0.0, 100.0);
  }
  if (auto turntable = views.find("turntable")) {
    if (!plan.inputs.machine.turntable)
      turntable->fail(fmt::format("the machine file {} states no turntable axis",
                                  plan.inputs.job.machine_file.string()));
    std::optional<std::array<double, 2>> reach;
    if (auto r = turntable->find("range_deg")) reach = rangeOf(*r, 360.0);
    angles = valuesOf(turntable->at("angles_deg"), 360.0, reach, "turntable's range_deg");
    if (auto u = turntable->find("angle_uncertainty_deg"))
      plan.turn_uncertainty_deg = u->number(0.0, 10.0);
  }
  const auto& rb = plan.inputs.job.rotation_bounds_deg;
  const auto& cb = plan.inputs.job.centre_bounds_mm;
  // The part's reference centre, as the measurement's poses place it
  // (ForwardModel: the centre of its nominal bounding box).
  const BoundingBox box = boundingBox(plan.inputs.part->mesh(plan.inputs.part->nominalValues()));
  const Vec3 part_centre = 0.5 * (box.min_mm + box.max_mm);
  for (const Vec3& rotation : rotations)
    for (double angle : angles)
      for (double position : positions) {
        CandidateView v;
        v.name = fmt::format("v{:02}", plan.views.size());
        v.rotation_deg = rotation, v.turntable_deg = angle, v.stage_mm = position;
        Pose pose = Pose::fromEulerDeg(rotation, Vec3::Zero());
        pose.translation_mm = centre + position * plan.stage_axis - pose.rotation * part_centre;
        if (plan.inputs.machine.turntable) pose = plan.inputs.machine.turntable->turn(pose, angle);
        v.pose = pose;
        // The measurement searches each free pose within the job's bounds,
        // and a fit that ends at one is not a measurement (the failure
        // rule): a view on a bound's edge would not be measured.
        const Vec3 euler = pose.eulerDeg();
        const Vec3 world = pose.rotation * part_centre + pose.translation_mm;
        for (int k = 0; k < 3; ++k) {
          const auto inside = [](double x, const std::array<double, 2>& r) {
            const double margin = kBoundMargin * (r[1] - r[0]);
            return r[0] == r[1] || (x >= r[0] + margin && x <= r[1] - margin);
          };
          if (!inside(euler[k], rb[static_cast<size_t>(k)]) ||
              !inside(world[k], cb[static_cast<size_t>(k)]))
            views.fail(fmt::format(
                "view {} (rotation [{:.3f}, {:.3f}, {:.3f}] deg, centre [{:.3f}, {:.3f}, {:.3f}] mm) "
                "lies outside the job's pose_bounds or within {} % of their range from an edge, "
                "where the measurement would end at a bound and refuse the fit",
                v.name, euler[0], euler[1], euler[2], world[0], world[1], world[2],
                100.0 * kBoundMargin));
        }
        plan.views.push_back(std::move(v));
      }
}

void readCriterion(const ConfigNode& root, PlanJob& plan) {
  const auto criterion = root.find("criterion");
  if (!criterion) return;
  if (criterion->isObject()) {
    plan.criterion = PlanCriterion::kDimension;
    plan.criterion_dimension = criterion->get<std::string>("dimension");
    const auto& free = plan.inputs.job.free_dimensions;
    if (std::find(free.begin(), free.end(), plan.criterion_dimension) == free.end())
      criterion->at("dimension")
          .fail(fmt::format("'{}' is not a free dimension of the job", plan.criterion_dimension));
    criterion->finish();
    return;
  }
  const std::string name = criterion->string();
  if (name == "worst")
    plan.criterion = PlanCriterion::kWorst;
  else if (name == "sum")
    plan.criterion = PlanCriterion::kSum;
  else
    criterion->fail(fmt::format(
        "unknown criterion '{}' (known: \"worst\", \"sum\", {{\"dimension\": NAME}})", name));
  if (plan.tolerances.empty())
    criterion->fail(fmt::format("\"{}\" ranks by U/T, and no free dimension has a tolerance "
                                "(give the job's tolerances, or {{\"dimension\": NAME}})",
                                name));
}

void readCompare(const ConfigNode& root, PlanJob& plan) {
  const auto compare = root.find("compare");
  if (!compare) return;
  if (!compare->isArray()) compare->fail("expected a list of view sets ([[\"v00\", \"v03\"]])");
  for (size_t i = 0; i < compare->size(); ++i) {
    const ConfigNode set = (*compare)[i];
    if (!set.isArray() || static_cast<int>(set.size()) != plan.per_set)
      set.fail(fmt::format("expected {} view names", plan.per_set));
    std::vector<int> indices;
    for (size_t k = 0; k < set.size(); ++k) {
      const std::string name = set[k].string();
      const auto it = std::find_if(plan.views.begin(), plan.views.end(),
                                   [&](const CandidateView& v) { return v.name == name; });
      if (it == plan.views.end())
        set[k].fail(fmt::format("no candidate view named '{}' (v00 .. v{:02})", name,
                                plan.views.size() - 1));
      const int index = static_cast<int>(it - plan.views.begin());
      if (std::find(indices.begin(), indices.end(), index) != indices.end())
        set[k].fail(fmt::format("view '{}' twice in one set", name));
      indices.push_back(index);
    }
    plan.compare.push_back(std::move(indices));
  }
}

}  // namespace

PlanJob PlanJob::load(const fs::path& path) {
  const ConfigNode root = ConfigNode::loadFile(path);
  PlanJob plan;
  plan.file = path;
  plan.description = root.get<std::string>("description", "");
  readJob(root, plan);
  {
    const ConfigNode exposure = root.at("exposure");
    plan.open_beam_noise = exposure.at("open_beam_noise").number(1e-6, 0.5);
    if (auto floor = exposure.find("noise_floor")) plan.noise_floor = floor->number(0.0, 0.5);
    exposure.finish();
  }
  readViews(root, plan);
  plan.per_set = static_cast<int>(root.at("radiographs").integer(2, 3));
  if (static_cast<int>(plan.views.size()) < plan.per_set)
    root.at("views").fail(fmt::format("{} candidate view(s), fewer than the {} radiographs of a set",
                                      plan.views.size(), plan.per_set));
  readCriterion(root, plan);
  if (auto b = root.find("budgeted")) plan.budgeted = static_cast<int>(b->integer(1, 100));
  if (auto sets = root.find("sets")) {
    const std::string which = sets->string();
    if (which != "any" && which != "known_moves")
      sets->fail(fmt::format("unknown sets '{}' (known: \"any\", \"known_moves\")", which));
    plan.known_moves_only = which == "known_moves";
  }
  if (auto e = root.find("exhaustive_up_to")) plan.exhaustive_up_to = e->integer(0, int64_t{1} << 40);
  readCompare(root, plan);
  if (auto seed = root.find("seed")) plan.seed = static_cast<uint64_t>(seed->integer(0, int64_t{1} << 53));
  root.finish();
  return plan;
}

}  // namespace xgauge
