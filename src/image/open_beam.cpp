#include "xgauge/image/open_beam.h"

#include "xgauge/core/error.h"
#include "xgauge/image/blur.h"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

namespace xgauge {

namespace {

// cos^3 of the ray's angle at (x, y) mm from the principal point.
double cosineCubed(double distance_mm, double x, double y) {
  const double c = distance_mm / std::sqrt(distance_mm * distance_mm + x * x + y * y);
  return c * c * c;
}

}  // namespace

double OpenBeamField::at(double u, double v) const {
  if (!geometry_) return 1.0;
  const OpenBeamGeometry& g = *geometry_;
  const double x = (u - g.cx_px) * g.pitch_u_mm, y = (v - g.cy_px) * g.pitch_v_mm;
  return cosineCubed(g.source_detector_distance_mm, x, y) * (1.0 + heel_u_ * x + heel_v_ * y);
}

Image OpenBeamField::sampled(int width, int height, double scale) const {
  Image out(width, height, 1.0f);
  if (uniform()) return out;
  tbb::parallel_for(0, height, [&](int j) {
    for (int i = 0; i < width; ++i)
      out(i, j) = static_cast<float>(at((i + 0.5) * scale, (j + 0.5) * scale));
  });
  return out;
}

Image OpenBeamField::blurredOverThePlane(int width, int height, double scale,
                                         double sigma_mm) const {
  if (uniform()) return Image(width, height, 1.0f);
  // A grid of cells of `cell` image pixels (an eighth of sigma, 1 for a
  // narrow kernel: then exact), padded by 5 sigma (the blur's taps reach
  // 4.5), blurred with a zero border and read back bilinearly: O is smooth
  // over a cell (its curvature about 3 / D^2).
  const double pixel_mm = scale * geometry_->pitch_u_mm;
  const int cell = std::max(1, static_cast<int>(sigma_mm / pixel_mm / 8.0));
  const int pad = static_cast<int>(std::ceil(5.0 * sigma_mm / (cell * pixel_mm))) + 1;
  const int nx = (width + cell - 1) / cell + 2 * pad, ny = (height + cell - 1) / cell + 2 * pad;
  // Row by row on every core: each value is the field's or the grid's alone.
  Image grid(nx, ny);
  tbb::parallel_for(0, ny, [&](int j) {
    for (int i = 0; i < nx; ++i)
      grid(i, j) =
          static_cast<float>(at((i - pad + 0.5) * cell * scale, (j - pad + 0.5) * cell * scale));
  });
  grid = gaussianBlur(std::move(grid), sigma_mm / (cell * pixel_mm), BlurBorder::kZero);
  Image out(width, height);
  tbb::parallel_for(0, height, [&](int y) {
    const double gy = std::clamp((y + 0.5) / cell + pad - 0.5, 0.0, ny - 1.0);
    const int y0 = std::min(static_cast<int>(gy), ny - 2);
    const double fy = gy - y0;
    for (int x = 0; x < width; ++x) {
      const double gx = std::clamp((x + 0.5) / cell + pad - 0.5, 0.0, nx - 1.0);
      const int x0 = std::min(static_cast<int>(gx), nx - 2);
      const double fx = gx - x0;
      auto value = [&](int i, int j) { return static_cast<double>(grid(i, j)); };
      out(x, y) =
          static_cast<float>((1 - fy) * ((1 - fx) * value(x0, y0) + fx * value(x0 + 1, y0)) +
                             fy * ((1 - fx) * value(x0, y0 + 1) + fx * value(x0 + 1, y0 + 1)));
    }
  });
  return out;
}

namespace {

// The fall-off's source distance for a share s of the machine's cos^3
// curvature (its curvature near the centre, 3 / (2 D^2), scales as 1 / D^2):
// D / sqrt(s); s = 0, no fall-off, a source at 1e6 D (cos^3 within 1e-12
// of 1 over the panel).
double falloffDistance(double distance_mm, double share) {
  return share > 1e-12 ? distance_mm / std::sqrt(share) : distance_mm * 1e6;
}

struct HeelFit {
  double c0 = 0.0, a = 0.0, b = 0.0;
  double residual = std::numeric_limits<double>::infinity();  // relative, over the kept pixels
};

// flat / cos^3 = c0 (1 + a x + b y) by linear least squares in (c0, c0 a,
// c0 b) on every step-th pixel along each axis; a second pass leaves out the
// pixels more than 5 % off the first (bad pixels).
HeelFit fitHeel(const OpenBeamGeometry& geometry, const Image& flat, int step) {
  const OpenBeamField cosine(geometry, 0.0, 0.0);
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  HeelFit out;
  for (int pass = 0; pass < 2; ++pass) {
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d right = Eigen::Vector3d::Zero();
    double squares = 0.0;
    int count = 0;
    for (int v = step / 2; v < flat.height(); v += step)
      for (int u = step / 2; u < flat.width(); u += step) {
        const double value = static_cast<double>(flat(u, v));
        if (!(value > 0.0) || !std::isfinite(value)) continue;
        const double x = (u + 0.5 - geometry.cx_px) * geometry.pitch_u_mm;
        const double y = (v + 0.5 - geometry.cy_px) * geometry.pitch_v_mm;
        const double c = cosine.at(u + 0.5, v + 0.5);
        const Eigen::Vector3d row(c, c * x, c * y);
        if (pass == 1 && !(std::abs(value / row.dot(p) - 1.0) <= 0.05)) continue;
        normal += row * row.transpose(), right += row * value, squares += value * value, ++count;
      }
    if (count < 100)
      fail("the flat frame has only {} usable pixels for the open beam's heel", count);
    p = normal.ldlt().solve(right);
    if (!(p(0) > 0.0)) fail("the flat frame's level is not positive: {}", p(0));
    // |value - row p|^2 summed = squares - 2 p.right + p' N p = squares - p.right.
    out.residual = std::max(0.0, squares - p.dot(right)) / (p(0) * p(0) * count);
  }
  out.c0 = p(0), out.a = p(1) / p(0), out.b = p(2) / p(0);
  return out;
}

}  // namespace

OpenBeamField OpenBeamField::fit(const OpenBeamGeometry& geometry, const Image& flat) {
  // The flat decides how much of the fall-off the panel shows (a real panel
  // all of cos^3; a simulator may have none): the share s of the machine's
  // cos^3 curvature, on a grid of 0 .. 2 by 0.05, refined by the parabola
  // through the best point's neighbours; then the heel at that s. About
  // 256^2 pixels are plenty.
  const int step = std::max(1, std::max(flat.width(), flat.height()) / 256);
  auto fitAt = [&](double share) {
    OpenBeamGeometry g = geometry;
    g.source_detector_distance_mm = falloffDistance(geometry.source_detector_distance_mm, share);
    return std::pair{g, fitHeel(g, flat, step)};
  };
  constexpr int kShares = 41;
  constexpr double kShareStep = 0.05;
  std::array<double, kShares> residual{};
  int best = 0;
  for (int k = 0; k < kShares; ++k) {
    residual[static_cast<size_t>(k)] = fitAt(k * kShareStep).second.residual;
    if (residual[static_cast<size_t>(k)] < residual[static_cast<size_t>(best)]) best = k;
  }
  auto [chosen, heel] = fitAt(best * kShareStep);
  if (best > 0 && best + 1 < kShares) {
    const double r0 = residual[static_cast<size_t>(best - 1)],
                 r1 = residual[static_cast<size_t>(best)],
                 r2 = residual[static_cast<size_t>(best + 1)];
    const double curvature = r0 - 2.0 * r1 + r2;
    if (curvature > 0.0) {
      const double share = (best + 0.5 * (r0 - r2) / curvature) * kShareStep;
      auto [g, refined] = fitAt(share);
      if (refined.residual < heel.residual) chosen = g, heel = refined;
    }
  }
  return OpenBeamField(chosen, kHeelShare * heel.a, kHeelShare * heel.b);
}

OpenBeamField OpenBeamField::withHeelShare(double share) const {
  OpenBeamField out = *this;
  out.heel_u_ *= share / kHeelShare;
  out.heel_v_ *= share / kHeelShare;
  return out;
}

OpenBeamField OpenBeamField::fromFrames(const OpenBeamGeometry& geometry, const Image* dark,
                                        const Image* flat) {
  if (!flat) return {};
  if (!dark) return fit(geometry, *flat);
  if (dark->width() != flat->width() || dark->height() != flat->height())
    fail("the dark frame is {}x{} and the flat {}x{}", dark->width(), dark->height(), flat->width(),
         flat->height());
  Image signal = *flat;
  for (size_t i = 0; i < signal.size(); ++i) signal.pixels()[i] -= dark->pixels()[i];
  return fit(geometry, signal);
}

}  // namespace xgauge
