// The forward model's derivatives (model.h): the residuals' Jacobian,
// assembled per radiograph from the render with derivatives (xray/
// derivatives.h) chained through the part model and the poses (vertex
// velocities) and through the scatter (model_scatter.cpp), and the material's
// columns by central differences of whole renders.
#include "xgauge/measure/model.h"

#include "xgauge/xray/derivatives.h"
#include "xgauge/xray/renderer.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace xgauge {

namespace {

// One radiograph's rows: the residuals (simulated - measured) over `roi` and
// their derivatives d r_m / d theta[indices[moving[k]]] from the render's
// per-parameter images `d`, the scatter chained in where `spread` is given
// (its `rates`: the scatter of each derivative image). Rows `first` on of
// `out` and `jacobian` (p columns), which are sized already.
void writeRadiographRows(const IntensityDerivatives& d, const ScatterEstimate* spread,
                         std::span<const ScatterEstimate> rates, const ScatterModel& scatter,
                         const Image& measured, const PixelRect& roi, std::span<const int> moving,
                         size_t first, size_t p, std::vector<double>& out,
                         std::vector<double>& jacobian) {
  const int count = static_cast<int>(moving.size());
  const double scale = 1.0 / std::sqrt(static_cast<double>(roi.area()));
  const double w = scatter.weight;
  // Rows in parallel: every pixel writes only its own residual and row.
  tbb::parallel_for(0, roi.height, [&](int y) {
    for (int x = 0; x < roi.width; ++x) {
      const size_t m =
          first + static_cast<size_t>(y) * static_cast<size_t>(roi.width) + static_cast<size_t>(x);
      const auto intensity = static_cast<double>(d.intensity(x, y));
      double* row = jacobian.data() + m * p;
      double simulated = intensity;
      if (!spread) {
        for (int k = 0; k < count; ++k)
          row[moving[static_cast<size_t>(k)]] =
              scale * static_cast<double>(d.per_parameter[static_cast<size_t>(k)](x, y));
      } else {
        // out = mix(I, G) / (open F), as simulatePosed (F the flat's own
        // halo, 1 in a uniform field).
        const ScatterEstimate::Tap tap = spread->tap(roi.x + x + 0.5, roi.y + y + 0.5);
        simulated = static_cast<double>(spread->simulated(scatter, intensity, tap));
        for (int k = 0; k < count; ++k) {
          const ScatterEstimate& rate = rates[static_cast<size_t>(k)];
          const double mixed =
              (1.0 - w) * static_cast<double>(d.per_parameter[static_cast<size_t>(k)](x, y)) +
              w * rate.at(tap);
          row[moving[static_cast<size_t>(k)]] =
              scale * (mixed / spread->flatAt(tap) - simulated * rate.open) / spread->open;
        }
      }
      out[m] = scale * (simulated - static_cast<double>(measured(roi.x + x, roi.y + y)));
    }
  });
}

}  // namespace

bool ForwardModel::poseVelocities(std::span<const double> theta, std::span<const int> indices,
                                  int radiograph, std::vector<int>& moving,
                                  std::vector<Vec3>& velocities) {
  std::vector<int> vertex_indices;
  std::vector<double> steps;
  std::vector<int> position;
  for (size_t k = 0; k < indices.size(); ++k) {
    if (kind(indices[k]) == ParameterKind::kMaterial ||
        kind(indices[k]) == ParameterKind::kDetector)
      continue;
    vertex_indices.push_back(indices[k]);
    position.push_back(static_cast<int>(k));
    // Small against any feature, large against rounding; most vertex
    // expressions are linear in the dimensions, where any step is exact.
    steps.push_back(1e-4 * std::max(1.0, std::abs(theta[static_cast<size_t>(indices[k])])));
  }
  const size_t dims = part_.dimensions().size();
  const VertexMap map = [&](std::span<const double> t, std::vector<Vec3>& world) {
    if (part_.tryEvaluate(t.first(dims), part_vertices_)) return false;
    poseVertices(pose(t, radiograph), part_vertices_, world);
    return true;
  };
  std::vector<Vec3> all;
  if (!vertexVelocities(map, theta, vertex_indices, steps, all)) return false;
  // Keep the parameters that move this radiograph's part (another
  // radiograph's pose does not).
  const size_t vertices = part_.vertexCount();
  moving.clear();
  velocities.clear();
  for (size_t k = 0; k < vertex_indices.size(); ++k) {
    const auto first = all.begin() + static_cast<ptrdiff_t>(k * vertices);
    if (std::all_of(first, first + static_cast<ptrdiff_t>(vertices),
                    [](const Vec3& v) { return v.isZero(0.0); }))
      continue;
    moving.push_back(position[k]);
    velocities.insert(velocities.end(), first, first + static_cast<ptrdiff_t>(vertices));
  }
  return true;
}

bool ForwardModel::appendRadiographJacobian(std::span<const double> theta,
                                            std::span<const int> indices, int r, int level,
                                            int samples, std::vector<double>& out,
                                            std::vector<double>& jacobian) {
  if (tryPose(theta, r)) return false;
  const WorldMesh mesh = worldMesh();
  const PreparedRadiograph& rad = radiograph(r);
  const PixelRect roi = rad.rois[static_cast<size_t>(level)];
  std::vector<int> moving;
  std::vector<Vec3> velocities;
  if (!poseVelocities(theta, indices, r, moving, velocities)) return false;
  const int count = static_cast<int>(moving.size());
  IntensityDerivatives d;
  renderIntensityDerivatives(machineAt(level), mesh, transmission_, renderOptions(samples, roi),
                             velocities, count, d);
  // The scatter and its derivatives, from coarse renders of the whole detector.
  std::optional<ScatterEstimate> spread;
  std::vector<ScatterEstimate> spread_rates;
  if (job().scatter.enabled())
    spread = scatterWithRates(mesh, r, level, velocities, count, spread_rates);
  const size_t first = out.size();
  out.resize(first + static_cast<size_t>(roi.area()));
  jacobian.resize(out.size() * indices.size(), 0.0);
  writeRadiographRows(d, spread ? &*spread : nullptr, spread_rates, job().scatter,
                      rad.levels[static_cast<size_t>(level)], roi, moving, first, indices.size(),
                      out, jacobian);
  return true;
}

bool ForwardModel::addMaterialColumns(std::span<const double> theta, std::span<const int> indices,
                                      int level, int samples, std::span<const int> radiographs,
                                      std::span<const double> out, std::vector<double>& jacobian) {
  const size_t p = indices.size();
  std::vector<double> at(theta.begin(), theta.end()), plus, minus;
  for (size_t k = 0; k < p; ++k) {
    const auto i = static_cast<size_t>(indices[k]);
    if (kind(indices[k]) != ParameterKind::kMaterial &&
        kind(indices[k]) != ParameterKind::kDetector)
      continue;
    // A detector angle: 0.01 deg moves the panel's edge by a tenth of a
    // pixel, well above the float image's rounding.
    const double h = kind(indices[k]) == ParameterKind::kDetector
                         ? 1e-2
                         : 1e-4 * std::max(1.0, std::abs(theta[i]));
    at[i] = std::min(theta[i] + h, upper()[i]);
    const double hi = at[i];
    const bool ok_plus = residuals(at, level, samples, radiographs, plus);
    at[i] = std::max(theta[i] - h, lower()[i]);
    const double lo = at[i];
    const bool ok_minus = residuals(at, level, samples, radiographs, minus);
    at[i] = theta[i];
    if (!ok_plus || !ok_minus || plus.size() != out.size() || !(hi > lo)) return false;
    for (size_t m = 0; m < out.size(); ++m) jacobian[m * p + k] = (plus[m] - minus[m]) / (hi - lo);
  }
  return true;
}

bool ForwardModel::residualsAndJacobian(std::span<const double> theta, std::span<const int> indices,
                                        int level, int samples, std::span<const int> radiographs,
                                        std::vector<double>& out, std::vector<double>& jacobian) {
  out.clear();
  jacobian.clear();
  XG_CHECK(theta.size() == static_cast<size_t>(size()), "theta has the wrong size");
  if (part_.invalidity(theta.first(part_.dimensions().size()))) return false;
  useMaterialOf(theta);
  for (int r : radiographs)
    if (!appendRadiographJacobian(theta, indices, r, level, samples, out, jacobian)) {
      out.clear(), jacobian.clear();
      return false;
    }
  // Material and detector parameters: central differences of whole renders (a failure
  // leaves the model on the last one's material, as it finds it again).
  if (!addMaterialColumns(theta, indices, level, samples, radiographs, out, jacobian)) {
    out.clear(), jacobian.clear();
    return false;
  }
  useMaterialOf(theta);
  return true;
}

}  // namespace xgauge
