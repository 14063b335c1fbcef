#include "xgauge/lab/defect.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace xgauge {

namespace {

constexpr double kMinDiameterMm = 0.05;
constexpr double kMaxDiameterMm = 20.0;

// Solid angle of triangle (a, b, c) seen from the origin, signed positive when
// the origin is on the inner side of an outward (CCW from outside) triangle
// (Van Oosterom and Strackee 1983).
double solidAngle(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double la = a.norm(), lb = b.norm(), lc = c.norm();
  const double numerator = a.dot(b.cross(c));
  const double denominator = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
  return 2.0 * std::atan2(numerator, denominator);
}

// Winding number of the closed surface made of triangles [begin, end) about p:
// 1 inside, 0 outside (up to rounding).
double windingNumber(const TriangleMesh& mesh, size_t begin, size_t end, const Vec3& p) {
  double sum = 0.0;
  for (size_t t = begin; t < end; ++t) {
    const Triangle& tri = mesh.triangles[t];
    sum +=
        solidAngle(mesh.vertices[tri[0]] - p, mesh.vertices[tri[1]] - p, mesh.vertices[tri[2]] - p);
  }
  return sum / (4.0 * std::numbers::pi);
}

Vec3 vec3(const ConfigNode& node) {
  if (!node.isArray() || node.size() != 3) node.fail("expected [x, y, z], 3 numbers");
  return {node[0].number(-1e6, 1e6), node[1].number(-1e6, 1e6), node[2].number(-1e6, 1e6)};
}

}  // namespace

Vec3 closestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  // Voronoi regions of the vertices, then the edges, then the face.
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return a;
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return a + d1 / (d1 - d3) * ab;
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0)
    return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denominator = 1.0 / (va + vb + vc);
  return a + ab * (vb * denominator) + ac * (vc * denominator);
}

bool insideMesh(const TriangleMesh& mesh, const Vec3& point_mm) {
  if (!mesh.csg) return windingNumber(mesh, 0, mesh.triangles.size(), point_mm) > 0.5;
  // A CSG part: which pieces hold the point, then the tree decides.
  uint64_t inside = 0;
  size_t begin = 0;
  const auto ends = mesh.csg->pieceTriangleEnds();
  for (size_t i = 0; i < ends.size(); ++i) {
    if (windingNumber(mesh, begin, ends[i], point_mm) > 0.5) inside |= uint64_t{1} << i;
    begin = ends[i];
  }
  return mesh.csg->contains(inside);
}

double distanceToTrianglesMm(const TriangleMesh& mesh, const Vec3& point_mm) {
  double best = std::numeric_limits<double>::infinity();
  for (const Triangle& t : mesh.triangles) {
    const Vec3 q = closestPointOnTriangle(point_mm, mesh.vertices[t[0]], mesh.vertices[t[1]],
                                          mesh.vertices[t[2]]);
    best = std::min(best, (q - point_mm).norm());
  }
  return best;
}

std::optional<std::string> voidOutsidePart(const TriangleMesh& part_mesh, const Vec3& centre_mm,
                                           double radius_mm) {
  // Inside the solid and farther from every triangle than the radius: then
  // the sphere crosses no surface, so all of it is on the centre's side. For
  // a CSG part the triangles of every piece count, also those the boolean
  // combination hides: a little stricter than needed, never too lax.
  if (!insideMesh(part_mesh, centre_mm))
    return fmt::format("the centre ({:.4g}, {:.4g}, {:.4g}) mm is not inside the part",
                       centre_mm.x(), centre_mm.y(), centre_mm.z());
  const double clearance = distanceToTrianglesMm(part_mesh, centre_mm);
  if (radius_mm >= clearance)
    return fmt::format(
        "the void pokes out of the part: its radius {:.4g} mm is not smaller than the distance "
        "{:.4g} mm from its centre to the part's surface",
        radius_mm, clearance);
  return std::nullopt;
}

std::vector<Defect> readDefects(const ConfigNode& defects, const TriangleMesh& part_mesh) {
  if (!defects.isArray()) defects.fail("expected an array of defects");
  std::vector<Defect> out;
  for (size_t i = 0; i < defects.size(); ++i) {
    const ConfigNode item = defects[i];
    if (!item.isObject())
      item.fail("expected {\"type\": \"void\", \"centre_mm\", \"diameter_mm\"}");
    Defect d;
    const ConfigNode type = item.at("type");
    d.type = type.string();
    if (d.type != "void")
      type.fail(fmt::format("unknown defect type '{}'; expected 'void'", d.type));
    const ConfigNode centre = item.at("centre_mm");
    d.centre_part_mm = vec3(centre);
    d.diameter_mm = item.at("diameter_mm").number(kMinDiameterMm, kMaxDiameterMm);
    if (auto why = voidOutsidePart(part_mesh, d.centre_part_mm, d.radiusMm()))
      centre.fail(*why + " at its true dimensions");
    for (size_t j = 0; j < out.size(); ++j)
      if ((d.centre_part_mm - out[j].centre_part_mm).norm() < d.radiusMm() + out[j].radiusMm())
        item.fail(fmt::format("overlaps defect {}: voids must not overlap", j));
    out.push_back(d);
  }
  return out;
}

double segmentSphereChordMm(const Vec3& from, const Vec3& to, const Vec3& centre_mm,
                            double radius_mm) {
  const Vec3 segment = to - from;
  const double length = segment.norm();
  if (length == 0.0) return 0.0;
  const Vec3 direction = segment / length;
  // Along the line, the centre's foot at t_c; the sphere spans t_c +- h.
  // The perpendicular offset is formed as a vector (not |c - from|^2 - t_c^2),
  // which would cancel badly with the source a metre away.
  const Vec3 to_centre = centre_mm - from;
  const double t_c = to_centre.dot(direction);
  const double d2 = (to_centre - t_c * direction).squaredNorm();
  const double h2 = radius_mm * radius_mm - d2;
  if (h2 <= 0.0) return 0.0;
  const double h = std::sqrt(h2);
  const double t0 = std::max(0.0, t_c - h), t1 = std::min(length, t_c + h);
  return std::max(0.0, t1 - t0);
}

PixelRect sphereFootprint(const Machine& machine, const WorldSphere& sphere) {
  // Central projection of the sphere's bounding cube is the convex hull of its
  // projected corners, so their bounding box holds the sphere's shadow.
  double u0 = std::numeric_limits<double>::infinity(), v0 = u0, u1 = -u0, v1 = -u0;
  for (int corner = 0; corner < 8; ++corner) {
    const Vec3 offset((corner & 1) ? 1.0 : -1.0, (corner & 2) ? 1.0 : -1.0,
                      (corner & 4) ? 1.0 : -1.0);
    const Vec3 p = sphere.centre_mm + sphere.radius_mm * offset;
    if (p.z() >= machine.source_detector_distance_mm) return machine.detectorRect();
    const Vec2 q = machine.project(p);
    u0 = std::min(u0, q.x()), u1 = std::max(u1, q.x());
    v0 = std::min(v0, q.y()), v1 = std::max(v1, q.y());
  }
  // Clamp before converting, so a shadow far off the detector cannot overflow.
  const auto clampPx = [](double x) { return std::clamp(x, -1e8, 1e8); };
  const int x0 = static_cast<int>(std::floor(clampPx(u0))) - 1;
  const int y0 = static_cast<int>(std::floor(clampPx(v0))) - 1;
  const int x1 = static_cast<int>(std::ceil(clampPx(u1))) + 1;
  const int y1 = static_cast<int>(std::ceil(clampPx(v1))) + 1;
  return PixelRect{x0, y0, x1 - x0, y1 - y0}.intersect(machine.detectorRect());
}

void carveVoids(const Machine& machine, const WorldMesh& mesh, std::span<const WorldSphere> voids,
                const TransmissionTable& transmission, int samples_per_axis, Image& intensity) {
  XG_CHECK(intensity.width() == machine.columns && intensity.height() == machine.rows,
           "carveVoids needs a full-detector intensity image");
  const int n = samples_per_axis;
  const Vec3 source = machine.sourceWorld();
  for (const WorldSphere& sphere : voids) {
    const PixelRect region = sphereFootprint(machine, sphere);
    if (region.empty()) continue;

    // Path length through the part of every sample ray of the region: a
    // detector of the region's samples as pixels (pitch / n, principal point
    // moved to match), rendered with one sample each. Its pixel (k, l) is
    // sample (k % n, l % n) of pixel (region.x + k / n, region.y + l / n).
    Machine fine = machine;
    fine.columns = region.width * n;
    fine.rows = region.height * n;
    fine.pitch_u_mm = machine.pitch_u_mm / n;
    fine.pitch_v_mm = machine.pitch_v_mm / n;
    fine.cx_px = (machine.cx_px - region.x) * n;
    fine.cy_px = (machine.cy_px - region.y) * n;
    ImageT<double> path;
    renderPathLength(fine, mesh, RenderOptions{}, path);

    // Recompute the pixels that any sample ray through a void reaches, with
    // every void's chord (a pixel may see more than one).
    for (int v = region.y; v < region.bottom(); ++v) {
      for (int u = region.x; u < region.right(); ++u) {
        double value = 0.0;
        bool crossed = false;
        for (int j = 0; j < n; ++j) {
          for (int i = 0; i < n; ++i) {
            const Vec3 sample = machine.detectorPoint(u + (i + 0.5) / n, v + (j + 0.5) / n);
            double chord = 0.0;
            for (const WorldSphere& s : voids)
              chord += segmentSphereChordMm(source, sample, s.centre_mm, s.radius_mm);
            crossed = crossed || chord > 0.0;
            const double part = path((u - region.x) * n + i, (v - region.y) * n + j);
            const double left = std::max(0.0, part - chord);
            // As the renderer shades: a ray through no material is open beam.
            value += left == 0.0 ? 1.0 : transmission(left);
          }
        }
        if (crossed) intensity(u, v) = static_cast<float>(value / (n * n));
      }
    }
  }
}

}  // namespace xgauge
