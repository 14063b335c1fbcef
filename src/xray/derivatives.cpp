// The render with derivatives (renderer.h, renderIntensityDerivatives).
//
// Written here rather than taken from a library: automatic differentiation
// (Ceres' Jets, or an AD tool) of the rasterizer would differentiate the
// exact orientation tests and the span search too, and carry P derivatives
// through every operation of every sample; the closed form below needs four
// numbers per parameter and triangle, formed once per render, and a few
// multiply-adds per parameter where a triangle covers a sample.
#include "xgauge/xray/derivatives.h"

#include "footprint.h"

#include "xgauge/core/error.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>

namespace xgauge {

namespace {

using raster::Band;
using raster::Footprint;
using raster::SceneSetup;
using raster::TriangleSetup;

// The plane of each triangle as the renderer's depth formula sees it, and how
// it moves: lambda = D / (r . N) with D = A . (B x C) and N = A x B + B x C +
// C x A (A, B, C the vertices relative to the source), so
// d lambda = (dD - lambda r . dN) / (r . N).
struct PlaneRates {
  int parameters = 0;
  std::vector<double> normal;  // N per triangle: 3 values
  std::vector<double> rates;   // per triangle, per parameter: dD, dNx, dNy, D_sd * dNz
  const double* normalOf(uint32_t t) const { return normal.data() + 3 * size_t{t}; }
  const double* ratesOf(uint32_t t) const {
    return rates.data() + 4 * static_cast<size_t>(parameters) * t;
  }
};

PlaneRates planeRates(const Machine& machine, const WorldMesh& mesh, const SceneSetup& scene,
                      std::span<const Vec3> velocities, int parameters) {
  PlaneRates out;
  out.parameters = parameters;
  const size_t triangles = mesh.triangles.size();
  const size_t vertices = mesh.vertices_mm.size();
  out.normal.assign(3 * triangles, 0.0);
  out.rates.assign(4 * static_cast<size_t>(parameters) * triangles, 0.0);
  const Vec3 source = machine.sourceWorld();
  const double d = machine.source_detector_distance_mm;
  tbb::parallel_for(size_t{0}, scene.visible.size(), [&](size_t v) {
    const uint32_t t = scene.visible[v];
    const auto& tri = mesh.triangles[t];
    const Vec3 a = mesh.vertices_mm[tri[0]] - source;
    const Vec3 b = mesh.vertices_mm[tri[1]] - source;
    const Vec3 c = mesh.vertices_mm[tri[2]] - source;
    const Vec3 bc = b.cross(c), ca = c.cross(a), ab = a.cross(b);
    const Vec3 n = ab + bc + ca;
    std::copy_n(n.data(), 3, out.normal.data() + 3 * size_t{t});
    const Vec3 b_c = b - c, c_a = c - a, a_b = a - b;
    double* q = out.rates.data() + 4 * static_cast<size_t>(parameters) * t;
    for (int k = 0; k < parameters; ++k, q += 4) {
      const size_t base = static_cast<size_t>(k) * vertices;
      const Vec3& va = velocities[base + tri[0]];
      const Vec3& vb = velocities[base + tri[1]];
      const Vec3& vc = velocities[base + tri[2]];
      const Vec3 dn = va.cross(b_c) + vb.cross(c_a) + vc.cross(a_b);
      q[0] = va.dot(bc) + vb.dot(ca) + vc.dot(ab);
      q[1] = dn.x();
      q[2] = dn.y();
      q[3] = d * dn.z();
    }
  });
  return out;
}

// One band's sums: per sample, the path over |P - S| (as the image render)
// and its derivative per parameter (parameter-contiguous).
class BandTerms final : public raster::PathTerms {
 public:
  // `gradient`: the band's samples times the parameters, zeroed by the
  // caller where it will be read.
  BandTerms(const Machine& machine, const SceneSetup& scene, const PlaneRates& rates,
            const Footprint& f, const Band& band, double* gradient)
      : machine_(machine),
        scene_(scene),
        rates_(rates),
        f_(f),
        band_(band),
        p_(static_cast<size_t>(rates.parameters)),
        gradient_(gradient),
        tilted_(machine.tilted()) {}

  double* at(int row, int column) {
    return gradient_ +
           (static_cast<size_t>(row - band_.row_begin) * static_cast<size_t>(f_.width()) +
            static_cast<size_t>(column - f_.col_begin)) *
               p_;
  }

  // sign * d lambda_t / d theta at sample (row, column), added.
  void add(int row, int column, uint32_t triangle, double sign) override {
    // A tilted panel's samples out of line: the untilted body stays small
    // enough to inline into the scan (render_bench's derivatives were 10 %
    // slower with both bodies here).
    if (tilted_) [[unlikely]]
      return addTilted(row, column, triangle, sign);
    const TriangleSetup& t = scene_.triangles[triangle];
    const double lambda = raster::inverseMagnification(t, row, column);
    const double n = f_.n;
    const double px = ((column + 0.5) / n - machine_.cx_px) * machine_.pitch_u_mm;
    const double py = (machine_.cy_px - (row + 0.5) / n) * machine_.pitch_v_mm;
    const double* normal = rates_.normalOf(triangle);
    const double rn =
        px * normal[0] + py * normal[1] - machine_.source_detector_distance_mm * normal[2];
    if (rn == 0.0) return;  // a ray in the plane: the triangle is seen edge-on
    const double alpha = sign / rn, beta = alpha * lambda;
    const double* q = rates_.ratesOf(triangle);
    double* g = at(row, column);
    for (size_t k = 0; k < p_; ++k, q += 4)
      g[k] += alpha * q[0] - beta * (px * q[1] + py * q[2] - q[3]);
  }

  // The same with the ray r = P - S to the tilted panel's point
  // P = R (px, py, 0).
  [[gnu::noinline]] void addTilted(int row, int column, uint32_t triangle, double sign) {
    const TriangleSetup& t = scene_.triangles[triangle];
    const double lambda = raster::inverseMagnification(t, row, column);
    const double n = f_.n;
    const double px = ((column + 0.5) / n - machine_.cx_px) * machine_.pitch_u_mm;
    const double py = (machine_.cy_px - (row + 0.5) / n) * machine_.pitch_v_mm;
    const double d = machine_.source_detector_distance_mm;
    const Vec3 r = machine_.detector_rotation.col(0) * px + machine_.detector_rotation.col(1) * py -
                   Vec3(0.0, 0.0, d);
    const double* normal = rates_.normalOf(triangle);
    const double rn = r.x() * normal[0] + r.y() * normal[1] + r.z() * normal[2];
    if (rn == 0.0) return;
    const double alpha = sign / rn, beta = alpha * lambda;
    const double* q = rates_.ratesOf(triangle);
    double* g = at(row, column);
    // q[3] is d * dn_z (planeRates).
    for (size_t k = 0; k < p_; ++k, q += 4)
      g[k] += alpha * q[0] - beta * (r.x() * q[1] + r.y() * q[2] + r.z() / d * q[3]);
  }

  void reset(int row, int column) override { std::fill_n(at(row, column), p_, 0.0); }

 private:
  const Machine& machine_;
  const SceneSetup& scene_;
  const PlaneRates& rates_;
  const Footprint& f_;
  const Band& band_;
  size_t p_;
  double* gradient_;
  bool tilted_;
};

// Pixel (u, v)'s mean of I(x_s) and of I'(x_s) |r_s| d(sum_s) over its
// samples, from a band's per-sample sums and derivatives (footprint `f`):
// `pixel` gets the p derivatives.
double resolvePixel(const std::vector<double>& sum, const std::vector<double>& gradient,
                    const Band& band, const Footprint& f, const raster::SampleDistances& distances,
                    const TransmissionTable& transmission, size_t p, int u, int v,
                    std::vector<double>& pixel) {
  const int n = f.n;
  const size_t width = static_cast<size_t>(f.width());
  double value = 0.0;
  std::fill(pixel.begin(), pixel.end(), 0.0);
  for (int j = 0; j < n; ++j) {
    const int sample_row = v * n + j;
    const double py2d2 = distances.py2d2(sample_row);
    const size_t line = static_cast<size_t>(sample_row - band.row_begin) * width;
    for (int i = 0; i < n; ++i) {
      const size_t k = static_cast<size_t>(u * n + i - f.col_begin);
      const double s = sum[line + k];
      if (s == 0.0) {
        value += 1.0;
        continue;
      }
      const double distance = std::sqrt(distances.px2[k] + py2d2);
      const double path = std::max(0.0, s * distance);
      if (!(path > 0.0)) {  // held at zero: no attenuation and no derivative
        value += 1.0;
        continue;
      }
      value += transmission(path);
      const double weight = transmission.slope(path) * distance;
      const double* g = gradient.data() + (line + k) * p;
      for (size_t q = 0; q < p; ++q) pixel[q] += weight * g[q];
    }
  }
  const double inv_samples = 1.0 / (n * n);
  for (double& q : pixel) q *= inv_samples;
  return value * inv_samples;
}

void store(IntensityDerivatives& out, int x, int y, double value,
           const std::vector<double>& pixel) {
  out.intensity(x, y) = static_cast<float>(value);
  for (size_t q = 0; q < pixel.size(); ++q)
    out.per_parameter[q](x, y) = static_cast<float>(pixel[q]);
}

// The pixels of `runs` sampled again with m x m samples, their values and
// derivatives replacing the n x n ones in `out` (as renderer.cpp's
// refinePixels does for the image: the same samples, in the same order).
void refineDerivatives(const Machine& machine, const WorldMesh& mesh,
                       const TransmissionTable& transmission, int m,
                       const raster::RefinedRuns& runs, std::span<const Vec3> velocities,
                       int parameters, IntensityDerivatives& out) {
  thread_local SceneSetup scratch;
  SceneSetup& scene = scratch;
  raster::setupMesh(machine, mesh, m, runs.region, scene);
  if (scene.empty()) return;
  const PlaneRates rates = planeRates(machine, mesh, scene, velocities, parameters);
  const Footprint f = raster::layoutFootprint(scene, m, 1 + parameters);
  const raster::SampleDistances distances = raster::sampleDistances(machine, f);
  const size_t width = static_cast<size_t>(f.width());
  const size_t p = static_cast<size_t>(parameters);
  const PixelRect& region = runs.region;
  tbb::parallel_for(size_t{0}, f.bands.size(), [&](size_t b) {
    const Band& band = f.bands[b];
    // Kept from render to render, as refinePixels' sums: only the refined
    // samples are zeroed and read.
    thread_local std::vector<double> sum, gradient, pixel;
    const size_t samples = static_cast<size_t>(band.row_end - band.row_begin) * width;
    sum.resize(std::max(sum.size(), samples));
    gradient.resize(std::max(gradient.size(), samples * p));
    pixel.resize(p);
    int lo = 0, hi = 0;
    for (int r = band.row_begin; r < band.row_end; ++r)
      for (const auto& run : runs.row(r / m))
        if (raster::clipRun(run, m, f.col_begin, f.col_end - 1, lo, hi)) {
          const size_t first = static_cast<size_t>(r - band.row_begin) * width +
                               static_cast<size_t>(lo - f.col_begin);
          const size_t count = static_cast<size_t>(hi - lo + 1);
          std::fill_n(sum.begin() + static_cast<ptrdiff_t>(first), count, 0.0);
          std::fill_n(gradient.begin() + static_cast<ptrdiff_t>(first * p), count * p, 0.0);
        }
    BandTerms terms(machine, scene, rates, f, band, gradient.data());
    for (uint32_t i : f.bins[b]) {
      const TriangleSetup& t = scene.triangles[i];
      const double sigma = t.sigma;
      raster::forEachSpan(t, band.row_begin, band.row_end, [&](int line, int k0, int k1) {
        // A row scan's line is a sample row, a column scan's a sample column.
        for (const auto& run : t.by_rows ? runs.row(line / m) : runs.column(line / m)) {
          if (!raster::clipRun(run, m, k0, k1, lo, hi)) continue;
          for (int k = lo; k <= hi; ++k) {
            const int row = t.by_rows ? line : k, column = t.by_rows ? k : line;
            sum[static_cast<size_t>(row - band.row_begin) * width +
                static_cast<size_t>(column - f.col_begin)] +=
                sigma * raster::inverseMagnification(t, row, column);
            terms.add(row, column, i, sigma);
          }
        }
      });
    }
    for (int v = band.row_begin / m; v < band.row_end / m; ++v)
      for (const auto& run : runs.row(v))
        for (int u = std::max(run.first, f.col_begin / m);
             u <= std::min(run.second, f.col_end / m - 1); ++u) {
          const double value =
              resolvePixel(sum, gradient, band, f, distances, transmission, p, u, v, pixel);
          store(out, u - region.x, v - region.y, value, pixel);
        }
  });
}

void renderDerivativesIsolated(const Machine& machine, const WorldMesh& mesh,
                               const TransmissionTable& transmission, const RenderOptions& options,
                               std::span<const Vec3> velocities, int parameters,
                               IntensityDerivatives& out) {
  const PixelRect region = raster::resolveRegion(machine, options);
  const int n = options.samples_per_axis;
  XG_CHECK(parameters >= 0 &&
               velocities.size() == static_cast<size_t>(parameters) * mesh.vertices_mm.size(),
           "{} vertex velocities for {} parameters and {} vertices", velocities.size(), parameters,
           mesh.vertices_mm.size());
  thread_local SceneSetup scratch;
  SceneSetup& scene = scratch;
  raster::setupMesh(machine, mesh, n, region, scene);

  out.intensity.resize(region.width, region.height, 1.0f);
  out.per_parameter.resize(static_cast<size_t>(parameters));
  for (Image& d : out.per_parameter) d.resize(region.width, region.height, 0.0f);
  if (scene.empty()) return;

  const PlaneRates rates = planeRates(machine, mesh, scene, velocities, parameters);
  const Footprint f = raster::layoutFootprint(scene, n, 1 + parameters);
  const raster::SampleDistances distances = raster::sampleDistances(machine, f);
  const size_t p = static_cast<size_t>(parameters);
  struct Buffers {
    std::vector<double> sum, gradient, pixel;
    raster::CsgScratch csg;
  };
  tbb::enumerable_thread_specific<Buffers> buffers;
  tbb::parallel_for(size_t{0}, f.bands.size(), [&](size_t b) {
    const Band& band = f.bands[b];
    Buffers& buf = buffers.local();
    const size_t width = static_cast<size_t>(f.width());
    buf.sum.assign(static_cast<size_t>(band.row_end - band.row_begin) * width, 0.0);
    buf.gradient.assign(buf.sum.size() * p, 0.0);
    BandTerms terms(machine, scene, rates, f, band, buf.gradient.data());
    if (mesh.csg) {
      raster::accumulateCsgBand(scene, f.bins[b], *mesh.csg, band.row_begin, band.row_end,
                                f.col_begin, f.width(), buf.sum.data(), buf.csg, &terms);
    } else {
      for (uint32_t i : f.bins[b]) {
        const TriangleSetup& t = scene.triangles[i];
        const double sigma = t.sigma;
        raster::forEachSample(t, band.row_begin, band.row_end, [&](int row, int column) {
          buf.sum[static_cast<size_t>(row - band.row_begin) * width +
                  static_cast<size_t>(column - f.col_begin)] +=
              sigma * raster::inverseMagnification(t, row, column);
          terms.add(row, column, i, sigma);
        });
      }
    }
    buf.pixel.resize(p);
    for (int v = band.row_begin / n; v < band.row_end / n; ++v) {
      const int y = v - region.y;
      if (y < 0 || y >= region.height) continue;
      for (int u = f.col_begin / n; u < f.col_end / n; ++u) {
        const int x = u - region.x;
        if (x < 0 || x >= region.width) continue;
        const double value = resolvePixel(buf.sum, buf.gradient, band, f, distances, transmission,
                                          p, u, v, buf.pixel);
        store(out, x, y, value, buf.pixel);
      }
    }
  });
  // The edge refinement: as renderIntensity's, the same pixels sampled again.
  const int m = options.edge_samples_per_axis;
  if (m != 0 && !mesh.csg)
    refineDerivatives(machine, mesh, transmission, m, raster::edgeRuns(machine, mesh, options),
                      velocities, parameters, out);
}

}  // namespace

void renderIntensityDerivatives(const Machine& machine, const WorldMesh& mesh,
                                const TransmissionTable& transmission, const RenderOptions& options,
                                std::span<const Vec3> velocities, int parameters,
                                IntensityDerivatives& out) {
  // Isolated, as the image renders (renderer.cpp): a waiting thread must not
  // pick up another render that would reuse its thread_local scene.
  tbb::this_task_arena::isolate([&] {
    renderDerivativesIsolated(machine, mesh, transmission, options, velocities, parameters, out);
  });
}

}  // namespace xgauge

namespace xgauge {

bool vertexVelocities(const VertexMap& map, std::span<const double> theta,
                      std::span<const int> indices, std::span<const double> steps,
                      std::vector<Vec3>& velocities) {
  XG_CHECK(indices.size() == steps.size(), "{} steps for {} parameters", steps.size(),
           indices.size());
  std::vector<double> at(theta.begin(), theta.end());
  std::vector<Vec3> centre, up, down;
  if (!map(at, centre)) return false;
  const size_t vertices = centre.size();
  velocities.resize(indices.size() * vertices);
  for (size_t k = 0; k < indices.size(); ++k) {
    const auto i = static_cast<size_t>(indices[k]);
    const double h = steps[k];
    at[i] = theta[i] + h;
    const bool has_up = map(at, up);
    at[i] = theta[i] - h;
    const bool has_down = map(at, down);
    at[i] = theta[i];
    if (!has_up && !has_down) return false;
    const std::vector<Vec3>& plus = has_up ? up : centre;
    const std::vector<Vec3>& minus = has_down ? down : centre;
    const double span = (has_up ? h : 0.0) + (has_down ? h : 0.0);
    Vec3* out = velocities.data() + k * vertices;
    for (size_t v = 0; v < vertices; ++v) out[v] = (plus[v] - minus[v]) / span;
  }
  return true;
}

}  // namespace xgauge
