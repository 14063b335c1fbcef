// The forward model (model.h): its construction, the material it renders
// with, the posed part and the simulated radiographs, their residuals and
// loss. The parameter layout is in model_parameters.cpp, the scatter in
// model_scatter.cpp, the Jacobian in model_derivatives.cpp.
#include "xgauge/measure/model.h"

#include "xgauge/loss/loss.h"
#include "xgauge/xray/renderer.h"

#include <algorithm>
#include <cmath>

namespace xgauge {

namespace {

// Refuses pose bounds under which the part can never be inside the beam or
// cast a shadow on the detector; `reach_mm` bounds the distance from the
// part's centre to any of its points.
void checkPoseBounds(const MeasurementJob& job, const Machine& machine, double reach_mm) {
  const auto& c = job.centre_bounds_mm;
  const double d = machine.source_detector_distance_mm;
  const SourceLocation where = SourceLocation::at(job.file.string(), "/pose_bounds/centre_mm");
  const double z0 = std::max(c[2][0] - reach_mm, 1e-6), z1 = std::min(c[2][1] + reach_mm, d - 1e-6);
  if (c[2][1] - reach_mm <= 0.0 || c[2][0] + reach_mm >= d || z0 >= z1)
    failAt(where,
           "centre z in [{}, {}] mm keeps the part (reaching {:.1f} mm from its centre) out of "
           "the beam: it must lie between the detector (z = 0) and the source (z = {} mm)",
           c[2][0], c[2][1], reach_mm, d);
  // The shadows of every allowed position lie within the shadow of this box.
  std::vector<Vec3> corners;
  for (int k = 0; k < 8; ++k)
    corners.emplace_back(k & 1 ? c[0][1] + reach_mm : c[0][0] - reach_mm,
                         k & 2 ? c[1][1] + reach_mm : c[1][0] - reach_mm, k & 4 ? z1 : z0);
  if (auto why = shadowMissesDetector(machine, corners))
    failAt(where, "no centre within these bounds puts the part in view: {}", *why);
}

}  // namespace

ForwardModel::ForwardModel(const MeasurementInputs& inputs)
    : ForwardModel(inputs, [&]() -> const ExponentialSum& {
        if (!inputs.material) fail("{}: the job names no material", inputs.job.file.string());
        return *inputs.material;
      }()) {}

ForwardModel::ForwardModel(const MeasurementInputs& inputs, const ExponentialSum& material)
    : inputs_(inputs),
      machine_(inputs.machine),
      part_(*inputs.part),
      base_material_(material),
      material_(material) {
  XG_CHECK(
      inputs.radiographs.size() == inputs.job.radiographs.size() && !inputs.radiographs.empty(),
      "the inputs hold {} prepared radiographs for {} in the job", inputs.radiographs.size(),
      inputs.job.radiographs.size());
  const MeasurementJob& job = inputs.job;

  // The part: its reference centre and the dimension parameters.
  const std::vector<double> nominal = part_.nominalValues();
  const BoundingBox box = boundingBox(part_.mesh(nominal));
  centre_part_ = 0.5 * (box.min_mm + box.max_mm);
  part_size_mm_ = box.diagonal();
  addDimensionParameters();
  if (const auto why = part_.invalidity(layout_.start()))
    failAt(SourceLocation::at(job.file.string(), "/dimensions"),
           "the values the fit starts from do not make a valid part: {}", *why);
  checkPoseBounds(job, machine(), 0.5 * part_size_mm_);

  // The material: tabulated over the longest chord the part can have.
  double longest = 0.0;
  for (const Dimension& d : part_.dimensions()) longest = std::max(longest, d.max);
  max_path_mm_ = 4.0 * box.diagonal() + 2.0 * longest;
  setMaterial(material);

  // Each radiograph's pose parameters.
  addPoseParameters();
  if (job.refine_material == MaterialRefinement::kRateScale) addRateScale();
}

void ForwardModel::setMaterial(const ExponentialSum& material) {
  base_material_ = material;
  useMaterial(material);
}

void ForwardModel::useMaterial(const ExponentialSum& material) {
  material_ = material;
  transmission_ = TransmissionTable::forMaterial(material, max_path_mm_);
}

void ForwardModel::useMaterialOf(std::span<const double> theta) {
  if (layout_.hasBlock("detector")) {
    const double* pose = theta.data() + layout_.block("detector").front();
    if (pose[0] != machine_.detector_tilt_deg[0] || pose[1] != machine_.detector_tilt_deg[1] ||
        pose[2] != machine_.detector_rotation_deg)
      machine_.setDetectorPose(pose[0], pose[1], pose[2]);
  }
  if (material_terms_ == 0 && rate_scale_index_ < 0) return;
  const ExponentialSum wanted = materialOf(theta);
  const auto& now = material_.terms();
  bool same = now.size() == wanted.terms().size();
  for (size_t k = 0; same && k < now.size(); ++k)
    same = now[k].weight == wanted.terms()[k].weight &&
           now[k].mu_per_mm == wanted.terms()[k].mu_per_mm;
  if (!same) useMaterial(wanted);
}

int ForwardModel::levelForWidth(int min_width) const {
  if (min_width <= 0) return 0;
  int level = levels() - 1;
  while (level > 0 && radiograph(0).levels[static_cast<size_t>(level)].width() < min_width) --level;
  return level;
}

Machine ForwardModel::machineAt(int level) const {
  Machine m = machine();
  const double s = static_cast<double>(1 << level);
  const Image& image = radiograph(0).levels[static_cast<size_t>(level)];
  m.columns = image.width();
  m.rows = image.height();
  m.pitch_u_mm *= s;
  m.pitch_v_mm *= s;
  m.cx_px /= s;
  m.cy_px /= s;
  return m;
}

std::optional<std::string> ForwardModel::tryPose(std::span<const double> theta, int radiograph) {
  if (auto why = part_.tryEvaluate(theta.first(part_.dimensions().size()), part_vertices_))
    return why;
  poseVertices(pose(theta, radiograph), part_vertices_, world_vertices_);
  if (auto why = outsideBeam(machine(), world_vertices_))
    return fmt::format("{} in radiograph {}", *why, spec(radiograph).name);
  return std::nullopt;
}

WorldMesh ForwardModel::worldMesh() const {
  return WorldMesh{world_vertices_, part_.triangles(), part_.csg().get()};
}

WorldMesh ForwardModel::posedMesh(std::span<const double> theta, int radiograph) {
  if (auto why = tryPose(theta, radiograph)) fail("cannot simulate these parameters: {}", *why);
  return worldMesh();
}

std::optional<std::string> ForwardModel::infeasibility(std::span<const double> theta) {
  XG_CHECK(theta.size() == static_cast<size_t>(size()), "theta has the wrong size");
  if (auto why = part_.invalidity(theta.first(part_.dimensions().size()))) return why;
  for (int r = 0; r < radiographCount(); ++r)
    if (auto why = tryPose(theta, r)) return why;
  return std::nullopt;
}

Image ForwardModel::pathLengths(std::span<const double> theta, int radiograph, int level,
                                const PixelRect& region) {
  useMaterialOf(theta);
  const WorldMesh mesh = posedMesh(theta, radiograph);
  RenderOptions options;
  options.region = region;
  Image out;
  renderPathLength(machineAt(level), mesh, options, out);
  return out;
}

std::vector<Segment2> ForwardModel::outline(std::span<const double> theta, int radiograph) {
  return projectedContour(machine(), posedMesh(theta, radiograph));
}

Image ForwardModel::simulate(std::span<const double> theta, int radiograph, int level, int samples,
                             const PixelRect& region) {
  useMaterialOf(theta);
  return simulatePosed(posedMesh(theta, radiograph), radiograph, level, samples, region);
}

RenderOptions ForwardModel::renderOptions(int samples, const PixelRect& region) const {
  RenderOptions options;
  options.samples_per_axis = samples;
  options.edge_samples_per_axis = edge_samples_ > samples ? std::min(edge_samples_, 32) : 0;
  options.region = region;
  return options;
}

Image ForwardModel::simulatePosed(const WorldMesh& mesh, int radiograph, int level, int samples,
                                  const PixelRect& region) {
  Image out;
  renderIntensity(machineAt(level), mesh, transmission_, renderOptions(samples, region), out);
  if (job().scatter.enabled()) addScatter(mesh, radiograph, level, region, out);
  return out;
}

bool ForwardModel::forEachSimulated(
    std::span<const double> theta, int level, int samples, std::span<const int> radiographs,
    const std::function<void(const PreparedRadiograph&, const PixelRect&, const Image&)>& use) {
  XG_CHECK(theta.size() == static_cast<size_t>(size()), "theta has the wrong size");
  if (part_.invalidity(theta.first(part_.dimensions().size()))) return false;
  useMaterialOf(theta);
  for (int r : radiographs) {
    if (tryPose(theta, r)) return false;
    const PreparedRadiograph& rad = radiograph(r);
    const PixelRect roi = rad.rois[static_cast<size_t>(level)];
    rendered_ = simulatePosed(worldMesh(), r, level, samples, roi);
    use(rad, roi, rendered_);
  }
  return true;
}

bool ForwardModel::residuals(std::span<const double> theta, int level, int samples,
                             std::span<const int> radiographs, std::vector<double>& out) {
  out.clear();
  const bool feasible = forEachSimulated(
      theta, level, samples, radiographs,
      [&](const PreparedRadiograph& rad, const PixelRect& roi, const Image& simulated) {
        const Image& measured = rad.levels[static_cast<size_t>(level)];
        const double scale = 1.0 / std::sqrt(static_cast<double>(roi.area()));
        for (int y = 0; y < roi.height; ++y)
          for (int x = 0; x < roi.width; ++x)
            out.push_back(scale * (static_cast<double>(simulated(x, y)) -
                                   static_cast<double>(measured(roi.x + x, roi.y + y))));
      });
  if (!feasible) out.clear();
  return feasible;
}

std::optional<double> ForwardModel::loss(std::span<const double> theta, int level, int samples,
                                         std::span<const int> radiographs) {
  double total = 0.0;
  const bool feasible = forEachSimulated(
      theta, level, samples, radiographs,
      [&](const PreparedRadiograph& rad, const PixelRect& roi, const Image& simulated) {
        total += imageLoss(simulated, rad.levels[static_cast<size_t>(level)], roi, job().loss);
      });
  if (!feasible) return std::nullopt;
  return total;
}

}  // namespace xgauge
