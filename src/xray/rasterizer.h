// The projective rasterizer behind render*(): private to the xray module.
//
// Method. Project every vertex through the source onto the detector and work
// in "sample space": continuous pixel coordinates times n for n x n samples
// per pixel, so sample (kx, ky) sits at (kx + 0.5, ky + 0.5). A sample is
// inside a projected triangle when the exact, tie-broken orientation test
// (orient2d.h) puts it on the inner side of all three edges. Shared edges are
// evaluated identically by both triangles, so for a closed mesh every sample
// is covered by as many entering (front) as exiting (back) triangles: the
// rasterizer is exactly watertight, with no snapping of vertices.
//
// Depth. Along the ray from the source S to a detector point P, a point is
// S + lambda (P - S); at a vertex with height z, 1/lambda = D / (D - z) is its
// magnification m, and m is an affine function of the projected position over
// a planar triangle (perspective-correct interpolation). The path length
// through the part is |P - S| * sum_i sigma_i / m_i(P), sigma = +1 for an
// exit and -1 for an entry (Vidal et al. 2009; docs/method.md, "Renderer").
//
// Work. Each triangle is scanned along its bounding box's shorter axis (rows
// or columns), so thin slivers cost little; each scan line's span comes from
// floating-point edge crossings refined by the exact test. The detector is
// cut into bands of sample rows processed in parallel; every sample sums its
// triangles in mesh order, so results do not depend on the thread count.
#pragma once

#include "orient2d.h"

#include "xgauge/core/transform.h"
#include "xgauge/image/image.h"
#include "xgauge/xray/machine.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

namespace xgauge::raster {

// One edge seen from the scan lines of its triangle. On the line with fixed
// coordinate q it bounds the inside from below at
// lower + slope (q - across) or from above at upper + slope (q - across)
// (the other bound is -inf or +inf, so spans need no branches). Both bounds
// include a tolerance a thousand times the rounding error. An edge parallel
// to the lines bounds the range of lines instead (parallel == true).
struct EdgeCrossing {
  double lower;
  double upper;
  double slope;
  double across;
  bool parallel;
};

// One triangle, ready to scan.
struct TriangleSetup {
  double x[3], y[3];  // vertices in sample space
  // Magnification m(q) = m0 + gx (qx - x[0]) + gy (qy - y[0]), clamped to [m_lo, m_hi].
  double m0, gx, gy, m_lo, m_hi;
  int sigma;               // +1: the ray leaves the part here; -1: enters
  uint8_t piece = 0;       // the CSG piece the triangle belongs to (see csg_paths.h)
  int kx0, kx1, ky0, ky1;  // candidate samples (inclusive), clipped to the region
  bool by_rows;            // scan rows (else columns)
  EdgeCrossing edges[3];   // edge i runs from vertex i to vertex i + 1

  // m from its two terms gx (qx - x[0]) and gy (qy - y[0]). Their sum is
  // commutative, so a sample gets the same bits whether its triangle is
  // scanned by rows or by columns (which can differ between a full render and
  // a region render).
  double magnification(double x_term, double y_term) const {
    return std::clamp(m0 + (x_term + y_term), m_lo, m_hi);
  }
};

struct SceneSetup {
  std::vector<TriangleSetup> triangles;  // one per mesh triangle
  std::vector<uint32_t> visible;         // those that may cover a sample, mesh order
  int kx0 = 0, kx1 = -1, ky0 = 0, ky1 = -1;  // union of their boxes (inclusive)
  bool empty() const { return visible.empty(); }
};

// Projects the mesh (world coordinates, mm) and prepares its triangles for the
// sample grid of `samples` x `samples` per pixel, restricted to `region`
// (pixels), into `scene` (whose memory is reused from call to call). Throws
// Error if a vertex is not between the detector plane and the source plane
// (0 <= z < D).
void setupScene(const Machine& machine, std::span<const Vec3> world_vertices,
                std::span<const std::array<uint32_t, 3>> triangles, int samples,
                const PixelRect& region, SceneSetup& scene);

// Columns [first, last] that can hold samples of `t` in sample rows
// [row_begin, row_end): the triangle clipped to that slab, conservatively.
inline void columnsInRows(const TriangleSetup& t, int row_begin, int row_end, int& first,
                          int& last) {
  const double y0 = row_begin + 0.5, y1 = row_end - 0.5;
  double lo = HUGE_VAL, hi = -HUGE_VAL;
  for (int e = 0; e < 3; ++e) {
    const int f = e == 2 ? 0 : e + 1;
    if (t.y[e] >= y0 && t.y[e] <= y1) lo = std::min(lo, t.x[e]), hi = std::max(hi, t.x[e]);
    for (double y : {y0, y1}) {
      if ((t.y[e] - y) * (t.y[f] - y) < 0) {  // the edge crosses this row
        const double x = t.x[e] + (y - t.y[e]) * (t.x[f] - t.x[e]) / (t.y[f] - t.y[e]);
        lo = std::min(lo, x), hi = std::max(hi, x);
      }
    }
  }
  // One sample of margin covers the rounding of the crossings.
  first = std::max(t.kx0, static_cast<int>(std::max(std::floor(lo - 0.5) - 1.0, -1e9)));
  last = std::min(t.kx1, static_cast<int>(std::min(std::ceil(hi - 0.5) + 1.0, 1e9)));
}

// Calls emit(line, k_lo, k_hi) for every non-empty scan line of `t` whose
// samples lie in sample rows [row_begin, row_end). For a row scan, line is the
// sample row and [k_lo, k_hi] the sample columns; for a column scan, line is
// the sample column and [k_lo, k_hi] the sample rows.
template <typename Emit>
void forEachSpan(const TriangleSetup& t, int row_begin, int row_end, Emit&& emit) {
  const bool rows = t.by_rows;
  // Lines run along the scan axis; k counts samples along each line.
  int line0 = std::max(t.ky0, row_begin), line1 = std::min(t.ky1, row_end - 1);
  const int k_min = rows ? t.kx0 : line0;
  const int k_max = rows ? t.kx1 : line1;
  if (!rows) columnsInRows(t, row_begin, row_end, line0, line1);

  // Exact test of one sample (px, py).
  auto sample_inside = [&](double px, double py) {
    for (int e = 0; e < 3; ++e) {
      const int f = e == 2 ? 0 : e + 1;
      if (orientSign(t.x[e], t.y[e], t.x[f], t.y[f], px, py) != t.sigma) return false;
    }
    return true;
  };
  // An edge parallel to the lines keeps the lines on one side of it (and the
  // line through it exactly if the tie-break says so).
  for (int e = 0; e < 3; ++e) {
    if (!t.edges[e].parallel) continue;
    const int f = e == 2 ? 0 : e + 1;
    const double at = t.edges[e].across;
    auto line_inside = [&](double q) {
      return orientSign(t.x[e], t.y[e], t.x[f], t.y[f], rows ? 0.0 : q, rows ? q : 0.0) == t.sigma;
    };
    const double first_f = std::ceil(at - 0.5);  // first line with q >= at
    if (first_f > 1e9 || first_f < -1e9) return;  // beyond any detector: no line qualifies
    const int first = static_cast<int>(first_f);
    const bool on_line = first + 0.5 == at;
    if (line_inside(at + 1.0)) line0 = std::max(line0, on_line && !line_inside(at) ? first + 1 : first);
    else line1 = std::min(line1, on_line && line_inside(at) ? first : first - 1);
  }
  if (line0 > line1 || k_min > k_max) return;

  // Candidate spans for a chunk of lines at a time (a loop without branches,
  // which the compiler vectorizes), then exact refinement of the few
  // non-empty ones.
  constexpr int kChunk = 64;
  double k_lo_f[kChunk], k_hi_f[kChunk];
  int candidates[kChunk];
  const EdgeCrossing& e0 = t.edges[0];
  const EdgeCrossing& e1 = t.edges[1];
  const EdgeCrossing& e2 = t.edges[2];
  const double k_min_f = k_min, k_max_f = k_max;
  for (int base = line0; base <= line1; base += kChunk) {
    const int count = std::min(kChunk, line1 - base + 1);
    for (int j = 0; j < count; ++j) {
      const double q = (base + j) + 0.5;
      const double d0 = e0.slope * (q - e0.across), d1 = e1.slope * (q - e1.across),
                   d2 = e2.slope * (q - e2.across);
      const double lo = std::max(std::max(e0.lower + d0, e1.lower + d1), e2.lower + d2);
      const double hi = std::min(std::min(e0.upper + d0, e1.upper + d1), e2.upper + d2);
      k_lo_f[j] = std::max(std::ceil(lo - 0.5), k_min_f);
      k_hi_f[j] = std::min(std::floor(hi - 0.5), k_max_f);
    }
    // Branch-free compaction: most lines of a sliver hold no sample.
    int found = 0;
    for (int j = 0; j < count; ++j) {
      candidates[found] = j;
      found += k_lo_f[j] <= k_hi_f[j];
    }
    for (int c = 0; c < found; ++c) {
      const int j = candidates[c];
      const int line = base + j;
      const double q = line + 0.5;
      int k_lo = static_cast<int>(k_lo_f[j]);
      int k_hi = static_cast<int>(k_hi_f[j]);
      // The true span is an interval within [k_lo, k_hi].
      auto inside = [&](int k) { return rows ? sample_inside(k + 0.5, q) : sample_inside(q, k + 0.5); };
      while (k_lo <= k_hi && !inside(k_lo)) ++k_lo;
      while (k_hi >= k_lo && !inside(k_hi)) --k_hi;
      if (k_lo <= k_hi) emit(line, k_lo, k_hi);
    }
  }
}

}  // namespace xgauge::raster

namespace xgauge::raster {

// Calls visit(sample_row, sample_column) for every sample of `t` in sample
// rows [row_begin, row_end), in scan order.
template <typename Visit>
void forEachSample(const TriangleSetup& t, int row_begin, int row_end, Visit&& visit) {
  forEachSpan(t, row_begin, row_end, [&](int line, int k0, int k1) {
    if (t.by_rows)
      for (int k = k0; k <= k1; ++k) visit(line, k);
    else
      for (int k = k0; k <= k1; ++k) visit(k, line);
  });
}

// 1 / m at sample (row, column): the depth of the triangle's plane along the
// sample's ray, as a fraction of the source-detector ray. Bit for bit what
// the renderer's sums use.
inline double inverseMagnification(const TriangleSetup& t, int row, int column) {
  return 1.0 / t.magnification(t.gx * ((column + 0.5) - t.x[0]), t.gy * ((row + 0.5) - t.y[0]));
}

}  // namespace xgauge::raster
