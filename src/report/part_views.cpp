#include "xgauge/report/part_views.h"

#include "xgauge/core/error.h"
#include "xgauge/image/preview.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace xgauge {
namespace {

// The picture's frame: right, up and towards the viewer, unit and orthogonal.
struct Frame {
  Vec3 right, up, towards;
  Frame(const ViewDirection& view) {
    towards = view.towards_viewer.normalized();
    right = view.up.cross(towards).normalized();
    up = towards.cross(right);
  }
};

// City-block distance of each pixel to the nearest pixel of another region
// (two passes, Rosenfeld and Pfaltz), the picture's edge counting as another
// region.
std::vector<int> distanceToBorder(const std::vector<int>& region, int width, int height) {
  const int far = width + height;
  std::vector<int> d(region.size(), far);
  const auto at = [&](int x, int y) { return static_cast<size_t>(y) * width + x; };
  const auto differs = [&](int x, int y, int nx, int ny) {
    return nx < 0 || ny < 0 || nx >= width || ny >= height || region[at(nx, ny)] != region[at(x, y)];
  };
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      int& here = d[at(x, y)];
      if (differs(x, y, x - 1, y) || differs(x, y, x, y - 1) || differs(x, y, x + 1, y) ||
          differs(x, y, x, y + 1)) {
        here = 0;
        continue;
      }
      here = std::min({here, d[at(x - 1, y)] + 1, d[at(x, y - 1)] + 1});
    }
  for (int y = height - 1; y >= 0; --y)
    for (int x = width - 1; x >= 0; --x) {
      int& here = d[at(x, y)];
      if (x + 1 < width) here = std::min(here, d[at(x + 1, y)] + 1);
      if (y + 1 < height) here = std::min(here, d[at(x, y + 1)] + 1);
    }
  return d;
}

}  // namespace

std::vector<ViewDirection> standardViews() {
  return {{"top", Vec3(0, 0, 1), Vec3(0, 1, 0)},
          {"front", Vec3(0, -1, 0), Vec3(0, 0, 1)},
          {"front right, above", Vec3(1, -1, 1), Vec3(0, 0, 1)}};
}

PartPicture drawPart(std::span<const Vec3> vertices, std::span<const Triangle> triangles,
                     std::span<const int> region, const std::function<Rgb(int)>& colour,
                     const ViewDirection& view, const BoundingBox& frame_mm, int size_px) {
  XG_CHECK(region.size() == triangles.size(), "a region per triangle");
  XG_CHECK(size_px > 8, "picture of {} pixels", size_px);
  const Frame frame(view);
  // The frame box's corners seen from the view, with a margin of 4 %.
  double lo_x = std::numeric_limits<double>::infinity(), hi_x = -lo_x, lo_y = lo_x, hi_y = -lo_x;
  for (int corner = 0; corner < 8; ++corner) {
    const Vec3 p(corner & 1 ? frame_mm.max_mm.x() : frame_mm.min_mm.x(),
                 corner & 2 ? frame_mm.max_mm.y() : frame_mm.min_mm.y(),
                 corner & 4 ? frame_mm.max_mm.z() : frame_mm.min_mm.z());
    lo_x = std::min(lo_x, p.dot(frame.right)), hi_x = std::max(hi_x, p.dot(frame.right));
    lo_y = std::min(lo_y, p.dot(frame.up)), hi_y = std::max(hi_y, p.dot(frame.up));
  }
  const double span = 1.08 * std::max({hi_x - lo_x, hi_y - lo_y, 1e-6});
  const double mm_per_px = span / size_px;
  const double centre_x = 0.5 * (lo_x + hi_x), centre_y = 0.5 * (lo_y + hi_y);

  PartPicture picture;
  picture.view = view.name;
  picture.width = picture.height = size_px;
  const size_t pixels = static_cast<size_t>(size_px) * size_px;
  picture.region.assign(pixels, -1);
  std::vector<double> depth(pixels, -std::numeric_limits<double>::infinity());
  std::vector<double> light(pixels, 0.0);

  for (size_t t = 0; t < triangles.size(); ++t) {
    const Vec3& a = vertices[triangles[t][0]];
    const Vec3& b = vertices[triangles[t][1]];
    const Vec3& c = vertices[triangles[t][2]];
    const Vec3 normal = (b - a).cross(c - a);
    const double facing = normal.dot(frame.towards);
    if (!(facing > 0.0)) continue;  // a back face, or seen edge-on
    // Pixel coordinates (continuous, x right, y down) and depth.
    const auto project = [&](const Vec3& p) {
      return Vec3((p.dot(frame.right) - centre_x) / mm_per_px + 0.5 * size_px,
                  (centre_y - p.dot(frame.up)) / mm_per_px + 0.5 * size_px, p.dot(frame.towards));
    };
    const Vec3 pa = project(a), pb = project(b), pc = project(c);
    const double area = (pb.x() - pa.x()) * (pc.y() - pa.y()) - (pb.y() - pa.y()) * (pc.x() - pa.x());
    if (area == 0.0) continue;
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({pa.x(), pb.x(), pc.x()}))));
    const int x1 = std::min(size_px - 1, static_cast<int>(std::ceil(std::max({pa.x(), pb.x(), pc.x()}))));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({pa.y(), pb.y(), pc.y()}))));
    const int y1 = std::min(size_px - 1, static_cast<int>(std::ceil(std::max({pa.y(), pb.y(), pc.y()}))));
    const double shade = 0.35 + 0.65 * facing / normal.norm();
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const double px = x + 0.5, py = y + 0.5;
        // Barycentric weights from the edge functions (the sign of `area`
        // follows the picture's downward y).
        const double wa = ((pb.x() - px) * (pc.y() - py) - (pb.y() - py) * (pc.x() - px)) / area;
        const double wb = ((pc.x() - px) * (pa.y() - py) - (pc.y() - py) * (pa.x() - px)) / area;
        const double wc = 1.0 - wa - wb;
        if (wa < 0 || wb < 0 || wc < 0) continue;
        const double z = wa * pa.z() + wb * pb.z() + wc * pc.z();
        const size_t i = static_cast<size_t>(y) * size_px + x;
        if (z <= depth[i]) continue;
        depth[i] = z;
        picture.region[i] = region[t];
        light[i] = shade;
      }
  }

  // Shade, then darken the borders between regions.
  picture.rgb.assign(3 * pixels, 255);
  std::map<int, Rgb> colours;
  for (size_t i = 0; i < pixels; ++i) {
    const int r = picture.region[i];
    if (r < 0) continue;
    const auto [it, added] = colours.try_emplace(r);
    if (added) it->second = colour(r);
    for (int k = 0; k < 3; ++k)
      picture.rgb[3 * i + k] = static_cast<uint8_t>(std::lround(it->second[k] * light[i]));
  }
  for (int y = 0; y < size_px; ++y)
    for (int x = 0; x < size_px; ++x) {
      const size_t i = static_cast<size_t>(y) * size_px + x;
      const bool border = (x + 1 < size_px && picture.region[i + 1] != picture.region[i]) ||
                          (y + 1 < size_px && picture.region[i + size_px] != picture.region[i]);
      if (!border) continue;
      for (int k = 0; k < 3; ++k) picture.rgb[3 * i + k] = 40;
    }

  // Each region's label where it is widest.
  const std::vector<int> distance = distanceToBorder(picture.region, size_px, size_px);
  std::map<int, PartPicture::Label> best;
  for (int y = 0; y < size_px; ++y)
    for (int x = 0; x < size_px; ++x) {
      const size_t i = static_cast<size_t>(y) * size_px + x;
      const int r = picture.region[i];
      if (r < 0) continue;
      auto [it, added] = best.try_emplace(r, PartPicture::Label{r, x, y, 0});
      ++it->second.pixels;
      const size_t j = static_cast<size_t>(it->second.y) * size_px + it->second.x;
      if (distance[i] > distance[j]) it->second.x = x, it->second.y = y;
    }
  for (const auto& [r, label] : best) picture.labels.push_back(label);
  return picture;
}

namespace {

bool isBorder(const PartPicture& p, int x, int y) {
  const size_t i = static_cast<size_t>(y) * p.width + x;
  return (x + 1 < p.width && p.region[i + 1] != p.region[i]) ||
         (y + 1 < p.height && p.region[i + p.width] != p.region[i]);
}

}  // namespace

void overlayOutline(PartPicture& picture, const PartPicture& other, const PartPicture* unchanged,
                    const Rgb& colour) {
  XG_CHECK(picture.width == other.width && picture.height == other.height, "pictures differ");
  for (int y = 0; y < other.height; ++y)
    for (int x = 0; x < other.width; ++x) {
      if (!isBorder(other, x, y) || (unchanged && isBorder(*unchanged, x, y))) continue;
      const size_t i = static_cast<size_t>(y) * other.width + x;
      for (int k = 0; k < 3; ++k) picture.rgb[3 * i + k] = colour[k];
    }
}

std::string encodePicture(const PartPicture& picture) {
  return encodePng(picture.width, picture.height, 3, picture.rgb);
}

}  // namespace xgauge
