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
// exit and -1 for an entry (Vidal et al. 2009; METHOD.md component 4).
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

// One triangle, ready to scan.
struct TriangleSetup {
  double x[3], y[3];  // vertices in sample space
  // Magnification m(q) = m0 + gx (qx - x[0]) + gy (qy - y[0]), clamped to [m_lo, m_hi].
  double m0, gx, gy, m_lo, m_hi;
  int sigma;               // +1: the ray leaves the part here; -1: enters
  int kx0, kx1, ky0, ky1;  // candidate samples (inclusive), clipped to the region
  bool by_rows;            // scan rows (else columns)

  // m from its two terms gx (qx - x[0]) and gy (qy - y[0]). Their sum is
  // commutative, so a sample gets the same bits whether its triangle is
  // scanned by rows or by columns (which can differ between a full render and
  // a region render).
  double magnification(double x_term, double y_term) const {
    return std::clamp(m0 + (x_term + y_term), m_lo, m_hi);
  }
};

struct SceneSetup {
  std::vector<TriangleSetup> triangles;  // those that may cover a sample, mesh order
  int kx0 = 0, kx1 = -1, ky0 = 0, ky1 = -1;  // union of their boxes (inclusive)
  bool empty() const { return triangles.empty(); }
};

// Projects the mesh (world coordinates, mm) and prepares its triangles for the
// sample grid of `samples` x `samples` per pixel, restricted to `region`
// (pixels). Throws Error if a vertex is not strictly between the detector
// plane and the source plane (0 <= z < D).
SceneSetup setupScene(const Machine& machine, std::span<const Vec3> world_vertices,
                      std::span<const std::array<uint32_t, 3>> triangles, int samples,
                      const PixelRect& region);

// Calls emit(line, k_lo, k_hi) for every non-empty scan line of `t` whose
// samples lie in sample rows [row_begin, row_end). For a row scan, line is the
// sample row and [k_lo, k_hi] the sample columns; for a column scan, line is
// the sample column and [k_lo, k_hi] the sample rows.
template <typename Emit>
void forEachSpan(const TriangleSetup& t, int row_begin, int row_end, Emit&& emit) {
  const bool rows = t.by_rows;
  // Lines run along the scan axis; k counts samples along each line.
  const int line0 = rows ? std::max(t.ky0, row_begin) : t.kx0;
  const int line1 = rows ? std::min(t.ky1, row_end - 1) : t.kx1;
  const int k_min = rows ? t.kx0 : std::max(t.ky0, row_begin);
  const int k_max = rows ? t.kx1 : std::min(t.ky1, row_end - 1);
  if (line0 > line1 || k_min > k_max) return;

  auto inside = [&](double px, double py) {
    for (int e = 0; e < 3; ++e) {
      const int f = e == 2 ? 0 : e + 1;
      if (orientSign(t.x[e], t.y[e], t.x[f], t.y[f], px, py) != t.sigma) return false;
    }
    return true;
  };

  for (int line = line0; line <= line1; ++line) {
    const double q = line + 0.5;  // the line's fixed coordinate
    // Conservative floating-point span [lo, hi] along the line.
    double lo = -HUGE_VAL, hi = HUGE_VAL;
    bool empty = false;
    for (int e = 0; e < 3 && !empty; ++e) {
      const int f = e == 2 ? 0 : e + 1;
      // (a, b): edge coordinates along the line, (a_q, b_q): across it.
      const double a = rows ? t.x[e] : t.y[e], b = rows ? t.x[f] : t.y[f];
      const double a_q = rows ? t.y[e] : t.x[e], b_q = rows ? t.y[f] : t.x[f];
      if (a_q == b_q) {
        // Edge parallel to the line: the same side for every sample on it.
        const double px = rows ? 0.0 : q, py = rows ? q : 0.0;
        if (orientSign(t.x[e], t.y[e], t.x[f], t.y[f], px, py) != t.sigma) empty = true;
        continue;
      }
      const double offset = (q - a_q) * (b - a) / (b_q - a_q);
      const double crossing = a + offset;
      const double tol = 1e-12 * (std::abs(a) + std::abs(offset)) + 1e-9;
      // d det / d(along): rows: ay - by; columns: bx - ax.
      const double slope = rows ? (t.y[e] - t.y[f]) : (t.x[f] - t.x[e]);
      if ((slope > 0) == (t.sigma > 0)) lo = std::max(lo, crossing - tol);
      else hi = std::min(hi, crossing + tol);
    }
    if (empty || !(lo <= hi)) continue;
    const double k_lo_f = std::ceil(lo - 0.5), k_hi_f = std::floor(hi - 0.5);
    int k_lo = k_lo_f > k_max ? k_max + 1 : std::max(k_min, static_cast<int>(std::max(k_lo_f, -1e9)));
    int k_hi = k_hi_f < k_min ? k_min - 1 : std::min(k_max, static_cast<int>(std::min(k_hi_f, 1e9)));
    if (k_lo > k_hi) continue;
    // Exact refinement: the true span is an interval within [k_lo, k_hi].
    auto sample_inside = [&](int k) {
      return rows ? inside(k + 0.5, q) : inside(q, k + 0.5);
    };
    while (k_lo <= k_hi && !sample_inside(k_lo)) ++k_lo;
    while (k_hi >= k_lo && !sample_inside(k_hi)) --k_hi;
    if (k_lo <= k_hi) emit(line, k_lo, k_hi);
  }
}

}  // namespace xgauge::raster
