#include "footprint.h"

#include "xgauge/core/error.h"

#include <tbb/task_arena.h>
#include <algorithm>

namespace xgauge::raster {

PixelRect resolveRegion(const Machine& machine, const RenderOptions& options) {
  machine.validate();
  if (options.samples_per_axis < 1 || options.samples_per_axis > 16)
    fail("samples per pixel axis must be 1 to 16, got {}", options.samples_per_axis);
  const int n = options.samples_per_axis, m = options.edge_samples_per_axis;
  if (m != 0 && (m <= n || m > 32))
    fail("edge samples per pixel axis must be 0 or from {} to 32, got {}", n + 1, m);
  if (m != 0 && !(options.edge_threshold > 0.0))
    fail("the edge threshold must be positive, got {}", options.edge_threshold);
  if (options.region.empty()) return machine.detectorRect();
  if (!machine.detectorRect().contains(options.region))
    fail("render region {}x{}+{}+{} lies outside the {}x{} detector", options.region.width,
         options.region.height, options.region.x, options.region.y, machine.columns, machine.rows);
  return options.region;
}

Footprint layoutFootprint(const SceneSetup& scene, int n, int doubles_per_sample) {
  Footprint f;
  f.n = n;
  f.col_begin = scene.kx0 / n * n;
  f.col_end = (scene.kx1 / n + 1) * n;
  const int row_begin = scene.ky0 / n * n, row_end = (scene.ky1 / n + 1) * n;
  // Band height: enough bands to keep every thread busy, each buffer within
  // about 1 MiB so it stays in cache.
  const int pixel_rows = (row_end - row_begin) / n;
  const int threads = std::max(1, tbb::this_task_arena::max_concurrency());
  const long row_bytes = 8L * doubles_per_sample * f.width() * n;
  const int by_memory = std::max(1, static_cast<int>((1L << 20) / row_bytes));
  const int by_threads = std::max(1, (pixel_rows + 8 * threads - 1) / (8 * threads));
  const int band_rows = std::min(by_memory, by_threads) * n;
  for (int r = row_begin; r < row_end; r += band_rows)
    f.bands.push_back({r, std::min(row_end, r + band_rows)});
  // Bin the triangles by band, keeping mesh order within each bin.
  f.bins.resize(f.bands.size());
  const auto band_of = [&](int row) { return static_cast<size_t>((row - row_begin) / band_rows); };
  for (uint32_t i : scene.visible) {
    const TriangleSetup& t = scene.triangles[i];
    for (size_t b = band_of(t.ky0); b <= band_of(t.ky1); ++b) f.bins[b].push_back(i);
  }
  return f;
}

PixelRect footprintPixels(const SceneSetup& scene, int n) {
  if (scene.empty()) return {};
  return {scene.kx0 / n, scene.ky0 / n, scene.kx1 / n + 1 - scene.kx0 / n,
          scene.ky1 / n + 1 - scene.ky0 / n};
}

SampleDistances sampleDistances(const Machine& machine, const Footprint& f) {
  SampleDistances s{
      {}, machine.source_detector_distance_mm * machine.source_detector_distance_mm, &machine, f.n};
  s.px2.resize(static_cast<size_t>(f.width()));
  // A tilted panel: |P - S|^2 = |l|^2 - 2 S.(R l) + D^2 for the panel's own
  // coordinates l = (px, py, 0), still a column's term plus a row's.
  const Vec3 source = machine.sourceWorld();
  s.cross_u = machine.tilted() ? 2.0 * source.dot(machine.detector_rotation.col(0)) : 0.0;
  s.cross_v = machine.tilted() ? 2.0 * source.dot(machine.detector_rotation.col(1)) : 0.0;
  for (int k = 0; k < f.width(); ++k) {
    const double px = ((f.col_begin + k + 0.5) / f.n - machine.cx_px) * machine.pitch_u_mm;
    s.px2[static_cast<size_t>(k)] = px * px - s.cross_u * px;
  }
  return s;
}

void setupMesh(const Machine& machine, const WorldMesh& mesh, int n, const PixelRect& region,
               SceneSetup& scene) {
  setupScene(machine, mesh.vertices_mm, mesh.triangles, n, region, scene);
  if (mesh.csg) assignPieces(*mesh.csg, scene);
}

}  // namespace xgauge::raster
