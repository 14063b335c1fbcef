#include "xgauge/lab/recipe.h"

#include "xgauge/geometry/part_model.h"
#include "xgauge/xray/machine.h"

#include <random>

namespace xgauge {

namespace {

Vec3 vec3(const ConfigNode& node) {
  if (node.size() != 3) node.fail(fmt::format("expected 3 numbers, got {}", node.size()));
  return {node[0].number(-1e6, 1e6), node[1].number(-1e6, 1e6), node[2].number(-1e6, 1e6)};
}

Vec3 unitAxis(const ConfigNode& node) {
  const Vec3 axis = vec3(node);
  if (axis.norm() < 1e-12) node.fail("the axis must not be zero");
  return axis.normalized();
}

// A rotation by `angle_deg` about `axis` through the world point `pivot`.
Pose turnAbout(const Pose& pose, const Vec3& axis, double angle_deg, const Vec3& pivot_world) {
  const Mat3 r = Eigen::AngleAxisd(angle_deg * kDegToRad, axis).toRotationMatrix();
  Pose out;
  out.rotation = r * pose.rotation;
  out.translation_mm = r * (pose.translation_mm - pivot_world) + pivot_world;
  return out;
}

}  // namespace

std::vector<ShotPlan> planShots(const ConfigNode& shots, const Vec3& pivot_part_mm, uint64_t seed,
                                std::optional<Turntable>* turntable) {
  const Pose base = poseFromConfig(shots.at("base_pose"));
  std::vector<ShotPlan> plan;

  if (auto t = shots.find("translations")) {
    const int count = static_cast<int>(t->at("count").integer(1, 1000));
    const double distance = t->at("distance_mm").number(1e-6, 1e4);
    const Vec3 axis = unitAxis(t->at("axis"));
    for (int i = 0; i < count; ++i) {
      ShotPlan shot;
      shot.name = fmt::format("t{:02d}", i);
      shot.pattern = i == 0 ? "free" : "translated";
      shot.reference = i == 0 ? "" : "t00";
      shot.distance_mm = i * distance;
      shot.axis = axis;
      shot.pose = base;
      shot.pose.translation_mm = base.translation_mm + shot.distance_mm * axis;
      plan.push_back(shot);
    }
  }

  if (auto r = shots.find("rotations")) {
    const auto angles = r->at("angles_deg");
    const Vec3 axis = unitAxis(r->at("axis"));
    const double jitter = r->get<double>("angle_jitter_deg", 0.0);
    const double wobble = r->get<double>("wobble_deg", 0.0);
    if (jitter < 0 || wobble < 0) r->fail("angle_jitter_deg and wobble_deg must be >= 0");
    // The stage's errors, drawn in shot order from the recipe's seed.
    std::mt19937_64 rng(seed ^ 0x5eed0fa11u);
    std::normal_distribution<double> gauss(0.0, 1.0);
    std::uniform_real_distribution<double> turn(0.0, 2.0 * std::numbers::pi);
    const Pose start = r->has("base_pose") ? poseFromConfig(r->at("base_pose")) : base;
    const Vec3 pivot_world = start.apply(pivot_part_mm);
    const bool calibrated = r->get<bool>("turntable", false);
    if (calibrated && turntable) {
      Turntable stage;
      stage.point_mm = pivot_world;
      stage.direction = axis;
      // A stated wobble is the axis's own uncertainty.
      if (wobble > 0.0) stage.direction_uncertainty_deg = std::min(wobble, 10.0);
      *turntable = stage;
    }
    const Vec3 across = axis.unitOrthogonal();
    for (size_t i = 0; i < angles.size(); ++i) {
      ShotPlan shot;
      shot.name = fmt::format("r{:02d}", i);
      shot.pattern = "rotated";
      shot.nominal_angle_deg = angles[i].number(-360.0, 360.0);
      const double angle = shot.nominal_angle_deg + jitter * gauss(rng);
      const Vec3 tilt_axis = Eigen::AngleAxisd(turn(rng), axis) * across;
      shot.pose = turnAbout(start, axis, angle, pivot_world);
      shot.pose = turnAbout(shot.pose, tilt_axis, wobble * gauss(rng), pivot_world);
      plan.push_back(shot);
    }
  }

  if (auto extra = shots.find("extra")) {
    for (size_t i = 0; i < extra->size(); ++i) {
      const ConfigNode item = (*extra)[i];
      ShotPlan shot;
      shot.name = item.get<std::string>("name");
      shot.pattern = "free";
      shot.pose = poseFromConfig(item.at("pose"));
      plan.push_back(shot);
    }
  }

  if (plan.empty()) shots.fail("no shots: give translations, rotations or extra");
  for (size_t i = 0; i < plan.size(); ++i)
    for (size_t j = 0; j < i; ++j)
      if (plan[i].name == plan[j].name)
        shots.fail(fmt::format("two shots named '{}'", plan[i].name));
  return plan;
}

Recipe Recipe::load(const std::filesystem::path& path) {
  Recipe recipe;
  recipe.file = path;
  recipe.root.emplace(ConfigNode::loadFile(path));
  const ConfigNode& root = *recipe.root;
  const auto folder = path.parent_path();
  recipe.description = root.get<std::string>("description", "");
  recipe.seed = static_cast<uint64_t>(root.at("seed").integer(0, int64_t{1} << 53));
  recipe.machine_file = folder / root.get<std::string>("machine");

  const ConfigNode part = root.at("part");
  recipe.part_file = folder / part.get<std::string>("model");
  if (const auto physical = part.find("physical")) {
    if (root.has("lot")) physical->fail("a lot's parts differ: one physical solid cannot show them");
    recipe.physical_file = folder / physical->string();
  }
  const PartModel model = PartModel::load(recipe.part_file);
  if (auto dims = part.find("dimensions")) {
    for (const auto& name : dims->keys()) recipe.true_dimensions[name] = dims->at(name).number();
  }
  std::vector<double> values;
  try {
    values = model.values(recipe.true_dimensions);
  } catch (const Error& e) {
    part.at("dimensions").fail(e.message());
  }

  const ConfigNode shots = root.at("shots");
  const TriangleMesh mesh = model.mesh(values);
  const BoundingBox box = boundingBox(mesh);
  const Vec3 pivot =
      shots.has("pivot_mm") ? vec3(shots.at("pivot_mm")) : Vec3(0.5 * (box.min_mm + box.max_mm));
  recipe.shots = planShots(shots, pivot, recipe.seed, &recipe.turntable);

  if (auto white = root.find("white_region")) {
    const auto r = white->as<std::vector<int>>();
    if (r.size() != 4 || r[2] <= 0 || r[3] <= 0)
      white->fail("expected [x, y, width, height] with a positive size");
    recipe.white_region = PixelRect{r[0], r[1], r[2], r[3]};
  }
  if (auto defects = root.find("defects")) recipe.defects = readDefects(*defects, mesh);
  if (auto c = root.find("characterization")) {
    CharacterizationPlan plan;
    plan.frames = static_cast<int>(c->get<double>("frames", 8.0));
    if (plan.frames < 2 || plan.frames > 256) c->at("frames").fail("expected 2 to 256");
    recipe.characterization = plan;
  }
  return recipe;
}

}  // namespace xgauge
