#include "xgauge/xray/renderer.h"

#include "footprint.h"

#include "xgauge/core/error.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <algorithm>
#include <limits>

namespace xgauge {

using raster::Band;
using raster::Footprint;
using raster::layoutFootprint;
using raster::RefinedRuns;
using raster::resolveRegion;
using raster::SampleDistances;
using raster::sampleDistances;
using raster::SceneSetup;
using raster::setupMesh;
using raster::TriangleSetup;

namespace {

// Adds sigma / m over one triangle's spans inside a band to `sum` (row-major,
// band rows x footprint width). `within(line, k0, k1, add)` calls add(lo, hi)
// for the parts [lo, hi] of each span to sample: the whole span for a plain
// render, the refined pixels' samples for the edge refinement.
template <typename Within>
void accumulateTriangle(const TriangleSetup& t, const Band& band, const Footprint& f,
                        double* sum, Within within) {
  const double sigma = t.sigma;
  const size_t width = static_cast<size_t>(f.width());
  raster::forEachSpan(t, band.row_begin, band.row_end, [&](int line, int k0, int k1) {
    if (t.by_rows) {
      const double across = t.gy * ((line + 0.5) - t.y[0]);
      double* row = sum + static_cast<size_t>(line - band.row_begin) * width;
      within(line, k0, k1, [&](int lo, int hi) {
        for (int k = lo; k <= hi; ++k)
          row[k - f.col_begin] += sigma / t.magnification(t.gx * ((k + 0.5) - t.x[0]), across);
      });
    } else {
      const double across = t.gx * ((line + 0.5) - t.x[0]);
      double* column = sum + (line - f.col_begin);
      within(line, k0, k1, [&](int lo, int hi) {
        for (int k = lo; k <= hi; ++k)
          column[static_cast<size_t>(k - band.row_begin) * width] +=
              sigma / t.magnification(across, t.gy * ((k + 0.5) - t.y[0]));
      });
    }
  });
}

// Each sample's path / |P - S| over one band into `sum` (resized, zeroed).
void bandSums(const SceneSetup& scene, const WorldMesh& mesh, const Band& band, const Footprint& f,
              size_t b, std::vector<double>& sum, raster::CsgScratch& csg_scratch) {
  sum.assign(static_cast<size_t>(band.row_end - band.row_begin) * static_cast<size_t>(f.width()),
             0.0);
  if (mesh.csg) {
    raster::accumulateCsgBand(scene, f.bins[b], *mesh.csg, band.row_begin, band.row_end,
                              f.col_begin, f.width(), sum.data(), csg_scratch);
    return;
  }
  const auto whole = [](int, int k0, int k1, auto&& add) { add(k0, k1); };
  for (uint32_t i : f.bins[b]) accumulateTriangle(scene.triangles[i], band, f, sum.data(), whole);
}


// The path length itself, as a shade.
auto identity = [](double path) { return path; };

// Mean of shade(path) over the n x n samples of pixel (u, v), from a band's
// per-sample sums (footprint layout `f`, n = f.n).
template <typename Shade>
double pixelMean(const std::vector<double>& sum, const Band& band, const Footprint& f,
                 const SampleDistances& distances, int u, int v, Shade& shade) {
  const int n = f.n;
  const size_t width = static_cast<size_t>(f.width());
  double value = 0.0;
  for (int j = 0; j < n; ++j) {
    const int sample_row = v * n + j;
    const double py2d2 = distances.py2d2(sample_row);
    const double* s = sum.data() + static_cast<size_t>(sample_row - band.row_begin) * width;
    for (int i = 0; i < n; ++i) {
      const size_t k = static_cast<size_t>(u * n + i - f.col_begin);
      const double path =
          s[k] == 0.0 ? 0.0 : std::max(0.0, s[k] * std::sqrt(distances.px2[k] + py2d2));
      value += shade(path);
    }
  }
  return value * (1.0 / (n * n));
}

// (`out` is resized to the region; `background` where the part's footprint is not.)
template <typename T, typename Shade>
void renderPixelsIsolated(const Machine& machine, const WorldMesh& mesh, const RenderOptions& options,
                          double background, Shade shade, ImageT<T>& out,
                          PixelRect* footprint = nullptr, ImageT<double>* mean_path = nullptr);

// Grown by `by` pixels on every side.
PixelRect grown(const PixelRect& r, int by) {
  return {r.x - by, r.y - by, r.width + 2 * by, r.height + 2 * by};
}

// The pixels of `region` to refine: those where the mean path `image`
// (covering `wide`, which holds `region` and 2 pixels around it where the
// detector has them) bends by more than `threshold` mm along a row or a
// column, and their four neighbours. The path is piecewise linear across the
// detector except at the projections of edges and silhouettes, so its bends
// are where point samples step; the intensity, a curved function of the
// path, also bends inside every steep ramp, where 2 x 2 samples are close.
// Outside the part's footprint (and 1 pixel around it) the path is 0:
// nothing bends there.
template <typename T>
RefinedRuns bentPixels(const ImageT<T>& image, const PixelRect& wide, const PixelRect& region,
                       const PixelRect& footprint, double threshold) {
  const int w = wide.width, h = wide.height;
  std::vector<uint8_t> bent(static_cast<size_t>(w) * static_cast<size_t>(h), 0);
  const PixelRect scan = grown(footprint, 1).intersect(wide);
  tbb::parallel_for(scan.y - wide.y, scan.bottom() - wide.y, [&](int y) {
    for (int x = scan.x - wide.x; x < scan.right() - wide.x; ++x) {
      const double c = 2.0 * static_cast<double>(image(x, y));
      bool b = x > 0 && x + 1 < w &&
               std::abs(static_cast<double>(image(x - 1, y)) - c +
                        static_cast<double>(image(x + 1, y))) > threshold;
      b = b || (y > 0 && y + 1 < h &&
                std::abs(static_cast<double>(image(x, y - 1)) - c +
                         static_cast<double>(image(x, y + 1))) > threshold);
      bent[static_cast<size_t>(y) * static_cast<size_t>(w) + static_cast<size_t>(x)] = b;
    }
  });
  const auto at = [&](int u, int v) {  // detector coordinates, inside `wide`
    const int x = u - wide.x, y = v - wide.y;
    if (x < 0 || y < 0 || x >= w || y >= h) return false;
    return bent[static_cast<size_t>(y) * static_cast<size_t>(w) + static_cast<size_t>(x)] != 0;
  };
  const auto refined = [&](int u, int v) {
    return at(u, v) || at(u - 1, v) || at(u + 1, v) || at(u, v - 1) || at(u, v + 1);
  };
  RefinedRuns runs{region, {}, {}};
  runs.rows.resize(static_cast<size_t>(region.height));
  runs.columns.resize(static_cast<size_t>(region.width));
  // Only `near` (the footprint and 2 pixels around it) holds refined pixels.
  const PixelRect near = grown(footprint, 2).intersect(region);
  if (near.empty()) return runs;
  const int nw = near.width, nh = near.height;
  std::vector<uint8_t> refine(static_cast<size_t>(nw) * static_cast<size_t>(nh), 0);
  tbb::parallel_for(0, nh, [&](int y) {
    for (int x = 0; x < nw; ++x)
      refine[static_cast<size_t>(y) * static_cast<size_t>(nw) + static_cast<size_t>(x)] =
          refined(near.x + x, near.y + y);
  });
  // Extends `out` by `pixel` (a column of a row, or a row of a column).
  const auto extend = [](std::vector<std::pair<int, int>>& out, int pixel) {
    if (!out.empty() && out.back().second == pixel - 1)
      out.back().second = pixel;
    else
      out.emplace_back(pixel, pixel);
  };
  tbb::parallel_for(0, nh, [&](int y) {
    const uint8_t* row = refine.data() + static_cast<size_t>(y) * static_cast<size_t>(nw);
    auto& out = runs.rows[static_cast<size_t>(near.y - region.y + y)];
    for (int x = 0; x < nw; ++x)
      if (row[x]) extend(out, near.x + x);
  });
  // The columns' runs a block of columns at a time, reading the rows in
  // order (a walk down each column touched a cache line per pixel: a sixth
  // of a refined 2048^2 render).
  constexpr int kColumnBlock = 64;
  tbb::parallel_for(
      tbb::blocked_range<int>(0, nw, kColumnBlock), [&](const tbb::blocked_range<int>& columns) {
        for (int y = 0; y < nh; ++y) {
          const uint8_t* row = refine.data() + static_cast<size_t>(y) * static_cast<size_t>(nw);
          for (int x = columns.begin(); x < columns.end(); ++x)
            if (row[x])
              extend(runs.columns[static_cast<size_t>(near.x - region.x + x)], near.y + y);
        }
      });
  return runs;
}

// The refined pixels of `runs` sampled with m x m samples into `image`
// (covering `wide`). The same walk as the plain render (bands, triangles in
// mesh order per sample), restricted to the refined pixels' samples.
template <typename T, typename Shade>
void refinePixels(const Machine& machine, const WorldMesh& mesh, int m, const RefinedRuns& runs,
                  const PixelRect& wide, Shade shade, ImageT<T>& image) {
  thread_local SceneSetup scratch;
  SceneSetup& scene = scratch;
  setupMesh(machine, mesh, m, runs.region, scene);
  if (scene.empty()) return;
  const Footprint f = layoutFootprint(scene, m);
  const SampleDistances distances = sampleDistances(machine, f);
  const size_t width = static_cast<size_t>(f.width());
  const auto clip = [m](const std::pair<int, int>& r, int k0, int k1, int& lo, int& hi) {
    return raster::clipRun(r, m, k0, k1, lo, hi);
  };
  tbb::parallel_for(size_t{0}, f.bands.size(), [&](size_t b) {
    const Band& band = f.bands[b];
    // Kept from render to render: only the refined samples are zeroed and
    // read, so a buffer of the band's size need not be cleared (at m x m
    // that would cost more than the refinement).
    thread_local std::vector<double> sum;
    sum.resize(std::max(sum.size(), static_cast<size_t>(band.row_end - band.row_begin) * width));
    int lo = 0, hi = 0;
    for (int r = band.row_begin; r < band.row_end; ++r)
      for (const auto& run : runs.row(r / m))
        if (clip(run, f.col_begin, f.col_end - 1, lo, hi))
          std::fill(sum.begin() + static_cast<ptrdiff_t>(static_cast<size_t>(r - band.row_begin) * width +
                                                         static_cast<size_t>(lo - f.col_begin)),
                    sum.begin() + static_cast<ptrdiff_t>(static_cast<size_t>(r - band.row_begin) * width +
                                                         static_cast<size_t>(hi + 1 - f.col_begin)),
                    0.0);
    for (uint32_t i : f.bins[b]) {
      const TriangleSetup& t = scene.triangles[i];
      // A row scan's line is a sample row, a column scan's a sample column.
      const auto refined = [&](int line, int k0, int k1, auto&& add) {
        for (const auto& run : t.by_rows ? runs.row(line / m) : runs.column(line / m))
          if (clip(run, k0, k1, lo, hi)) add(lo, hi);
      };
      accumulateTriangle(t, band, f, sum.data(), refined);
    }
    for (int v = band.row_begin / m; v < band.row_end / m; ++v)
      for (const auto& run : runs.row(v))
        for (int u = std::max(run.first, f.col_begin / m); u <= std::min(run.second, f.col_end / m - 1);
             ++u)
          image(u - wide.x, v - wide.y) =
              static_cast<T>(pixelMean(sum, band, f, distances, u, v, shade));
  });
}

// The region the bend test reads for `region`: 2 pixels more on every side
// where the detector has them.
PixelRect bendTestRegion(const Machine& machine, const PixelRect& region) {
  return grown(region, 2).intersect(machine.detectorRect());
}

// Renders value(path_mm) averaged over each pixel's samples into `out`.
// Isolated: while this thread waits inside its parallel loops it must not pick
// up an unrelated render (say, another measurement of a study) that would
// reuse its thread_local scene.
template <typename T, typename Shade>
void renderPixels(const Machine& machine, const WorldMesh& mesh, const RenderOptions& options,
                  double background, Shade shade, ImageT<T>& out) {
  const int m = options.edge_samples_per_axis;
  if (m == 0 || mesh.csg) {
    tbb::this_task_arena::isolate(
        [&] { renderPixelsIsolated(machine, mesh, options, background, shade, out); });
    return;
  }
  // n x n over the region and 2 pixels around it (so that a region's bend
  // test sees what a full render's does), then m x m where it bends.
  const PixelRect region = resolveRegion(machine, options);
  const PixelRect wide = bendTestRegion(machine, region);
  RenderOptions plain = options;
  plain.region = wide;
  // Kept from render to render (an optimiser renders thousands of times):
  // every pixel is written again.
  thread_local ImageT<T> image;
  thread_local ImageT<double> path;
  tbb::this_task_arena::isolate([&] {
    PixelRect footprint;
    renderPixelsIsolated(machine, mesh, plain, background, shade, image, &footprint, &path);
    if (footprint.empty()) return;
    const RefinedRuns runs = bentPixels(path, wide, region, footprint, options.edge_threshold);
    refinePixels(machine, mesh, m, runs, wide, shade, image);
  });
  if (out.width() != region.width || out.height() != region.height)
    out.resize(region.width, region.height);
  for (int y = 0; y < region.height; ++y)
    std::copy_n(image.row(y + region.y - wide.y) + (region.x - wide.x), region.width, out.row(y));
}

template <typename T, typename Shade>
void renderPixelsIsolated(const Machine& machine, const WorldMesh& mesh, const RenderOptions& options,
                          double background, Shade shade, ImageT<T>& out, PixelRect* footprint,
                          ImageT<double>* mean_path) {
  const PixelRect region = resolveRegion(machine, options);
  const int n = options.samples_per_axis;
  // Per calling thread, reused: an optimiser renders thousands of times. The
  // reference matters: worker threads must see this thread's scene, not
  // their own thread_local instance.
  thread_local SceneSetup scratch;
  SceneSetup& scene = scratch;
  setupMesh(machine, mesh, n, region, scene);
  // Every pixel is written below (the background or the path's value): the
  // images are only resized, not cleared (at 2048^2 the clearing cost a
  // twentieth of a refined render).
  if (out.width() != region.width || out.height() != region.height)
    out.resize(region.width, region.height);
  if (mean_path && (mean_path->width() != region.width || mean_path->height() != region.height))
    mean_path->resize(region.width, region.height, 0.0);

  const PixelRect footprint_px = raster::footprintPixels(scene, n);
  if (footprint) *footprint = footprint_px;
  // Background outside the footprint (and no path).
  const auto fillOutside = [&](auto& image, auto value) {
    tbb::parallel_for(0, region.height, [&](int y) {
      auto* row = image.row(y);
      const int v = region.y + y;
      if (v < footprint_px.y || v >= footprint_px.bottom()) {
        std::fill_n(row, region.width, value);
      } else {
        std::fill_n(row, footprint_px.x - region.x, value);
        std::fill(row + (footprint_px.right() - region.x), row + region.width, value);
      }
    });
  };
  fillOutside(out, static_cast<T>(background));
  if (mean_path) fillOutside(*mean_path, 0.0);
  if (scene.empty()) return;

  const Footprint f = layoutFootprint(scene, n);
  const SampleDistances distances = sampleDistances(machine, f);
  tbb::enumerable_thread_specific<std::vector<double>> buffers;
  tbb::enumerable_thread_specific<raster::CsgScratch> csg_buffers;
  tbb::parallel_for(size_t{0}, f.bands.size(), [&](size_t b) {
    const Band& band = f.bands[b];
    std::vector<double>& sum = buffers.local();
    bandSums(scene, mesh, band, f, b, sum, csg_buffers.local());
    // Resolve: path per sample, shade, average over the pixel's samples.
    for (int v = band.row_begin / n; v < band.row_end / n; ++v) {
      T* out_row = out.row(v - region.y);
      for (int u = f.col_begin / n; u < f.col_end / n; ++u) {
        out_row[u - region.x] = static_cast<T>(pixelMean(sum, band, f, distances, u, v, shade));
        if (mean_path)
          (*mean_path)(u - region.x, v - region.y) =
              pixelMean(sum, band, f, distances, u, v, identity);
      }
    }
  });
}

}  // namespace

RefinedRuns raster::edgeRuns(const Machine& machine, const WorldMesh& mesh,
                             const RenderOptions& options) {
  const PixelRect region = resolveRegion(machine, options);
  XG_CHECK(options.edge_samples_per_axis > options.samples_per_axis && !mesh.csg,
           "edge runs without an edge refinement");
  RenderOptions plain = options;
  plain.edge_samples_per_axis = 0;
  plain.region = bendTestRegion(machine, region);
  thread_local ImageT<double> path;
  PixelRect footprint;
  renderPixelsIsolated(machine, mesh, plain, 0.0, identity, path, &footprint);
  if (footprint.empty()) {  // nothing in the region: nothing to refine
    RefinedRuns none{region, {}, {}};
    none.rows.resize(static_cast<size_t>(region.height));
    none.columns.resize(static_cast<size_t>(region.width));
    return none;
  }
  return bentPixels(path, plain.region, region, footprint, options.edge_threshold);
}

RenderDiagnostics renderDiagnosticsIsolated(const Machine& machine, const WorldMesh& mesh,
                                            const RenderOptions& options);

std::optional<std::string> outsideBeam(const Machine& machine,
                                       std::span<const Vec3> world_vertices_mm) {
  const double d = machine.source_detector_distance_mm;
  for (size_t i = 0; i < world_vertices_mm.size(); ++i) {
    const double z = world_vertices_mm[i].z();
    if (!(z >= 0.0 && z < d) || !world_vertices_mm[i].allFinite())
      return fmt::format(
          "part vertex {} at z = {:.6g} mm is not between the detector plane (z = 0) and the "
          "source (z = {} mm)",
          i, z, d);
  }
  return std::nullopt;
}

std::optional<std::string> shadowMissesDetector(const Machine& machine,
                                                std::span<const Vec3> world_vertices_mm) {
  if (world_vertices_mm.empty()) return "the part has no vertices";
  double u0 = std::numeric_limits<double>::infinity(), v0 = u0, u1 = -u0, v1 = -u0;
  for (const Vec3& p : world_vertices_mm) {
    const Vec2 q = machine.project(p);
    u0 = std::min(u0, q.x()), u1 = std::max(u1, q.x());
    v0 = std::min(v0, q.y()), v1 = std::max(v1, q.y());
  }
  if (u1 > 0.0 && u0 < machine.columns && v1 > 0.0 && v0 < machine.rows) return std::nullopt;
  return fmt::format(
      "the part's shadow (columns {:.0f} to {:.0f}, rows {:.0f} to {:.0f}) misses the {}x{} "
      "detector",
      u0, u1, v0, v1, machine.columns, machine.rows);
}

void poseVertices(const Pose& pose, std::span<const Vec3> part_vertices,
                  std::vector<Vec3>& world_vertices) {
  world_vertices.resize(part_vertices.size());
  for (size_t i = 0; i < part_vertices.size(); ++i)
    world_vertices[i] = pose.apply(part_vertices[i]);
}

void renderPathLength(const Machine& machine, const WorldMesh& mesh,
                      const RenderOptions& options, ImageT<double>& out) {
  renderPixels(machine, mesh, options, 0.0, [](double path) { return path; }, out);
}

void renderPathLength(const Machine& machine, const WorldMesh& mesh,
                      const RenderOptions& options, Image& out) {
  renderPixels(machine, mesh, options, 0.0, [](double path) { return path; }, out);
}

void renderIntensity(const Machine& machine, const WorldMesh& mesh,
                     const TransmissionTable& transmission, const RenderOptions& options,
                     Image& out) {
  renderPixels(machine, mesh, options, 1.0,
               [&](double path) { return path == 0.0 ? 1.0 : transmission(path); }, out);
}

void renderIntensity(const Machine& machine, const WorldMesh& mesh,
                     const TransmissionTable& transmission, const RenderOptions& options,
                     ImageT<double>& out) {
  renderPixels(machine, mesh, options, 1.0,
               [&](double path) { return path == 0.0 ? 1.0 : transmission(path); }, out);
}

RenderDiagnostics renderDiagnostics(const Machine& machine, const WorldMesh& mesh,
                                    const RenderOptions& options) {
  RenderDiagnostics d;
  tbb::this_task_arena::isolate([&] { d = renderDiagnosticsIsolated(machine, mesh, options); });
  return d;
}

RenderDiagnostics renderDiagnosticsIsolated(const Machine& machine, const WorldMesh& mesh,
                                            const RenderOptions& options) {
  const PixelRect region = resolveRegion(machine, options);
  const int n = options.samples_per_axis;
  // Per calling thread, reused: an optimiser renders thousands of times. The
  // reference matters: worker threads must see this thread's scene, not
  // their own thread_local instance.
  thread_local SceneSetup scratch;
  SceneSetup& scene = scratch;
  setupMesh(machine, mesh, n, region, scene);
  RenderDiagnostics d;
  d.entries.resize(region.width, region.height, 0);
  d.exits.resize(region.width, region.height, 0);
  d.unbalanced.resize(region.width, region.height, 0);
  d.min_path_mm.resize(region.width, region.height, 0.0);
  d.max_path_mm.resize(region.width, region.height, 0.0);
  if (scene.empty()) return d;

  // Sample by sample, single pass per band: sums plus entry and exit counts.
  const Footprint f = layoutFootprint(scene, n);
  const SampleDistances distances = sampleDistances(machine, f);
  const size_t width = static_cast<size_t>(f.width());
  tbb::parallel_for(size_t{0}, f.bands.size(), [&](size_t b) {
    const Band& band = f.bands[b];
    const size_t count = static_cast<size_t>(band.row_end - band.row_begin) * width;
    std::vector<double> sum;
    raster::CsgScratch csg_scratch;
    bandSums(scene, mesh, band, f, b, sum, csg_scratch);
    std::vector<int32_t> entries(count, 0), exits(count, 0);
    for (uint32_t i : f.bins[b]) {
      const TriangleSetup& t = scene.triangles[i];
      auto& counter = t.sigma > 0 ? exits : entries;
      raster::forEachSpan(t, band.row_begin, band.row_end, [&](int line, int k0, int k1) {
        for (int k = k0; k <= k1; ++k) {
          const int row = t.by_rows ? line : k, col = t.by_rows ? k : line;
          ++counter[static_cast<size_t>(row - band.row_begin) * width +
                    static_cast<size_t>(col - f.col_begin)];
        }
      });
    }
    for (int v = band.row_begin / n; v < band.row_end / n; ++v) {
      for (int u = f.col_begin / n; u < f.col_end / n; ++u) {
        const int x = u - region.x, y = v - region.y;
        double lo = HUGE_VAL, hi = -HUGE_VAL;
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < n; ++i) {
            const size_t k = static_cast<size_t>(u * n + i - f.col_begin);
            const size_t s = static_cast<size_t>(v * n + j - band.row_begin) * width + k;
            const double path = sum[s] * std::sqrt(distances.px2[k] + distances.py2d2(v * n + j));
            lo = std::min(lo, path);
            hi = std::max(hi, path);
            d.entries(x, y) += entries[s];
            d.exits(x, y) += exits[s];
            d.unbalanced(x, y) += entries[s] != exits[s] ? 1 : 0;
          }
        d.min_path_mm(x, y) = lo;
        d.max_path_mm(x, y) = hi;
      }
    }
  });
  return d;
}

}  // namespace xgauge
