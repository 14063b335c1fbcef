#include "xgauge/image/open_beam.h"

#include "xgauge/core/error.h"
#include "xgauge/image/blur.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

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
  for (int j = 0; j < height; ++j)
    for (int i = 0; i < width; ++i)
      out(i, j) = static_cast<float>(at((i + 0.5) * scale, (j + 0.5) * scale));
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
  Image grid(nx, ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i)
      grid(i, j) =
          static_cast<float>(at((i - pad + 0.5) * cell * scale, (j - pad + 0.5) * cell * scale));
  grid = gaussianBlur(std::move(grid), sigma_mm / (cell * pixel_mm), BlurBorder::kZero);
  Image out(width, height);
  for (int y = 0; y < height; ++y) {
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
  }
  return out;
}

OpenBeamField OpenBeamField::fit(const OpenBeamGeometry& geometry, const Image& flat) {
  // flat / cos^3 = c0 (1 + a x + b y): linear in (c0, c0 a, c0 b); every
  // step-th pixel along each axis (about 256^2 of them) is plenty.
  const int step = std::max(1, std::max(flat.width(), flat.height()) / 256);
  const OpenBeamField cosine(geometry, 0.0, 0.0);
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (int pass = 0; pass < 2; ++pass) {
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d right = Eigen::Vector3d::Zero();
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
        normal += row * row.transpose(), right += row * value, ++count;
      }
    if (count < 100)
      fail("the flat frame has only {} usable pixels for the open beam's heel", count);
    p = normal.ldlt().solve(right);
    if (!(p(0) > 0.0)) fail("the flat frame's level is not positive: {}", p(0));
  }
  return OpenBeamField(geometry, p(1) / p(0), p(2) / p(0));
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
