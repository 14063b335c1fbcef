#include "xgauge/xray/machine.h"

#include "xgauge/xray/detector_file.h"

#include <cmath>

namespace xgauge {

namespace {

std::array<double, 2> pair(const ConfigNode& node, double min, double max) {
  if (node.size() != 2) node.fail(fmt::format("expected 2 numbers, got {}", node.size()));
  return {node[0].number(min, max), node[1].number(min, max)};
}

Vec3 triple(const ConfigNode& node, double limit) {
  if (node.size() != 3) node.fail(fmt::format("expected 3 numbers, got {}", node.size()));
  return {node[0].number(-limit, limit), node[1].number(-limit, limit),
          node[2].number(-limit, limit)};
}

Turntable turntableFromConfig(const ConfigNode& node) {
  Turntable t;
  t.point_mm = triple(node.at("point_mm"), 1e6);
  const Vec3 direction = triple(node.at("direction"), 1e6);
  if (!(direction.norm() > 1e-9)) node.at("direction").fail("the axis direction is zero");
  t.direction = direction.normalized();
  if (auto u = node.find("point_uncertainty_mm")) t.point_uncertainty_mm = u->number(0.0, 100.0);
  if (auto u = node.find("direction_uncertainty_deg"))
    t.direction_uncertainty_deg = u->number(0.0, 10.0);
  return t;
}

}  // namespace

void Machine::setDetectorPose(double tilt_u_deg, double tilt_v_deg, double rotation_deg) {
  detector_tilt_deg = {tilt_u_deg, tilt_v_deg};
  detector_rotation_deg = rotation_deg;
  detector_rotation =
      Pose::fromEulerDeg(Vec3(tilt_u_deg, tilt_v_deg, rotation_deg), Vec3::Zero()).rotation;
  tilted_ = !detector_rotation.isIdentity(0.0);
}

Vec2 Machine::projectTilted(const Vec3& world) const {
  const Vec3 source = sourceWorld();
  const Vec3 on_panel = source + magnificationAt(world) * (world - source);
  const Vec3 local = detector_rotation.transpose() * on_panel;
  return {local.x() / pitch_u_mm + cx_px, cy_px - local.y() / pitch_v_mm};
}

Pose Turntable::turn(const Pose& reference, double angle_deg) const {
  const Mat3 turn = Eigen::AngleAxisd(angle_deg * kDegToRad, direction).toRotationMatrix();
  Pose out = reference;
  out.rotation = turn * reference.rotation;
  out.translation_mm = turn * (reference.translation_mm - point_mm) + point_mm;
  return out;
}

Machine Machine::fromConfig(const ConfigNode& node) {
  Machine m;
  m.source_detector_distance_mm = node.at("source_detector_distance_mm").number(1.0, 1e5);
  const ConfigNode detector = node.at("detector");
  m.columns = static_cast<int>(detector.at("columns").integer(1, 65536));
  m.rows = static_cast<int>(detector.at("rows").integer(1, 65536));
  if (detector.at("columns").number() != m.columns) detector.at("columns").fail("expected a whole number");
  if (detector.at("rows").number() != m.rows) detector.at("rows").fail("expected a whole number");
  const auto pitch = pair(detector.at("pixel_pitch_mm"), 1e-6, 100.0);
  m.pitch_u_mm = pitch[0];
  m.pitch_v_mm = pitch[1];
  if (auto pp = detector.find("principal_point_px")) {
    const auto c = pair(*pp, -1e6, 1e6);
    m.cx_px = c[0];
    m.cy_px = c[1];
  } else {
    m.cx_px = 0.5 * m.columns;
    m.cy_px = 0.5 * m.rows;
  }
  if (auto lag = detector.find("lag_fraction")) m.lag_fraction = lag->number(0.0, 0.5);
  if (detector.has("tilt_deg") || detector.has("rotation_deg")) {
    const auto tilt = detector.has("tilt_deg") ? pair(detector.at("tilt_deg"), -10.0, 10.0)
                                               : std::array<double, 2>{0.0, 0.0};
    const double rotation =
        detector.has("rotation_deg") ? detector.at("rotation_deg").number(-10.0, 10.0) : 0.0;
    m.setDetectorPose(tilt[0], tilt[1], rotation);
  }
  // A characterised detector: its lag where the machine states none, and its
  // column crosstalk (the halo is read by the jobs, xray/detector_file.h).
  if (auto name = detector.find("characterization")) {
    const DetectorFile file =
        loadDetectorFile(std::filesystem::path(node.file()).parent_path() / name->string());
    if (std::isnan(m.lag_fraction) && !std::isnan(file.lag_fraction))
      m.lag_fraction = file.lag_fraction,
      m.lag_fraction_uncertainty = file.lag_fraction_uncertainty;
    if (!std::isnan(file.column_crosstalk))
      m.column_crosstalk = file.column_crosstalk,
      m.column_crosstalk_uncertainty = file.column_crosstalk_uncertainty;
    if (!file.bad_pixels.empty())
      m.bad_pixels = std::make_shared<const ImageT<uint8_t>>(
          loadBadPixelMask(file.bad_pixels, m.columns, m.rows));
  }
  m.description = node.get<std::string>("description", "");
  if (auto t = node.find("turntable")) m.turntable = turntableFromConfig(*t);
  if (auto u = node.find("uncertainty")) {
    if (auto d = u->find("source_detector_distance_mm"))
      m.source_detector_distance_uncertainty_mm = d->number(0.0, 1e3);
    if (auto p = u->find("pixel_pitch_relative"))
      m.pixel_pitch_uncertainty_relative = p->number(0.0, 0.1);
    if (auto pose = u->find("detector_pose_deg")) {
      if (pose->size() != 3)
        pose->fail("expected [tilt about u, tilt about v, rotation] in degrees");
      for (size_t k = 0; k < 3; ++k)
        m.detector_pose_uncertainty_deg[k] = (*pose)[k].number(0.0, 10.0);
    }
    if (auto g = u->find("lag_fraction")) {
      if (std::isnan(m.lag_fraction))
        g->fail("a lag fraction's uncertainty needs detector.lag_fraction");
      m.lag_fraction_uncertainty = g->number(0.0, 0.5);
    }
  }
  return m;
}

Machine Machine::load(const std::filesystem::path& path) {
  const ConfigNode root = ConfigNode::loadFile(path);
  Machine m = fromConfig(root);
  root.finish();
  return m;
}

void Machine::validate() const {
  if (!(source_detector_distance_mm > 0) || !std::isfinite(source_detector_distance_mm))
    fail("source-detector distance must be positive, got {}", source_detector_distance_mm);
  if (columns < 1 || rows < 1) fail("detector size must be positive, got {}x{}", columns, rows);
  if (!(pitch_u_mm > 0) || !(pitch_v_mm > 0))
    fail("pixel pitch must be positive, got {} x {}", pitch_u_mm, pitch_v_mm);
  if (!std::isfinite(cx_px) || !std::isfinite(cy_px)) fail("principal point must be finite");
}

double Machine::lagFractionUncertainty() const {
  if (std::isnan(lag_fraction)) return 0.0;
  if (!std::isnan(lag_fraction_uncertainty)) return lag_fraction_uncertainty;
  return kDefaultLagUncertaintyRelative * lag_fraction;
}

nlohmann::json Machine::toJson() const {
  nlohmann::json out = {
      {"source_detector_distance_mm", source_detector_distance_mm},
      {"detector",
       {{"columns", columns},
        {"rows", rows},
        {"pixel_pitch_mm", {pitch_u_mm, pitch_v_mm}},
        {"principal_point_px", {cx_px, cy_px}}}},
      {"uncertainty",
       {{"source_detector_distance_mm", source_detector_distance_uncertainty_mm},
        {"pixel_pitch_relative", pixel_pitch_uncertainty_relative}}}};
  if (!std::isnan(lag_fraction)) out["detector"]["lag_fraction"] = lag_fraction;
  if (tilted()) {
    out["detector"]["tilt_deg"] = {detector_tilt_deg[0], detector_tilt_deg[1]};
    out["detector"]["rotation_deg"] = detector_rotation_deg;
  }
  if (detector_pose_uncertainty_deg != std::array<double, 3>{0.0, 0.0, 0.0})
    out["uncertainty"]["detector_pose_deg"] = {detector_pose_uncertainty_deg[0],
                                               detector_pose_uncertainty_deg[1],
                                               detector_pose_uncertainty_deg[2]};
  if (!std::isnan(lag_fraction_uncertainty))
    out["uncertainty"]["lag_fraction"] = lag_fraction_uncertainty;
  if (turntable)
    out["turntable"] = {
        {"point_mm", {turntable->point_mm.x(), turntable->point_mm.y(), turntable->point_mm.z()}},
        {"direction",
         {turntable->direction.x(), turntable->direction.y(), turntable->direction.z()}},
        {"point_uncertainty_mm", turntable->point_uncertainty_mm},
        {"direction_uncertainty_deg", turntable->direction_uncertainty_deg}};
  if (!description.empty()) out["description"] = description;
  return out;
}

Pose poseFromConfig(const ConfigNode& node) {
  node.get<std::string>("description", "");  // free text, allowed
  if (auto matrix = node.find("matrix")) {
    if (node.has("rotation_deg") || node.has("translation_mm"))
      node.fail("give either 'matrix' or 'rotation_deg' and 'translation_mm', not both");
    if (matrix->size() != 16) matrix->fail(fmt::format("expected 16 numbers, got {}", matrix->size()));
    Mat4 m;
    for (int i = 0; i < 16; ++i) m(i / 4, i % 4) = (*matrix)[static_cast<size_t>(i)].number();
    try {
      return Pose::fromMatrix(m);
    } catch (const Error& e) {
      matrix->fail(e.message());
    }
  }
  const Vec3 angles = node.has("rotation_deg") ? triple(node.at("rotation_deg"), 1e4) : Vec3::Zero();
  return Pose::fromEulerDeg(angles, triple(node.at("translation_mm"), 1e6));
}

Pose loadPose(const std::filesystem::path& path) {
  const ConfigNode root = ConfigNode::loadFile(path);
  Pose pose = poseFromConfig(root);
  root.finish();
  return pose;
}

nlohmann::json poseToJson(const Pose& pose) {
  const Vec3 angles = pose.eulerDeg();
  const Vec3& t = pose.translation_mm;
  return {{"rotation_deg", {angles.x(), angles.y(), angles.z()}},
          {"translation_mm", {t.x(), t.y(), t.z()}},
          {"matrix", pose.rowMajor()}};
}

}  // namespace xgauge
