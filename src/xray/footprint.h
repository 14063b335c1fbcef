// How a render walks the detector (private to the xray module): the part's
// footprint in sample space cut into bands of whole pixel rows, the
// triangles binned by band, and each sample's distance from the source.
// Shared by the image renders (renderer.cpp) and the render with
// derivatives (derivatives.cpp), so both visit the same samples in the same
// order.
#pragma once

#include "csg_paths.h"
#include "rasterizer.h"

#include "xgauge/xray/renderer.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

namespace xgauge::raster {

// The region a render covers: the whole detector for an empty one; throws
// Error for bad sampling or a region off the detector.
PixelRect resolveRegion(const Machine& machine, const RenderOptions& options);

// A band of whole pixel rows, in sample rows [row_begin, row_end).
struct Band {
  int row_begin;
  int row_end;
};

// Sample-space layout of the part's footprint, aligned to whole pixels.
struct Footprint {
  int n;
  int col_begin, col_end;  // sample columns [col_begin, col_end)
  std::vector<Band> bands;
  std::vector<std::vector<uint32_t>> bins;  // triangles per band, mesh order
  int width() const { return col_end - col_begin; }
};

// Bands sized so that every thread has work and a band's buffer of
// `doubles_per_sample` doubles per sample stays within about 1 MiB.
Footprint layoutFootprint(const SceneSetup& scene, int n, int doubles_per_sample = 1);

// The footprint in whole pixels of the level (empty for an empty scene).
PixelRect footprintPixels(const SceneSetup& scene, int n);

// Distance from the source to each sample's detector point: sqrt(px2[col] + py2d2[row]).
struct SampleDistances {
  std::vector<double> px2;  // indexed by sample column - col_begin
  double d2;
  const Machine* machine;
  int n;
  // A tilted panel's cross terms 2 S.(R e_u), 2 S.(R e_v); 0 untilted.
  double cross_u = 0.0, cross_v = 0.0;
  double py2d2(int sample_row) const {
    const double py = (machine->cy_px - (sample_row + 0.5) / n) * machine->pitch_v_mm;
    return py * py - cross_v * py + d2;
  }
};
SampleDistances sampleDistances(const Machine& machine, const Footprint& f);

// Runs [first, last] of pixels (detector coordinates) along each pixel row
// and each pixel column of a region: the pixels the edge refinement samples
// again with m x m samples (RenderOptions::edge_samples_per_axis).
struct RefinedRuns {
  PixelRect region;
  std::vector<std::vector<std::pair<int, int>>> rows, columns;
  const std::vector<std::pair<int, int>>& row(int v) const {
    return rows[static_cast<size_t>(v - region.y)];
  }
  const std::vector<std::pair<int, int>>& column(int u) const {
    return columns[static_cast<size_t>(u - region.x)];
  }
};

// Sample columns (or rows) [lo, hi] of pixel run `run` at m x m samples
// per pixel, within [k0, k1]; false when none.
inline bool clipRun(const std::pair<int, int>& run, int m, int k0, int k1, int& lo, int& hi) {
  lo = std::max(k0, run.first * m), hi = std::min(k1, run.second * m + m - 1);
  return lo <= hi;
}

// The pixels of options.region that renderIntensity refines with
// options.edge_samples_per_axis (> samples_per_axis; not for CSG parts):
// the same n x n render of the mean path and the same bend test, so that
// the render with derivatives refines exactly those pixels. Call inside an
// isolated task arena (renderer.cpp).
RefinedRuns edgeRuns(const Machine& machine, const WorldMesh& mesh, const RenderOptions& options);

// Projects the mesh into `scene` and, for a CSG part, marks the pieces.
void setupMesh(const Machine& machine, const WorldMesh& mesh, int n, const PixelRect& region,
               SceneSetup& scene);

}  // namespace xgauge::raster
