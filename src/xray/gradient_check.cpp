#include "xgauge/xray/derivatives.h"

#include "xgauge/core/error.h"

#include <algorithm>
#include <cmath>

namespace xgauge {

double GradientCheck::worst() const {
  double worst = 0.0;
  for (const GradientColumn& c : columns)
    if (c.scale > kMovesNothing) worst = std::max(worst, c.worst);
  return worst;
}

GradientColumn compareWithDifferences(std::string name, std::span<const double> coarse,
                                      std::span<const double> fine,
                                      const std::function<double(size_t)>& analytic,
                                      double agreement) {
  XG_CHECK(coarse.size() == fine.size(), "two differences of one column");
  GradientColumn column;
  column.name = std::move(name);
  for (double v : coarse) column.scale = std::max(column.scale, std::abs(v));
  double error2 = 0.0, norm2 = 0.0, error2_all = 0.0, norm2_all = 0.0;
  for (size_t m = 0; m < fine.size(); ++m) {
    const double fd = fine[m], e = analytic(m) - fd;
    error2_all += e * e, norm2_all += fd * fd;
    if (std::abs(coarse[m] - fd) > agreement * column.scale) {
      ++column.kinked;
      continue;
    }
    ++column.pixels;
    error2 += e * e, norm2 += fd * fd;
    if (column.scale > 0.0) column.worst = std::max(column.worst, std::abs(e) / column.scale);
  }
  column.norm_error = norm2 > 0.0 ? std::sqrt(error2 / norm2) : 0.0;
  column.norm_error_all = norm2_all > 0.0 ? std::sqrt(error2_all / norm2_all) : 0.0;
  return column;
}

GradientCheck checkPartGradients(const Machine& machine, const PartModel& part,
                                 std::span<const double> dimensions, const Vec3& rotation_deg,
                                 const Vec3& translation_mm, const ExponentialSum& material,
                                 const RenderOptions& options, std::span<const double> steps) {
  const size_t dims = part.dimensions().size();
  XG_CHECK(dimensions.size() == dims, "{} values for {} dimensions", dimensions.size(), dims);
  std::vector<double> theta(dimensions.begin(), dimensions.end());
  for (int a = 0; a < 3; ++a) theta.push_back(rotation_deg[a]);
  for (int a = 0; a < 3; ++a) theta.push_back(translation_mm[a]);
  std::vector<std::string> names;
  for (const Dimension& d : part.dimensions()) names.push_back(d.name);
  for (const char* n : {"rx", "ry", "rz", "x", "y", "z"}) names.emplace_back(n);
  std::vector<double> h(steps.begin(), steps.end());
  if (h.empty()) h.assign(theta.size(), 3e-4);
  XG_CHECK(h.size() == theta.size(), "{} steps for {} parameters", h.size(), theta.size());

  std::vector<Vec3> part_vertices;
  const VertexMap map = [&](std::span<const double> t, std::vector<Vec3>& world) {
    if (part.invalidity(t.first(dims)) || part.tryEvaluate(t.first(dims), part_vertices))
      return false;
    poseVertices(Pose::fromEulerDeg(Vec3(t[dims], t[dims + 1], t[dims + 2]),
                                    Vec3(t[dims + 3], t[dims + 4], t[dims + 5])),
                 part_vertices, world);
    return !outsideBeam(machine, world);
  };
  std::vector<Vec3> world;
  if (!map(theta, world)) {
    if (auto why = part.invalidity(dimensions)) fail("cannot check gradients: {}", *why);
    fail("cannot check gradients: the part cannot be built or leaves the beam at this pose");
  }
  std::vector<int> indices(theta.size());
  for (size_t i = 0; i < theta.size(); ++i) indices[i] = static_cast<int>(i);
  std::vector<Vec3> velocities;
  if (!vertexVelocities(map, theta, indices, h, velocities))
    fail("cannot check gradients: no step of some parameter gives a valid part");

  const TransmissionTable table = TransmissionTable::forMaterial(material, 1e4);
  const WorldMesh mesh{world, part.triangles(), part.csg().get()};
  IntensityDerivatives analytic;
  renderIntensityDerivatives(machine, mesh, table, options, velocities,
                             static_cast<int>(theta.size()), analytic);

  // Central differences with steps h and h / 2 (the second tells where the
  // first can be trusted).
  auto difference = [&](size_t i, double step, ImageT<double>& out) {
    std::vector<double> at = theta;
    std::vector<Vec3> moved;
    ImageT<double> plus, minus;
    at[i] = theta[i] + step;
    if (!map(at, moved)) return false;
    renderIntensity(machine, WorldMesh{moved, part.triangles(), part.csg().get()}, table, options,
                    plus);
    at[i] = theta[i] - step;
    if (!map(at, moved)) return false;
    renderIntensity(machine, WorldMesh{moved, part.triangles(), part.csg().get()}, table, options,
                    minus);
    out.resize(plus.width(), plus.height());
    for (int y = 0; y < out.height(); ++y)
      for (int x = 0; x < out.width(); ++x) out(x, y) = (plus(x, y) - minus(x, y)) / (2.0 * step);
    return true;
  };

  GradientCheck check;
  for (size_t i = 0; i < theta.size(); ++i) {
    ImageT<double> coarse, fine;
    if (!difference(i, h[i], coarse) || !difference(i, 0.5 * h[i], fine))
      fail("cannot check gradients: parameter {} at {} +- {} does not give a valid part", names[i],
           theta[i], h[i]);
    const Image& a = analytic.per_parameter[i];
    const GradientColumn column = compareWithDifferences(
        names[i], coarse.pixels(), fine.pixels(),
        [&a](size_t m) { return static_cast<double>(a.pixels()[m]); }, 1e-6);
    check.columns.push_back(column);
  }
  return check;
}

}  // namespace xgauge
