#include "rasterizer.h"

#include <tbb/parallel_for.h>

namespace xgauge::raster {

namespace {

// Orientation of a triangle without tie-break: 0 for collinear vertices.
int triangleOrientation(const TriangleSetup& t) {
  constexpr double kEpsilon = 0x1p-53;
  constexpr double kBound = (3.0 + 16.0 * kEpsilon) * kEpsilon;
  const double left = (t.x[0] - t.x[2]) * (t.y[1] - t.y[2]);
  const double right = (t.y[0] - t.y[2]) * (t.x[1] - t.x[2]);
  const double det = left - right;
  if (std::abs(det) > kBound * (std::abs(left) + std::abs(right))) return det > 0 ? 1 : -1;
  return exactOrientSign(t.x[0], t.y[0], t.x[1], t.y[1], t.x[2], t.y[2]);
}

// First and last sample index whose centre k + 0.5 lies in [lo, hi], clipped
// to [k_min, k_max]; returns false when there is none.
bool sampleRange(double lo, double hi, int k_min, int k_max, int& k0, int& k1) {
  const double f0 = std::ceil(lo - 0.5), f1 = std::floor(hi - 0.5);
  if (f0 > k_max || f1 < k_min) return false;
  k0 = std::max(k_min, static_cast<int>(f0));
  k1 = std::min(k_max, static_cast<int>(f1));
  return k0 <= k1;
}

// Edge crossings along the triangle's scan lines (see forEachSpan).
void setupEdges(TriangleSetup& t) {
  const bool rows = t.by_rows;
  const double line_lo = (rows ? t.ky0 : t.kx0) + 0.5, line_hi = (rows ? t.ky1 : t.kx1) + 0.5;
  for (int e = 0; e < 3; ++e) {
    const int f = e == 2 ? 0 : e + 1;
    EdgeCrossing& c = t.edges[e];
    const double a = rows ? t.x[e] : t.y[e], b = rows ? t.x[f] : t.y[f];
    const double a_q = rows ? t.y[e] : t.x[e], b_q = rows ? t.y[f] : t.x[f];
    if (a_q == b_q) {
      c = {-HUGE_VAL, HUGE_VAL, 0.0, a_q, true};
      continue;
    }
    const double slope = (b - a) / (b_q - a_q);
    // Rounding of a + slope (q - a_q) is a few ulps of its terms.
    const double reach = std::max(std::abs(line_lo - a_q), std::abs(line_hi - a_q));
    const double tolerance = 1e-12 * (std::abs(a) + std::abs(slope) * reach) + 1e-9;
    // d det / d(along) is ay - by for rows and bx - ax for columns; the
    // inside is where the orientation equals sigma.
    const double growth = rows ? (t.y[e] - t.y[f]) : (t.x[f] - t.x[e]);
    if ((growth > 0) == (t.sigma > 0)) c = {a - tolerance, HUGE_VAL, slope, a_q, false};
    else c = {-HUGE_VAL, a + tolerance, slope, a_q, false};
  }
}

}  // namespace

void setupScene(const Machine& machine, std::span<const Vec3> world_vertices,
                std::span<const std::array<uint32_t, 3>> triangles, int samples,
                const PixelRect& region, SceneSetup& scene) {
  const double d = machine.source_detector_distance_mm;
  const double n = samples;

  // Project every vertex into sample space; keep its magnification.
  struct Projected {
    double x, y, m;
  };
  std::vector<Projected> projected(world_vertices.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, world_vertices.size(), 4096), [&](auto range) {
    for (size_t i = range.begin(); i != range.end(); ++i) {
      const Vec3& v = world_vertices[i];
      if (machine.tilted()) {
        const Vec2 q = machine.project(v);
        projected[i] = {q.x() * n, q.y() * n, machine.magnificationAt(v)};
        continue;
      }
      const double m = d / (d - v.z());
      projected[i] = {(v.x() * m / machine.pitch_u_mm + machine.cx_px) * n,
                      (machine.cy_px - v.y() * m / machine.pitch_v_mm) * n, m};
    }
  });
  for (size_t i = 0; i < world_vertices.size(); ++i) {
    const double z = world_vertices[i].z();
    if (!(z >= 0.0 && z < d) || !(projected[i].m >= 1.0) || !std::isfinite(projected[i].x) ||
        !std::isfinite(projected[i].y))
      fail("part vertex {} at z = {:.6g} mm is not between the detector plane (z = 0) and the "
           "source (z = {} mm): check the pose",
           i, z, d);
  }

  const int rx0 = region.x * samples, rx1 = region.right() * samples - 1;
  const int ry0 = region.y * samples, ry1 = region.bottom() * samples - 1;

  scene.triangles.resize(triangles.size());
  scene.visible.clear();
  std::vector<uint8_t> keep(triangles.size(), 0);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, triangles.size(), 2048), [&](auto range) {
    for (size_t i = range.begin(); i != range.end(); ++i) {
      TriangleSetup& t = scene.triangles[i];
      double m[3];
      for (int c = 0; c < 3; ++c) {
        const Projected& p = projected[triangles[i][static_cast<size_t>(c)]];
        t.x[c] = p.x;
        t.y[c] = p.y;
        m[c] = p.m;
      }
      // Candidate samples: centres inside the closed bounding box.
      const double x_lo = std::min({t.x[0], t.x[1], t.x[2]}), x_hi = std::max({t.x[0], t.x[1], t.x[2]});
      const double y_lo = std::min({t.y[0], t.y[1], t.y[2]}), y_hi = std::max({t.y[0], t.y[1], t.y[2]});
      if (!sampleRange(x_lo, x_hi, rx0, rx1, t.kx0, t.kx1) ||
          !sampleRange(y_lo, y_hi, ry0, ry1, t.ky0, t.ky1))
        continue;
      t.sigma = triangleOrientation(t);
      if (t.sigma == 0) continue;  // seen edge-on: covers no sample
      t.by_rows = (t.ky1 - t.ky0) <= (t.kx1 - t.kx0);
      setupEdges(t);
      // Affine magnification from the three vertices.
      const double ex1 = t.x[1] - t.x[0], ey1 = t.y[1] - t.y[0];
      const double ex2 = t.x[2] - t.x[0], ey2 = t.y[2] - t.y[0];
      const double det = ex1 * ey2 - ey1 * ex2;
      t.m0 = m[0];
      t.gx = ((m[1] - m[0]) * ey2 - (m[2] - m[0]) * ey1) / det;
      t.gy = ((m[2] - m[0]) * ex1 - (m[1] - m[0]) * ex2) / det;
      t.m_lo = std::min({m[0], m[1], m[2]});
      t.m_hi = std::max({m[0], m[1], m[2]});
      if (!std::isfinite(t.gx) || !std::isfinite(t.gy)) {
        // A sliver too thin for a gradient: its depth range is all there is.
        t.gx = t.gy = 0.0;
        t.m0 = 0.5 * (t.m_lo + t.m_hi);
      }
      keep[i] = 1;
    }
  });

  scene.kx0 = scene.ky0 = std::numeric_limits<int>::max();
  scene.kx1 = scene.ky1 = std::numeric_limits<int>::min();
  for (uint32_t i = 0; i < triangles.size(); ++i) {
    if (!keep[i]) continue;
    const TriangleSetup& t = scene.triangles[i];
    scene.kx0 = std::min(scene.kx0, t.kx0);
    scene.kx1 = std::max(scene.kx1, t.kx1);
    scene.ky0 = std::min(scene.ky0, t.ky0);
    scene.ky1 = std::max(scene.ky1, t.ky1);
    scene.visible.push_back(i);
  }
  if (scene.visible.empty()) scene.kx0 = scene.ky0 = 0, scene.kx1 = scene.ky1 = -1;
}

}  // namespace xgauge::raster
